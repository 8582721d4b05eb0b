"""The gait library in the controller (protocol/library.md): named slots of tables and
programs that survive power-off, listed, stored, played, deleted and backed up through the
Library window page.

    slots = list_slots(ctl)
    store_slot(ctl, 2, "walk", table_bytes)
    play_slot(ctl, 2)
    saved = backup(ctl)          # every slot's bytes, e.g. before flashing
    restore(ctl, saved)

A controller that keeps its library in flash (the CM-530) writes it a step per control
tick, after the call that began the write has been answered; so does it save a newly
committed table. These functions wait for such a write (Store State, on the Program page)
before they begin and until theirs has ended, telling ``on_progress(state, percent)``.
"""

from __future__ import annotations

import base64
import time
import zlib
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

from snakebot.errors import quoted
from snakebot.formats.upload_writes import chunk_writes, commit_write
from snakebot.link.controller import messages as words
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.errors import LibraryFailed, LibraryRefused

PAGE = "Library"

# What each library result means, and what to do about it.
LIBRARY_RESULTS: dict[str, tuple[str, str]] = {
    "LIBRARY_NONE": (
        "this controller has no gait library",
        "flash firmware with a library (`snakebot flash`)",
    ),
    "LIBRARY_BAD_SLOT": (
        "no such slot",
        "pick a slot below Library Slots (`snakebot library list`)",
    ),
    "LIBRARY_EMPTY": ("the slot is empty", "store a table in it first (`snakebot library store`)"),
    "LIBRARY_DAMAGED": (
        "the slot's bytes no longer match its CRC (its flash was erased or worn)",
        "store the table again",
    ),
    "LIBRARY_BAD_NAME": ("the name is not printable ASCII", "use letters, digits and spaces"),
    "LIBRARY_BAD_KIND": (
        "the library does not keep that kind of blob here",
        "store gait tables (QEMU's one-slot library keeps nothing else)",
    ),
    "LIBRARY_FLASH": (
        "the controller could not write its flash; the slot is unchanged",
        "try again; if it persists, the flash is worn: use another slot",
    ),
    "LIBRARY_NOT_PLAYABLE": ("the slot holds no gait table", "play a slot holding a table"),
    "STORE_BUSY": (
        "the controller is still writing its flash (a table it saves, or a library store)",
        "wait for the save to finish (`snakebot library list` shows it), then try again",
    ),
}

STORE_WAIT_S = 30.0
"""How long to wait for a flash write to end: a 32 KB store takes about 3.5 s of control
ticks on the CM-530; far longer means the controller is not stepping it."""

Progress = Callable[[str, int], None]
"""``on_progress(state, percent)``: the flash write under way (Store State's name, TABLE
or LIBRARY) and how far it is, each time it is polled."""


@dataclass(frozen=True)
class Slot:
    """One library slot as the controller reports it."""

    slot: int
    status: str  # EMPTY, OK, DAMAGED
    kind: str  # the Upload Commit name its blob is committed with; NONE when empty
    length: int
    crc: int
    name: str

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def line(self) -> str:
        if self.status == "EMPTY":
            return f"{self.slot}  (empty)"
        return (
            f"{self.slot}  {self.name or '(no name)':16}  {self.kind:<7} {self.length:5d} B  "
            f"CRC {self.crc:08X}  {self.status}"
        )


def _enum_name(ctl: ControllerClient, enum: str, value: int) -> str:
    for name, code in ctl.table.enums[enum].items():
        if code == value:
            return name
    return f"UNKNOWN({value})"


def _text(ctl: ControllerClient, name: str) -> bytes:
    reg = ctl.table.register(name)
    ctl.show_page(ctl.table.page_number(name))
    return ctl.read_block(reg.address, reg.size)


IN_RAM = (
    "this controller keeps its library in RAM (the QEMU board): one slot, 0, which is its "
    "active table; it empties when another table becomes active and at power-off"
)


def library_memory(ctl: ControllerClient) -> str:
    """Where the library keeps its slots (Library Memory): FLASH, RAM or NONE."""
    return _enum_name(ctl, "Library Memory", ctl.read("Library Memory")["Library Memory"])


def library_size(ctl: ControllerClient) -> tuple[int, int]:
    """(Library Slots, Slot Capacity): 0 slots when the controller has no library."""
    r = ctl.read("Library Slots", "Slot Capacity")
    return r["Library Slots"], r["Slot Capacity"]


