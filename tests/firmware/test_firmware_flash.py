"""The flash-programming driver (firmware/hal/hal_flash.c) and the two-slot table store on
it (firmware/app/store_slots.c), compiled for the host and run against the register model
of the STM32F1 flash controller in tests/support/flash_model.py: QEMU has no flash
controller, so this is where their logic is proven."""

from __future__ import annotations

import random
import zlib

import pytest
from firmware_support import RegisterModels, hal_fixture
from flash_model import (
    BASE,
    CR_PER,
    CR_PG,
    PAGE,
    PAGES,
    SR_PGERR,
    SR_WRPRTERR,
    FlashModel,
    PowerCutModel,
    QemuLikeModel,
)
from hypothesis import given
from hypothesis import strategies as st

BUSY_POLLS = 500  # the driver's poll bound for these tests (the firmware's is 2 000 000)

OK, RANGE, LOCKED, TIMEOUT, PROGRAM, WRPROT, VERIFY = range(7)

CDEF = """
typedef struct { uint32_t base; uint32_t size; uint32_t page_size; } hal_flash_region_t;
int hal_flash_erase(const hal_flash_region_t *r, uint32_t offset, uint32_t len);
int hal_flash_write(const hal_flash_region_t *r, uint32_t offset, const uint8_t *data,
                    uint32_t len);
typedef struct { uint32_t offset; uint32_t len; uint32_t seq; } store_record_t;
uint32_t store_slots_capacity(const hal_flash_region_t *r);
bool store_slots_newest(const hal_flash_region_t *r, store_record_t *out);
int store_slots_save(const hal_flash_region_t *r, const uint8_t *data, uint32_t len);
typedef struct {
    const hal_flash_region_t *r;
    const uint8_t *data;
    uint32_t len;
    uint32_t slot;
    uint32_t seq;
    uint32_t done;
    uint32_t expect;
    uint32_t crc;
    uint8_t phase;
    uint8_t status;
    uint8_t bare;
} store_slots_job_t;
int store_slots_begin(store_slots_job_t *job, const hal_flash_region_t *r,
                      const uint8_t *data, uint32_t len);
bool store_slots_step(store_slots_job_t *job, uint32_t halfwords);
"""


MODELS = RegisterModels()


hal = hal_fixture(
    "_hal_flash_host",
    ["hal_flash.c", "../app/store_slots.c", "../core/crc32.c"],
    ["hal_flash.h", "store_slots.h"],
    CDEF,
    MODELS,
    defines=[("HAL_FLASH_BUSY_POLLS", str(BUSY_POLLS))],
    include_dirs=["app", "core"],
    io16=True,
)


@pytest.fixture
def model():
    with MODELS.use(FlashModel()) as m:
        yield m
    assert m.unexpected == []


def region(hal, base=BASE, size=PAGE * PAGES, page=PAGE):
    r = hal.ffi.new("hal_flash_region_t *")
    r.base, r.size, r.page_size = base, size, page
    return r


def write(hal, r, offset, data: bytes) -> int:
    return hal.lib.hal_flash_write(r, offset, hal.ffi.from_buffer(data), len(data))


def test_erase_then_write_reads_back(hal, model):
    r = region(hal)
    data = bytes(range(200))
    assert hal.lib.hal_flash_erase(r, 0, len(data)) == OK
    assert write(hal, r, 0, data) == OK
    assert model.mem[: len(data)] == data
    assert model.mem[len(data) : PAGE] == b"\xff" * (PAGE - len(data))
    assert model.locked() and not model.cr & (CR_PG | CR_PER)


def test_erase_touches_exactly_the_overlapping_pages(hal, model):
    r = region(hal)
    assert hal.lib.hal_flash_erase(r, PAGE - 10, 20) == OK  # straddles pages 0 and 1
    assert model.mem[: 2 * PAGE] == b"\xff" * (2 * PAGE)
    assert model.mem[2 * PAGE :] == b"\xa5" * (2 * PAGE)
    assert model.locked()


def test_odd_length_pads_with_erased_byte(hal, model):
    r = region(hal)
    assert hal.lib.hal_flash_erase(r, 0, PAGE) == OK
    assert write(hal, r, 4, b"\x01\x02\x03") == OK
    assert model.mem[:8] == b"\xff\xff\xff\xff\x01\x02\x03\xff"


