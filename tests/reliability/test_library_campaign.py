"""The gait library's power-cut campaign (`--only library-power-cut` of
tests/reliability/rig/campaigns/): seeded stores and deletes on the flash store, most
cut by a power failure at a random flash operation, and no slot ever found corrupted
after a fresh start."""

from __future__ import annotations

from snakebot.settings import resolve_int
from tests.reliability.rig.campaigns import LIBRARY_CUT, main, run

SEED = resolve_int("SNAKEBOT_CAMPAIGN_SEED")


def test_no_power_cut_corrupts_a_slot():
    outcome = run(LIBRARY_CUT, SEED)
    assert outcome.ok, f"{'; '.join(outcome.problems)}\nrerun: .venv/bin/{outcome.command}"
    counts = outcome.counts
    assert counts["corrupted_slots"] == 0
    assert counts["cuts"] >= counts["operations"] // 2 > 0
    assert counts["slots_checked"] == 8 * counts["operations"]
    assert set(outcome.checks) == {"library", "done"}


def test_the_campaign_runs_from_the_command_line(capsys):
    assert main(["--only", LIBRARY_CUT, "--seed", "3"]) == 0
    table = capsys.readouterr().out
    assert LIBRARY_CUT in table and "ok" in table