def read_slot(ctl: ControllerClient, slot: int) -> Slot:
    """Slot ``slot`` as the controller's library has it."""
    ctl.write({"Library Slot": slot})
    r = ctl.read("Slot Status", "Slot Kind", "Slot Length", "Slot CRC")
    name = _text(ctl, "Slot Name").rstrip(b"\0").decode("ascii", "replace")
    return Slot(
        slot,
        _enum_name(ctl, "Slot Status", r["Slot Status"]),
        _enum_name(ctl, "Upload Commit", r["Slot Kind"]),
        r["Slot Length"],
        r["Slot CRC"],
        name,
    )


def list_slots(ctl: ControllerClient) -> list[Slot]:
    """Every slot of the library (an empty list if the controller has none)."""
    count, _ = library_size(ctl)
    return [read_slot(ctl, s) for s in range(count)]


@dataclass(frozen=True)
class StoreState:
    """What the controller is writing to its flash (Store State, Store Progress)."""

    state: str  # IDLE, TABLE (the committed table's save), LIBRARY (a store or delete)
    percent: int

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def line(self) -> str:
        what = {"TABLE": "saving its active table", "LIBRARY": "storing a library slot"}
        return f"the controller is {what.get(self.state, self.state)}: {self.percent}% done"


def store_state(ctl: ControllerClient) -> StoreState:
    """The flash write under way, if any (IDLE on a controller without a flash store)."""
    r = ctl.read("Store State", "Store Progress")
    return StoreState(_enum_name(ctl, "Store State", r["Store State"]), r["Store Progress"])


