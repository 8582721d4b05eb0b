"""One campaign's rig: a board's machine running the firmware (:mod:`.targets`), the
emulated bus with its taps, the PC-link client, and the watch over the controller's
promises."""

from __future__ import annotations

import time
import zlib
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from snakebot.facts.boards import PC_LINK_BAUD as PC_BAUD
from snakebot.formats.protocol import (
    ProtocolError,
)
from snakebot.formats.upload_writes import chunk_writes, commit_write
from snakebot.link.controller import Command, State, UploadResult
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.limits import LimitsError, limits_state, set_limits
from snakebot.link.controller.monitor import Sample, sample
from snakebot.sim.bus.faults import FaultConfig
from tests.reliability.rig.campaigns.ram import RamMap
from tests.reliability.rig.campaigns.taps import AuditedServo, Tap, TappedBus
from tests.reliability.rig.campaigns.targets import TARGETS, Target
from tests.reliability.rig.campaigns.testbed import (
    CONTROLLER_ID,
    CTL,
    IDS,
    LIMITS,
    REBUILD,
    SAMPLE_S,
    STALL_MS,
    UPTIME_SLACK_MS,
    UPTIME_STILL_S,
    CampaignFailed,
    support,
)

PC_RETRIES = 3
"""The PC-link client's tries after the first: with the library's allowance for a program
on this host (``timing.PROGRAM_MARGIN_S``) the controller under QEMU counts as lost only
after two seconds of silence, which a busy host's scheduling does not make; the emulated
CM-530, in the client's own process, gets a wider margin still (:class:`.Cm530Target`)."""
BOOT_WAIT_S = 10.0
"""How long the firmware may take to answer its first PING."""
MACHINE_SLOWEST = 10.0
"""How many times slower than the wall clock a machine's clock may run before a wait on it
gives up (the emulated CM-530 slows its clock rather than fall behind)."""
QUIET_WAIT_S = 5.0
"""How long a stopped controller may take to stop using the bus on a busy host."""


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
    reboot_details: list[str] = field(default_factory=list)  # registers and the machine's log


