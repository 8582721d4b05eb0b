"""Talking to the controller on its PC link: registers by name, the roster, commands.

    from snakebot.link.controller.client import ControllerClient
    with ControllerClient.open("/dev/ttyUSB0") as ctl:     # 57600 baud, ID 200
        ctl.identify()                                      # NotAController if it is not one
        print(ctl.read("State", "Error Flags"))             # {"State": 0, "Error Flags": 0}
        ctl.write({"Speed Scale": 512})                     # range-checked by its description

Every transaction goes through :class:`snakebot.link.transport.DxlClient` (timeouts from the
wire, retries, stale-reply handling). Its READ/WRITE helpers are not used: they track an
AX-12's Status Return Level at address 16, which on the controller is Speed Scale, so
packets are built with :mod:`snakebot.formats.protocol` and sent with ``transact``. Link failures
become :class:`ControllerLinkError` with hints about the controller, not about servos.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import asdict, dataclass
from types import TracebackType
from typing import Any

from snakebot.errors import quoted
from snakebot.facts import devices
from snakebot.facts.boards import PC_LINK_BAUD
from snakebot.facts.controller import Controller, Register, load
from snakebot.formats import protocol
from snakebot.formats.protocol import CorruptPacket, DxlTimeout, ErrorFlags, ServoError
from snakebot.link.controller.errors import (
    ControllerInputError,
    ControllerLinkError,
    ControllerRefused,
    ControllerStateError,
    NotAController,
)
from snakebot.link.transport import DxlClient, settings, timing
from snakebot.link.transport.ports import is_pseudo_terminal

IDENTITY_REGISTERS = ("Model Number", "Firmware Version", "ID", "Status Return Level", "State")
"""What :meth:`ControllerClient.identify` reads and checks."""

ROSTER_FIELDS = ("ID", "Reverse", "Zero Tick", "Min Tick", "Max Tick")
"""The writable head of a servo-window record (the roster configuration), in order."""


@dataclass(frozen=True)
class JointRecord:
    """One roster joint as the controller reports it (servo-window record)."""

    joint: int
    id: int
    reverse: int
    zero_tick: int
    min_tick: int
    max_tick: int
    goal: int
    position: int
    speed: int
    load: int
    voltage: int
    temperature: int
    error: int
    error_count: int
    timeout_count: int

    @classmethod
    def from_record(cls, joint: int, record: Mapping[str, int]) -> JointRecord:
        return cls(
            joint=joint,
            id=record["ID"],
            reverse=record["Reverse"],
            zero_tick=record["Zero Tick"],
            min_tick=record["Min Tick"],
            max_tick=record["Max Tick"],
            goal=record["Goal Position"],
            position=record["Present Position"],
            speed=record["Present Speed"],
            load=record["Present Load"],
            voltage=record["Present Voltage"],
            temperature=record["Present Temperature"],
            error=record["Servo Error"],
            error_count=record["Error Count"],
            timeout_count=record["Timeout Count"],
        )

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


_POSITION = devices.ax12().require_position()


@dataclass(frozen=True)
class RosterEntry:
    """What the roster needs to know about one joint (written through the servo window)."""

    id: int
    reverse: bool = False
    zero_tick: int = _POSITION.centre
    min_tick: int = _POSITION.range[0]
    max_tick: int = _POSITION.range[1]


class ControllerClient:
    """The controller at ``controller_id`` on an open :class:`DxlClient` (its PC link)."""

    def __init__(
        self,
        link: DxlClient,
        controller_id: int | None = None,
        *,
        table: Controller | None = None,
        port_name: str = "",
    ) -> None:
        self.table = table or load()
        self.link = link
        self.id = self.table.default_id if controller_id is None else controller_id
        if not 0 <= self.id <= 253:
            raise ControllerInputError(
                f"controller ID {self.id} is outside 0..253: use {self.table.default_id}, the "
                "controller's own"
            ).about("controller_id")
        self.port_name = port_name or str(getattr(link.port, "port", "") or "")

    @classmethod
    def open(
        cls,
        port: str,
        baudrate: int = PC_LINK_BAUD,
        controller_id: int | None = None,
        **link_options: Any,
    ) -> ControllerClient:
        """Open ``port`` (device path or URL). The PC link never echoes, so the client is
        told so (``echo=False``) unless ``link_options`` say otherwise; and the device
        there is the controller (its Status Return Level is not where a servo's is).

        On a pseudo-terminal the controller is a program on this host (`snakebot sim
        serve`), which a busy host may deschedule far longer than a UART stalls: unless
        ``margin_s`` or ``SNAKEBOT_MARGIN_MS`` says otherwise, replies there get
        ``timing.PROGRAM_MARGIN_S`` of slack. It costs nothing while the controller
        answers; the controller is one device at one ID, never scanned for."""
        link_options.setdefault("echo", False)
        if link_options.get("margin_s") is None and is_pseudo_terminal(port):
            link_options["margin_s"] = settings.resolve_margin_s(default=timing.PROGRAM_MARGIN_S)
        link_options.setdefault("device", devices.controller())
        link = DxlClient(port, baudrate, **link_options)
        return cls(link, controller_id, port_name=port)

    def close(self) -> None:
        self.link.close()

    def __enter__(self) -> ControllerClient:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    @property
    def baudrate(self) -> int:
        return self.link.baudrate

    # -- errors -----------------------------------------------------------------------------

    @contextlib.contextmanager
    def link_errors(self, what: str) -> Iterator[None]:
        """Turn transport failures during ``what`` into errors that name the controller."""
        where = f"the controller (ID {self.id}) on {self.port_name or 'the port'}"
        try:
            yield
        except DxlTimeout:
            raise ControllerLinkError(
                f"{where} did not answer {what} at {self.baudrate} baud",
                "check that the CM-530 is powered and its USB cable connected, that it runs "
                "the snakebot firmware (not the ROBOTIS bootloader; `snakebot flash` installs "
                "it), and that "
                f"the baud rate ({self.baudrate}) and the controller ID ({self.id}) match it",
            ).about("baud", "controller_id") from None
        except CorruptPacket as exc:
            raise ControllerLinkError(
                f"{where} answered {what} with damaged packets ({exc})",
                f"check the USB cable and that the baud rate ({self.baudrate}) matches the "
                "controller",
            ).about("baud") from None
        except ServoError as exc:
            flags = ErrorFlags(exc.flags)
            hint = (
                "a value outside the register's range, a register that cannot be written, "
                "or, while the serpenoid runs, a value its joints' limits or the servos' "
                "speed refuse (the Refusal Reason register says which)"
                if flags & ErrorFlags.RANGE
                else "an instruction it does not support"
                if flags & ErrorFlags.INSTRUCTION
                else flags.describe()
            )
            raise ControllerRefused(
                f"{where} refused {what} ({flags.describe()}: {hint}); check that this "
                "snakebot matches the controller's firmware version",
                exc.flags,
            ) from None

    # -- raw transactions -----------------------------------------------------------------

    def read_block(self, address: int, length: int) -> bytes:
        """READ ``length`` bytes of the controller's table from ``address``."""
        with self.link_errors(f"READ {address}..{address + length - 1}"):
            packet = protocol.read(self.id, address, length)
            return self.link.transact(packet, self.id, length).params

    def write_block(self, address: int, data: bytes, *, retries: int | None = None) -> None:
        """WRITE ``data`` at ``address`` and wait for the acknowledgement."""
        with self.link_errors(f"WRITE {address}..{address + len(data) - 1}"):
            packet = protocol.write(self.id, address, bytes(data))
            self.link.transact(packet, self.id, 0, retries=retries)

    # -- registers by name ----------------------------------------------------------------

    def registers(self, names: Iterable[str]) -> list[Register]:
        return [self.table.register(n) for n in names]

    def _by_page(self, names: Iterable[str]) -> dict[int | None, list[str]]:
        """``names`` grouped by the window page that shows them (None: no page needed)."""
        groups: dict[int | None, list[str]] = {}
        for name in names:
            groups.setdefault(self.table.page_number(name), []).append(name)
        return groups

    def show_page(self, page: int) -> None:
        """WRITE Window Page = ``page``."""
        selector = self.table.register("Window Page")
        self.write_block(selector.address, selector.encode(page))

    def read(self, *names: str) -> dict[str, int]:
        """The named registers, fetched with one READ spanning them all (per window page:
        a field of a page is read after writing its page to Window Page)."""
        values: dict[str, int] = {}
        for page, group in self._by_page(names).items():
            regs = self.registers(group)
            if page is not None:
                self.show_page(page)
            start = min(r.address for r in regs)
            end = max(r.end for r in regs)
            data = self.read_block(start, end - start)
            values.update({r.name: r.decode(data[r.address - start : r.end - start]) for r in regs})
        return {self.table.register(n).name: values[self.table.register(n).name] for n in names}

    def read_all(self) -> dict[str, int]:
        """Every readable register below the upload window (one READ)."""
        end = self.table.register("Upload Offset").end
        return self.table.decode(0, self.read_block(0, end))

    def write(self, values: Mapping[str, int]) -> None:
        """WRITE registers by name; each value is range-checked first (ControllerTableError
        names the range), and adjacent registers go out in one packet, in address order.
        Fields of a window page go after their page: Window Page travels in the same
        packet when the window's first field is written."""
        for page, group in self._by_page(values).items():
            encoded = [
                (r.address, r.encode(int(values[n])))
                for n, r in zip(group, self.registers(group), strict=True)
            ]
            if page is not None:
                selector = self.table.register("Window Page")
                encoded.append((selector.address, selector.encode(page)))
            self._write_runs(sorted(encoded))

    def _write_runs(self, encoded: list[tuple[int, bytes]]) -> None:
        """WRITE (address, bytes) pairs in address order, adjacent ones in one packet."""
        run_start, run = -1, b""
        for address, data in encoded:
            if run and address == run_start + len(run):
                run += data
                continue
            if run:
                self.write_block(run_start, run)
            run_start, run = address, data
        if run:
            self.write_block(run_start, run)

    def command(self, name: str) -> None:
        """Write ``Command`` = ``name`` (PLAY, SERPENOID, STOP, CLEAR)."""
        code = self.table.enums["Command"].get(name.upper())
        if code is None:
            raise ControllerInputError(
                f"no controller command {quoted(name)}: use one of "
                + ", ".join(self.table.enums["Command"])
            )
        self.write({"Command": code})

    # -- identity ---------------------------------------------------------------------------

    def identify(self) -> dict[str, int]:
        """Check that a snakebot controller of our table version answers at our ID and that
        it acknowledges WRITEs; returns Model Number, Firmware Version, ID, Status Return
        Level and State."""
        info = self.read(*IDENTITY_REGISTERS)
        self.check_identity(info)
        return info

    def check_identity(self, info: Mapping[str, int]) -> None:
        """The checks of :meth:`identify` on registers already read (the
        :data:`IDENTITY_REGISTERS`, e.g. within a longer READ)."""
        if info["Model Number"] != self.table.model_number:
            raise NotAController(
                f"the device at ID {self.id} on {self.port_name} reports model number "
                f"{info['Model Number']}, not a snakebot controller ({self.table.model_number}): "
                "check the port and the controller ID (a servo answers here, or another "
                "firmware runs on the CM-530; `snakebot flash` installs the snakebot firmware)"
            ).about("port", "controller_id")
        if info["Firmware Version"] != self.table.firmware_version:
            raise NotAController(
                f"the controller's control table is version {info['Firmware Version']}, this "
                f"snakebot speaks version {self.table.firmware_version}: flash the firmware "
                "built from this snakebot (`make firmware`, then `snakebot flash`), or install "
                "the snakebot that matches the controller"
            )
        if info["Status Return Level"] < 2:
            raise ControllerStateError(
                f"the controller's Status Return Level is {info['Status Return Level']}, so it "
                "does not acknowledge WRITEs and nothing can be checked: power-cycle it (the "
                "level returns to 2) or write 2 to its register 4"
            )

    # -- the roster -------------------------------------------------------------------------

    def roster(self, count: int | None = None) -> list[JointRecord]:
        """The first ``count`` roster joints (default: Joint Count), page by page."""
        if count is None:
            count = self.read("Joint Count")["Joint Count"]
        per_page = self.table.servo_records
        size = self.table.servo_record_size
        page_reg = self.table.register("Window Page")
        records: list[JointRecord] = []
        for first in range(0, count, per_page):
            page, _ = self.table.servo_page(first)
            shown = min(per_page, count - first)
            self.write_block(page_reg.address, page_reg.encode(page))
            data = self.read_block(self.table.servo_window_address, shown * size)
            for slot, record in enumerate(self.table.decode_servo_window(data)):
                records.append(JointRecord.from_record(first + slot, record))
        return records

    def set_roster(self, joints: Iterable[RosterEntry]) -> None:
        """Make ``joints`` the roster: each record's configuration, then Joint Count."""
        entries = list(joints)
        limit = self.table.register("Joint Count").max or 0
        if not 1 <= len(entries) <= limit:
            raise ControllerInputError(
                f"a roster needs 1..{limit} joints, got {len(entries)}: check the robot file"
            )
        page_reg = self.table.register("Window Page")
        fields = [self.table.servo_field(n) for n in ROSTER_FIELDS]
        shown_page = -1
        for joint, entry in enumerate(entries):
            page, slot = self.table.servo_page(joint)
            values = (entry.id, int(entry.reverse), entry.zero_tick, entry.min_tick, entry.max_tick)
            data = b"".join(f.encode(v) for f, v in zip(fields, values, strict=True))
            address = self.table.servo_address(slot, ROSTER_FIELDS[0])
            if page != shown_page:
                self.write_block(page_reg.address, page_reg.encode(page))
                shown_page = page
            self.write_block(address, data)
        self.write({"Joint Count": len(entries)})
