"""Fault campaigns: the real controller firmware (QEMU) driving the emulated robot while
faults are injected from a seed, and what the controller promises checked throughout.

    python -m tests.reliability.rig.campaigns      # every campaign, a table of results
    python -m tests.reliability.rig.campaigns --only corrupt-1pct --seed 7 --json

Each campaign boots ``build/qemu/flash.bin`` (``make firmware``) with USART1 on an
emulated bus of three AX-12s and USART3 on a pseudo-terminal, uploads a gait table whose
frames sit on the joint limits and plays it with a steering offset that pushes every goal
past a limit (so the clamp is what keeps the servos inside), then injects its fault for a
few seconds of bus time. What it checks, in every campaign:

limits
    every goal position the firmware writes on the bus (read from its bytes before the
    bus damages them) lies within the table's limits for that joint;
alive
    the controller answers every PING (the client retries twice); it never reboots (its
    SysTick uptime, read from RAM through QEMU, only grows); its control loop never stalls
    (the bus-packet counter in RAM grows between samples); no bus packet or PC reply was
    ever refused for want of buffer room;
table
    the committed table is never lost or damaged: Table Size and Table CRC, and the CRC of
    the active table's bytes read back from the emulated RAM, equal the committed file's;
counted
    every fault the controller can see shows up in its counters, read the way
    ``snakebot monitor`` reads them (:func:`snakebot.link.controller.monitor.sample`): each
    telemetry READ the firmware sent ends as exactly one Bus Read or Bus Timeout, no more
    Bus Reads than intact replies came back, no fewer Bus Timeouts than were lost, no more
    Bus Errors than damaged replies were heard; plus each campaign's own (BUS_LOSS for a
    long brown-out, PC Errors equal to the rejections the noise must cause, INCOMPLETE
    for every cut upload).

The rig's own view: what it reads from RAM (through QEMU's monitor, at addresses from the
symbols of ``build/qemu/firmware.elf``) counts only once it is shown to be the running
firmware's: at start, the monitor must name this rig's QEMU, the flash must hold what that
ELF loads (QEMU booted that very build), and the uptime counter must advance, never faster
than the wall clock; right after the first commit, the table found in RAM must be the one
Table Size and Table CRC describe. A mismatch stops the campaign with ``CampaignFailed``
(exit 2 from the command line) naming it, instead of passing as a broken promise; a
reboot is reported with the CPU's PC and SP and QEMU's log.

The watchdog: QEMU does not model the STM32's IWDG (see firmware/boards/qemu/board.h),
so it cannot fire here. What it guards against (a main loop that stops feeding it for
500 ms) is checked directly instead: the loop's progress counter, PING, and the longest
silence between the firmware's bus packets while the roster is polled (``max_bus_gap_ms``,
reported; the control tick is 10 ms).

Reproducibility: the faults are drawn from streams seeded by ``--seed``
(:mod:`snakebot.sim.bus.faults`; the PC-link noise from its own stream), so a seed fixes which
byte of the wire's traffic is hit, which reply is dropped, what noise is sent. The bus
runs on the wall clock against QEMU, so how many bytes flow in a campaign (and therefore
the counts) varies by a few percent from run to run and machine to machine; the checks
hold in every run.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import random
import re
import subprocess
import sys
import tempfile
import time
import zlib
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from elftools.common.exceptions import ELFError
from elftools.elf.elffile import ELFFile

from snakebot.facts import devices
from snakebot.facts.boards import PC_LINK_BAUD as PC_BAUD
from snakebot.formats import protocol
from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol import (
    MAX_PACKET_LEN,
    Instruction,
    Packet,
    PacketParser,
    ProtocolError,
    Rejected,
)
from snakebot.formats.upload_writes import chunk_writes, commit_write
from snakebot.link.controller import Command, ControllerErrors, State, UploadResult, load
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.errors import ControllerError
from snakebot.link.controller.limits import LimitsError, limits_state, set_limits
from snakebot.link.controller.monitor import Sample, sample
from snakebot.paths import REPO_ROOT
from snakebot.sim.bus.bus import Bus
from snakebot.sim.bus.faults import FaultConfig
from snakebot.sim.errors import SimError, SimFailure
from snakebot.sim.qemu import Endpoint, QemuFirmware
from snakebot.sim.servo.fast import VirtualServo
from snakebot.sim.transports.unixsock import UnixSocketServer

BUILD = REPO_ROOT / "build" / "qemu"
IMAGE = BUILD / "flash.bin"
ELF_FILE = BUILD / "firmware.elf"
CORE_DIR = REPO_ROOT / "firmware" / "core"

IDS = (1, 2, 3)
LIMITS = ((300, 724), (320, 700), (300, 724))
FRAMES = np.array([[724, 320, 724], [300, 700, 300], [512, 510, 512], [700, 330, 650]], np.uint16)
PERIOD_MS = 150
STEERING = 150  # ticks added to every goal: half the goals would leave the limits unclamped
CONTROLLER_ID = load().default_id
MARGIN_S = 0.3  # the PC-link client's allowance beyond the wire time (QEMU may be slow)
SAMPLE_S = 0.1  # how often the watch loop looks
STALL_MS = 100  # ten control ticks without a bus packet while the roster is polled
UPTIME_SLACK_MS = 500  # SysTick counts QEMU's virtual time, which never runs ahead of ours
UPTIME_STILL_S = 2.0  # how long the uptime counter may seem to stand still at the start
LOG_TAIL = 2000  # characters of QEMU's log in a problem report
REBUILD = "rebuild the firmware with `make firmware` and run again"
CTL = load()
MAX_LEN_FIELD = MAX_PACKET_LEN - 4  # the largest LEN byte a packet can carry
_AX12 = devices.ax12()
GOAL_POSITION, GOAL_BLOCK = _AX12.span("Goal Position", "Moving Speed")
"""What the firmware's goal SYNC_WRITE sets per servo: Goal Position and Moving Speed."""
TORQUE_ENABLE = _AX12.register("Torque Enable").address
_, TELEMETRY_PARAMS = _AX12.span("Present Position", "Present Temperature")
"""The telemetry READ's length."""
TELEMETRY_ADDRESS = _AX12.register("Present Position").address
"""Where the telemetry READ starts (the firmware also READs angle limits: not telemetry)."""


def _reg(name: str) -> int:
    return CTL.register(name).address


# -- what the firmware puts on the bus, and what comes back -----------------------------------


