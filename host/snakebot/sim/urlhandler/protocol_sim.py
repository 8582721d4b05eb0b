"""``sim://``: a pyserial port whose far end is an emulated Dynamixel bus.

    port = serial.serial_for_url("sim://?robot=snake5&echo=1&corrupt=0.01", baudrate=1000000)

Anything that takes a pyserial URL reaches the emulator unchanged. Options are listed
in ``snakebot.sim.options.OPTIONS``. ``sim://NAME?...`` names the bus: it lives as long as
the process, so a later ``sim://NAME`` finds the servos as they were left (settings,
positions), like a robot that stayed powered; one port at a time may have it open.

Time: by default the bus runs as fast as possible. A blocking read runs the bus's
virtual clock forward until the bytes it waits for have arrived or its timeout has
passed in bus time; a non-blocking read (or ``in_waiting``) lets the bus run to its
next happening, so a polling client is not left waiting. A read that times out with
nothing at all still takes its timeout in wall time, so a client retrying on the wall
clock does not race the bus clock ahead. With ``realtime=1`` the bus clock follows the
wall clock instead.
"""

from __future__ import annotations

import math
import threading
import time
from urllib.parse import urlsplit

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, to_bytes

from snakebot.errors import SnakebotError, quoted
from snakebot.sim.bus.bus import Bus
from snakebot.sim.bus.clock import WallClockPacer
from snakebot.sim.options import URL_FORM, SimOptions

POLL_HORIZON_S = 0.1
"""A non-blocking read lets the bus run at most this far ahead to find the next byte."""

BLOCKING_SLICE_S = 0.1
"""A read with no timeout waits in slices of this much bus (and wall) time."""

_named: dict[str, tuple[SimOptions, Bus]] = {}
_in_use: set[str] = set()
_registry_lock = threading.Lock()


def wall_clock_url(url: str) -> str:
    """The ``sim://`` ``url`` for a client that keeps the wall clock's time (a player that
    ticks every 10 ms): its bus tied to the wall clock (``realtime=1``), or else the bus
    runs only while the client waits for a reply and the servos hardly move. A URL that
    names its own ``realtime`` is left alone, as is ``sim://NAME`` with no options (a bus
    opened earlier keeps its own)."""
    if "realtime=" in url or "?" not in url:
        return url
    return url + ("" if url.endswith(("?", "&")) else "&") + "realtime=1"


def named_bus(name: str) -> Bus | None:
    """The bus opened earlier as ``sim://NAME`` (None if there is none)."""
    with _registry_lock:
        entry = _named.get(name)
    return entry[1] if entry else None


def forget_named_buses() -> None:
    """Drop every named bus (tests use this for a clean slate)."""
    with _registry_lock:
        _named.clear()
        _in_use.clear()


