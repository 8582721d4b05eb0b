"""The gait library's flash store (firmware/app/store_lib.c), compiled for the host with the
flash driver and store_slots under it, run against the flash register model: named slots
that a store or a delete replaces atomically, with a power cut at any step leaving every
other slot intact and the slot being written either as it was or as it was to become."""

from __future__ import annotations

import random

import pytest
from firmware_support import RegisterModels, hal_fixture
from flash_model import BASE, PAGE, PowerCutModel

SLOTS, NAME_MAX = 8, 16
DIR_PAGES, AREA_PAGES = 2, 1
AREAS = SLOTS + 1
SIZE = PAGE * (DIR_PAGES + AREAS * AREA_PAGES)
OK, EMPTY, DAMAGED, BAD_SLOT, BAD_BLOB, FLASH = range(6)
TABLE, PROGRAM = 1, 2

CDEF = """
typedef struct { uint32_t base; uint32_t size; uint32_t page_size; } hal_flash_region_t;
typedef struct { hal_flash_region_t dir; hal_flash_region_t areas; uint32_t area_size; }
    store_lib_t;
typedef struct { uint8_t kind; uint16_t len; uint32_t crc; uint32_t addr; uint8_t name[16]; }
    store_lib_entry_t;
uint32_t store_lib_capacity(const store_lib_t *lib);
int store_lib_entry(const store_lib_t *lib, uint8_t slot, store_lib_entry_t *out);
int store_lib_put(const store_lib_t *lib, uint8_t slot, uint8_t kind, const uint8_t *name,
                  const uint8_t *data, uint32_t len);
int store_lib_delete(const store_lib_t *lib, uint8_t slot);
"""

MODELS = RegisterModels()

hal = hal_fixture(
    "_hal_library_host",
    ["hal_flash.c", "../app/store_slots.c", "../app/store_lib.c", "../core/crc32.c"],
    ["hal_flash.h", "store_lib.h"],
    CDEF,
    MODELS,
    defines=[("HAL_FLASH_BUSY_POLLS", "500")],
    include_dirs=["app", "core"],
    io16=True,
)

ERASED_LONG_AGO = b"\xa5" * SIZE  # never-erased flash: no directory, no data


def lib(hal):
    s = hal.ffi.new("store_lib_t *")
    s.dir.base, s.dir.size, s.dir.page_size = BASE, DIR_PAGES * PAGE, PAGE
    area = AREA_PAGES * PAGE
    s.areas.base, s.areas.size, s.areas.page_size = BASE + DIR_PAGES * PAGE, AREAS * area, PAGE
    s.area_size = area
    return s


Slot = tuple[int, bytes, bytes]  # kind, name, data


def contents(hal, mem: bytes) -> list[Slot | int]:
    """What a fresh start finds in each slot: (kind, name, data), or the status if none."""
    out: list[Slot | int] = []
    with MODELS.use(PowerCutModel(mem)) as m:
        e = hal.ffi.new("store_lib_entry_t *")
        for slot in range(SLOTS):
            st = hal.lib.store_lib_entry(lib(hal), slot, e)
            if st != OK:
                out.append(st)
                continue
            at = e.addr - BASE
            name = bytes(hal.ffi.buffer(e.name)).rstrip(b"\0")
            out.append((e.kind, name, bytes(m.mem[at : at + e.len])))
        assert m.unexpected == []
    return out


def run(hal, mem: bytes, op, cut_at: int | None = None, seed: int = 0):
    """Run ``op(lib)`` on flash holding ``mem``: (status, flash after, flash operations)."""
    with MODELS.use(PowerCutModel(mem, cut_at, seed)) as m:
        status = op(lib(hal))
        assert m.unexpected == []
        return status, bytes(m.mem), m.ops


def put(hal, slot: int, kind: int, name: bytes, data: bytes):
    padded = name.ljust(NAME_MAX, b"\0")
    return lambda s: hal.lib.store_lib_put(
        s, slot, kind, hal.ffi.from_buffer(padded), hal.ffi.from_buffer(data), len(data)
    )


def delete(hal, slot: int):
    return lambda s: hal.lib.store_lib_delete(s, slot)


def blob(n: int, seed: int) -> bytes:
    rng = random.Random(seed)
    return bytes(rng.getrandbits(8) for _ in range(n))


def filled(hal, slots: dict[int, Slot]) -> bytes:
    mem = ERASED_LONG_AGO
    for slot, (kind, name, data) in slots.items():
        status, mem, _ = run(hal, mem, put(hal, slot, kind, name, data))
        assert status == OK
    return mem