@dataclass
class Tap:
    """Counts the firmware's bus traffic: its own bytes (before any damage) and the bytes
    that reach it, transaction by transaction."""

    limits: dict[int, tuple[int, int]]
    goal_packets: int = 0
    goals: int = 0
    goals_outside: int = 0
    torque_on: int = 0
    torque_off: int = 0
    reads_sent: int = 0
    reads_answered: int = 0  # an intact reply of the right shape reached the firmware
    reads_damaged: int = 0  # a damaged reply from the addressed servo reached it
    unanswered: Counter = field(default_factory=Counter)  # per servo ID
    max_gap_s: float = 0.0
    _sent: PacketParser = field(default_factory=PacketParser)
    _pending: int | None = None  # ID of the READ in flight
    _rx: bytearray = field(default_factory=bytearray)  # what reached the firmware since
    _prelude: bytearray = field(default_factory=bytearray)  # heard since the last packet
    _last_t: float | None = None
    outside_examples: list[tuple[int, int]] = field(default_factory=list)

    def _close_read(self) -> None:
        """Judge the READ in flight by the bytes that may have reached the firmware in its
        reply window: an intact status packet of its servo with the telemetry block
        anywhere in them is an answer; otherwise a damaged one (right header, ID and
        length, wrong checksum) makes it a damaged reply, and nothing at all a lost one.
        The window is taken as wide as it can be, so these are upper bounds on the reads
        and damaged replies the firmware can count."""
        sid = self._pending
        if sid is None:
            return
        rx, n = bytes(self._rx), TELEMETRY_PARAMS + 6
        answered = damaged = False
        for i in range(len(rx) - n + 1):
            w = rx[i : i + n]
            if w[:4] != bytes([0xFF, 0xFF, sid, TELEMETRY_PARAMS + 2]):
                continue
            if protocol.checksum(w[2:-1]) == w[-1]:
                answered = True
                break
            damaged = True
        if answered:
            self.reads_answered += 1
        else:
            self.unanswered[sid] += 1
            self.reads_damaged += damaged
        self._pending = None
        self._rx.clear()

    def sent(self, t: float, data: bytes) -> None:
        if self._last_t is not None:
            self.max_gap_s = max(self.max_gap_s, t - self._last_t)
        self._last_t = t
        for event in self._sent.feed(data):
            if not isinstance(event, Packet):
                continue
            self._close_read()
            prelude = bytes(self._prelude)
            self._prelude.clear()
            p = event.params
            if event.code == Instruction.SYNC_WRITE and p[:2] == bytes([GOAL_POSITION, GOAL_BLOCK]):
                self.goal_packets += 1
                for k in range(2, len(p) - GOAL_BLOCK, GOAL_BLOCK + 1):
                    sid, goal = p[k], p[k + 1] | p[k + 2] << 8
                    lo, hi = self.limits.get(sid, _AX12.require_position().range)
                    self.goals += 1
                    if not lo <= goal <= hi:
                        self.goals_outside += 1
                        self.outside_examples.append((sid, goal))
            elif event.code == Instruction.SYNC_WRITE and p[:1] == bytes([TORQUE_ENABLE]):
                self.torque_on += 1
            elif event.code == Instruction.WRITE and p[:2] == bytes([TORQUE_ENABLE, 0]):
                self.torque_off += 1
            elif event.code == Instruction.READ and p[:1] == bytes([TELEMETRY_ADDRESS]):
                self.reads_sent += 1
                # The firmware empties its receiver just before it sends, so what reached
                # the bus side since the previous packet may still count for this READ.
                self._pending = event.id
                self._rx[:] = prelude

    def heard(self, data: bytes) -> None:
        (self._rx if self._pending is not None else self._prelude).extend(data)

    def quiet(self) -> None:
        """The bus is idle now: the READ in flight, if any, is over; gaps restart."""
        self._close_read()
        self._last_t = None

    def restart_gaps(self) -> None:
        """Measure the longest silence between packets from now on."""
        self._last_t = None


class TappedBus(Bus):
    """The emulated bus, with the firmware's side of the wire counted by a :class:`Tap`."""

    def __init__(self, tap: Tap, *args: Any, **kwargs: Any) -> None:
        self.tap = tap
        super().__init__(*args, **kwargs)

    def master_write(self, data: bytes) -> None:
        self.tap.sent(self.now, bytes(data))  # before the wire can damage it
        super().master_write(data)

    def master_read(self, size: int) -> bytes:
        out = super().master_read(size)
        if out:
            self.tap.heard(out)
        return out


class AuditedServo(VirtualServo):
    """A virtual AX-12 that keeps account of what it accepted: WRITEs that reached its
    angle limits (EEPROM), and every goal it took outside the robot's limits for it
    (whatever the wire did to the packet that carried it)."""

    def __init__(self, servo_id: int, robot_limits: tuple[int, int]) -> None:
        super().__init__(servo_id)
        self.robot_limits = robot_limits
        cw, ccw = self.regs.entry("CW Angle Limit"), self.regs.entry("CCW Angle Limit")
        self._angle_span = (cw.address, ccw.address + ccw.size)
        self.angle_limit_writes = 0
        self.goals_outside: list[int] = []

    def _write_at(self, address: int, data: bytes, registered: bool) -> int:
        goal = self._goal
        flags = super()._write_at(address, data, registered)
        if flags == 0 and not registered:
            lo, hi = self._angle_span
            self.angle_limit_writes += address < hi and address + len(data) > lo
            low, high = self.robot_limits
            if self._goal != goal and not low <= self._goal <= high:
                self.goals_outside.append(self._goal)
        return flags

    def angle_limits(self) -> tuple[int, int]:
        return self.regs.get("CW Angle Limit"), self.regs.get("CCW Angle Limit")


# -- the firmware's RAM, through QEMU -----------------------------------------------------------


@dataclass(frozen=True)
class RamMap:
    """Where the firmware keeps what the campaigns read back: from the symbol table of the
    ELF the flash image was made from (``build/qemu/firmware.elf``), and a probe compiled
    for the Cortex-M3 for the layout of ``ctl_device``. ``flash`` holds what that ELF
    loads into flash (address, bytes), so a rig can check that QEMU booted this very build
    before it trusts an address (:meth:`Rig.check_view`)."""

    ticks_ms: int
    busport_stats: int
    pclink_stats: int
    ctl: int
    ctl_size: int
    active_offset: int
    active_len_offset: int
    flash: tuple[tuple[int, bytes], ...] = ()
    source: str = ""

    @classmethod
    def from_build(cls, elf_file: Path = ELF_FILE) -> RamMap:
        try:
            with elf_file.open("rb") as f:
                elf = ELFFile(f)
                found = _objects(elf)
                flash = tuple(
                    (seg["p_paddr"], seg.data())
                    for seg in elf.iter_segments()
                    if seg["p_type"] == "PT_LOAD" and seg["p_filesz"] > 0
                )
        except (OSError, ELFError) as exc:
            raise CampaignFailed(f"cannot read {elf_file} ({exc}): {REBUILD}") from None

        def where(name: str, source: str) -> tuple[int, int]:
            try:
                return found[(name, source)]
            except KeyError:
                raise CampaignFailed(f"{name} ({source}) is not in {elf_file}: {REBUILD}") from None

        ctl, ctl_size = where("ctl", "main.c")  # the device, then its table arena
        active, active_len, size = _ctl_layout()
        if size > ctl_size:
            raise CampaignFailed(
                f"ctl_device is {size} bytes in the probe, {ctl_size} in {elf_file}: {REBUILD}"
            )
        return cls(
            ticks_ms=where("ticks_ms", "hal_systick.c")[0],
            busport_stats=where("stats", "busport.c")[0],
            pclink_stats=where("stats", "pclink.c")[0],
            ctl=ctl,
            ctl_size=ctl_size,
            active_offset=active,
            active_len_offset=active_len,
            flash=flash,
            source=str(elf_file),
        )


def _objects(elf: ELFFile) -> dict[tuple[str, str], tuple[int, int]]:
    """(name, source file) -> (address, size) of the ELF's data objects. A file's static
    objects follow its STT_FILE symbol in the table; globals come after every file's
    locals, so they are keyed by no file."""
    symtab = elf.get_section_by_name(".symtab")
    if symtab is None:
        raise ELFError("no symbol table (stripped?)")
    found: dict[tuple[str, str], tuple[int, int]] = {}
    source = ""
    for sym in symtab.iter_symbols():
        kind, bind = sym["st_info"]["type"], sym["st_info"]["bind"]
        if kind == "STT_FILE":
            source = sym.name
        elif kind == "STT_OBJECT":
            found[(sym.name, source if bind == "STB_LOCAL" else "")] = (
                sym["st_value"],
                sym["st_size"],
            )
    return found


