"""Fault campaigns on the emulated robot with the real firmware on both emulated boards
(tests/reliability/rig/campaigns/; docs/reliability.md has the table of results).

Each campaign runs the board's image (the CM-530's on the emulated STM32F103RE, the qemu
board's under QEMU) on an emulated bus of three AX-12s, plays a table that is steered
against its joint limits, injects its fault from a seed and checks, throughout: no goal
outside the limits on the wire, the controller always answers and never reboots or
stalls (on the CM-530, its watchdog never fires), the committed table survives
(registers and RAM), and every fault it can see is in its counters as `snakebot
monitor` reads them. A failure names the broken promise and the numbers; rerun it alone
with the command in the message.
"""

from __future__ import annotations

import pytest
from firmware_support import BOARDS, build_firmware

from snakebot.settings import resolve_int
from tests.reliability.rig.campaigns import CAMPAIGNS, run

# One campaign at a time: `make test` runs this file in a process of its own beside the
# serial stage (test-campaigns); two at once, an emulated CM-530 in one worker's process
# beside QEMU in another's, a QEMU campaign lost a PING (a fresh clone's CI run).
pytestmark = [pytest.mark.qemu, pytest.mark.slow, pytest.mark.serial]

SEED = resolve_int("SNAKEBOT_CAMPAIGN_SEED")


@pytest.fixture(scope="module", autouse=True)
def firmware() -> None:
    build_firmware()


@pytest.mark.parametrize(
    ("board", "name"),
    [pytest.param(board, name, id=f"{board}-{name}") for board in BOARDS for name in CAMPAIGNS],
)
def test_campaign_keeps_every_promise(board: str, name: str):
    if board == "cm530":
        pytest.importorskip("unicorn")
    outcome = run(name, SEED, board=board)
    record = outcome.as_record()
    assert outcome.ok, (
        f"{name} on {board} (seed {SEED}) broke: {'; '.join(outcome.problems)}\n"
        f"counts: {record['counts']}\nrerun: .venv/bin/{outcome.command}"
    )
    # every check was actually made
    assert set(outcome.checks) >= {"limits", "alive", "table", "counted"}
    assert outcome.counts["goals"] > 0 and outcome.counts["pings"] > 0
    assert outcome.board == board and f"--board {board}" in outcome.command
    if board == "cm530":  # the one board whose emulation has the watchdog
        assert outcome.counts["watchdog_feeds"] > 0
