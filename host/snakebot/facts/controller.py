"""The controller's control table, as the host tools use it: a thin view of the
controller's description in :mod:`snakebot.facts.devices` (``devices/data/controller.json``).

That file is the one source of the addresses: ``firmware/core/ctl_table.h`` is generated
from it (``protocol/gen_headers.py``), and host tools look registers up here by name, so
no address is ever typed twice.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from snakebot.facts import devices
from snakebot.facts.devices import Device, DeviceError, Register
from snakebot.facts.devices.device import find

ControllerTableError = DeviceError
"""An unknown register name, a value out of range, or a broken description."""

__all__ = ["Controller", "ControllerTableError", "Register", "load"]


@dataclass(frozen=True)
class Controller:
    """The controller's control table: registers, the servo window, limits and enums."""

    device: Device

    @property
    def model_number(self) -> int:
        return self.device.model_number

    @property
    def firmware_version(self) -> int:
        return self.register("Firmware Version").default or 0

    @property
    def default_id(self) -> int:
        return self.register("ID").default or 0

    @property
    def table_size(self) -> int:
        return self.device.table_size

    @property
    def limits(self) -> dict[str, int]:
        return self.device.limits

    @property
    def registers(self) -> tuple[Register, ...]:
        return self.device.registers

    @property
    def enums(self) -> dict[str, dict[str, int]]:
        return self.device.enums

    @property
    def _window(self) -> devices.ServoWindow:
        assert self.device.servo_window is not None  # the loader requires it
        return self.device.servo_window

    @property
    def servo_window_address(self) -> int:
        return self._window.address

    @property
    def servo_record_size(self) -> int:
        return self._window.record_size

    @property
    def servo_records(self) -> int:
        """Records shown at once (one page)."""
        return self._window.records

    @property
    def servo_fields(self) -> tuple[Register, ...]:
        return self._window.fields

    @property
    def servo_pages(self) -> int:
        """Window pages showing servo records (0 .. servo_pages - 1)."""
        return -(-self.limits["max_joints"] // self.servo_records)

    @property
    def pages(self) -> tuple[devices.Page, ...]:
        """The window's described pages (Program, ...)."""
        return self.device.pages

    def page(self, name: str | int) -> devices.Page:
        """The window page called or numbered ``name``."""
        return self.device.page(name)

    def register(self, name: str) -> Register:
        """The register called ``name`` (case-insensitive), e.g. "Speed Scale"; a field of
        a window page ("Table Capacity") comes at its absolute address, shown only while
        Window Page holds its page (:meth:`page_number`)."""
        page = self.device.page_of(name)
        if page is not None:
            return page.register(name)
        return self.device.register(name)

    def page_number(self, name: str) -> int | None:
        """The Window Page value that shows register ``name``; None for an ordinary one."""
        page = self.device.page_of(name)
        return None if page is None else page.number

    def servo_field(self, name: str) -> Register:
        """The servo-record field called ``name`` (its address is the offset in a record)."""
        return find(self.servo_fields, name, "no servo-window field")

    def servo_page(self, joint: int) -> tuple[int, int]:
        """(page, slot): write ``page`` to Window Page, then the joint is record ``slot``."""
        if not 0 <= joint < self.limits["max_joints"]:
            raise ControllerTableError(
                f"joint index {joint} is outside the roster: the controller has joints "
                f"0..{self.limits['max_joints'] - 1}"
            )
        return divmod(joint, self.servo_records)

    def servo_address(self, slot: int, name: str) -> int:
        """Absolute address of field ``name`` of record ``slot`` in the servo window."""
        if not 0 <= slot < self.servo_records:
            raise ControllerTableError(
                f"servo window slot {slot} does not exist: slots are 0..{self.servo_records - 1}"
            )
        return (
            self.servo_window_address
            + slot * self.servo_record_size
            + self.servo_field(name).address
        )

    def decode(self, start: int, data: bytes) -> dict[str, int]:
        """Values of every register lying wholly inside ``data`` read from ``start``."""
        values = {}
        for reg in self.registers:
            if reg.readable and start <= reg.address and reg.end <= start + len(data):
                values[reg.name] = reg.decode(data[reg.address - start : reg.end - start])
        return values

    def decode_servo_window(self, data: bytes) -> list[dict[str, int]]:
        """One dict per whole servo record in ``data`` read from the window's first byte."""
        records = []
        for slot in range(min(self.servo_records, len(data) // self.servo_record_size)):
            base = slot * self.servo_record_size
            records.append(
                {f.name: f.decode(data[base + f.address : base + f.end]) for f in self.servo_fields}
            )
        return records


@cache
def load() -> Controller:
    """The controller's table (read once from its description)."""
    return Controller(devices.controller())