class Rig:
    """``board``'s machine running the firmware, wired to a tapped emulated bus; a
    controller client on the PC link; the firmware's RAM within reach. Use as a context
    manager."""

    def __init__(
        self,
        board: str,
        faults: FaultConfig,
        workdir: Path,
        play_s: float | None = None,
        ram: RamMap | None = None,
    ) -> None:
        self.tap = Tap(dict(zip(IDS, LIMITS, strict=True)))
        self.servos = [AuditedServo(i, lim) for i, lim in zip(IDS, LIMITS, strict=True)]
        self.bus = TappedBus(self.tap, self.servos, faults=faults)
        self.play_s = play_s  # overrides how long the campaigns that play, play
        self.target: Target = TARGETS[board](self.bus, workdir)
        self.ram = ram if ram is not None else RamMap.from_build(self.target.elf)
        self.health = Health()
        self._started = 0.0  # time.monotonic() when the machine started
        self._table_view_checked = False
        self.ctl: ControllerClient | None = None
        self.committed: tuple[int, int] | None = None  # (size, CRC) of the table on board
        self._uptime = -1
        self._resets = 0  # the resets the machine counted (the emulated CM-530 does)
        self._progress: tuple[int, int] | None = None  # (bus packets, uptime) at last change
        self.polling = False  # the roster is polled: the bus must keep moving
        self.last_polled: Sample | None = None  # the last look with the roster in place
        self.last_polled_s = 0.0  # how long that look took, registers to servo window
        self._last_state = State.IDLE

    @property
    def lock(self) -> AbstractContextManager[Any]:
        """Hold it to touch the bus (the machine runs it from another thread)."""
        return self.target.lock

    def __enter__(self) -> Rig:
        try:
            self._started = time.monotonic()
            self.target.start()
            self._wait_for_boot()
            self.ctl = ControllerClient.open(
                self.target.pc_link,
                PC_BAUD,
                CONTROLLER_ID,
                retries=PC_RETRIES,
                margin_s=self.target.margin_s,
            )
            self.check_view()
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        if self.ctl is not None:
            self.ctl.close()
        self.target.stop()

    def _wait_for_boot(self) -> None:
        """Until the firmware answers PING, on a client of its own with the pseudo-
        terminal's usual margin: each PING sent before the firmware listens costs that
        margin, and the emulated CM-530's client has a far wider one."""
        try:
            support("firmware_support").wait_for_boot(self.target.pc_link, BOOT_WAIT_S)
        except ProtocolError:
            raise CampaignFailed(
                f"the firmware never answered PING in {BOOT_WAIT_S:.0f} s "
                f"({self.target.label}'s log: {self.target.log()}); {REBUILD}"
            ) from None

    # -- the rig's own view of the machine ----------------------------------------------------

    def check_view(self) -> None:
        """Make sure that what this rig reads of the machine is the running firmware's RAM
        where the RAM map says, before any of it counts as a result: the machine is this
        rig's (:meth:`Target.check_identity`: QEMU's monitor answers with this rig's
        name; the emulated CM-530's thread runs), the flash holds what the ELF the map
        comes from loads there (the machine booted that very build), and the uptime
        counter advances, never faster than the wall clock since the machine started. A
        mismatch is :class:`CampaignFailed` naming it, not a broken promise of the
        firmware."""
        target = self.target
        target.check_identity()
        for address, data in self.ram.flash:
            held = target.read(address, len(data))
            if held != data:
                at = next(i for i in range(len(data)) if i >= len(held) or held[i] != data[i])
                raise CampaignFailed(
                    f"{target.label} booted {target.image}, but its flash at "
                    f"{address + at:#x} differs from "
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
            int.from_bytes(self.target.read(self.ram.ticks_ms, 4), "little")
        )

    def _plausible_uptime(self, ticks: int) -> int:
        """``ticks``, if the firmware can have counted that far since the machine started."""
        ran_ms = (time.monotonic() - self._started) * 1000
        if ticks > ran_ms + UPTIME_SLACK_MS:
            raise CampaignFailed(
                f"ticks_ms at {self.ram.ticks_ms:#x} reads {ticks} ms, but "
                f"{self.target.label} started "
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
        """The CPU's PC, SP and xPSR, and what the machine logged, for a problem report."""
        target = self.target
        cpu = ", ".join(f"{name} {value:08x}" for name, value in target.cpu().items())
        return f"CPU: {cpu or 'no registers'}; {target.label}'s log: {target.log()}"

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
        bp = self.target.read(self.ram.busport_stats, 6)
        pc = self.target.read(self.ram.pclink_stats, 4)
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
        n = int.from_bytes(self.target.read(base + self.ram.active_len_offset, 2), "little")
        n = min(n, self.ram.ctl_size - self.ram.active_offset)  # no further than the arena
        return self.target.read(base + self.ram.active_offset, n) if n else b""

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
        self._check_reboot(uptime)
        if not self.polling or self._progress is None or packets != self._progress[0]:
            self._progress = (packets, uptime)
        elif uptime - self._progress[1] >= STALL_MS:
            h.stalls += 1  # ticks due, and not one bus packet
            self._progress = (packets, uptime)

    def _check_reboot(self, uptime: int) -> None:
        """Count a reboot since the last look: the uptime went back or, where the machine
        counts its resets (the emulated CM-530), one came, however long ago (a look that
        waited out lost replies may find a fresh uptime already past the last one)."""
        resets = self.target.resets()
        if uptime >= self._uptime and resets in (None, self._resets):
            self._uptime = uptime
            return
        came = 1 if resets is None else max(resets - self._resets, 1)
        self.health.reboots += came
        self.health.reboot_details.append(
            f"the firmware started again (uptime {self._uptime} ms, then {uptime} ms); "
            f"{self.machine_state()}"
        )
        self._uptime, self._resets = uptime, resets or 0
        self.check_view()  # a real reboot, not the rig's view of the machine failing

    def look(self) -> Sample:
        """One look as ``snakebot monitor`` takes it, plus the servos' own goals."""
        t0 = time.monotonic()
        s = sample(self.ctl)
        h = self.health
        h.samples += 1
        h.flags_seen |= s.registers["Error Flags"]
        if s.servos:
            self.last_polled, self.last_polled_s = s, time.monotonic() - t0
        state = s.registers["State"]
        if state == State.SAFE and self._last_state != State.SAFE:
            h.safe_entries += 1
        self._last_state = state
        with self.lock:
            goals = [self.bus.servo(i).regs.get("Goal Position") for i in IDS]
        for goal, (lo, hi) in zip(goals, LIMITS, strict=True):
            h.servo_goals_outside += not lo <= goal <= hi
        return s

    def bus_now(self) -> float:
        """The bus's clock, which what is scheduled on the bus (a brown-out) runs on:
        under QEMU it follows the wall clock; the emulated CM-530's bus runs on the
        chip's, which falls behind when the host keeps the chip waiting."""
        with self.lock:
            return self.bus.now

    def lasting(self, seconds: float, clock: Callable[[], float]) -> Callable[[], bool]:
        """Whether ``seconds`` on ``clock`` (the wall clock, or :meth:`bus_now`) have
        passed since this call; on the bus's clock, at most :data:`MACHINE_SLOWEST`
        times as long on the wall clock."""
        end, wall_end = clock() + seconds, time.monotonic() + seconds * MACHINE_SLOWEST
        return lambda: clock() >= end or time.monotonic() >= wall_end

    def watch(
        self,
        seconds: float,
        on_look: Callable[[Sample], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """Look, check life and the table, and let ``on_look`` act, for ``seconds`` on
        ``clock`` (:meth:`lasting`)."""
        over = self.lasting(seconds, clock)
        while True:
            self.check_alive()
            s = self.look()
            if on_look is not None:
                on_look(s)
            if over():
                break
            time.sleep(SAMPLE_S)
        self.check_table("while playing")

    def operator(
        self, recover_after_s: float = 0.3, clock: Callable[[], float] = time.monotonic
    ) -> Callable[[Sample], None]:
        """What a person at ``snakebot monitor`` would do: when the controller has gone
        SAFE, wait a little (``recover_after_s`` on ``clock``), CLEAR and PLAY again."""
        since: list[float] = []

        def act(s: Sample) -> None:
            if s.registers["State"] != State.SAFE:
                since.clear()
                return
            if not since:
                since.append(clock())
            elif clock() - since[0] >= recover_after_s:
                self.command(Command.CLEAR)
                self.command(Command.PLAY)
                self.health.recoveries += 1
                since.clear()

        return act

    def freeze(self) -> Sample:
        """Stop and empty the roster so the bus goes quiet; the last look. Once it is
        quiet, every byte the servos sent must have reached the firmware's UART, or the
        machine's wiring to the bus failed (:class:`CampaignFailed`)."""
        self.command(Command.STOP)
        self.polling = False
        self.write({"Joint Count": 0})
        # A READ already in flight finishes in the firmware's time, which a busy host
        # stretches: wait until no packet has come for a while (past the last reply
        # window, 30 ms, and a few ticks), so the tap and the registers count the same.
        deadline = time.monotonic() + QUIET_WAIT_S
        with self.lock:
            seen = self.tap.packets
        while True:
            time.sleep(0.15)
            with self.lock:
                if self.tap.packets == seen:
                    self.tap.quiet()
                    unread = self.bus.master_in_waiting()
                    break
                seen = self.tap.packets
            if time.monotonic() > deadline:
                raise CampaignFailed(f"the bus did not go quiet within {QUIET_WAIT_S} s of STOP")
        if unread:
            raise CampaignFailed(
                f"{unread} bytes the servos sent never reached the firmware's UART: "
                f"{self.target.label}'s wiring to the emulated bus stopped passing them on "
                "(the counts would say the bus went deaf); report it with the campaign's "
                "command"
            )
        self.check_alive()
        return self.look()

    def started_polling(self) -> None:
        """The roster is set: from now on the bus must carry a READ every tick."""
        with self.lock:
            self.tap.restart_gaps()
        self.polling = True
