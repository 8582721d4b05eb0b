"""The machine a campaign runs the firmware on, one kind per board: what differs between
QEMU running the qemu board's build and the emulated STM32F103RE running the CM-530's
image in this process (how each starts and stops, where its bus is served and locked, how
the firmware's RAM is read, what tells the machine is this rig's, its CPU registers and
its log, and the watchdog where it is modelled). The rig (:class:`~.rig.Rig`) and the
campaigns see only this interface."""

from __future__ import annotations

import contextlib
import os
import re
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from snakebot.facts.boards import ROBOT_BOARD
from snakebot.sim.bus.bus import Bus
from snakebot.sim.qemu import Endpoint, QemuFirmware
from snakebot.sim.transports.unixsock import UnixSocketServer
from tests.reliability.rig.campaigns.testbed import (
    BUILD,
    LOG_TAIL,
    CampaignFailed,
    support,
)


@dataclass(frozen=True)
class Watchdog:
    """The independent watchdog as the emulated chip saw it: the times it reset the chip
    (seconds of the chip's time), its reloads, the longest time between two, and how
    long it waits for one before it resets."""

    resets: tuple[float, ...]
    feeds: int
    largest_gap_s: float
    timeout_s: float


class Target(ABC):
    """One board's machine running the firmware on ``bus``; ``workdir`` holds its files.
    :meth:`start` it, then talk to the firmware on :attr:`pc_link`; hold :attr:`lock` to
    touch the bus (the machine runs it from another thread)."""

    board: ClassVar[str]
    label: ClassVar[str]  # the machine's name in a report
    image: ClassVar[Path]  # what it boots (`make firmware`)
    elf: ClassVar[Path]  # the ELF that image was made from: the RAM map's symbols
    margin_s: ClassVar[float | None] = None  # the PC-link client's margin (None: the pty's)

    @abstractmethod
    def start(self) -> None: ...

    @abstractmethod
    def stop(self) -> None:
        """Stop the machine and free what it holds (idempotent; after a failed start too)."""

    @property
    @abstractmethod
    def lock(self) -> contextlib.AbstractContextManager[Any]: ...

    @property
    @abstractmethod
    def pc_link(self) -> str:
        """The firmware's PC link (a pseudo-terminal)."""

    @abstractmethod
    def read(self, address: int, length: int) -> bytes:
        """``length`` bytes of the machine's memory at ``address``."""

    @abstractmethod
    def check_identity(self) -> None:
        """:class:`CampaignFailed` unless what :meth:`read` reads is this rig's machine."""

    @abstractmethod
    def cpu(self) -> dict[str, int]:
        """The CPU's PC, SP and xPSR (those the machine shows)."""

    @abstractmethod
    def log(self) -> str:
        """What the machine reported of itself, for a problem report."""

    def resets(self) -> int | None:
        """How many times the machine was reset since it started (None: it does not say)."""
        return None

    def watchdog(self) -> Watchdog | None:
        """The watchdog's record, where the machine models it (None: it does not)."""
        return None


class QemuTarget(Target):
    """QEMU's stm32vldiscovery running ``build/qemu/flash.bin``, its USART1 on the bus
    served on a Unix socket; RAM read through QEMU's monitor. QEMU does not model the
    IWDG (firmware/boards/qemu/board.h)."""

    board = "qemu"
    label = "QEMU"
    image = BUILD / "qemu" / "flash.bin"
    elf = BUILD / "qemu" / "firmware.elf"

    def __init__(self, bus: Bus, workdir: Path) -> None:
        self.server = UnixSocketServer(bus, workdir / "bus.sock")
        # A name only this QEMU has: the monitor must be this machine's (check_identity).
        self.name = f"snakebot-campaign-{os.getpid()}-{workdir.name}"
        self.fw = QemuFirmware(
            self.image,
            bus=Endpoint.unix_client(workdir / "bus.sock"),
            extra_args=["-name", self.name],
        )

    def start(self) -> None:
        self.server.start()
        self.fw.start()

    def stop(self) -> None:
        self.fw.stop()
        self.server.close()

    @property
    def lock(self) -> contextlib.AbstractContextManager[Any]:
        return self.server.lock

    @property
    def pc_link(self) -> str:
        return self.fw.ports.pc_link

    def read(self, address: int, length: int) -> bytes:
        """Through the monitor's ``xp``, whole words."""
        return self.fw.read(address, length)

    def check_identity(self) -> None:
        """The monitor answers for this rig's QEMU (its name)."""
        named = self.fw.monitor("info name").strip()
        if named != self.name:
            raise CampaignFailed(
                f"asked for its name, QEMU's monitor answered {named!r}, not this rig's "
                f"{self.name!r}: another QEMU's monitor, or answers out of step with the "
                "questions; stop stray qemu-system-arm processes and run again"
            )

    def cpu(self) -> dict[str, int]:
        regs = dict(re.findall(r"(R1[35]|XPSR)=([0-9a-f]+)", self.fw.monitor("info registers")))
        names = {"R15": "PC", "R13": "SP", "XPSR": "xPSR"}
        return {names[key]: int(value, 16) for key, value in regs.items()}

    def log(self) -> str:
        return self.fw.log().strip()[-LOG_TAIL:] or "nothing"


