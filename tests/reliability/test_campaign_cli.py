"""The fault campaigns' command line (``python -m tests.reliability.rig.campaigns``) without
a board running: ``--board`` picks the emulated board (the CM-530 unless told), a wrong
option is one line and exit 2, every result says the board it ran on, and the command
that reruns a campaign names it."""

from __future__ import annotations

import json

import pytest

from tests.reliability.rig.campaigns import LIBRARY_CUT, Outcome, main
from tests.reliability.rig.campaigns.cli import planned_runs


@pytest.mark.parametrize(
    ("argv", "what"),
    [
        (["--board", "cm510"], "argument --board: invalid choice: 'cm510' (choose from "),
        (["--only", "nothing"], "argument --only: invalid choice: 'nothing' (choose from "),
        (["--seed", "x"], "argument --seed: invalid int value: 'x'"),
    ],
)
def test_a_wrong_option_is_one_line_and_exit_2(
    argv: list[str], what: str, capsys: pytest.CaptureFixture[str]
):
    with pytest.raises(SystemExit) as exited:
        main(argv)
    assert exited.value.code == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert what in line and line.endswith("; see --help")


def test_the_campaigns_run_board_by_board_and_the_librarys_once():
    names = ["clean", LIBRARY_CUT, "pc-noise"]
    assert planned_runs(names, ["qemu", "cm530", "qemu"]) == [
        ("clean", "qemu"),
        ("pc-noise", "qemu"),
        ("clean", "cm530"),
        ("pc-noise", "cm530"),
        (LIBRARY_CUT, "qemu"),  # on the host, whichever board is named
    ]
    assert planned_runs(["clean"], ["cm530"]) == [("clean", "cm530")]


def test_the_rerun_command_names_the_board():
    on_board = Outcome("corrupt-1pct", 7, "", "qemu")
    assert on_board.command.endswith("--only corrupt-1pct --seed 7 --board qemu")
    assert on_board.as_record()["board"] == "qemu"
    on_host = Outcome(LIBRARY_CUT, 7, "")
    assert on_host.command.endswith(f"--only {LIBRARY_CUT} --seed 7")
    assert on_host.as_record()["board"] is None


def test_the_table_and_the_records_say_where_a_campaign_ran(capsys: pytest.CaptureFixture[str]):
    assert main(["--only", LIBRARY_CUT, "--json"]) == 0
    (record,) = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert record["board"] is None and record["ok"]
    assert main(["--only", LIBRARY_CUT, "--board", "qemu"]) == 0
    header, row = capsys.readouterr().out.splitlines()
    assert header.split()[:2] == ["campaign", "board"]
    assert row.split()[:2] == [LIBRARY_CUT, "host"]