class Serial(SerialBase):
    """A serial port onto an emulated bus; the host is the bus master."""

    adapter_latency_s = 0.0
    """No adapter holds the replies back (``snakebot.link.transport.adapter`` reads this)."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        self.bus: Bus | None = None
        self.options: SimOptions | None = None
        self._name = ""
        self._lock = threading.RLock()
        self._pacer: WallClockPacer | None = None
        super().__init__(*args, **kwargs)

    # -- opening --------------------------------------------------------------------------

    def open(self) -> None:
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        self.bus, self.options, self._name = self._attach(self.port)
        if self.options.realtime:
            self._pacer = WallClockPacer()
            self._pacer.anchor(self.bus.now)
        self.is_open = True
        self._reconfigure_port()
        self.reset_input_buffer()

    def _attach(self, url: str) -> tuple[Bus, SimOptions, str]:
        parts = urlsplit(url)
        if parts.scheme != "sim":
            raise SerialException(f"expected {URL_FORM}, not {quoted(url)}")
        try:
            options = SimOptions.from_query(parts.query)
            name = parts.netloc + parts.path.strip("/")
            if not name:
                return options.build_bus(self._baudrate), options, ""
            with _registry_lock:
                if name in _in_use:
                    raise SerialException(
                        f"sim://{name} is already open: close the other port first (one "
                        "master per bus), or use another name"
                    )
                entry = _named.get(name)
                if entry is None:
                    entry = _named[name] = (options, options.build_bus(self._baudrate))
                elif parts.query and entry[0] != options:
                    raise SerialException(
                        f"sim://{name} already exists with other options: open it as "
                        f"sim://{name} without options, or use another name"
                    )
                _in_use.add(name)
            return entry[1], entry[0], name
        except SnakebotError as exc:  # a bad option, a robot file or state file that fails
            raise SerialException(str(exc)) from exc

    def close(self) -> None:
        if self.is_open and self._name:
            with _registry_lock:
                _in_use.discard(self._name)
        self.is_open = False
        super().close()

    def _reconfigure_port(self) -> None:
        if not self.is_open or self.bus is None:
            return
        if not (isinstance(self._baudrate, (int, float)) and self._baudrate > 0):
            raise ValueError(f"invalid baudrate: {quoted(self._baudrate)}")
        with self._lock:
            self.bus.baudrate = self._baudrate

    # -- time -----------------------------------------------------------------------------

    def port_clock(self) -> float:
        """The clock a client counts this port's reply timeouts on
        (``snakebot.link.transport.portio`` reads it): the bus's own, so that a reply due in
        bus time is never missed because the host ran the client late; the wall clock's
        with ``realtime=1``, where the bus follows it."""
        if self._pacer is not None or self.bus is None:
            return time.monotonic()
        return self.bus.now

    def _sync(self) -> None:
        if self._pacer is not None:
            self.bus.run_until(self._pacer.now())

    def _poll_step(self) -> None:
        """Nothing for us yet: let the bus run to its next happening, if one is near."""
        bus = self.bus
        times = [t for t in (bus.next_master_arrival(), bus.next_event_time()) if t is not None]
        if times and min(times) <= bus.now + POLL_HORIZON_S:
            bus.run_until(min(times))

    # -- the data path --------------------------------------------------------------------

    @property
    def in_waiting(self) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        with self._lock:
            self._sync()
            n = self.bus.master_in_waiting()
            if n == 0 and self._pacer is None:
                self._poll_step()
                n = self.bus.master_in_waiting()
            return n

    def read(self, size: int = 1) -> bytes:
        if not self.is_open:
            raise PortNotOpenError()
        if size <= 0:
            return b""
        if self._pacer is not None:
            return self._read_realtime(size)
        began = time.monotonic()
        with self._lock:
            bus = self.bus
            timeout = self._timeout
            if timeout:
                out = self._timed_read(size, timeout)
                if len(out) >= size:
                    return out
            else:
                out = bytearray(bus.master_read(size))
                if len(out) >= size:
                    return bytes(out)
                if timeout == 0:
                    for _ in range(size - len(out)):
                        before = bus.now
                        self._poll_step()
                        out += bus.master_read(size - len(out))
                        if len(out) >= size or bus.now == before:
                            break
                    return bytes(out)
                self._read_until(out, size, bus.now + BLOCKING_SLICE_S, blocking=True)
        return self._timed_out(out, began, timeout)

    def exchange(self, data: bytes, size: int) -> bytes:
        """What :meth:`reset_input_buffer`, :meth:`write` (``data``) and :meth:`read`
        (``size``) do one after the other (a transaction's first round), in one call and
        under one lock where the bus runs as fast as possible and the read is timed."""
        timeout = self._timeout
        if self._pacer is not None or not timeout or size <= 0 or type(data) is not bytes:
            self.reset_input_buffer()
            self.write(data)
            return self.read(size)
        if not self.is_open:
            raise PortNotOpenError()
        with self._lock:
            bus = self.bus
            bus.master_flush_input()
            if bus.master_tx_done > bus.now:  # as write
                bus.run_until(bus.master_tx_done)
            bus.master_write(data)
            began = time.monotonic()
            out = self._timed_read(size, timeout)
            if len(out) >= size:
                return out
        return self._timed_out(out, began, timeout)

    def _timed_read(self, size: int, timeout: float) -> bytes | bytearray:
        """A timed read, as a client's transaction makes (the lock held): the bus runs
        until the whole answer is in, which is then handed over in one piece (one call
        each, where :meth:`_read_until` would take two rounds); if it is not, what came
        by the timeout, in bus time."""
        bus = self.bus
        deadline = bus.now + timeout
        got = bus.master_receive(size, deadline)
        if len(got) >= size:
            return got
        out = bytearray(got)
        self._read_until(out, size, deadline, blocking=False)
        return out

    def _read_until(self, out: bytearray, size: int, deadline: float, *, blocking: bool) -> None:
        """Add to ``out`` what arrives until it holds ``size`` bytes or the bus reaches
        ``deadline`` (the lock held); ``blocking``: then on, in slices, until it does."""
        bus = self.bus
        while len(out) < size and self.is_open:
            if bus.run_until_master_data(deadline, size - len(out)):
                got = bus.master_read(size - len(out))
                out += got
                if got:
                    continue
            if not blocking:
                break
            time.sleep(BLOCKING_SLICE_S)  # nothing on its way: wait like a real port
            deadline = bus.now + BLOCKING_SLICE_S

    @staticmethod
    def _timed_out(out: bytes | bytearray, began: float, timeout: float | None) -> bytes:
        """``out``, what a read begun at ``began`` got; a timed read that got nothing
        costs its time first (counting the bus's own), or a retrying client spins."""
        if not out and timeout:
            time.sleep(max(0.0, began + timeout - time.monotonic()))
        return bytes(out)

    def _read_realtime(self, size: int) -> bytes:
        timeout = self._timeout
        wall_deadline = math.inf if timeout is None else time.monotonic() + timeout
        out = bytearray()
        while self.is_open:
            with self._lock:
                self._sync()
                out += self.bus.master_read(size - len(out))
                nxt = self.bus.next_master_arrival()
                wait = self._pacer.wall_delay(nxt) if nxt is not None else BLOCKING_SLICE_S
            if len(out) >= size or timeout == 0:
                break
            remaining = wall_deadline - time.monotonic()
            if remaining <= 0:
                break
            time.sleep(min(max(wait, 0.0), remaining, BLOCKING_SLICE_S))
        return bytes(out)

    def write(self, data: bytes) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        if type(data) is not bytes:
            data = to_bytes(data)
        with self._lock:
            bus = self.bus
            if self._pacer is not None:  # (a call saved on the closed loop's path)
                self._sync()
            elif bus.master_tx_done > bus.now:
                # The bus clock moves only when the master waits for something; a master
                # that only writes (a gait played with no reads) would otherwise queue
                # its packets one behind the other in bus time, and the reply to its
                # next READ would come after all of them. A write comes no sooner than
                # the one before it has left the UART, as on a host pacing its writes.
                bus.run_until(bus.master_tx_done)
            bus.master_write(data)
        return len(data)

    def reset_input_buffer(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()
        with self._lock:
            if self._pacer is not None:
                self._sync()
            self.bus.master_flush_input()

    def reset_output_buffer(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()

    @property
    def out_waiting(self) -> int:
        return 0

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True
