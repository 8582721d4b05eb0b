"""A library store of a 32 KB blob a bounded step per control tick (store_lib_begin_put and
store_lib_step, firmware/app/store_lib.c) in the CM-530's library layout, against the flash
register model: each step does no more flash work than a step of the committed table's
save (tests/firmware/test_store_incremental.py holds the bounds), and a power cut during
any step leaves every other slot as it was and the slot being written old or new."""

from __future__ import annotations

import random

import pytest
from firmware_support import board_value
from flash_model import BASE, PAGE, PowerCutModel
from library_flash import (
    EMPTY,
    ENTRY_BYTES,
    FLASH,
    MODELS,
    NAME_MAX,
    OK,
    PROGRAM,
    SLOTS,
    TABLE,
    blob,
    build,
    contents,
)
from test_store_incremental import (
    ERASE_MS,
    HALFWORDS,
    PROGRAM_MS,
    TICK_MS,
    CountingModel,
    step_cut,
)

CAPACITY = board_value("cm530", "BOARD_TABLE_CAPACITY")
DIR_SIZE = board_value("cm530", "BOARD_LIB_DIR_SIZE")
AREA = board_value("cm530", "BOARD_LIB_AREA_SIZE")
AREAS = SLOTS + 1
SIZE = DIR_SIZE + AREAS * AREA
assert board_value("cm530", "BOARD_FLASH_PAGE_SIZE") == PAGE
HEADER = 16  # STORE_SLOTS_HEADER_BYTES: the directory record's

NEIGHBOURS = {
    0: (TABLE, b"first", blob(700, 10)),
    4: (PROGRAM, b"middle", blob(333, 11)),
    7: (TABLE, b"last", blob(CAPACITY, 12)),
}
NEW = (TABLE, b"big walk", blob(CAPACITY, 13))


@pytest.fixture(scope="module")
def hal(tmp_path_factory):
    return build(tmp_path_factory.mktemp("hal_library_steps"))


def layout(hal):
    """The CM-530's library (board.h's sizes), at the model's flash."""
    s = hal.ffi.new("store_lib_t *")
    s.dir.base, s.dir.size, s.dir.page_size = BASE, DIR_SIZE, PAGE
    s.areas.base, s.areas.size, s.areas.page_size = BASE + DIR_SIZE, AREAS * AREA, PAGE
    s.area_size = AREA
    return s


def begin_put(hal, job, lib, slot: int, kind: int, name: bytes, data) -> int:
    padded = hal.ffi.new("uint8_t[]", name.ljust(NAME_MAX, b"\0"))
    return hal.lib.store_lib_begin_put(job, lib, slot, kind, padded, data, len(data))


@pytest.fixture(scope="module")
def neighbours(hal) -> bytes:
    """Flash holding NEIGHBOURS, stored all at once, the rest never erased."""
    lib = layout(hal)
    with MODELS.use(PowerCutModel(b"\xa5" * SIZE)) as m:
        for slot, (kind, name, data) in NEIGHBOURS.items():
            padded = hal.ffi.from_buffer(name.ljust(NAME_MAX, b"\0"))
            assert hal.lib.store_lib_put(lib, slot, kind, padded, data, len(data)) == OK
        return bytes(m.mem)


@pytest.fixture(scope="module")
def run(hal, neighbours):
    """NEW stored into slot 4 a step at a time: before each step the flash and the job as
    they were, each step's page erases and half-word programs, and the progress after."""
    lib = layout(hal)
    data = hal.ffi.from_buffer(NEW[2])
    job = hal.ffi.new("store_lib_job_t *")
    steps = []
    with MODELS.use(CountingModel(neighbours)) as m:
        assert begin_put(hal, job, lib, 4, NEW[0], NEW[1], data) == OK
        assert hal.lib.store_lib_progress(job) == 0
        more = True
        while more:
            before = (bytes(m.mem), bytes(hal.ffi.buffer(job)))
            erases, programs = m.erases, m.programs
            more = hal.lib.store_lib_step(job, HALFWORDS)
            progress = hal.lib.store_lib_progress(job)
            steps.append((*before, m.erases - erases, m.programs - programs, progress))
        assert m.unexpected == []
        return {
            "lib": lib,
            "data": data,
            "steps": steps,
            "status": job.status,
            "after": bytes(m.mem),
        }


