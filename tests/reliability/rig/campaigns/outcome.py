"""One campaign's outcome: what was injected, what was counted, which checks held."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class Outcome:
    """One campaign's result: what was injected, what was counted, what held."""

    name: str
    seed: int
    description: str
    board: str | None = None  # the emulated board it ran on (None: on the host)
    seconds: float = 0.0
    counts: dict[str, int | float] = field(default_factory=dict)
    checks: dict[str, bool] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return all(self.checks.values())

    @property
    def command(self) -> str:
        command = f"python -m tests.reliability.rig.campaigns --only {self.name} --seed {self.seed}"
        return f"{command} --board {self.board}" if self.board else command

    def check(self, name: str, held: bool, why: str = "") -> None:
        self.checks[name] = self.checks.get(name, True) and bool(held)
        if not held:
            self.problems.append(f"{name}: {why}" if why else name)

    def as_record(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "board": self.board,
            "seed": self.seed,
            "description": self.description,
            "command": self.command,
            "ok": self.ok,
            "seconds": round(self.seconds, 1),
            "counts": self.counts,
            "checks": self.checks,
            "problems": self.problems,
        }