def test_slots_store_list_replace_and_delete(hal):
    assert contents(hal, ERASED_LONG_AGO) == [EMPTY] * SLOTS
    walk = (TABLE, b"serpentine", blob(300, 1))
    spin = (PROGRAM, b"x" * NAME_MAX, blob(PAGE, 2))  # a full area, a full-length name
    mem = filled(hal, {0: walk, 7: spin})
    assert contents(hal, mem) == [walk, *[EMPTY] * 6, spin]
    other = (TABLE, b"sidewind", blob(51, 3))  # odd length
    status, mem, _ = run(hal, mem, put(hal, 0, *other))
    assert status == OK
    assert contents(hal, mem) == [other, *[EMPTY] * 6, spin]
    status, mem, _ = run(hal, mem, delete(hal, 7))
    assert status == OK and contents(hal, mem) == [other, *[EMPTY] * 7]
    status, again, ops = run(hal, mem, delete(hal, 7))
    assert status == OK and again == mem and ops == 0  # deleting nothing writes nothing


def test_every_slot_at_once_and_rewriting_wanders_over_the_areas(hal):
    slots = {s: (TABLE, f"gait{s}".encode(), blob(100 + s, s)) for s in range(SLOTS)}
    mem = filled(hal, slots)
    assert contents(hal, mem) == list(slots.values())
    areas = set()
    with MODELS.use(PowerCutModel(mem)):
        e = hal.ffi.new("store_lib_entry_t *")
        for s in range(SLOTS):
            assert hal.lib.store_lib_entry(lib(hal), s, e) == OK
            areas.add(e.addr)
    assert len(areas) == SLOTS
    used = set()
    for i in range(2 * AREAS):  # rewrite one slot over and over: the spare area moves
        status, mem, _ = run(hal, mem, put(hal, 3, TABLE, b"again", blob(60, 100 + i)))
        assert status == OK
        with MODELS.use(PowerCutModel(mem)):
            assert hal.lib.store_lib_entry(lib(hal), 3, e) == OK
            used.add(e.addr)
    assert len(used) >= 2
    assert contents(hal, mem)[:3] == [slots[0], slots[1], slots[2]]
    assert contents(hal, mem)[4:] == [slots[s] for s in range(4, SLOTS)]


@pytest.mark.parametrize(
    ("slot", "kind", "name", "size", "expected"),
    [
        (SLOTS, TABLE, b"a", 10, BAD_SLOT),
        (0, 0, b"a", 10, BAD_BLOB),  # kind 0 means empty
        (0, TABLE, b"a", 0, BAD_BLOB),
        (0, TABLE, b"a", AREA_PAGES * PAGE + 1, BAD_BLOB),
    ],
)
def test_bad_requests_are_refused_and_write_nothing(hal, slot, kind, name, size, expected):
    mem = filled(hal, {1: (TABLE, b"keep", blob(40, 9))})
    status, after, ops = run(hal, mem, put(hal, slot, kind, name, bytes(size)))
    assert status == expected and after == mem and ops == 0
    assert run(hal, mem, delete(hal, SLOTS))[0] == BAD_SLOT


def test_a_slot_whose_data_was_erased_reads_damaged(hal):
    """As after a bootloader that erased the application area: the directory survives,
    the data does not, and the slot must not be played."""
    mem = bytearray(filled(hal, {2: (TABLE, b"walk", blob(80, 4))}))
    mem[DIR_PAGES * PAGE :] = b"\xff" * (AREAS * AREA_PAGES * PAGE)
    assert contents(hal, bytes(mem))[2] == DAMAGED


NEIGHBOURS = {
    0: (TABLE, b"first", blob(70, 10)),
    4: (PROGRAM, b"middle", blob(33, 11)),
    7: (TABLE, b"last", blob(90, 12)),
}


@pytest.mark.parametrize(
    ("what", "slot"),
    [("store-new", 2), ("replace", 4), ("delete", 4)],
)
def test_a_power_cut_at_every_step_keeps_the_others_and_the_old_or_new_slot(hal, what, slot):
    """The operation is cut at each of its flash operations in turn (torn: an erase half
    done, a half-word half programmed); a fresh start must find every other slot as it
    was, and the slot being written as it was or as it was to become; and the library
    must take the next store."""
    mem = filled(hal, NEIGHBOURS)
    before = contents(hal, mem)
    new = (TABLE, b"fresh", blob(64, 13))
    op = delete(hal, slot) if what == "delete" else put(hal, slot, *new)
    status, done, steps = run(hal, mem, op)
    assert status == OK
    after_ok = contents(hal, done)
    assert after_ok[slot] == (EMPTY if what == "delete" else new)
    assert steps > 3
    for cut in range(steps):
        for seed in range(2):
            _, torn, _ = run(hal, mem, op, cut_at=cut, seed=seed)
            found = contents(hal, torn)
            for s in range(SLOTS):
                if s != slot:
                    assert found[s] == before[s], f"cut at step {cut} changed slot {s}"
            assert found[slot] in (before[slot], after_ok[slot]), f"cut at step {cut}"
            status, again, _ = run(hal, torn, put(hal, slot, TABLE, b"next", blob(20, cut)))
            assert status == OK
            assert contents(hal, again)[slot] == (TABLE, b"next", blob(20, cut))
