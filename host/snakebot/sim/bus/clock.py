"""Time on the emulated bus.

The bus keeps its own virtual clock (seconds, a float) and only moves it forward when
asked: in process a client can run hundreds of times faster than the wire. A server
that faces a real client (a pseudo-terminal, QEMU over a socket) ties the virtual clock
to the wall clock with a :class:`WallClockPacer`, so replies arrive when a real servo's
would and the client's timeouts mean what they say.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from snakebot.formats.protocol.instructions import BITS_PER_BYTE


def byte_time(baudrate: float) -> float:
    """Seconds one 8N1 byte occupies the wire at ``baudrate``."""
    return BITS_PER_BYTE / baudrate


class WallClockPacer:
    """Maps the wall clock onto a virtual clock running ``speed`` times as fast.

    ``anchor(virtual_now)`` pins the current wall time to ``virtual_now``; afterwards
    :meth:`now` is the virtual time that corresponds to the wall clock, and
    :meth:`wall_delay` how long to sleep until a virtual instant is reached.
    """

    def __init__(self, speed: float = 1.0, wall: Callable[[], float] = time.monotonic) -> None:
        if not speed > 0:
            raise ValueError(f"speed must be positive, got {speed!r}")
        self.speed = speed
        self._wall = wall
        self._wall0 = wall()
        self._virtual0 = 0.0

    def anchor(self, virtual_now: float) -> None:
        """From now on, the current wall instant corresponds to ``virtual_now``."""
        self._wall0 = self._wall()
        self._virtual0 = virtual_now

    def now(self) -> float:
        """The virtual time that corresponds to the wall clock now."""
        return self._virtual0 + (self._wall() - self._wall0) * self.speed

    def wall_delay(self, virtual_t: float) -> float:
        """Wall seconds until the virtual clock reaches ``virtual_t`` (0 if it has)."""
        return max(0.0, (virtual_t - self.now()) / self.speed)
