"""The gait library's flash store (firmware/app/store_lib.c), compiled for the host with the
flash driver and store_slots under it, run against the flash register model: named slots
that a store or a delete replaces atomically, with a power cut at any step leaving every
other slot intact and the slot being written either as it was or as it was to become."""

from __future__ import annotations

import pytest
from library_flash import (
    AREA_PAGES,
    AREAS,
    BAD_BLOB,
    BAD_SLOT,
    DAMAGED,
    DIR_PAGES,
    EMPTY,
    ERASED_LONG_AGO,
    MODELS,
    NAME_MAX,
    OK,
    PAGE,
    PROGRAM,
    SLOTS,
    TABLE,
    PowerCutModel,
    Slot,
    blob,
    build,
    contents,
    delete,
    lib,
    put,
    run,
)


@pytest.fixture(scope="module")
def hal(tmp_path_factory):
    return build(tmp_path_factory.mktemp("hal_library_host"))


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
