"""Fault campaigns: the real controller firmware on an emulated board driving the emulated
robot while faults are injected from a seed, and what the controller promises checked
throughout, on either board.

    python -m tests.reliability.rig.campaigns                 # every campaign on the CM-530
    python -m tests.reliability.rig.campaigns --board qemu --board cm530   # on both boards
    python -m tests.reliability.rig.campaigns --only corrupt-1pct --seed 7 --json

The boards (``--board``, :mod:`.targets`): ``cm530`` (the default, the board users flash)
runs the CM-530's own image, ``build/cm530/firmware.bin``, on the emulated STM32F103RE in
this process (:class:`snakebot.sim.mcu.runner.McuFirmware`), its USART1 wired to the
emulated bus directly; ``qemu`` boots ``build/qemu/flash.bin`` under QEMU's
stm32vldiscovery, its USART1 on the bus through a Unix socket. Both need ``make
firmware``. On either, USART3 is the PC link on a pseudo-terminal; each campaign uploads
a gait table whose frames sit on the joint limits and plays it with a steering offset
that pushes every goal past a limit (so the clamp is what keeps the servos inside), then
injects its fault for a few seconds of bus time. What it checks, in every campaign:

limits
    every goal position the firmware writes on the bus (read from its bytes before the
    bus damages them) lies within the table's limits for that joint;
alive
    the controller answers every PING (the client retries three times); it never reboots
    (its SysTick uptime, read from its RAM, only grows); its control loop never stalls
    (the bus-packet counter in RAM grows between samples); no bus packet or PC reply was
    ever refused for want of buffer room; on the CM-530, the independent watchdog was
    fed and never reset the chip;
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

The rig's own view: what it reads from RAM (through QEMU's monitor, or from the emulated
chip under its lock, at addresses from the symbols of the board's ``firmware.elf``)
counts only once it is shown to be the running firmware's: at start, the machine must be
this rig's (QEMU's monitor answers with this rig's name; the emulated chip's thread
runs), its flash must hold what that ELF loads (the machine booted that very build), and
the uptime counter must advance, never faster than the wall clock; right after the first
commit, the table found in RAM must be the one Table Size and Table CRC describe. A
mismatch stops the campaign with ``CampaignFailed`` (exit 2 from the command line) naming
it, instead of passing as a broken promise; a reboot is reported with the CPU's PC, SP
and xPSR and the machine's log (QEMU's output; the emulated chip's resets and errors).

The watchdog: the emulated CM-530 models the STM32's IWDG (:mod:`snakebot.sim.mcu.iwdg`),
so there the campaigns check that it never reset the chip and report the longest time
between two feeds beside its timeout (``watchdog_largest_gap_ms``,
``watchdog_timeout_ms``). QEMU does not model it (see firmware/boards/qemu/board.h), so it
cannot fire there; what it guards against (a main loop that stops feeding it for 500 ms)
is checked directly on both boards: the loop's progress counter, PING, and the longest
silence between the firmware's bus packets while the roster is polled
(``max_bus_gap_ms``, reported; the control tick is 10 ms).

Reproducibility: the faults are drawn from streams seeded by ``--seed``
(:mod:`snakebot.sim.bus.faults`; the PC-link noise from its own stream), so a seed fixes
which byte of the wire's traffic is hit, which reply is dropped, what noise is sent. The
emulators run in real time against the host's clients, so how many bytes flow in a
campaign (and therefore the counts) varies by a few percent from run to run and machine
to machine; the checks hold in every run.
"""

from __future__ import annotations

from tests.reliability.rig.campaigns.catalogue import CAMPAIGNS, Campaign, run
from tests.reliability.rig.campaigns.cli import main
from tests.reliability.rig.campaigns.library import LIBRARY_CUT
from tests.reliability.rig.campaigns.outcome import Outcome
from tests.reliability.rig.campaigns.ram import RamMap
from tests.reliability.rig.campaigns.rig import Rig
from tests.reliability.rig.campaigns.targets import DEFAULT_BOARD, TARGETS, Target
from tests.reliability.rig.campaigns.testbed import (
    FRAMES,
    IDS,
    LIMITS,
    PERIOD_MS,
    CampaignFailed,
    gait_table,
)

__all__ = [
    "CAMPAIGNS",
    "Campaign",
    "CampaignFailed",
    "DEFAULT_BOARD",
    "FRAMES",
    "IDS",
    "LIBRARY_CUT",
    "LIMITS",
    "Outcome",
    "PERIOD_MS",
    "RamMap",
    "Rig",
    "TARGETS",
    "Target",
    "gait_table",
    "main",
    "run",
]
