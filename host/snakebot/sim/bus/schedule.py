"""The bus's virtual clock and its events: calls due at bus times, run in time order
(ties in the order they were made), and calls repeated on the clock (:class:`Schedule`,
how a world steps with the servos). The clock moves only when :meth:`run_until` (or the
master's port, on a read's behalf) moves it."""

from __future__ import annotations

import heapq
from collections.abc import Callable

from snakebot.sim.bus.state import BusState


class Schedule:
    """A call repeated on the bus clock (:meth:`EventScheduler.every`): the ``n``-th at
    ``first + n * period``, until :meth:`cancel`."""

    __slots__ = ("bus", "period", "fn", "first", "count", "cancelled")

    def __init__(
        self, bus: EventScheduler, period: float, fn: Callable[[float], object], first: float
    ) -> None:
        self.bus = bus
        self.period = period
        self.fn = fn
        self.first = first
        self.count = 0
        self.cancelled = False

    def tick(self, t: float) -> None:
        if self.cancelled:
            return
        self.fn(t)
        self.count += 1
        if not self.cancelled:
            self.bus.at(self.first + self.count * self.period, self.tick)

    def cancel(self) -> None:
        """No more calls (also when called from the schedule's own call)."""
        if not self.cancelled:
            self.cancelled = True
            self.bus._unschedule(self.tick)


class EventScheduler(BusState):
    """The bus's clock and event queue (a part of :class:`~snakebot.sim.bus.bus.Bus`)."""

    def at(self, t: float, fn: Callable, arg: object = None) -> None:
        """Call ``fn(t)`` (or ``fn(t, arg)`` when ``arg`` is given) at bus time ``t``."""
        heapq.heappush(self._events, (t, next(self._seq), fn, arg))

    def every(
        self, period: float, fn: Callable[[float], object], start: float | None = None
    ) -> Schedule:
        """Call ``fn(t)`` at ``start`` (default: now) and every ``period`` seconds after,
        in time order with the bus's own events: how a world steps with the servos.
        ``fn`` puts nothing on the wire (see :meth:`next_sounding_time`). Returns the
        schedule, to :meth:`Schedule.cancel` it."""
        if not period > 0:
            raise ValueError("period must be positive")
        schedule = Schedule(self, period, fn, self.now if start is None else start)
        self.at(schedule.first, schedule.tick)
        return schedule

    def _unschedule(self, fn: Callable) -> None:
        """Drop the pending events that would call ``fn``."""
        kept = [e for e in self._events if e[2] != fn]
        if len(kept) != len(self._events):
            heapq.heapify(kept)
            self._events[:] = kept

    def next_event_time(self) -> float | None:
        """When the next scheduled event happens (None if none)."""
        if self._held is not None:
            self._release()
        return self._events[0][0] if self._events else None

    def next_sounding_time(self) -> float | None:
        """When the next event that may put bytes on the wire happens (None if none):
        any but a schedule's call (:meth:`every`: a world stepping moves the servos and
        sends nothing; what a servo sends is made when a frame reaches it, an event of
        its own). The calls before it run in their order all the same, whenever the
        clock passes them."""
        if self._held is not None:
            self._release()
        quiet = Schedule.tick
        sounding = [e[0] for e in self._events if getattr(e[2], "__func__", None) is not quiet]
        return min(sounding, default=None)

    def run_until(self, t: float) -> None:
        """Run every event up to bus time ``t`` and leave the clock at ``t``."""
        held = self._held
        if held is not None and held[1] <= t:
            self._release()
        events = self._events
        while events and events[0][0] <= t:
            et, _, fn, arg = heapq.heappop(events)
            if et > self.now:
                self.now = et
            if arg is None:
                fn(self.now)
            else:
                fn(self.now, arg)
        if t > self.now:
            self.now = t

    def advance(self, dt: float) -> None:
        """Run the bus for ``dt`` seconds."""
        self.run_until(self.now + dt)
