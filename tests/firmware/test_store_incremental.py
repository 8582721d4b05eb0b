"""The incremental table save (store_slots_begin/step, firmware/app/store_slots.c) of a
32 KB table into the CM-530's table store, against the register model of the STM32F1
flash controller (tests/support/flash_model.py): each control tick's step does a bounded
amount of flash work, and a power cut during any step leaves the previous table."""

from __future__ import annotations

import random
import re

import pytest
import test_firmware_flash as flash_tests
from firmware_support import FIRMWARE, board_value
from flash_model import PAGE, PowerCutModel

HALFWORDS = int(
    re.search(r"#define STORE_SAVE_HALFWORDS (\d+)U", (FIRMWARE / "app" / "store.c").read_text())[1]
)
# Flash timings of the F103 (datasheet, tERASE and tPROG maxima): a step's stall.
ERASE_MS, PROGRAM_MS = 40.0, 0.070
TICK_MS = 10.0
OK, RANGE, VERIFY = 0, 1, 6
# The flash driver and store built for the host, as test_firmware_flash.py builds them.
hal = flash_tests.hal
MODELS = flash_tests.MODELS
stored = flash_tests.stored

CAPACITY = board_value("cm530", "BOARD_TABLE_CAPACITY")
STORE_SIZE = board_value("cm530", "BOARD_STORE_SIZE")
assert board_value("cm530", "BOARD_FLASH_PAGE_SIZE") == PAGE


class CountingModel(PowerCutModel):
    """A PowerCutModel that also counts page erases and half-word programs."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.erases = 0
        self.programs = 0

    def erase(self, addr: int) -> None:
        self.erases += 1
        super().erase(addr)

    def write16(self, addr: int, value: int) -> None:
        self.programs += 1
        super().write16(addr, value)


def step_cut(models, ffi, step, job, recorded: tuple, rng: random.Random, seed: int) -> bytes:
    """Replay one recorded step (flash and job bytes before it, its erases and programs)
    with the power failing at one of its flash operations, chosen with rng and torn:
    the flash after."""
    mem, job_bytes, erases, programs = recorded[:4]
    count = erases + programs
    cut = rng.randrange(count) if count else None
    with models.use(PowerCutModel(mem, cut_at=cut, seed=seed)) as m:
        ffi.buffer(job)[:] = job_bytes
        step(job, HALFWORDS)
        assert m.unexpected == []
        return bytes(m.mem)


def region(hal):
    """The CM-530's table store, as board.h sizes it (at the model's flash)."""
    return flash_tests.region(hal, size=STORE_SIZE)


def table(seed: int) -> bytes:
    rng = random.Random(seed)
    return bytes(rng.getrandbits(8) for _ in range(CAPACITY))


@pytest.fixture(scope="module")
def previous(hal) -> bytes:
    """Flash holding one saved 32 KB table (sequence 1), the rest never erased."""
    old = table(1)
    with MODELS.use(PowerCutModel(b"\xa5" * STORE_SIZE)) as m:
        r = region(hal)
        assert hal.lib.store_slots_capacity(r) >= CAPACITY
        assert hal.lib.store_slots_save(r, hal.ffi.from_buffer(old), len(old)) == OK
        return bytes(m.mem)


@pytest.fixture(scope="module")
def run(hal, previous):
    """A save of a second 32 KB table, a step at a time: before each step the flash and
    the job as they were, and each step's page erases and half-word programs."""
    new = table(2)
    data = hal.ffi.from_buffer(new)
    r = region(hal)
    job = hal.ffi.new("store_slots_job_t *")
    steps = []
    with MODELS.use(CountingModel(previous)) as m:
        assert hal.lib.store_slots_begin(job, r, data, len(new)) == OK
        more = True
        while more:
            before = (bytes(m.mem), bytes(hal.ffi.buffer(job)))
            erases, programs = m.erases, m.programs
            more = hal.lib.store_slots_step(job, HALFWORDS)
            steps.append((*before, m.erases - erases, m.programs - programs))
        assert m.unexpected == []
        return {
            "new": new,
            "data": data,
            "r": r,
            "steps": steps,
            "status": job.status,
            "after": bytes(m.mem),
        }


def test_a_32_kb_save_completes_a_bounded_step_at_a_time(hal, run):
    assert run["status"] == OK
    assert stored(hal, run["after"]) == (run["new"], 2)
    work = [(erases, programs) for *_, erases, programs in run["steps"]]
    assert sum(e for e, _ in work) == -(-(16 + CAPACITY) // PAGE)  # only the pages it needs
    for erases, programs in work:
        # one page erase, or a bounded run of half-words (the header's 6 at most above it)
        assert (erases, programs) == (1, 0) or (erases == 0 and programs <= max(HALFWORDS, 6))
    stall = max(e * ERASE_MS + p * PROGRAM_MS for e, p in work)
    assert stall <= ERASE_MS < 0.1 * 500  # the watchdog (BOARD_WATCHDOG_MS) is far away
    programming = max(p * PROGRAM_MS for _, p in work)
    assert programming < 0.5 * TICK_MS  # a programming tick leaves the loop most of the tick
    seconds = sum(max(TICK_MS, e * ERASE_MS + p * PROGRAM_MS) for e, p in work) / 1000
    assert seconds < 5.0, f"a 32 KB save takes {seconds:.1f} s of ticks"


def test_a_cut_during_any_step_leaves_the_previous_table(hal, previous, run):
    """For every step, the power fails at one of its flash operations (chosen at random,
    torn): a fresh start finds the previous table, until the magic's last half-word."""
    before = stored(hal, previous)
    assert before == (table(1), 1)
    job = hal.ffi.new("store_slots_job_t *")
    rng = random.Random(13)
    last = len(run["steps"]) - 1
    for k, recorded in enumerate(run["steps"]):
        after = step_cut(MODELS, hal.ffi, hal.lib.store_slots_step, job, recorded, rng, k)
        found = stored(hal, after)
        magic = k >= last - 1  # the magic's step, and the read-back after it
        assert found == before or (magic and found == (run["new"], 2)), f"cut in step {k}"


def test_a_table_that_changes_under_the_save_never_gets_a_magic(hal, previous):
    new = bytearray(table(3))
    data = hal.ffi.from_buffer(new)
    job = hal.ffi.new("store_slots_job_t *")
    with MODELS.use(PowerCutModel(previous)) as m:
        assert hal.lib.store_slots_begin(job, region(hal), data, len(new)) == OK
        for _ in range(40):  # finding the slot, erasing, then some programming
            assert hal.lib.store_slots_step(job, HALFWORDS)
        new[-1] ^= 0xFF  # e.g. another table made active meanwhile
        while hal.lib.store_slots_step(job, HALFWORDS):
            pass
        assert job.status == VERIFY
        after = bytes(m.mem)
    assert stored(hal, after) == (table(1), 1)


def test_a_save_that_does_not_fit_is_refused_before_any_flash_work(hal):
    big = bytes(STORE_SIZE // 2)
    job = hal.ffi.new("store_slots_job_t *")
    with MODELS.use(PowerCutModel(b"\xa5" * STORE_SIZE)) as m:
        r = region(hal)
        assert hal.lib.store_slots_begin(job, r, hal.ffi.from_buffer(big), len(big)) == RANGE
        assert not hal.lib.store_slots_step(job, HALFWORDS)
        assert m.writes == 0
