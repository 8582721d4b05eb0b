"""The gait library as the controller core shows it (firmware/core/lib_regs.c with its
hooks in ctl_state.c and ctl_pages.c): the Library window page, Upload Commit
LIBRARY_STORE and LIBRARY_DELETE, Command LIBRARY_PLAY and the button panel, on a store
kept here in Python (the firmware's flash store has its own tests,
tests/firmware/test_library_store.py)."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from ctl_support import CTL, CTL_ID, Device, lib_value
from hypothesis import given
from hypothesis import strategies as st
from py_library import NAME_BYTES, PyStore
from test_program_controller import program

from snakebot.core import ffi, lib
from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol import ErrorFlags, write
from snakebot.link.controller import ControllerErrors

LIBRARY = CTL.page("Library")

OK = lib_value("Upload Result", "OK")
TABLE = lib_value("Upload Commit", "TABLE")
SCANS = lib.BUTTONS_DEBOUNCE_SCANS


def result(name: str) -> int:
    return lib_value("Upload Result", name)


def table(frames: int = 3, low: int = 400) -> bytes:
    values = np.array([[low + f, 600 - f] for f in range(frames)])
    return GaitTable((1, 2), 50, True, ((300, 700), (300, 700)), values, {}).encode()


class Lib:
    """A ctl_device with a PyStore, spoken to through the Library page."""

    def __init__(self, store: PyStore | None = None) -> None:
        self.dev = Device()
        self.store = store
        lib.ctl_set_library(self.dev.d, store.c if store else ffi.NULL)
        assert self.dev.set("Window Page", LIBRARY.number) == 0

    def get(self, name: str) -> int:
        return self.dev.get(name)

    def text(self, name: str) -> bytes:
        reg = CTL.register(name)
        return self.dev.read(reg.address, reg.size)

    def name(self, text: bytes) -> int:
        reg = CTL.register("Store Name")
        return self.dev.one(write(CTL_ID, reg.address, text.ljust(reg.size, b"\0"))).error

    def stage(self, blob: bytes) -> None:
        assert self.dev.upload(blob, commit=False) is not None

    def commit(self, what: str, blob: bytes = b"") -> int:
        start = CTL.register("Upload Length").address
        payload = len(blob).to_bytes(2, "little") + zlib.crc32(blob).to_bytes(4, "little")
        payload += bytes([lib_value("Upload Commit", what)])
        assert self.dev.one(write(CTL_ID, start, payload)).error == 0
        return self.get("Upload Result")

    def store_blob(self, slot: int, name: bytes, blob: bytes, kind: int = TABLE) -> int:
        assert self.dev.set("Library Slot", slot) == 0
        assert self.name(name) == 0
        assert self.dev.set("Store Kind", kind) == 0
        self.stage(blob)
        return self.commit("LIBRARY_STORE", blob)

    def press(self, buttons: int) -> None:
        """Hold ``buttons`` through the Buttons register long enough, then let go."""
        for held in (buttons, 0):
            assert self.dev.set("Buttons", held) == 0
            for _ in range(SCANS):
                self.dev.now += 10
                lib.ctl_buttons(self.dev.d, 0, self.dev.now)


def test_without_a_library_everything_is_refused_by_name():
    c = Lib(None)
    assert c.get("Library Slots") == 0 and c.get("Slot Capacity") == 0
    assert c.dev.set("Library Slot", 1) == ErrorFlags.RANGE
    assert c.commit("LIBRARY_DELETE") == result("LIBRARY_NONE")
    assert c.dev.flags & ControllerErrors.LIBRARY
    assert not c.dev.flags & ControllerErrors.UPLOAD_LAYOUT
    assert c.dev.command("CLEAR") == 0
    assert c.dev.command("LIBRARY_PLAY") == 0
    assert c.dev.flags & ControllerErrors.LIBRARY and c.dev.flags & ControllerErrors.REFUSED
    assert c.get("Library Result") == result("LIBRARY_NONE")


def test_store_shows_and_deletes_a_slot():
    store = PyStore()
    c = Lib(store)
    assert c.get("Library Slots") == 8 and c.get("Slot Capacity") == 2048
    walk = table()
    assert c.store_blob(5, b"walk forward", walk) == OK
    assert store.slots[5] == (TABLE, b"walk forward", walk)
    assert c.get("Library Result") == OK and not c.dev.flags & ControllerErrors.LIBRARY
    shown = {f.name: c.get(f.name) for f in LIBRARY.fields if f.size <= 4}
    assert shown["Library Slot"] == 5
    assert shown["Slot Status"] == lib.CTL_SLOT_STATUS_OK
    assert shown["Slot Kind"] == TABLE
    assert shown["Slot Length"] == len(walk) and shown["Slot CRC"] == zlib.crc32(walk)
    assert c.text("Slot Name") == b"walk forward".ljust(NAME_BYTES, b"\0")
    assert c.text("Store Name") == b"walk forward".ljust(NAME_BYTES, b"\0")
    # storing into the library leaves the active table alone
    assert lib.ctl_active_table(c.dev.d, ffi.new("size_t *")) == ffi.NULL
    assert c.dev.set("Library Slot", 4) == 0
    assert c.get("Slot Status") == lib.CTL_SLOT_STATUS_EMPTY and c.get("Slot Length") == 0
    assert c.dev.set("Library Slot", 5) == 0
    assert c.commit("LIBRARY_DELETE") == OK
    assert store.calls[-1] == ("remove", 5) and 5 not in store.slots
    assert c.get("Slot Status") == lib.CTL_SLOT_STATUS_EMPTY
    assert c.dev.set("Library Slot", 8) == ErrorFlags.RANGE
    assert c.get("Library Slot") == 5


@pytest.mark.parametrize(
    ("name", "blob", "kind", "expected"),
    [
        (b"bad\x01name", table(), TABLE, "LIBRARY_BAD_NAME"),
        (b"a\0b", table(), TABLE, "LIBRARY_BAD_NAME"),  # text after the padding
        (b"limits", table(), lib_value("Upload Commit", "LIMITS"), "LIBRARY_BAD_KIND"),
        (b"broken", table()[:-3], TABLE, "TRUNCATED"),  # checked as TABLE checks it
    ],
)
def test_a_bad_store_is_refused_and_stores_nothing(name, blob, kind, expected):
    store = PyStore()
    c = Lib(store)
    assert c.store_blob(2, name, blob, kind) == result(expected)
    assert store.calls == [] and c.dev.flags & ControllerErrors.LIBRARY
    assert c.get("Library Result") == result(expected)


def test_a_program_is_checked_as_its_commit_checks_it_and_plays_from_its_slot():
    store = PyStore()
    c = Lib(store)
    kind = lib_value("Upload Commit", "PROGRAM")
    assert c.store_blob(1, b"junk", b"\x01\x02\x03", kind=kind) == result("PROGRAM_TRUNCATED")
    assert 1 not in store.slots
    blob = program().encode()
    assert c.store_blob(1, b"plan", blob, kind=kind) == OK
    assert store.slots[1] == (kind, b"plan", blob)
    assert c.dev.set("Library Slot", 1) == 0
    assert c.dev.command("LIBRARY_PLAY") == 0
    assert c.get("Library Result") == OK and not c.dev.flags & ControllerErrors.REFUSED
    assert c.dev.state == lib.CTL_STATE_PLAYING, hex(c.dev.flags)
    assert c.dev.set("Window Page", CTL.page("Program").number) == 0
    assert c.get("Program State") == lib_value("Program State", "RUNNING")


def test_library_play_makes_the_slot_active_without_persisting_it_and_plays():
    store = PyStore()
    c = Lib(store)
    walk, turn = table(3), table(5, low=450)
    assert c.store_blob(0, b"walk", walk) == OK
    assert c.store_blob(3, b"turn", turn) == OK
    assert c.dev.set("Library Slot", 3) == 0
    assert c.dev.command("LIBRARY_PLAY") == 0
    assert c.dev.state == lib.CTL_STATE_PLAYING, hex(c.dev.flags)
    n = ffi.new("size_t *")
    active = lib.ctl_active_table(c.dev.d, n)
    assert bytes(ffi.buffer(active, n[0])) == turn
    assert not lib.ctl_table_changed(c.dev.d)
    # an empty or damaged slot is refused, and what plays keeps playing
    store.damaged.add(0)
    for slot, why in ((0, "LIBRARY_DAMAGED"), (6, "LIBRARY_EMPTY")):
        assert c.dev.set("Library Slot", slot) == 0
        assert c.dev.command("LIBRARY_PLAY") == 0
        assert c.get("Library Result") == result(why)
    assert c.dev.state == lib.CTL_STATE_PLAYING


def test_the_buttons_pick_a_slot_play_it_and_stop():
    store = PyStore()
    c = Lib(store)
    assert c.store_blob(2, b"two", table()) == OK
    c.press(lib.CTL_BUTTONS_U)
    c.press(lib.CTL_BUTTONS_U)
    assert c.get("Panel Slot") == 2 and c.get("LEDs") == 2
    c.press(lib.CTL_BUTTONS_START)
    assert c.dev.state == lib.CTL_STATE_PLAYING
    assert c.get("LEDs") == 2 | lib.CTL_LEDS_PLAY
    c.press(lib.CTL_BUTTONS_START)
    assert c.dev.state == lib.CTL_STATE_IDLE and c.get("LEDs") == 2
    c.press(lib.CTL_BUTTONS_D)
    c.press(lib.CTL_BUTTONS_START)  # slot 1 is empty
    assert c.dev.state == lib.CTL_STATE_IDLE
    assert c.get("Library Result") == result("LIBRARY_EMPTY")


@given(st.binary(min_size=1, max_size=40), st.integers(0, 255))
def test_any_write_to_the_page_leaves_it_consistent(data, start_offset):
    """Bytes written anywhere on the page: refused with RANGE, or the writable fields
    take them; the read-only ones never change."""
    c = Lib(PyStore())
    before = c.dev.read(CTL.servo_window_address, 126)
    start = CTL.servo_window_address + start_offset % 126
    data = data[: CTL.servo_window_address + 126 - start]
    err = c.dev.one(write(CTL_ID, start, data)).error
    after = c.dev.read(CTL.servo_window_address, 126)
    if err:
        assert after == before
    writable = set()
    for f in LIBRARY.fields:  # addresses relative to the window
        if "W" in f.access and f.name != "Buttons":  # it reads back the debounced buttons
            writable |= set(range(f.address, f.address + f.size))
    changed = {i for i, (a, b) in enumerate(zip(before, after, strict=True)) if a != b}
    assert changed <= writable


def test_a_slot_reads_back_through_the_slot_data_window():
    store = PyStore()
    c = Lib(store)
    blob = table(frames=150)  # several windows' worth
    assert c.store_blob(4, b"long", blob) == OK
    window = CTL.register("Slot Data")
    got = b""
    for at in range(0, len(blob) + window.size, window.size):
        assert c.dev.set("Slot Offset", at) == 0
        got += c.text("Slot Data")
    assert got[: len(blob)] == blob and set(got[len(blob) :]) == {0}
    store.damaged.add(4)  # a damaged slot shows nothing
    assert c.dev.set("Slot Offset", 0) == 0
    assert set(c.text("Slot Data")) == {0}


def program_page(c: Lib, *names: str) -> dict[str, int]:
    """Registers of the Program page (the window shows it meanwhile), then back to the
    Library page."""
    assert c.dev.set("Window Page", CTL.page("Program").number) == 0
    values = {n: c.get(n) for n in names}
    assert c.dev.set("Window Page", LIBRARY.number) == 0
    return values


def test_a_store_written_in_the_background_shows_its_state_and_ends_with_its_result():
    store = PyStore()
    store.write_in_background()
    c = Lib(store)
    assert program_page(c, "Store State", "Store Progress") == {
        "Store State": lib.CTL_STORE_STATE_IDLE,
        "Store Progress": 0,
    }
    assert c.store_blob(3, b"walk", table()) == result("LIBRARY_STORING")
    assert c.get("Library Result") == result("LIBRARY_STORING")
    assert not c.dev.flags & ControllerErrors.LIBRARY  # begun, not failed
    store.percent = 40
    assert program_page(c, "Store State", "Store Progress") == {
        "Store State": lib.CTL_STORE_STATE_LIBRARY,
        "Store Progress": 40,
    }
    store.writing = lib.CTL_STORE_STATE_IDLE
    lib.ctl_library_stored(c.dev.d, OK)
    assert c.get("Upload Result") == OK and c.get("Library Result") == OK
    assert not c.dev.flags & ControllerErrors.LIBRARY
    # a store that fails in flash says so when it ends
    assert c.store_blob(3, b"walk", table()) == result("LIBRARY_STORING")
    store.writing = lib.CTL_STORE_STATE_IDLE
    lib.ctl_library_stored(c.dev.d, result("LIBRARY_FLASH"))
    assert c.get("Upload Result") == result("LIBRARY_FLASH")
    assert c.get("Library Result") == result("LIBRARY_FLASH")
    assert c.dev.flags & ControllerErrors.LIBRARY


def test_while_a_library_store_runs_its_staged_blob_and_the_library_are_left_alone():
    """The store reads the staging area until it ends: chunks, commits, other library
    operations and plays (from the page or the buttons) are refused with STORE_BUSY."""
    store = PyStore()
    store.write_in_background()
    c = Lib(store)
    walk = table()
    store.background = False
    assert c.store_blob(1, b"walk", walk) == OK  # something to play
    store.background = True
    assert c.store_blob(2, b"turn", table(5)) == result("LIBRARY_STORING")
    busy = result("STORE_BUSY")
    chunk = CTL.register("Upload Offset")
    refused = c.dev.one(write(CTL_ID, chunk.address, bytes(2) + bytes(16)))
    assert refused.error == ErrorFlags.RANGE and c.get("Upload Result") == busy
    assert c.dev.flags & ControllerErrors.LIBRARY
    assert c.dev.command("CLEAR") == 0
    assert c.commit("TABLE", walk) == busy
    for what in ("LIBRARY_STORE", "LIBRARY_DELETE"):
        assert c.commit(what, walk) == busy and c.get("Library Result") == busy
    assert c.dev.set("Library Slot", 1) == 0
    assert c.dev.command("LIBRARY_PLAY") == 0
    assert c.get("Library Result") == busy and c.dev.state == lib.CTL_STATE_IDLE
    assert c.dev.flags & ControllerErrors.REFUSED
    c.press(lib.CTL_BUTTONS_U)
    c.press(lib.CTL_BUTTONS_START)
    assert c.get("Library Result") == busy and c.dev.state == lib.CTL_STATE_IDLE
    assert [call[0] for call in store.calls] == ["put", "put"]  # nothing more reached it
    store.writing = lib.CTL_STORE_STATE_IDLE
    lib.ctl_library_stored(c.dev.d, OK)
    c.press(lib.CTL_BUTTONS_START)  # now it plays
    assert c.get("Library Result") == OK and c.dev.state == lib.CTL_STATE_PLAYING


def test_while_the_committed_table_is_saved_library_operations_wait_but_commits_do_not():
    """A play would replace the table the save reads (abandoning it), a store would
    stage over it: both are refused until the save ends. A newer commit just restarts
    the save (the app's job), so it is taken."""
    store = PyStore()
    store.write_in_background()
    store.background = False
    c = Lib(store)
    walk = table()
    assert c.store_blob(1, b"walk", walk) == OK
    # committed, and the app has not begun to save it yet: that counts as saving too
    assert c.dev.upload(table(4)) == OK
    assert program_page(c, "Store State")["Store State"] == lib.CTL_STORE_STATE_TABLE
    assert c.store_blob(2, b"turn", table(5)) == result("STORE_BUSY")
    assert c.commit("LIBRARY_DELETE") == result("STORE_BUSY")
    assert c.dev.set("Library Slot", 1) == 0
    assert c.dev.command("LIBRARY_PLAY") == 0
    assert c.get("Library Result") == result("STORE_BUSY")
    assert lib.ctl_table_changed(c.dev.d)  # the app begins the save
    store.writing, store.percent = lib.CTL_STORE_STATE_TABLE, 70
    assert program_page(c, "Store State", "Store Progress") == {
        "Store State": lib.CTL_STORE_STATE_TABLE,
        "Store Progress": 70,
    }
    assert c.dev.command("LIBRARY_PLAY") == 0
    assert c.get("Library Result") == result("STORE_BUSY")
    assert c.store_blob(2, b"turn", table(5)) == result("STORE_BUSY")
    assert c.commit("LIBRARY_DELETE") == result("STORE_BUSY")
    assert [call[0] for call in store.calls] == ["put"]
    assert c.dev.upload(table(6)) == OK  # a newer table: the app restarts the save
    store.writing = lib.CTL_STORE_STATE_IDLE
    assert lib.ctl_table_changed(c.dev.d)
    assert c.dev.set("Library Slot", 1) == 0
    assert c.dev.command("LIBRARY_PLAY") == 0
    assert c.get("Library Result") == OK and c.dev.state == lib.CTL_STATE_PLAYING


def test_library_memory_says_where_the_slots_are_kept():
    assert program_page(Lib(None), "Library Memory")["Library Memory"] == 0  # NONE
    store = PyStore()
    assert program_page(Lib(store), "Library Memory")["Library Memory"] == (
        lib.CTL_LIBRARY_MEMORY_RAM
    )
    store.write_in_background()
    assert program_page(Lib(store), "Library Memory")["Library Memory"] == (
        lib.CTL_LIBRARY_MEMORY_FLASH
    )