def _ctl_layout() -> tuple[int, int, int]:
    """offsetof(ctl_device, active), offsetof(..., active_len), sizeof(ctl_device) on the
    Cortex-M3, from a probe compiled with the firmware's compiler."""
    source = (
        '#include <stddef.h>\n#include "ctl_device.h"\n'
        "const unsigned int snakebot_probe[3] = {offsetof(ctl_device, active), "
        "offsetof(ctl_device, active_len), sizeof(ctl_device)};\n"
    )
    with tempfile.TemporaryDirectory(prefix="snakebot.sim-probe-") as tmp:
        c, o, b = (Path(tmp) / n for n in ("probe.c", "probe.o", "probe.bin"))
        c.write_text(source)
        try:
            subprocess.run(
                [
                    "arm-none-eabi-gcc",
                    "-mcpu=cortex-m3",
                    "-mthumb",
                    "-std=c99",
                    "-Os",
                    f"-I{CORE_DIR}",
                    "-c",
                    str(c),
                    "-o",
                    str(o),
                ],
                check=True,
                capture_output=True,
                text=True,
            )
            subprocess.run(
                ["arm-none-eabi-objcopy", "-O", "binary", "-j", ".rodata", str(o), str(b)],
                check=True,
                capture_output=True,
                text=True,
            )
        except (OSError, subprocess.CalledProcessError) as exc:
            raise SimFailure(
                f"cannot compile the layout probe with arm-none-eabi-gcc ({exc}): run `make setup`"
            ) from exc
        words = np.frombuffer(b.read_bytes()[:12], "<u4")
        return int(words[0]), int(words[1]), int(words[2])


def read_ram(fw: QemuFirmware, address: int, length: int) -> bytes:
    """``length`` bytes of the emulated machine's memory (whole words are read)."""
    first = address & ~3
    words = (address + length - first + 3) // 4
    text = fw.monitor(f"xp /{words}wx {first:#x}")
    values = [
        int(v, 16)
        for line in text.splitlines()
        if ":" in line
        for v in line.split(":", 1)[1].split()
    ]
    raw = b"".join(v.to_bytes(4, "little") for v in values)
    return raw[address - first : address - first + length]


# -- one campaign's rig -----------------------------------------------------------------------


class CampaignFailed(SimFailure):
    """A campaign could not run (not: an invariant failed; that is a result)."""


@dataclass
class Health:
    """What the watch loop saw."""

    pings: int = 0
    ping_failures: int = 0
    reboots: int = 0
    stalls: int = 0
    samples: int = 0
    safe_entries: int = 0
    recoveries: int = 0
    flags_seen: int = 0
    servo_goals_outside: int = 0  # sampled servo goals outside the limits
    table_checks: int = 0
    table_failures: list[str] = field(default_factory=list)
    reboot_details: list[str] = field(default_factory=list)  # registers and QEMU's log


