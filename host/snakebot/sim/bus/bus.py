"""The emulated Dynamixel line: one master, several virtual servos, one wire.

Everything happens on the bus's virtual clock (:attr:`Bus.now`, seconds), which moves
only when :meth:`Bus.run_until` (or a transport on the bus's behalf) moves it:

* A transmission occupies the wire for 10 bits a byte at its sender's baud rate. Each
  receiver hears it at its own rate: the same bytes when the rates agree, and what a
  UART sampling at the wrong rate makes of it otherwise (``snakebot.sim.bus.uart``), which is
  how a servo left on another baud rate hears garbage.
* Servos that share a baud rate hear the same bytes, so they share one receiver
  (``snakebot.sim.bus.receiver``: byte by byte, a damaged frame dropped whole); a packet is
  handed to every servo when its last byte has arrived, and the status packet goes out
  Return Delay Time later. A gap of more than 100 ms inside a packet makes the servos
  drop it.
* Two drivers on the wire at once (two servos with one ID, a servo answering while the
  master still talks, a noise burst) garble every byte slot they share.
* With ``echo`` on, the master hears its own instruction, as on a one-wire adapter.
* Faults (``snakebot.sim.bus.faults``) are injected from a seed, reproducibly.

A world (body kinematics) steps on the same clock: register a callback with
:meth:`Bus.every` and read the servos' present positions in it (:meth:`Bus.positions`).

The bus is one object made of parts, each in its own module and all working on the
same attributes (``snakebot.sim.bus.state``): the clock and its events (``schedule``),
the servos grouped by what they hear (``listeners``), the line itself (``wire``), what
the servos hear and answer (``delivery``) and the master's port (``master``). This
module ties them together, with the set-up and the world's view.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable

from snakebot.core import ffi
from snakebot.sim.bus.delivery import INTER_BYTE_GAP_S, Delivery, frame_ends
from snakebot.sim.bus.faults import FaultConfig, FaultInjector
from snakebot.sim.bus.listeners import Listeners
from snakebot.sim.bus.master import MasterPort
from snakebot.sim.bus.schedule import EventScheduler, Schedule
from snakebot.sim.bus.wire import MASTER, NOISE, BusStats, Wire
from snakebot.sim.servo.fast import VirtualServo

__all__ = [
    "INTER_BYTE_GAP_S",
    "MASTER",
    "NOISE",
    "Bus",
    "BusStats",
    "Schedule",
    "frame_ends",
]


class Bus(MasterPort, Delivery, Wire, Listeners, EventScheduler):
    """A Dynamixel line with virtual servos on a virtual clock; the host is the master.

    ``baudrate`` is the master's UART rate (the servos each have their own, from their
    Baud Rate register). ``echo``: the master hears its own instructions.
    """

    def __init__(
        self,
        servos: Iterable[VirtualServo] = (),
        *,
        baudrate: float = 1_000_000,
        echo: bool = False,
        faults: FaultConfig | None = None,
        supply_v: float | None = None,
    ) -> None:
        self.now = 0.0
        self.servos = list(servos)
        self.baudrate = baudrate
        self.echo = echo
        self.fault_config = faults or FaultConfig()
        self.faults = FaultInjector(self.fault_config)
        self._corrupting = self.fault_config.corrupt > 0
        config = self.fault_config
        self._reply_faults = bool(config.drop or config.delay_s or config.jitter_s)
        self.stats = BusStats()
        self._events = []
        self._seq = itertools.count()
        self._wire = []
        self._wire_end = -math.inf
        self._c_reply = ffi.new("uint8_t[]", 256)
        self._c_reply_bytes = ffi.buffer(self._c_reply)
        self._deliver_read_cb = self._deliver_read
        self._held = None
        self._master_rx = []
        self._master_tx_free = 0.0
        self._servo_tx_free = {}
        self._receivers = {}
        self._groups = None
        self._quiet_reply = None
        self._c_path = True
        self._link_epoch = 0
        self._by_id = None
        self._indexed = 0
        for s in self.servos:
            s.on_link_change = self._link_changed
        if supply_v is not None:
            self.set_supply(supply_v)
        for b in self.fault_config.brownouts:
            victims = [s for s in self.servos if s.id == b.servo_id]
            for s in victims:
                self.at(b.start_s, lambda t, s=s: s.power_off(t))
                self.at(b.start_s + b.duration_s, lambda t, s=s: s.power_on(t))
        noise = self.faults.next_noise(0.0)
        if noise is not None:
            self.at(noise[0], self._noise_burst, noise[1])

    # -- set-up ---------------------------------------------------------------------------

    def add(self, servo: VirtualServo) -> VirtualServo:
        """Put another servo on the line."""
        servo.advance(self.now)
        servo.t = self.now
        servo.on_link_change = self._link_changed
        self.servos.append(servo)
        self._groups = None
        self._by_id = None
        return servo

    def servo(self, servo_id: int) -> VirtualServo:
        """The (first) servo answering to ``servo_id``."""
        by_id = self._by_id
        if by_id is None or self._indexed != len(self.servos):
            by_id = {}
            for s in self.servos:
                by_id.setdefault(s.id, s)
            self._by_id = by_id
            self._indexed = len(self.servos)
        try:
            return by_id[servo_id]
        except KeyError:
            raise KeyError(f"no servo with ID {servo_id} on the bus") from None

    def set_supply(self, volts: float) -> None:
        """Set the supply voltage every servo sees (from now on)."""
        for s in self.servos:
            s.set_supply(self.now, volts)

    # -- the world's view ------------------------------------------------------------------

    def positions(self, ids: Iterable[int] | None = None) -> list[float]:
        """Present positions (ticks, unrounded) now, for ``ids`` in order or every servo."""
        servos = self.servos if ids is None else [self.servo(i) for i in ids]
        now = self.now
        for s in servos:
            s.advance(now)
        return [s.pos for s in servos]