class Cm530Target(Target):
    """The emulated STM32F103RE running the CM-530's image (``build/cm530/firmware.bin``,
    what ``make flash`` sends) in this process, its USART1 on the bus directly; RAM read
    from the chip under its lock. Its thread gives way to QEMU and the other real-time
    work of a loaded machine, and the PC-link client gets the wider margin a chip in the
    client's own process needs (tests/support/firmware_support.py)."""

    board = "cm530"
    label = "the emulated CM-530"
    image = BUILD / "cm530" / "firmware.bin"
    elf = BUILD / "cm530" / "firmware.elf"
    margin_s = support("firmware_support").CM530_MARGIN_MS / 1000

    def __init__(self, bus: Bus, workdir: Path) -> None:
        from snakebot.sim.mcu.runner import McuFirmware  # unicorn: only for this board
        from snakebot.sim.serve import board_image

        self.fw = McuFirmware(board_image(self.image, self.board), bus=bus)

    def start(self) -> None:
        self.fw.start()
        support("firmware_support").give_way(self.fw)

    def stop(self) -> None:
        self.fw.stop()

    @property
    def lock(self) -> contextlib.AbstractContextManager[Any]:
        return self.fw.lock

    @property
    def pc_link(self) -> str:
        return self.fw.pc_link

    def read(self, address: int, length: int) -> bytes:
        with self.fw.lock:
            return self.fw.board.mcu.read(address, length)

    def check_identity(self) -> None:
        """The chip's thread runs (a chip that stopped would leave its RAM standing)."""
        error = self.fw.error
        if not self.fw.running or error is not None:
            why = f"it stopped on {error!r}" if error is not None else "its thread ended"
            raise CampaignFailed(
                f"the emulated CM-530 is not running ({why}): an error there is the "
                "emulator's, not the firmware's broken promise; report it with the "
                "campaign's command"
            )

    def cpu(self) -> dict[str, int]:
        from unicorn import arm_const as arm

        with self.fw.lock:
            cpu = self.fw.board.mcu.cpu
            return {
                "PC": cpu.pc,
                "SP": cpu.reg(arm.UC_ARM_REG_SP),
                "xPSR": cpu.reg(arm.UC_ARM_REG_XPSR),
            }

    def log(self) -> str:
        with self.fw.lock:
            resets = list(self.fw.board.mcu.resets)
        said = ", ".join(f"{kind} at {t:.3f} s" for t, kind in resets) or "none"
        return (
            f"resets {said}; clock held back {self.fw.slowed_s:.2f} s by the host; "
            f"error {self.fw.error!r}"
        )

    def resets(self) -> int:
        with self.fw.lock:
            return len(self.fw.board.mcu.resets)

    def watchdog(self) -> Watchdog:
        from snakebot.sim.mcu.machine import RESET_WATCHDOG

        with self.fw.lock:
            mcu = self.fw.board.mcu
            return Watchdog(
                resets=tuple(t for t, kind in mcu.resets if kind == RESET_WATCHDOG),
                feeds=mcu.iwdg.feeds,
                largest_gap_s=mcu.iwdg.largest_gap,
                timeout_s=mcu.iwdg.timeout_s(),
            )


TARGETS: dict[str, type[Target]] = {t.board: t for t in (Cm530Target, QemuTarget)}
"""Each board's machine, by the board's name."""
DEFAULT_BOARD = ROBOT_BOARD
"""The board the campaigns run on unless told otherwise: the CM-530, the one users flash."""