def test_programming_unerased_flash_fails_and_changes_nothing(hal, model):
    r = region(hal)
    assert write(hal, r, 0, b"\x12\x34") == PROGRAM
    assert model.mem[:2] == b"\xa5\xa5"
    assert model.locked() and not model.cr & CR_PG
    assert model.sr & (SR_PGERR | SR_WRPRTERR) == 0  # flags cleared for the next caller


def test_write_protected_page_is_reported(hal, model):
    r = region(hal)
    model.protected_pages.add(1)
    assert hal.lib.hal_flash_erase(r, 0, 2 * PAGE) == WRPROT
    assert model.mem[:PAGE] == b"\xff" * PAGE  # page 0 was erased before the failure
    assert model.mem[PAGE : 2 * PAGE] == b"\xa5" * PAGE
    assert model.locked()


def test_stuck_busy_times_out_instead_of_hanging(hal, model):
    r = region(hal)
    model.stuck_busy = True
    assert hal.lib.hal_flash_erase(r, 0, PAGE) == TIMEOUT
    assert model.locked()


def test_a_cell_that_does_not_take_the_value_fails_verification(hal, model):
    r = region(hal)
    model.weak_cells.add(6)
    assert hal.lib.hal_flash_erase(r, 0, PAGE) == OK
    assert write(hal, r, 0, bytes(16)) == VERIFY


def test_refused_unlock_is_reported(hal, model):
    r = region(hal)
    model.key_fault = True
    assert hal.lib.hal_flash_erase(r, 0, PAGE) == LOCKED
    assert model.mem == b"\xa5" * len(model.mem)


def test_stale_error_flags_are_not_blamed_on_the_next_operation(hal, model):
    r = region(hal)
    model.sr = SR_PGERR | SR_WRPRTERR
    assert hal.lib.hal_flash_erase(r, 0, PAGE) == OK
    assert write(hal, r, 0, b"ok") == OK


@pytest.mark.parametrize(
    ("offset", "length", "reg"),
    [
        (PAGE * PAGES, 2, {}),  # past the end
        (PAGE * PAGES - 2, 4, {}),  # runs past the end
        (PAGE * PAGES - 1, 1, {}),  # odd offset
        (0, 2, {"base": BASE + 2}),  # region not page-aligned
        (0, 2, {"size": PAGE + 2}),  # region size not whole pages
        (0, 2, {"page": 3000}),  # page size not a power of two
    ],
)
def test_out_of_range_requests_touch_nothing(hal, model, offset, length, reg):
    r = region(hal, **reg)
    assert write(hal, r, offset, b"\x00" * length) == RANGE
    assert hal.lib.hal_flash_erase(r, offset + (offset & 1), length + 2) == RANGE
    assert model.writes == 0


def test_odd_length_whose_pad_byte_leaves_the_region_is_refused(hal, model):
    r = region(hal)
    assert write(hal, r, PAGE * PAGES - 2, b"\x00\x01\x02") == RANGE
    assert write(hal, r, PAGE * PAGES - 2, b"\x00") == PROGRAM  # inside; just not erased


def test_under_qemu_every_write_ends_in_a_verify_error(hal):
    with MODELS.use(QemuLikeModel()):
        r = region(hal)
        assert hal.lib.hal_flash_erase(r, 0, PAGE) == VERIFY  # ROM still holds 0xA5
        assert write(hal, r, 0, b"\x00\x01") == VERIFY


@given(
    chunks=st.lists(
        st.tuples(st.integers(0, 300), st.binary(min_size=1, max_size=64)),
        min_size=1,
        max_size=6,
    )
)
def test_any_writes_into_erased_flash_read_back(hal, chunks):
    with MODELS.use(FlashModel(busy_reads=1)) as m:
        r = region(hal)
        assert hal.lib.hal_flash_erase(r, 0, PAGE * PAGES) == OK
        expected = bytearray(b"\xff" * (PAGE * PAGES))
        offset = 0
        for gap, data in chunks:  # one after another, never overlapping
            offset += 2 * gap
            padded = data + (b"\xff" if len(data) & 1 else b"")
            if offset + len(padded) > PAGE * PAGES:
                break
            assert write(hal, r, offset, data) == OK
            expected[offset : offset + len(padded)] = padded
            offset += len(padded)
        assert m.mem == expected
        assert m.locked()
        assert m.unexpected == []


# ---- the two-slot table store (store_slots.c) on the driver --------------------------------