def test_a_32_kb_store_completes_a_bounded_step_at_a_time(hal, run, neighbours):
    assert run["status"] == OK
    before = contents(hal, neighbours, run["lib"])
    assert contents(hal, run["after"], run["lib"]) == [*before[:4], NEW, *before[5:]]
    work = [(erases, programs) for *_, erases, programs, _ in run["steps"]]
    # the blob's pages, then one page of the directory's slot
    assert sum(e for e, _ in work) == CAPACITY // PAGE + -(-(HEADER + SLOTS * ENTRY_BYTES) // PAGE)
    for erases, programs in work:
        assert (erases, programs) == (1, 0) or (erases == 0 and programs <= max(HALFWORDS, 6))
    assert max(e * ERASE_MS + p * PROGRAM_MS for e, p in work) <= ERASE_MS
    seconds = sum(max(TICK_MS, e * ERASE_MS + p * PROGRAM_MS) for e, p in work) / 1000
    assert seconds < 5.0, f"a 32 KB library store takes {seconds:.1f} s of ticks"
    progress = [p for *_, p in run["steps"]]
    assert progress == sorted(progress) and progress[-1] == 100
    assert len(set(progress)) > 50  # it moves along, not 0 then 100


def test_a_cut_during_any_step_keeps_the_others_and_the_old_or_new_slot(hal, run, neighbours):
    """For every step, the power fails at one of its flash operations (chosen at random,
    torn): a fresh start finds the other slots as they were, and slot 4 as it was until
    the directory's magic is programmed."""
    lib = run["lib"]
    before = contents(hal, neighbours, lib)
    assert before[4] == NEIGHBOURS[4]
    job = hal.ffi.new("store_lib_job_t *")
    rng = random.Random(4)
    last = len(run["steps"]) - 1
    for k, recorded in enumerate(run["steps"]):
        after = step_cut(MODELS, hal.ffi, hal.lib.store_lib_step, job, recorded, rng, k)
        found = contents(hal, after, lib)
        magic = k >= last - 1  # the directory's magic, and its read-back
        assert found in (before, [*before[:4], NEW, *before[5:]] if magic else before), (
            f"cut in step {k}"
        )


def test_a_blob_that_changes_under_the_store_changes_nothing(hal, neighbours):
    """As if the staged blob were overwritten while it is stored (the controller refuses
    that, lib_regs.h): the directory is never written, the job ends in FLASH."""
    lib = layout(hal)
    new = bytearray(NEW[2])
    job = hal.ffi.new("store_lib_job_t *")
    with MODELS.use(PowerCutModel(neighbours)) as m:
        assert begin_put(hal, job, lib, 2, TABLE, b"torn", hal.ffi.from_buffer(new)) == OK
        for _ in range(40):
            assert hal.lib.store_lib_step(job, HALFWORDS)
        new[-1] ^= 0xFF  # not programmed yet
        while hal.lib.store_lib_step(job, HALFWORDS):
            pass
        assert job.status == FLASH
        after = bytes(m.mem)
    assert contents(hal, after, lib) == contents(hal, neighbours, lib)


def test_a_delete_is_a_few_bounded_steps(hal, neighbours):
    lib = layout(hal)
    job = hal.ffi.new("store_lib_job_t *")
    with MODELS.use(CountingModel(neighbours)) as m:
        assert hal.lib.store_lib_begin_delete(job, lib, 7) == OK
        steps = 0
        while True:
            erases, programs = m.erases, m.programs
            more = hal.lib.store_lib_step(job, HALFWORDS)
            steps += 1
            assert (m.erases - erases, m.programs - programs) == (1, 0) or (
                m.erases == erases and m.programs - programs <= max(HALFWORDS, 6)
            )
            if not more:
                break
        assert job.status == OK and m.unexpected == []
        after = bytes(m.mem)
    assert steps < 12
    assert contents(hal, after, lib)[7] == EMPTY
    # deleting an empty slot is a job with no steps
    with MODELS.use(CountingModel(after)) as m:
        assert hal.lib.store_lib_begin_delete(job, lib, 7) == OK
        assert not hal.lib.store_lib_step(job, HALFWORDS) and job.status == OK
        assert m.erases == m.programs == 0