class Rig:
    """QEMU running the firmware, wired to a tapped emulated bus; a controller client on
    the PC link; the firmware's RAM within reach. Use as a context manager."""

    def __init__(
        self,
        faults: FaultConfig,
        workdir: Path,
        play_s: float | None = None,
        ram: RamMap | None = None,
    ) -> None:
        self.tap = Tap(dict(zip(IDS, LIMITS, strict=True)))
        self.servos = [AuditedServo(i, lim) for i, lim in zip(IDS, LIMITS, strict=True)]
        self.bus = TappedBus(self.tap, self.servos, faults=faults)
        self.play_s = play_s  # overrides how long the campaigns that play, play
        self.server = UnixSocketServer(self.bus, workdir / "bus.sock")
        # A name only this QEMU has: the monitor must be this machine's (check_view).
        self.name = f"snakebot-campaign-{os.getpid()}-{workdir.name}"
        self.fw = QemuFirmware(
            IMAGE, bus=Endpoint.unix_client(workdir / "bus.sock"), extra_args=["-name", self.name]
        )
        self.ram = ram if ram is not None else RamMap.from_build()
        self.health = Health()
        self._started = 0.0  # time.monotonic() when QEMU started
        self._table_view_checked = False
        self.ctl: ControllerClient | None = None
        self.committed: tuple[int, int] | None = None  # (size, CRC) of the table on board
        self._uptime = -1
        self._progress: tuple[int, int] | None = None  # (bus packets, uptime) at last change
        self.polling = False  # the roster is polled: the bus must keep moving
        self.last_polled: Sample | None = None  # the last look with the roster in place
        self._last_state = State.IDLE

    def __enter__(self) -> Rig:
        self.server.start()
        try:
            self._started = time.monotonic()
            self.fw.start()
            self.ctl = ControllerClient.open(
                self.fw.ports.pc_link, PC_BAUD, CONTROLLER_ID, margin_s=MARGIN_S, retries=2
            )
            deadline = time.monotonic() + 10
            while not self._answers():
                if time.monotonic() > deadline:
                    raise CampaignFailed(f"the firmware never answered PING: {self.fw.log()}")
                time.sleep(0.05)
            self.check_view()
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        if self.ctl is not None:
            self.ctl.close()
        self.fw.stop()
        self.server.close()

    def _answers(self) -> bool:
        try:
            self.ctl.link.ping(CONTROLLER_ID, retries=0)
            return True
        except ProtocolError:
            return False

    # -- the rig's own view of the machine ----------------------------------------------------

    def check_view(self) -> None:
        """Make sure that what this rig reads through QEMU's monitor is the running
        firmware's RAM where the RAM map says, before any of it counts as a result: the
        monitor answers for this rig's QEMU (its name), the flash holds what the ELF the
        map comes from loads there (QEMU booted that very build), and the uptime counter
        advances, never faster than the wall clock since QEMU started. A mismatch is
        :class:`CampaignFailed` naming it, not a broken promise of the firmware."""
        named = self.fw.monitor("info name").strip()
        if named != self.name:
            raise CampaignFailed(
                f"asked for its name, QEMU's monitor answered {named!r}, not this rig's "
                f"{self.name!r}: another QEMU's monitor, or answers out of step with the "
                "questions; stop stray qemu-system-arm processes and run again"
            )
        for address, data in self.ram.flash:
            held = read_ram(self.fw, address, len(data))
            if held != data:
                at = next(i for i in range(len(data)) if i >= len(held) or held[i] != data[i])
                raise CampaignFailed(
                    f"QEMU booted {IMAGE}, but its flash at {address + at:#x} differs from "
                    f"{self.ram.source}, where the RAM map comes from: two different builds "
                    f"(was the firmware rebuilt after the image was made?); {REBUILD}"
                )
        t0 = time.monotonic()
        first = self._ticks()
        while (now := self._ticks()) == first:
            if time.monotonic() - t0 > UPTIME_STILL_S:
                raise CampaignFailed(
                    f"ticks_ms at {self.ram.ticks_ms:#x} stayed at {first} for "
                    f"{UPTIME_STILL_S:.0f} s: not the firmware's uptime counter; {REBUILD}"
                )
            time.sleep(0.01)
        if now < first:
            raise CampaignFailed(
                f"ticks_ms at {self.ram.ticks_ms:#x} went back from {first} to {now} "
                f"between two reads: not the firmware's uptime counter; {REBUILD}"
            )

    def _ticks(self) -> int:
        return self._plausible_uptime(
            int.from_bytes(read_ram(self.fw, self.ram.ticks_ms, 4), "little")
        )

    def _plausible_uptime(self, ticks: int) -> int:
        """``ticks``, if the firmware can have counted that far since QEMU started."""
        ran_ms = (time.monotonic() - self._started) * 1000
        if ticks > ran_ms + UPTIME_SLACK_MS:
            raise CampaignFailed(
                f"ticks_ms at {self.ram.ticks_ms:#x} reads {ticks} ms, but QEMU started "
                f"{ran_ms:.0f} ms ago: the RAM map ({self.ram.source}) does not describe the "
                f"running firmware; {REBUILD}"
            )
        return ticks

    def _check_table_view(self) -> None:
        """Right after a commit, the firmware's Table Size and Table CRC (set from the
        active table in the same step) and the active table as the RAM map finds it
        must agree; if the registers are right and RAM is not, the map is wrong."""
        self._table_view_checked = True
        assert self.committed is not None
        regs = self.ctl.read("Table Size", "Table CRC")
        if (regs["Table Size"], regs["Table CRC"]) != self.committed:
            return  # the firmware's own fault: check_table reports it
        ram = self.active_table()
        if (len(ram), zlib.crc32(ram)) != self.committed:
            raise CampaignFailed(
                f"right after the commit the firmware reports a {self.committed[0]}-byte "
                f"table CRC {self.committed[1]:#x}, but the RAM map (ctl at "
                f"{self.ram.ctl:#x}, active +{self.ram.active_offset}, length "
                f"+{self.ram.active_len_offset}) finds {len(ram)} bytes CRC "
                f"{zlib.crc32(ram):#x}: the map or the ctl_device layout probe is not the "
                f"running firmware's; {REBUILD}"
            )

    def machine_state(self) -> str:
        """The CPU's PC and SP, and what QEMU logged, for a problem report."""
        regs = dict(re.findall(r"(R1[35]|XPSR)=([0-9a-f]+)", self.fw.monitor("info registers")))
        cpu = ", ".join(
            f"{name} {regs[key]}"
            for name, key in (("PC", "R15"), ("SP", "R13"), ("xPSR", "XPSR"))
            if key in regs
        )
        log = self.fw.log().strip()[-LOG_TAIL:] or "nothing"
        return f"CPU: {cpu or 'no registers'}; QEMU log: {log}"

    # -- the PC link ------------------------------------------------------------------------

    def write(self, values: dict[str, int]) -> None:
        self.ctl.write(values)

    def command(self, cmd: Command) -> None:
        self.ctl.write({"Command": int(cmd)})

    def set_robot_limits(self, limits: dict[int, tuple[int, int]]) -> str:
        """The robot's limits onto the controller; returns Limits State once settled."""
        try:
            return set_limits(self.ctl, limits, timeout_s=20.0).state
        except LimitsError:
            return limits_state(self.ctl)[0]

    def upload(self, blob: bytes, *, commit: bool = True) -> int:
        """The upload sequence; returns Upload Result (after the commit) or -1."""
        for address, data in chunk_writes(blob, controller=CTL):
            self.ctl.write_block(address, data)
        if not commit:
            return -1
        self.ctl.write_block(*commit_write(blob, CTL))
        result = self.ctl.read("Upload Result")["Upload Result"]
        if result == UploadResult.OK:
            self.committed = (len(blob), zlib.crc32(blob))
            if not self._table_view_checked:
                self._check_table_view()
        return result

    # -- looking ----------------------------------------------------------------------------

    def ram_probe(self) -> dict[str, int]:
        ticks = self._ticks()
        bp = read_ram(self.fw, self.ram.busport_stats, 6)
        pc = read_ram(self.fw, self.ram.pclink_stats, 4)
        return {
            "uptime_ms": ticks,
            "bus_packets": int.from_bytes(bp[0:2], "little"),
            "bus_reply_timeouts": int.from_bytes(bp[2:4], "little"),
            "bus_refused": int.from_bytes(bp[4:6], "little"),
            "pc_gap_resets": int.from_bytes(pc[0:2], "little"),
            "pc_tx_dropped": int.from_bytes(pc[2:4], "little"),
        }

    def active_table(self) -> bytes:
        base = self.ram.ctl
        n = int.from_bytes(read_ram(self.fw, base + self.ram.active_len_offset, 2), "little")
        n = min(n, self.ram.ctl_size - self.ram.active_offset)  # no further than the arena
        return read_ram(self.fw, base + self.ram.active_offset, n) if n else b""

    def check_table(self, where: str) -> None:
        """The committed table, as the registers describe it and as RAM holds it."""
        if self.committed is None:
            return
        self.health.table_checks += 1
        size, crc = self.committed
        regs = self.ctl.read("Table Size", "Table CRC")
        ram = self.active_table()
        if (regs["Table Size"], regs["Table CRC"]) != (size, crc):
            self.health.table_failures.append(
                f"{where}: registers say {regs['Table Size']} bytes CRC {regs['Table CRC']:#x}, "
                f"committed {size} bytes CRC {crc:#x}"
            )
        if (len(ram), zlib.crc32(ram)) != (size, crc):
            self.health.table_failures.append(
                f"{where}: RAM holds {len(ram)} bytes CRC {zlib.crc32(ram):#x}, "
                f"committed {size} bytes CRC {crc:#x}"
            )

    def check_alive(self) -> None:
        h = self.health
        h.pings += 1
        try:
            self.ctl.link.ping(CONTROLLER_ID)
        except ProtocolError:
            h.ping_failures += 1
        probe = self.ram_probe()
        packets, uptime = probe["bus_packets"], probe["uptime_ms"]
        if uptime < self._uptime:
            h.reboots += 1
            h.reboot_details.append(
                f"uptime went from {self._uptime} to {uptime} ms; {self.machine_state()}"
            )
            self.check_view()  # a real reboot, not the rig's view of the machine failing
        self._uptime = uptime
        if not self.polling or self._progress is None or packets != self._progress[0]:
            self._progress = (packets, uptime)
        elif uptime - self._progress[1] >= STALL_MS:
            h.stalls += 1  # ticks due, and not one bus packet
            self._progress = (packets, uptime)

    def look(self) -> Sample:
        """One look as ``snakebot monitor`` takes it, plus the servos' own goals."""
        s = sample(self.ctl)
        h = self.health
        h.samples += 1
        h.flags_seen |= s.registers["Error Flags"]
        if s.servos:
            self.last_polled = s
        state = s.registers["State"]
        if state == State.SAFE and self._last_state != State.SAFE:
            h.safe_entries += 1
        self._last_state = state
        with self.server.lock:
            goals = [self.bus.servo(i).regs.get("Goal Position") for i in IDS]
        for goal, (lo, hi) in zip(goals, LIMITS, strict=True):
            h.servo_goals_outside += not lo <= goal <= hi
        return s

    def watch(self, seconds: float, on_look: Callable[[Sample], None] | None = None) -> None:
        """Look, check life and the table, and let ``on_look`` act, for ``seconds``."""
        end = time.monotonic() + seconds
        while True:
            self.check_alive()
            s = self.look()
            if on_look is not None:
                on_look(s)
            if time.monotonic() >= end:
                break
            time.sleep(SAMPLE_S)
        self.check_table("while playing")

    def operator(self, recover_after_s: float = 0.3) -> Callable[[Sample], None]:
        """What a person at ``snakebot monitor`` would do: when the controller has gone
        SAFE, wait a little, CLEAR and PLAY again."""
        since: list[float] = []

        def act(s: Sample) -> None:
            if s.registers["State"] != State.SAFE:
                since.clear()
                return
            if not since:
                since.append(time.monotonic())
            elif time.monotonic() - since[0] >= recover_after_s:
                self.command(Command.CLEAR)
                self.command(Command.PLAY)
                self.health.recoveries += 1
                since.clear()

        return act

    def freeze(self) -> Sample:
        """Stop and empty the roster so the bus goes quiet; the last look."""
        self.command(Command.STOP)
        self.polling = False
        self.write({"Joint Count": 0})
        time.sleep(0.15)  # past the last reply window (30 ms) and a few ticks
        with self.server.lock:
            self.tap.quiet()
        self.check_alive()
        return self.look()

    def started_polling(self) -> None:
        """The roster is set: from now on the bus must carry a READ every tick."""
        with self.server.lock:
            self.tap.restart_gaps()
        self.polling = True


