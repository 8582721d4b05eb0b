"""Fault campaigns on the emulated robot with the real firmware in QEMU
(tests/reliability/rig/campaigns/; docs/reliability.md has the table of results).

Each campaign boots the qemu image on an emulated bus of three AX-12s, plays a table that
is steered against its joint limits, injects its fault from a seed and checks, throughout:
no goal outside the limits on the wire, the controller always answers and never reboots
or stalls, the committed table survives (registers and RAM), and every fault it can see
is in its counters as `snakebot monitor` reads them. A failure names the broken promise
and the numbers; rerun it alone with the command in the message.
"""

from __future__ import annotations

import pytest
from firmware_support import build_firmware

from snakebot.settings import resolve_int
from tests.reliability.rig.campaigns import CAMPAIGNS, run

pytestmark = [pytest.mark.qemu, pytest.mark.slow, pytest.mark.serial]

SEED = resolve_int("SNAKEBOT_CAMPAIGN_SEED")


@pytest.fixture(scope="module", autouse=True)
def firmware() -> None:
    build_firmware()


@pytest.mark.parametrize("name", list(CAMPAIGNS))
def test_campaign_keeps_every_promise(name: str):
    outcome = run(name, SEED)
    record = outcome.as_record()
    assert outcome.ok, (
        f"{name} (seed {SEED}) broke: {'; '.join(outcome.problems)}\n"
        f"counts: {record['counts']}\nrerun: .venv/bin/{outcome.command}"
    )
    # every check was actually made
    assert set(outcome.checks) >= {"limits", "alive", "table", "counted"}
    assert outcome.counts["goals"] > 0 and outcome.counts["pings"] > 0
