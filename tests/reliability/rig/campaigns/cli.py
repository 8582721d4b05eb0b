"""The command line: ``python -m tests.reliability.rig.campaigns``."""

from __future__ import annotations

import argparse
import json
import sys
from typing import NoReturn

from snakebot.sim.errors import SimError
from tests.reliability.rig.campaigns.catalogue import CAMPAIGNS, run
from tests.reliability.rig.campaigns.library import LIBRARY_CUT
from tests.reliability.rig.campaigns.outcome import Outcome
from tests.reliability.rig.campaigns.targets import DEFAULT_BOARD, TARGETS

_COLUMNS = (
    ("campaign", lambda o: o.name),
    ("board", lambda o: o.board or "host"),
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


class _Parser(argparse.ArgumentParser):
    """Says what is wrong with the command line in one line (exit 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}; see --help\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="python -m tests.reliability.rig.campaigns",
        description="Fault campaigns: the controller firmware on an emulated board (the "
        "CM-530's image on the emulated STM32F103RE, or the qemu board's build under "
        "QEMU) drives three emulated AX-12s while faults are injected from a seed; checks "
        "that goals stay within the joint limits, the controller keeps answering (and, on "
        "the CM-530, its watchdog never fires), the committed table survives, and every "
        "fault is counted. Needs `make firmware` first.",
    )
    parser.add_argument(
        "--board",
        action="append",
        choices=list(TARGETS),
        help=f"run the campaigns on this board (repeatable: each board in turn); default "
        f"{DEFAULT_BOARD}, the one users flash (library-power-cut runs on the host)",
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
    return parser


def planned_runs(names: list[str], boards: list[str]) -> list[tuple[str, str]]:
    """(campaign, board) in the order they run: every board's campaigns, board by board;
    the library's once, on the host."""
    on_boards = [(n, b) for b in dict.fromkeys(boards) for n in names if n != LIBRARY_CUT]
    return on_boards + [(LIBRARY_CUT, boards[0])] * (LIBRARY_CUT in names)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    outcomes = []
    names, boards = args.only or [*CAMPAIGNS, LIBRARY_CUT], args.board or [DEFAULT_BOARD]
    for name, board in planned_runs(names, boards):
        try:
            outcome = run(name, args.seed, args.seconds, board)
        except SimError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        outcomes.append(outcome)
        if args.json:
            print(json.dumps(outcome.as_record()), flush=True)
        else:
            print(
                f"{name} ({outcome.board or 'host'}): {'ok' if outcome.ok else 'FAILED'} "
                f"({outcome.seconds:.1f} s)",
                file=sys.stderr,
                flush=True,
            )
    if not args.json:
        print(render(outcomes))
    return 0 if all(o.ok for o in outcomes) else 1