# -- the campaigns ---------------------------------------------------------------------------------


@dataclass
class Outcome:
    """One campaign's result: what was injected, what was counted, what held."""

    name: str
    seed: int
    description: str
    seconds: float = 0.0
    counts: dict[str, int | float] = field(default_factory=dict)
    checks: dict[str, bool] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return all(self.checks.values())

    @property
    def command(self) -> str:
        return f"python -m tests.reliability.rig.campaigns --only {self.name} --seed {self.seed}"

    def check(self, name: str, held: bool, why: str = "") -> None:
        self.checks[name] = self.checks.get(name, True) and bool(held)
        if not held:
            self.problems.append(f"{name}: {why}" if why else name)

    def as_record(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "seed": self.seed,
            "description": self.description,
            "command": self.command,
            "ok": self.ok,
            "seconds": round(self.seconds, 1),
            "counts": self.counts,
            "checks": self.checks,
            "problems": self.problems,
        }


def gait_table() -> bytes:
    return GaitTable(IDS, PERIOD_MS, True, LIMITS, FRAMES, {"campaign": "limits"}).encode()


def big_table() -> bytes:
    """A second, longer table (ten upload chunks) for the upload campaign."""
    t = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    frames = np.stack([512 + 150 * np.sin(t + k) for k in range(len(IDS))], axis=1)
    return GaitTable(IDS, 40, True, LIMITS, frames.round().astype(np.uint16), {}).encode()


def _start(rig: Rig, out: Outcome) -> None:
    """Upload the table, steer it against the limits, play."""
    result = rig.upload(gait_table())
    if result != UploadResult.OK:
        raise CampaignFailed(f"the campaign's own table was refused: Upload Result {result}")
    rig.started_polling()
    rig.write({"Steering Offset": STEERING})
    rig.command(Command.PLAY)
    rig.check_table("after commit")


def _common_checks(rig: Rig, out: Outcome, last: Sample) -> None:
    """The invariants every campaign checks; fills the common counts."""
    tap, h, r = rig.tap, rig.health, last.registers
    ram = rig.ram_probe()
    out.counts.update(
        goal_packets=tap.goal_packets,
        goals=tap.goals,
        goals_outside_limits=tap.goals_outside,
        servo_goals_outside_limits=h.servo_goals_outside,
        servo_goals_accepted_outside=sum(len(s.goals_outside) for s in rig.servos),
        angle_limit_writes=sum(s.angle_limit_writes for s in rig.servos),
        reads_sent=tap.reads_sent,
        reads_answered=tap.reads_answered,
        reads_damaged=tap.reads_damaged,
        bus_reads=r["Bus Reads"],
        bus_timeouts=r["Bus Timeouts"],
        bus_errors=r["Bus Errors"],
        pc_packets=r["PC Packets"],
        pc_errors=r["PC Errors"],
        pings=h.pings,
        ping_failures=h.ping_failures,
        reboots=h.reboots,
        loop_stalls=h.stalls,
        safe_entries=h.safe_entries,
        recoveries=h.recoveries,
        uptime_ms=ram["uptime_ms"],
        max_bus_gap_ms=round(tap.max_gap_s * 1000, 1),
        table_checks=h.table_checks,
        corrupted_bytes=rig.bus.faults.corrupted_bytes,
        dropped_replies=rig.bus.faults.dropped_replies,
    )
    out.counts["error_flags_seen"] = h.flags_seen
    # READs whose reply did come, but after the firmware's reply window (a busy host)
    out.counts["late_replies"] = r["Bus Timeouts"] - (tap.reads_sent - tap.reads_answered)
    out.check(
        "limits", tap.goals_outside == 0, f"goals outside the limits: {tap.outside_examples[:5]}"
    )
    out.check("limits", tap.goal_packets > 0, "no goals were sent at all")
    out.check("alive", h.ping_failures == 0, f"{h.ping_failures} PINGs unanswered")
    out.check(
        "alive",
        h.reboots == 0,
        f"the firmware rebooted {h.reboots} times ({'; '.join(h.reboot_details[:3])})",
    )
    out.check("alive", h.stalls == 0, f"the control loop stalled in {h.stalls} samples")
    out.check(
        "alive", ram["bus_refused"] == 0 and ram["pc_tx_dropped"] == 0, f"buffers overflowed: {ram}"
    )
    out.check("table", not h.table_failures, "; ".join(h.table_failures[:3]))
    out.check("table", h.table_checks > 0, "the table was never checked")
    accounted = r["Bus Reads"] + r["Bus Timeouts"]
    lost = tap.reads_sent - tap.reads_answered
    out.check(
        "counted",
        accounted == tap.reads_sent,
        f"{tap.reads_sent} READs sent, {accounted} counted as read or timed out",
    )
    out.check(
        "counted",
        r["Bus Reads"] <= tap.reads_answered,
        f"{r['Bus Reads']} Bus Reads but only {tap.reads_answered} intact replies",
    )
    out.check(
        "counted",
        r["Bus Timeouts"] >= lost,
        f"{lost} READs lost their reply, Bus Timeouts says {r['Bus Timeouts']}",
    )
    out.check(
        "counted",
        r["Bus Errors"] <= tap.reads_damaged,
        f"{r['Bus Errors']} Bus Errors, {tap.reads_damaged} damaged replies heard",
    )
    polled = rig.last_polled
    if polled is not None and all(j.timeout_count < 255 for j in polled.servos):
        # the registers, then the servo window a moment later: at most a READ or two apart
        per_servo = sum(j.timeout_count for j in polled.servos)
        then = polled.registers["Bus Timeouts"]
        out.check(
            "counted",
            then <= per_servo <= then + 2,
            f"per-servo Timeout Counts sum to {per_servo}, Bus Timeouts was {then}",
        )


def _play_under(seconds: float, recover: bool = True) -> Callable[[Rig, Outcome], None]:
    """A campaign body: play for ``seconds`` with the fault on, an operator recovering
    from SAFE."""

    def body(rig: Rig, out: Outcome) -> None:
        _start(rig, out)
        rig.watch(rig.play_s or seconds, rig.operator() if recover else None)

    return body


