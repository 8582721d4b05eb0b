"""How long the host kept an emulator's busiest thread waiting to run.

QEMU runs the firmware in real time: a stretch in which the host's scheduler kept QEMU's
emulated CPU waiting loses control ticks to the host, not to the firmware. Tests that
judge the firmware's timing measure that wait and try again when the host, not the
firmware, decided the outcome."""

from __future__ import annotations

import contextlib
import glob

STARVED_SHARE = 0.2
"""A stretch in which QEMU's CPU waited for the host longer than this share of it says
nothing about the firmware's timing: it is measured again."""


class HostQueue:
    """How long the host's scheduler kept process ``pid``'s busiest thread (QEMU's emulated
    CPU), or its thread ``tid`` (an emulator's thread in this process), waiting to run
    since :meth:`mark`, from ``/proc/PID/task/*/schedstat`` (nanoseconds on the CPU, then
    runnable but not running)."""

    def __init__(self, pid: int, tid: int | None = None) -> None:
        self._pid = pid
        self._task = "*" if tid is None else str(tid)  # None: the busiest of its threads
        self._base = self._stats()

    def _stats(self) -> dict[str, tuple[int, int]]:
        out = {}
        for stat in glob.glob(f"/proc/{self._pid}/task/{self._task}/schedstat"):
            with contextlib.suppress(OSError, IndexError, ValueError):
                ran, waited = open(stat).read().split()[:2]
                out[stat] = (int(ran), int(waited))
        return out

    def mark(self) -> None:
        """Count from now."""
        self._base = self._stats()

    def _busiest(self) -> tuple[int, int]:
        """(ns on a CPU, ns waiting to run) since :meth:`mark` of the thread that ran most."""
        deltas = [
            (
                ran - self._base.get(t, (ran, waited))[0],
                waited - self._base.get(t, (ran, waited))[1],
            )
            for t, (ran, waited) in self._stats().items()
        ]
        return max(deltas, default=(0, 0))

    def waited_s(self) -> float:
        """Seconds the busiest thread (most CPU since :meth:`mark`) waited to run."""
        return self._busiest()[1] / 1e9

    def ran_s(self) -> float:
        """Seconds the busiest thread ran on a CPU: next to its wait, it tells an emulator
        that was kept from running from one that was blocked (in a write, say) or idle."""
        return self._busiest()[0] / 1e9

    def starved(self, seconds: float) -> bool:
        """Whether the busiest thread waited more than :data:`STARVED_SHARE` of the last
        ``seconds``."""
        return self.waited_s() > STARVED_SHARE * seconds
