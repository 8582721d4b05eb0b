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

from tests.reliability.rig.campaigns.catalogue import CAMPAIGNS, Campaign, run
from tests.reliability.rig.campaigns.cli import main
from tests.reliability.rig.campaigns.library import LIBRARY_CUT
from tests.reliability.rig.campaigns.outcome import Outcome
from tests.reliability.rig.campaigns.ram import RamMap
from tests.reliability.rig.campaigns.rig import Rig
from tests.reliability.rig.campaigns.testbed import (
    FRAMES,
    IDS,
    IMAGE,
    LIMITS,
    PERIOD_MS,
    CampaignFailed,
    gait_table,
)

__all__ = [
    "CAMPAIGNS",
    "Campaign",
    "CampaignFailed",
    "FRAMES",
    "IDS",
    "IMAGE",
    "LIBRARY_CUT",
    "LIMITS",
    "Outcome",
    "PERIOD_MS",
    "RamMap",
    "Rig",
    "gait_table",
    "main",
    "run",
]