def _servo_limits(seconds: float) -> Callable[[Rig, Outcome], None]:
    """A campaign body: the robot's limits set on the controller first (the servos' angle
    limits start at the factory 0..1023), then play as the other campaigns do."""
    play = _play_under(seconds)

    def body(rig: Rig, out: Outcome) -> None:
        state = rig.set_robot_limits(dict(zip(IDS, LIMITS, strict=True)))
        out.check("servo-limits", state == "VERIFIED", f"Limits State {state} after setting")
        with rig.server.lock:
            held = [s.angle_limits() for s in rig.servos]
        out.check(
            "servo-limits",
            held == list(LIMITS),
            f"the servos' angle limits are {held}, the robot's {list(LIMITS)}",
        )
        play(rig, out)

    return body


def _after_servo_limits(rig: Rig, out: Outcome, last: Sample) -> None:
    """No servo took a goal outside the robot's limits, however the bus damaged packets."""
    _after_corrupt(rig, out, last)
    outside = {s.id: s.goals_outside[:5] for s in rig.servos if s.goals_outside}
    out.check("servo-limits", not outside, f"servos accepted goals outside the limits: {outside}")


def _clean(rig: Rig, out: Outcome) -> None:
    _play_under(3.0)(rig, out)


def _after_clean(rig: Rig, out: Outcome, last: Sample) -> None:
    """Nothing is lost or damaged in a healthy run. A reply that reaches the firmware
    after its 30 ms window (a busy host) is rightly a Bus Timeout: reported as late."""
    r, tap = last.registers, rig.tap
    out.check(
        "counted",
        tap.reads_answered == tap.reads_sent and r["Bus Errors"] == 0 and r["PC Errors"] == 0,
        f"a healthy run lost {tap.reads_sent - tap.reads_answered} replies and counted "
        f"{r['Bus Errors']} bus errors, {r['PC Errors']} PC errors",
    )
    out.check("alive", rig.health.safe_entries == 0, "a healthy run went SAFE")


def _after_corrupt(rig: Rig, out: Outcome, last: Sample) -> None:
    lost = rig.tap.reads_sent - rig.tap.reads_answered
    out.counts["reads_lost"] = lost
    if rig.bus.faults.corrupted_bytes > 50:
        out.check(
            "counted",
            last.registers["Bus Timeouts"] > 0,
            "bytes were corrupted but no READ ever timed out",
        )


def _after_drop(rig: Rig, out: Outcome, last: Sample) -> None:
    dropped = rig.bus.faults.dropped_replies
    out.check(
        "counted",
        last.registers["Bus Timeouts"] >= dropped,
        f"{dropped} replies dropped, Bus Timeouts {last.registers['Bus Timeouts']}",
    )
    out.check("counted", dropped > 0, "the campaign dropped nothing")


def _brownout(duration_s: float) -> Callable[[Rig, Outcome], None]:
    def body(rig: Rig, out: Outcome) -> None:
        _start(rig, out)
        rig.watch(0.5, rig.operator())
        rng = random.Random(f"{out.seed}/brownout")
        start = 0.1 + rng.uniform(0.0, 0.2)
        victim = rig.bus.servo(2)
        with rig.server.lock:
            t0 = rig.bus.now + start
            rig.bus.at(t0, victim.power_off)
            rig.bus.at(t0 + duration_s, victim.power_on)
            before = rig.tap.unanswered[2]
        out.counts["brownout_ms"] = round(duration_s * 1000)
        recover_wait = start + duration_s + 0.2  # the operator waits for the servo to be back
        rig.watch(start + duration_s + 1.5, rig.operator(recover_wait))
        with rig.server.lock:
            out.counts["servo2_reads_unanswered"] = rig.tap.unanswered[2] - before
            unanswered_total = rig.tap.unanswered[2]
            position = rig.bus.positions([2])[0]
        s = rig.look()
        counted = next(j.timeout_count for j in s.servos if j.id == 2)
        out.counts["servo2_timeout_count"] = counted
        out.check(
            "counted",
            counted >= min(unanswered_total, 255),
            f"servo 2 missed {unanswered_total} READs, its Timeout Count says {counted}",
        )
        # over one whole cycle of the gait, servo 2 sweeps its range again
        seen = [position]
        for _ in range(int(len(FRAMES) * PERIOD_MS / 50) + 2):
            time.sleep(0.05)
            with rig.server.lock:
                seen.append(rig.bus.positions([2])[0])
        sweep = max(seen) - min(seen)
        out.counts["servo2_sweep_after_ticks"] = round(sweep)
        out.check(
            "recovered", sweep > 50, f"servo 2 swept only {sweep:.0f} ticks after it came back"
        )

    return body


def _after_brownout(long: bool) -> Callable[[Rig, Outcome, Sample], None]:
    def check(rig: Rig, out: Outcome, last: Sample) -> None:
        unanswered = out.counts["servo2_reads_unanswered"]
        out.check("counted", unanswered > 0, "no READ of servo 2 went unanswered")
        if long:
            out.check(
                "counted",
                rig.health.flags_seen & ControllerErrors.BUS_LOSS,
                "the brown-out never raised BUS_LOSS",
            )
            out.check("counted", rig.health.safe_entries >= 1, "the controller never went SAFE")
            out.check("counted", rig.tap.torque_off >= 1, "no torque-off was sent on SAFE")
        else:
            out.check("alive", rig.health.safe_entries == 0, "a short brown-out tripped SAFE")

    return check


class PcLinkModel:
    """The controller's PC link as the firmware parses it, for predicting what noise does:
    the shared resynchronisation rule (:class:`snakebot.formats.protocol.PacketParser`), and after
    each byte the firmware's extra step (``dxl_parser_skip_to_hidden``): while a candidate
    is incomplete, the first later ``FF FF`` that starts a complete packet with a good
    checksum among the bytes held back wins, and what lay before it is one rejection."""

    def __init__(self) -> None:
        self.parser = PacketParser()
        self.held = b""  # the parser's pending bytes (the last ``pending`` bytes fed)

    def reset(self) -> None:
        self.parser.reset()
        self.held = b""

    def _feed(self, data: bytes) -> list[Packet | Rejected]:
        events = self.parser.feed(data)
        pending = self.parser.pending
        self.held = (self.held + data)[len(self.held) + len(data) - pending :] if pending else b""
        return events

    def _hidden(self) -> int | None:
        held = self.held
        for i in range(1, len(held) - 3):
            if held[i] != 0xFF or held[i + 1] != 0xFF or held[i + 2] == 0xFF:
                continue
            end = i + held[i + 3] + 4
            if 2 <= held[i + 3] <= MAX_LEN_FIELD and end <= len(held):
                if protocol.checksum(held[i + 2 : end - 1]) == held[end - 1]:
                    return i
        return None

    def feed(self, data: bytes) -> list[Packet | Rejected]:
        events: list[Packet | Rejected] = []
        for byte in data:
            events += self._feed(bytes([byte]))
            while self.parser.pending and (i := self._hidden()) is not None:
                events.append(Rejected("hidden", self.held[:i]))
                rest = self.held[i:]
                self.reset()
                events += self._feed(rest)
        return events