def stored(hal, mem: bytes) -> tuple[bytes, int] | None:
    """What a fresh start finds in flash holding ``mem`` (a store of all of it): (table,
    sequence) or None."""
    with MODELS.use(PowerCutModel(mem)) as m:
        rec = hal.ffi.new("store_record_t *")
        if not hal.lib.store_slots_newest(region(hal, size=len(mem)), rec):
            return None
        assert m.unexpected == []
        return bytes(m.mem[rec.offset : rec.offset + rec.len]), rec.seq


def save(hal, mem: bytes, table: bytes, cut_at: int | None = None, seed: int = 0):
    """Save ``table`` into flash holding ``mem``; returns (status, flash after, ops)."""
    with MODELS.use(PowerCutModel(mem, cut_at, seed)) as m:
        status = hal.lib.store_slots_save(region(hal), hal.ffi.from_buffer(table), len(table))
        assert m.unexpected == []
        return status, bytes(m.mem), m.ops


def tables(n: int, size: int = 60) -> list[bytes]:
    rng = random.Random(size)
    return [bytes(rng.getrandbits(8) for _ in range(size)) for _ in range(n)]


def test_store_keeps_the_newest_record_and_alternates_slots(hal):
    mem = b"\xa5" * (PAGE * PAGES)
    assert stored(hal, mem) is None
    slots = set()
    for seq, table in enumerate(tables(4), start=1):
        status, mem, _ = save(hal, mem, table)
        assert status == OK
        assert stored(hal, mem) == (table, seq)
        slots.add(mem.index(table) // (PAGE * PAGES // 2))
    assert slots == {0, 1}


def test_store_refuses_what_does_not_fit(hal):
    with MODELS.use(PowerCutModel()) as m:
        r = region(hal)
        cap = hal.lib.store_slots_capacity(r)
        assert cap == PAGE * PAGES // 2 - 16
        big = bytes(cap + 1)
        assert hal.lib.store_slots_save(r, hal.ffi.from_buffer(big), len(big)) == RANGE
        assert m.writes == 0


@pytest.mark.parametrize("earlier", [0, 1, 2], ids=["first-save", "second", "third"])
def test_a_power_cut_at_every_step_of_a_save_leaves_the_old_or_the_new_table(hal, earlier):
    """``earlier`` saves complete first; the next is cut at each of its flash operations
    in turn (torn), and a fresh start must find exactly the previous table, or the new
    one only once the save had finished programming it."""
    old, new = tables(earlier + 1)[:earlier], tables(earlier + 1)[earlier]
    mem = b"\xa5" * (PAGE * PAGES)
    for table in old:
        mem = save(hal, mem, table)[1]
    before = stored(hal, mem)
    status, done, steps = save(hal, mem, new)
    assert status == OK and stored(hal, done) == (new, earlier + 1)
    assert steps > len(new) // 2  # every half-word of the table is a step
    outcomes = []
    for cut in range(steps):
        for seed in range(2):
            status, after, _ = save(hal, mem, new, cut_at=cut, seed=seed)
            assert status != OK, f"a save cut at step {cut} reported success"
            found = stored(hal, after)
            assert found in (before, (new, earlier + 1)), f"cut at step {cut}: {found}"
            outcomes.append(found == before)
            # and the next save after the cut works, and wins
            status, again, _ = save(hal, after, new[::-1])
            assert status == OK and stored(hal, again)[0] == new[::-1]
    assert all(outcomes), "only the magic, written last, may make the new record count"


def test_sequence_numbers_wrap(hal):
    first, second = tables(2)
    mem = bytearray(save(hal, b"\xa5" * (PAGE * PAGES), first)[1])
    slot = mem.index(first) - 16
    mem[slot + 4 : slot + 8] = b"\xff\xff\xff\xff"  # as if 2^32 - 1 saves had happened
    assert stored(hal, bytes(mem)) == (first, 0xFFFFFFFF)
    status, after, _ = save(hal, bytes(mem), second)
    assert status == OK and stored(hal, after) == (second, 0)


def test_a_record_with_a_damaged_table_is_not_loaded(hal):
    first, second = tables(2)
    mem = save(hal, b"\xa5" * (PAGE * PAGES), first)[1]
    mem = bytearray(save(hal, mem, second)[1])
    at = mem.index(second)
    assert zlib.crc32(second) == int.from_bytes(mem[at - 4 : at], "little")
    mem[at + 7] ^= 0x10
    assert stored(hal, bytes(mem)) == (first, 1)
