"""The emulated microcontroller's clock: time in seconds, and the peripherals' events.

Peripherals schedule what happens later (a byte leaves the shift register, SysTick reaches
zero, a PLL locks) with :meth:`Scheduler.at`; the CPU runs up to the next event's time
exactly (:mod:`snakebot.sim.mcu.cpu` counts instructions), the event runs, and so on. An
event scheduled while the CPU runs, earlier than the CPU was allowed to go, shortens its
run through ``on_earlier`` (the CPU's instruction limit), so no event is ever late.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable


class Event:
    """One scheduled call; :meth:`cancel` keeps it from running."""

    __slots__ = ("time", "fn", "cancelled")

    def __init__(self, time: float, fn: Callable[[float], None]) -> None:
        self.time = time
        self.fn = fn
        self.cancelled = False

    def cancel(self) -> None:
        self.cancelled = True


class Scheduler:
    """Events in time order, ties in the order they were scheduled."""

    def __init__(self) -> None:
        self._heap: list[tuple[float, int, Event]] = []
        self._seq = itertools.count()
        self.on_earlier: Callable[[float], None] | None = None

    def at(self, time: float, fn: Callable[[float], None]) -> Event:
        """Run ``fn(time)`` at ``time`` (seconds)."""
        event = Event(time, fn)
        heapq.heappush(self._heap, (time, next(self._seq), event))
        if self.on_earlier is not None:
            self.on_earlier(time)
        return event

    def next_time(self) -> float | None:
        """When the next event that will run is due (None: nothing scheduled)."""
        heap = self._heap
        while heap and heap[0][2].cancelled:
            heapq.heappop(heap)
        return heap[0][0] if heap else None

    def run_due(self, now: float) -> int:
        """Run every event due by ``now``; returns how many ran."""
        heap = self._heap
        ran = 0
        while heap and heap[0][0] <= now:
            _, _, event = heapq.heappop(heap)
            if not event.cancelled:
                event.cancelled = True
                event.fn(event.time)
                ran += 1
        return ran

    def clear(self) -> None:
        """Forget every event (a reset)."""
        self._heap.clear()