def _pc_noise(rig: Rig, out: Outcome) -> None:
    """Noise bursts on the PC link while the table plays; each is followed at once by a
    PING, or first by a pause (the firmware drops a partial packet after 100 ms)."""
    _start(rig, out)
    rng = random.Random(f"{out.seed}/pc-noise")
    ctl = rig.ctl
    link = ctl.link
    base = ctl.read("PC Packets", "PC Errors")
    model = PcLinkModel()
    expected = Counter()
    predicted_wrong = 0
    bursts = noise_bytes = answered = 0
    for _ in range(40):
        size = rng.randint(1, 24)
        if rng.random() < 0.5:
            noise = bytes(rng.getrandbits(8) for _ in range(size))
        else:  # FF-rich: fake headers and length bytes
            noise = bytes(
                rng.choice((0xFF, 0xFF, 0x00, CONTROLLER_ID, 0x02, 0x04, 0xF0)) for _ in range(size)
            )
        bursts += 1
        noise_bytes += len(noise)
        link.port.write(noise)
        expected.update(type(e).__name__ for e in model.feed(noise))
        if rng.random() < 0.4:
            time.sleep(0.15)  # past PCLINK_GAP_MS: the firmware drops what it holds
            model.reset()
        ping = protocol.ping(CONTROLLER_ID)
        events = model.feed(ping)
        expected.update(type(e).__name__ for e in events)
        will_answer = any(isinstance(e, Packet) and e.encode() == ping for e in events)
        try:
            link.transact(ping, CONTROLLER_ID, 0, retries=0)
            did_answer = True
        except ProtocolError:
            did_answer = False
        answered += did_answer
        predicted_wrong += did_answer != will_answer
        if not did_answer:
            model.reset()  # the client waited past the firmware's 100 ms gap
        rig.check_alive()  # its PING is one more packet, parsed from a clean state
        expected["Packet"] += 1
    time.sleep(0.15)  # nothing left pending
    after = ctl.read("PC Packets", "PC Errors")
    expected["Packet"] += 1  # this READ itself
    got_packets = (after["PC Packets"] - base["PC Packets"]) & 0xFFFF
    got_errors = (after["PC Errors"] - base["PC Errors"]) & 0xFFFF
    out.counts.update(
        noise_bursts=bursts,
        noise_bytes=noise_bytes,
        pings_through_noise=answered,
        pc_errors_expected=expected["Rejected"],
        pc_errors_counted=got_errors,
        pc_packets_expected=expected["Packet"],
        pc_packets_counted=got_packets,
    )
    out.check(
        "counted",
        got_errors == expected["Rejected"],
        f"PC Errors grew by {got_errors}, the noise must cause {expected['Rejected']}",
    )
    out.check(
        "counted",
        got_packets == expected["Packet"],
        f"PC Packets grew by {got_packets}, expected {expected['Packet']}",
    )
    out.check(
        "counted",
        predicted_wrong == 0,
        f"{predicted_wrong} PINGs answered otherwise than the parser rule predicts",
    )
    out.check("counted", answered > 0, "no PING got through the noise")
    rig.watch(0.3, rig.operator())