def wait_for_store(
    ctl: ControllerClient,
    on_progress: Progress | None = None,
    timeout: float = STORE_WAIT_S,
    poll: float = 0.1,
) -> None:
    """Return once the controller writes nothing to its flash; LibraryError if a write
    is still under way after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while True:
        now = store_state(ctl)
        if now.state == "IDLE":
            return
        if time.monotonic() > deadline:
            raise LibraryFailed(
                f"{now.line()} after {timeout:.0f} s: power-cycle the controller if this "
                "persists (a power cut keeps the previous content)"
            )
        if on_progress is not None:
            on_progress(now.state, now.percent)
        time.sleep(poll)


def _check_slot(ctl: ControllerClient, slot: int) -> None:
    count, _ = library_size(ctl)
    if count == 0:
        raise LibraryRefused(f"the controller refused ({_reason(ctl, 'LIBRARY_NONE')})")
    if not 0 <= slot < count:
        if library_memory(ctl) == "RAM":
            raise LibraryRefused(f"slot {slot} does not exist: {IN_RAM}; use slot 0")
        raise LibraryRefused(
            f"slot {slot} does not exist: this controller has slots 0..{count - 1}"
        )


def _reason(ctl: ControllerClient, name: str) -> str:
    """A library result in words: what happened, and what to do."""
    if name in LIBRARY_RESULTS:
        what, fix = LIBRARY_RESULTS[name]
    else:
        code = ctl.table.enums["Upload Result"].get(name, -1)
        _, what, fix = words.upload_result_reason(code, ctl.table)
    return f"{name}: {what}; {fix}"


def _result(ctl: ControllerClient, register: str, what: str) -> None:
    value = ctl.read(register)[register]
    name = _enum_name(ctl, "Upload Result", value)
    if name != "OK":
        refused = LibraryFailed if words.is_runtime_result(name) else LibraryRefused
        raise refused(f"{what} ({_reason(ctl, name)})")


def encode_name(ctl: ControllerClient, name: str) -> bytes:
    """``name`` as Store Name takes it (printable ASCII, zero-padded); LibraryError if not."""
    size = ctl.table.register("Store Name").size
    raw = name.encode("ascii", "replace")
    if len(raw) > size or not name.isascii() or not all(0x20 <= b <= 0x7E for b in raw):
        raise LibraryRefused(
            f"slot name {quoted(name)} must be at most {size} printable ASCII characters: "
            "shorten it"
        )
    return raw.ljust(size, b"\0")


def _committed(
    ctl: ControllerClient, blob: bytes, what: str, failed: str, on_progress: Progress | None
) -> None:
    """Commit the staged ``blob`` as ``what`` (LIBRARY_STORE, LIBRARY_DELETE); if the
    controller writes it in the background, wait for that; LibraryError(``failed``) if it
    was refused or failed."""
    ctl.write_block(*commit_write(blob, ctl.table, what=what))
    begun = ctl.read("Upload Result")["Upload Result"]
    if _enum_name(ctl, "Upload Result", begun) != "LIBRARY_STORING":
        _result(ctl, "Upload Result", failed)
        return
    wait_for_store(ctl, on_progress)
    _result(ctl, "Library Result", failed)  # the write's outcome


def store_slot(
    ctl: ControllerClient,
    slot: int,
    name: str,
    blob: bytes,
    kind: str = "TABLE",
    on_progress: Progress | None = None,
) -> Slot:
    """Keep ``blob`` (a gait table's bytes, or a program's with ``kind`` PROGRAM) in slot
    ``slot`` named ``name``; returns the slot as stored. Raises LibraryError if refused.
    Waits for a flash write under way first: staging the blob could land on a table the
    controller is saving."""
    raw_name = encode_name(ctl, name)
    _check_slot(ctl, slot)
    kinds = ctl.table.enums["Upload Commit"]
    if kind not in kinds:
        raise LibraryRefused(f"no blob kind {quoted(kind)}: use TABLE")
    wait_for_store(ctl, on_progress)
    ctl.write({"Library Slot": slot, "Store Kind": kinds[kind]})
    store_name = ctl.table.register("Store Name")
    ctl.write_block(store_name.address, raw_name)
    for address, data in chunk_writes(blob, controller=ctl.table):
        ctl.write_block(address, data)
    _committed(ctl, blob, "LIBRARY_STORE", f"slot {slot} was not stored", on_progress)
    return read_slot(ctl, slot)


def delete_slot(ctl: ControllerClient, slot: int, on_progress: Progress | None = None) -> None:
    """Empty slot ``slot``."""
    _check_slot(ctl, slot)
    wait_for_store(ctl, on_progress)
    ctl.write({"Library Slot": slot})
    _committed(ctl, b"", "LIBRARY_DELETE", f"slot {slot} was not deleted", on_progress)


def play_slot(ctl: ControllerClient, slot: int, on_progress: Progress | None = None) -> str:
    """Make slot ``slot``'s table the active one and play it; returns the State by name.
    The controller refuses while it writes its flash (a play would replace the table it
    saves): this waits for that first."""
    _check_slot(ctl, slot)
    wait_for_store(ctl, on_progress)
    ctl.write({"Library Slot": slot})
    ctl.command("LIBRARY_PLAY")
    _result(ctl, "Library Result", f"slot {slot} was not played")
    r = ctl.read("State", "Error Flags")
    state = words.state_name(r["State"], ctl.table)
    if state != "PLAYING":
        raise LibraryFailed(
            f"slot {slot} was loaded but did not play (State {state}; Error Flags: "
            f"{words.describe_flags(r['Error Flags'], ctl.table)}): `snakebot stop --clear`, "
            "then try again"
        )
    return state


def read_blob(ctl: ControllerClient, slot: Slot) -> bytes:
    """The bytes of an OK slot, read through the Slot Data window and checked against its
    CRC."""
    window = ctl.table.register("Slot Data")
    ctl.write({"Library Slot": slot.slot})  # the window shows the selected slot
    out = b""
    for at in range(0, slot.length, window.size):
        ctl.write({"Slot Offset": at})
        out += _text(ctl, "Slot Data")
    out = out[: slot.length]
    if zlib.crc32(out) != slot.crc:
        raise LibraryFailed(
            f"slot {slot.slot} read back with a wrong CRC-32: the PC link damaged it; try again"
        )
    return out


def backup(ctl: ControllerClient) -> dict[str, Any]:
    """Every OK slot's name, kind and bytes (base64), as JSON-ready data; empty and
    damaged slots are listed without bytes."""
    slots = []
    for s in list_slots(ctl):
        entry = s.as_dict()
        if s.status == "OK":
            entry["data"] = base64.b64encode(read_blob(ctl, s)).decode("ascii")
        slots.append(entry)
    return {"format": "snakebot-library-backup", "version": 1, "slots": slots}


def stored_slots(saved: dict[str, Any]) -> list[dict[str, Any]]:
    """The slots of a :func:`backup` that hold bytes (the ones a restore writes)."""
    return [entry for entry in saved.get("slots", []) if "data" in entry]


def restore(ctl: ControllerClient, saved: dict[str, Any]) -> list[Slot]:
    """Store every slot of a :func:`backup` that has bytes and is not already in place
    (same name, kind, length and CRC); returns the slots written."""
    if saved.get("format") != "snakebot-library-backup":
        raise LibraryRefused(
            "not a snakebot library backup: pass a file `snakebot library backup` or "
            "`snakebot flash` wrote"
        )
    written = []
    for entry in stored_slots(saved):
        blob = base64.b64decode(entry["data"])
        now = read_slot(ctl, int(entry["slot"]))
        wanted = ("OK", entry["name"], entry["kind"], zlib.crc32(blob))
        if (now.status, now.name, now.kind, now.crc) == wanted:
            continue
        written.append(store_slot(ctl, int(entry["slot"]), entry["name"], blob, entry["kind"]))
    return written
