"""A gait library store (lib_store, firmware/core/lib_regs.h) kept in Python for tests
of the controller core: slots in a dict, the calls it received, and optionally a flash
write in the background a tick at a time, as the CM-530's store does (the firmware's own
store has its tests against the flash register model, tests/firmware)."""

from __future__ import annotations

import zlib

from ctl_support import CTL, lib_value

from snakebot.core import ffi, lib
from snakebot.sim.controller_pty import ControllerDevice

NAME_BYTES = CTL.register("Slot Name").size
OK = lib_value("Upload Result", "OK")
STORING = lib_value("Upload Result", "LIBRARY_STORING")


class PyStore:
    """A lib_store whose slots live in a dict, with the calls it received."""

    def __init__(self, slots: int = CTL.limits["max_library_slots"], capacity: int = 2048):
        """``slots`` slots of ``capacity`` bytes, all empty; every call finishes at once
        until :meth:`write_in_background`."""
        self.slots: dict[int, tuple[int, bytes, bytes]] = {}  # slot -> kind, name, data
        self.damaged: set[int] = set()
        self.calls: list[tuple] = []
        self._keep: list = []
        self.data_buffers: dict[int, object] = {}
        get = ffi.callback("void(uint8_t, lib_slot *, const uint8_t **)", self._get)
        put = ffi.callback(
            "uint8_t(uint8_t, uint8_t, const uint8_t *, const uint8_t *, uint16_t)", self._put
        )
        remove = ffi.callback("uint8_t(uint8_t)", self._remove)
        self._keep += [get, put, remove]
        memory = lib.CTL_LIBRARY_MEMORY_RAM
        self.c = ffi.new("lib_store *", {"slots": slots, "memory": memory, "capacity": capacity})
        self.c.get, self.c.put, self.c.remove = get, put, remove
        # a store that writes in the background, as the CM-530's does: what it writes
        self.writing = lib.CTL_STORE_STATE_IDLE
        self.percent = 0
        self.done = 0
        self.ticks_per_write = 50
        self.background = False  # put and remove begin a write rather than finish it

    def write_in_background(self) -> None:
        saving = ffi.callback("uint8_t(uint8_t *)", self._saving)
        self._keep.append(saving)
        self.c.saving = saving
        self.c.memory = lib.CTL_LIBRARY_MEMORY_FLASH  # as the CM-530's
        self.background = True

    def _saving(self, percent) -> int:
        percent[0] = self.percent
        return self.writing

    def _begun(self) -> int:
        if not self.background:
            return OK
        self.begin(lib.CTL_STORE_STATE_LIBRARY)
        return STORING

    def begin(self, state: int) -> None:
        """A write of ``state`` (CTL_STORE_STATE_*) starts: :meth:`tick` steps it."""
        self.writing, self.percent, self.done = state, 0, 0

    def tick(self, d) -> None:
        """One control tick of the write under way, if any: a library store ends with
        ctl_library_stored(OK) after ``ticks_per_write`` ticks, as the firmware's does."""
        if self.writing == lib.CTL_STORE_STATE_IDLE:
            return
        self.done += 1
        self.percent = min(100, 100 * self.done // self.ticks_per_write)
        if self.done >= self.ticks_per_write:
            ended, self.writing = self.writing, lib.CTL_STORE_STATE_IDLE
            if ended == lib.CTL_STORE_STATE_LIBRARY:
                lib.ctl_library_stored(d, OK)

    def _get(self, slot, out, data) -> None:
        if slot not in self.slots:
            return
        kind, name, blob = self.slots[slot]
        out.status = lib.CTL_SLOT_STATUS_DAMAGED if slot in self.damaged else lib.CTL_SLOT_STATUS_OK
        out.kind, out.len, out.crc = kind, len(blob), zlib.crc32(blob)
        ffi.memmove(out.name, name, len(name))
        buf = self.data_buffers.setdefault(slot, ffi.new("uint8_t[]", blob))
        data[0] = ffi.NULL if slot in self.damaged else buf

    def _put(self, slot, kind, name, data, length) -> int:
        blob = bytes(ffi.buffer(data, length))
        self.calls.append(("put", slot, kind))
        self.slots[slot] = (kind, bytes(ffi.buffer(name, NAME_BYTES)).rstrip(b"\0"), blob)
        self.data_buffers.pop(slot, None)
        return self._begun()

    def _remove(self, slot) -> int:
        self.calls.append(("remove", slot))
        self.slots.pop(slot, None)
        return self._begun()


class FlashController(ControllerDevice):
    """The controller's logic with ``store`` as its library; after each control tick,
    as the firmware's main loop: a newly committed table starts a save, and the write
    under way takes its step."""

    def __init__(self, bus, store: PyStore) -> None:
        super().__init__(bus)
        self.store = store
        lib.ctl_set_library(self.d, store.c)

    def tick(self, now_ms: int) -> None:
        super().tick(now_ms)
        if lib.ctl_table_changed(self.d):
            self.store.begin(lib.CTL_STORE_STATE_TABLE)
        self.store.tick(self.d)