def _upload_cut(rig: Rig, out: Outcome) -> None:
    """While table A plays, an upload of table B is cut after every chunk (and in the
    middle of every chunk's packet) and committed anyway; then B is uploaded whole."""
    _start(rig, out)
    ctl = rig.ctl
    b = big_table()
    chunks = chunk_writes(b, controller=CTL)
    out.counts["table_b_chunks"] = len(chunks)
    refused = incomplete_flag = still_playing = 0
    for cut in range(len(chunks)):
        for mid in (False, True):
            for address, data in chunks[:cut]:
                ctl.write_block(address, data)
            if mid:
                address, data = chunks[cut]
                packet = protocol.write(CONTROLLER_ID, address, data)
                ctl.link.port.write(packet[: len(packet) // 2])  # the cable is pulled
                time.sleep(0.15)
            ctl.write_block(*commit_write(b, CTL))
            regs = ctl.read("Upload Result", "Error Flags", "State")
            refused += regs["Upload Result"] == UploadResult.INCOMPLETE
            incomplete_flag += bool(regs["Error Flags"] & ControllerErrors.UPLOAD_LENGTH)
            still_playing += regs["State"] == State.PLAYING
            rig.check_alive()
            rig.check_table(f"after a cut at chunk {cut}{' (mid-packet)' if mid else ''}")
    cuts = 2 * len(chunks)
    out.counts.update(
        cuts=cuts,
        commits_refused_incomplete=refused,
        upload_length_flag_set=incomplete_flag,
        kept_playing=still_playing,
    )
    out.check("table", refused == cuts, f"{cuts - refused} cut uploads were not INCOMPLETE")
    out.check("counted", incomplete_flag == cuts, "UPLOAD_LENGTH was not raised for every cut")
    out.check("table", still_playing == cuts, "a refused commit stopped the playing table")
    # the whole table B now lands, and plays
    result = rig.upload(b)
    out.check("table", result == UploadResult.OK, f"the whole table B was refused: {result}")
    rig.check_table("after the whole upload")
    rig.command(Command.PLAY)
    rig.watch(0.5, rig.operator())


@dataclass(frozen=True)
class Campaign:
    name: str
    description: str
    faults: Callable[[int], FaultConfig]
    body: Callable[[Rig, Outcome], None]
    after: Callable[[Rig, Outcome, Sample], None] | None = None


def _corrupt(p: float) -> Callable[[int], FaultConfig]:
    return lambda seed: FaultConfig(seed=seed, corrupt=p)


CAMPAIGNS: dict[str, Campaign] = {
    c.name: c
    for c in (
        Campaign(
            "clean",
            "no faults: the healthy baseline (no reply lost, no error counted)",
            lambda s: FaultConfig(seed=s),
            _clean,
            _after_clean,
        ),
        Campaign(
            "corrupt-0.1pct",
            "each byte on the servo bus has one bit flipped w.p. 0.1 %",
            _corrupt(0.001),
            _play_under(4.0),
            _after_corrupt,
        ),
        Campaign(
            "corrupt-1pct",
            "each byte on the servo bus has one bit flipped w.p. 1 %",
            _corrupt(0.01),
            _play_under(4.0),
            _after_corrupt,
        ),
        Campaign(
            "corrupt-5pct",
            "each byte on the servo bus has one bit flipped w.p. 5 %",
            _corrupt(0.05),
            _play_under(4.0),
            _after_corrupt,
        ),
        Campaign(
            "servo-limits-1pct",
            "the robot's limits set in the servos first, then as corrupt-1pct: no servo "
            "may accept a goal outside them",
            _corrupt(0.01),
            _servo_limits(4.0),
            _after_servo_limits,
        ),
        Campaign(
            "servo-limits-5pct",
            "the robot's limits set in the servos first, then as corrupt-5pct: no servo "
            "may accept a goal outside them",
            _corrupt(0.05),
            _servo_limits(4.0),
            _after_servo_limits,
        ),
        Campaign(
            "drop-10pct",
            "each servo status packet is lost w.p. 10 %",
            lambda s: FaultConfig(seed=s, drop=0.10),
            _play_under(4.0),
            _after_drop,
        ),
        Campaign(
            "brownout-short",
            "servo 2 loses power for 60 ms (fewer misses than "
            "Bus Loss Limit) and comes back with its RAM reset",
            lambda s: FaultConfig(seed=s),
            _brownout(0.06),
            _after_brownout(False),
        ),
        Campaign(
            "brownout-long",
            "servo 2 loses power for 600 ms and comes back with its RAM "
            "reset; the operator CLEARs and PLAYs again",
            lambda s: FaultConfig(seed=s),
            _brownout(0.6),
            _after_brownout(True),
        ),
        Campaign(
            "pc-noise",
            "40 bursts of noise on the PC link (random and FF-rich, 1-24 "
            "bytes), each followed by a PING at once or after a pause",
            lambda s: FaultConfig(seed=s),
            _pc_noise,
        ),
        Campaign(
            "upload-cut",
            "an upload of a 10-chunk table cut after every chunk and in "
            "the middle of every chunk's packet, committed anyway, while another plays",
            lambda s: FaultConfig(seed=s),
            _upload_cut,
        ),
    )
}


# -- the gait library's flash store under power cuts --------------------------------------------

LIBRARY_CUT = "library-power-cut"
LIBRARY_CUT_DESCRIPTION = (
    "the CM-530's gait-library store (firmware/app/store_lib.c, on the host against the "
    "flash register model) takes seeded stores and deletes, most cut by a power failure at "
    "a random flash operation (torn erase or program), each followed by a fresh start"
)


def library_power_cut(seed: int, operations: int = 40) -> Outcome:
    """The library campaign: after every operation, cut or not, a fresh start must find
    every other slot as it was and the slot written as it was or as it was to become
    ("library"), and an uncut operation must have done what it said ("done")."""
    sys.path.insert(0, str(REPO_ROOT / "tests" / "support"))
    import library_flash as lf  # the test support's build of the store and flash model

    out = Outcome(LIBRARY_CUT, seed, LIBRARY_CUT_DESCRIPTION)
    rng = random.Random(seed)
    counts = Counter[str]()
    with tempfile.TemporaryDirectory(prefix="snakebot.library-campaign-") as tmp:
        hal = lf.build(Path(tmp))
        mem = lf.ERASED_LONG_AGO
        expected = lf.contents(hal, mem)
        for i in range(operations):
            slot = rng.randrange(lf.SLOTS)
            if rng.random() < 0.25:
                op, new = lf.delete(hal, slot), lf.EMPTY
            else:
                name = f"gait {i}".encode()
                new = (lf.TABLE, name, lf.blob(rng.randint(1, 400), seed * 1000 + i))
                op = lf.put(hal, slot, *new)
            _, _, steps = lf.run(hal, mem, op)  # how many flash operations it takes
            cut = rng.randrange(steps) if steps and rng.random() < 0.75 else None
            status, mem, _ = lf.run(hal, mem, op, cut_at=cut, seed=rng.randrange(1 << 16))
            found = lf.contents(hal, mem)
            counts["operations"] += 1
            counts["cuts"] += cut is not None
            counts["slots_checked"] += lf.SLOTS
            for s in range(lf.SLOTS):
                allowed = (expected[s], new) if s == slot else (expected[s],)
                if found[s] not in allowed:
                    counts["corrupted_slots"] += 1
                    out.check(
                        "library", False, f"operation {i} cut at {cut}: slot {s} is {found[s]!r}"
                    )
            if cut is None:
                out.check(
                    "done", status == lf.OK and found[slot] == new, f"operation {i}: {status}"
                )
            else:
                counts["new_after_cut" if found[slot] == new else "old_after_cut"] += 1
            expected = found
    out.counts = {"corrupted_slots": 0, **counts}
    out.check("library", True)
    out.check("done", True)
    return out


def run(name: str, seed: int = 1, seconds: float | None = None) -> Outcome:
    """Run one campaign; its Outcome says what was counted and which checks held.
    ``seconds``: how long the campaigns that play a table play (default: their own)."""
    if name == LIBRARY_CUT:
        t0 = time.monotonic()
        out = library_power_cut(seed)
        out.seconds = time.monotonic() - t0
        return out
    try:
        campaign = CAMPAIGNS[name]
    except KeyError:
        raise CampaignFailed(
            f"no campaign {name!r}: choose one of {', '.join(CAMPAIGNS)}"
        ) from None
    if not IMAGE.is_file():
        raise CampaignFailed(f"{IMAGE} not found: build the firmware with `make firmware`")
    out = Outcome(name, seed, campaign.description)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="snakebot.sim-campaign-") as tmp:
        with Rig(campaign.faults(seed), Path(tmp), seconds) as rig:
            try:
                campaign.body(rig, out)
                last = rig.freeze()
            except ControllerError as exc:
                out.check("alive", False, f"the campaign lost the controller: {exc}")
                out.seconds = time.monotonic() - t0
                return out
            rig.check_table("at the end")
            _common_checks(rig, out, last)
            if campaign.after is not None:
                campaign.after(rig, out, last)
    out.seconds = time.monotonic() - t0
    return out


# -- the command line ----------------------------------------------------------------------------

_COLUMNS = (
    ("campaign", lambda o: o.name),
    (
        "goals (out of limits)",
        lambda o: f"{o.counts.get('goals', 0)} ({o.counts.get('goals_outside_limits', 0)})",
    ),
    (
        "READs sent/answered",
        lambda o: f"{o.counts.get('reads_sent', 0)}/{o.counts.get('reads_answered', 0)}",
    ),
    (
        "Bus Reads/Timeouts/Errors",
        lambda o: (
            f"{o.counts.get('bus_reads', 0)}/"
            f"{o.counts.get('bus_timeouts', 0)}/{o.counts.get('bus_errors', 0)}"
        ),
    ),
    (
        "PINGs (failed)",
        lambda o: f"{o.counts.get('pings', 0)} ({o.counts.get('ping_failures', 0)})",
    ),
    ("SAFE", lambda o: str(o.counts.get("safe_entries", 0))),
    ("result", lambda o: "ok" if o.ok else "FAIL: " + "; ".join(o.problems)),
)


def render(outcomes: list[Outcome]) -> str:
    rows = [[h for h, _ in _COLUMNS]] + [[f(o) for _, f in _COLUMNS] for o in outcomes]
    widths = [max(len(r[i]) for r in rows) for i in range(len(_COLUMNS))]
    return "\n".join(
        "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tests.reliability.rig.campaigns",
        description="Fault campaigns: the controller firmware under QEMU drives three "
        "emulated AX-12s while faults are injected from a seed; checks that goals stay "
        "within the joint limits, the controller keeps answering, the committed table "
        "survives, and every fault is counted. Needs `make firmware` first.",
    )
    parser.add_argument(
        "--only",
        action="append",
        metavar="NAME",
        choices=[*CAMPAIGNS, LIBRARY_CUT],
        help="run this campaign (repeatable); default: all of them, namely "
        + ", ".join([*CAMPAIGNS, LIBRARY_CUT]),
    )
    parser.add_argument("--seed", type=int, default=1, help="seed of the faults (default 1)")
    parser.add_argument(
        "--seconds",
        type=float,
        metavar="S",
        help="how long the campaigns that play a table under a fault play (default: "
        "their own few seconds; e.g. 120 for the figures in docs/reliability.md)",
    )
    parser.add_argument("--json", action="store_true", help="one JSON record per campaign")
    args = parser.parse_args(argv)
    outcomes = []
    for name in args.only or [*CAMPAIGNS, LIBRARY_CUT]:
        try:
            outcome = run(name, args.seed, args.seconds)
        except SimError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        outcomes.append(outcome)
        if args.json:
            print(json.dumps(outcome.as_record()), flush=True)
        else:
            print(
                f"{name}: {'ok' if outcome.ok else 'FAILED'} ({outcome.seconds:.1f} s)",
                file=sys.stderr,
                flush=True,
            )
    if not args.json:
        print(render(outcomes))
    return 0 if all(o.ok for o in outcomes) else 1


if __name__ == "__main__":
    with contextlib.suppress(KeyboardInterrupt):
        sys.exit(main())
