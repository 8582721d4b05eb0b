"""The CM-530 around its STM32F103RE: what is wired to the chip's pins.

* USART1, remapped to PB6 (TX) / PB7 (RX), drives the Dynamixel bus through the
  half-duplex buffer: a byte reaches the wire only while PB4 (TX enable) is high and PB5
  (RX enable) low, with PB6 in alternate-function push-pull and the remap on; the master's
  bytes go onto the emulated bus (:class:`snakebot.sim.bus.bus.Bus`) at the time their
  start bit leaves, at the rate the firmware programmed (so a wrong divisor garbles them
  for the servos), and the servos' replies reach USART1's receiver, while PB5 is high, at
  the time their stop bit arrives. The bus runs on the chip's clock: there is no socket
  and no second clock between them.
* USART3 (PB10/PB11) is the PC link: bytes from the PC arrive back to back at the
  programmed rate (:meth:`Usart.feed`), bytes to the PC are collected for the caller.
* The ROBOTIS bootloader occupies the first 12 KB; after a reset it starts the application
  at the application base. It is not emulated here (``snakebot sim bootloader`` emulates
  its serial protocol): a reset starts the application at once, from the state a cold
  reset leaves, or from :class:`Leftovers` of a bootloader run (its clock, USART and
  interrupt state, which the public descriptions do not document).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from snakebot.core import lib
from snakebot.facts.boards import APP_BASE, FLASH_PAGE_SIZE, HSE_HZ
from snakebot.sim.bus.bus import Bus
from snakebot.sim.mcu import gpio, rcc, systick, usart
from snakebot.sim.mcu.flash import ACR_PRFTBE
from snakebot.sim.mcu.machine import USART3_IRQ, Stm32f103
from snakebot.sim.mcu.schedule import Event
from snakebot.sim.mcu.systick import CLKSOURCE, ENABLE, TICKINT

BOARD = "cm530"

REPLY_HORIZON_S = 0.003
"""How long after the master's last byte the board follows the bus event by event (a
servo's reply starts within its return delay, at most 0.5 ms, and the firmware waits 1.5
ms for it). Later bus events (servos moving), and a world's steps at any time (they send
nothing: :meth:`Bus.next_sounding_time`), run in order when the master next writes, a
servo's byte arrives or a run of the board ends, without stopping the CPU for each."""
BUS_TX_PIN, BUS_RX_PIN, BUS_TX_ENABLE, BUS_RX_ENABLE = 6, 7, 4, 5  # all on GPIOB
BUFFER_STATES_KEPT = 64  # pin states whose buffer direction is remembered (see Cm530._buffer)


@dataclass(frozen=True)
class Leftovers:
    """What a bootloader may leave running when it jumps to the application. A bootloader
    that leaves an interrupt armed jumps with interrupts masked (PRIMASK): unmasked, the
    interrupt would be taken at the application's first instruction, through the vector
    table VTOR still names (the bootloader's own), before the application can silence it;
    so ``usart3_pending`` and ``systick`` mask them too, as the firmware's start-up assumes
    (tests/firmware/test_firmware_startup.py)."""

    pll: bool = False  # SYSCLK from the PLL, HSE x6 (48 MHz), 2 wait states
    usart3_pending: bool = False  # USART3 on, RXNE interrupt enabled, a byte received
    systick: bool = False  # SysTick running with its interrupt, 1 ms
    primask: bool = False  # interrupts masked

    @classmethod
    def every(cls) -> Leftovers:
        return cls(True, True, True, True)


@dataclass
class BusStats:
    """What crossed the bus buffer."""

    sent: int = 0  # master bytes put on the wire
    blocked: int = 0  # bytes USART1 sent with the buffer not driving (pins wrong)
    received: int = 0  # bytes handed to USART1's receiver
    deaf: int = 0  # bytes that arrived while the receiver was disabled (PB5 low)


class Cm530:
    """The board with ``image`` (the bytes from the application base) in its flash.
    ``bus``: the emulated servo bus on USART1 (None: nothing on the bus). ``strict``:
    unmodelled register accesses are errors. ``on_pc_tx(byte)``: receives what USART3
    sends (default: collected in :attr:`pc_out`)."""

    def __init__(
        self,
        image: bytes,
        *,
        bus: Bus | None = None,
        strict: bool = True,
        leftovers: Leftovers | None = None,
        lsi_hz: float | None = None,
        on_pc_tx: Callable[[int], None] | None = None,
    ) -> None:
        self.image = image
        self.bus = bus
        self.leftovers = leftovers or Leftovers()
        self.mcu = Stm32f103(
            hse_hz=HSE_HZ[BOARD],
            protected_below=APP_BASE,
            page_size=FLASH_PAGE_SIZE[BOARD],
            strict=strict,
            lsi_hz=lsi_hz,
            on_reset=self._start_application,
        )
        self.mcu.load(APP_BASE, image)
        self.pc_out = bytearray()
        self.mcu.usart3.on_tx = self._pc_tx
        self._on_pc_tx = on_pc_tx
        self.mcu.usart1.hand_on_runs(self._bus_tx, self._bus_tx_run)
        self.mcu.usart1.on_idle = self._flush_bus_tx
        self.bus_stats = BusStats()
        self._tx_bytes = bytearray()  # master bytes on the wire the bus has not been given
        self._tx_start = 0.0  # when the first of them starts
        self._tx_end = 0.0  # when the last of them ends
        self._tx_baud = 0.0  # their rate
        self._bus_step: Event | None = None
        self._arrival: Event | None = None
        self._buffer_states: dict[tuple[int, int, int, int], tuple[bool, bool]] = {}
        self._rx_taken = self._rx_heard = 0  # of the replies' bytes USART1 took in C
        self.world_steps_wait = True
        """A world's steps wait for the bus's next run (REPLY_HORIZON_S); False: the board
        follows them as the bus's other events within the horizon (a test compares)."""
        # USART1's receiver in C hears the bus while PB5 listens (mcu_gpio.h)
        self.mcu.gpio["B"].link_receive_enable(self.mcu.usart1.fast, BUS_RX_ENABLE, BUS_TX_ENABLE)
        self._apply_leftovers()
        self._start_application("power")

    # -- start-up ----------------------------------------------------------------------------

    def _start_application(self, kind: str) -> None:
        self.mcu.boot(APP_BASE)
        left = self.leftovers
        if kind == "power" and (left.primask or left.usart3_pending or left.systick):
            self.mcu.cpu.set_primask(True)  # the bootloader jumped with interrupts masked

    def _apply_leftovers(self) -> None:
        left, m = self.leftovers, self.mcu
        if left.pll:
            m.flash.acr = 2 | ACR_PRFTBE
            m.rcc.cr |= rcc.HSEON | rcc.HSERDY | rcc.PLLON | rcc.PLLRDY
            m.rcc.cfgr = (1 << 16) | ((6 - 2) << 18) | (4 << 8) | rcc.SW_PLL | rcc.SW_PLL << 2
            m.rcc.refresh()
        if left.usart3_pending:
            m.rcc.apb1enr |= 1 << 18
            u = m.usart3
            u.brr = 0x271
            u.cr1 = usart.CR1_UE | usart.CR1_TE | usart.CR1_RE | usart.CR1_RXNEIE
            m.nvic.enabled |= 1 << USART3_IRQ
            u.receive(ord("#"))
        if left.systick:
            m.systick.write(systick.RVR, size=4, value=int(m.hz) // 1000 - 1)
            m.systick.write(systick.CSR, size=4, value=ENABLE | TICKINT | CLKSOURCE)

    # -- PC link -------------------------------------------------------------------------------

    def _pc_tx(self, byte: int, start: float, end: float, baud: float) -> None:
        if self._on_pc_tx is not None:
            self._on_pc_tx(byte)
        else:
            self.pc_out.append(byte)

    def pc_send(self, data: bytes) -> None:
        """The PC sends ``data`` on the link (back to back at the programmed rate)."""
        self.mcu.usart3.feed(data)

    # -- the bus ---------------------------------------------------------------------------------

    def _buffer_drives(self) -> bool:
        return self._buffer()[0]

    def _receiver_listens(self) -> bool:
        return self._buffer()[1]

    def _buffer(self) -> tuple[bool, bool]:
        """(the buffer drives the bus, the receiver listens), worked out once for each state
        of GPIOB's configuration and output latch and AFIO's remap (a few, every byte)."""
        port, afio = self.mcu.gpio["B"], self.mcu.afio
        key = (port.cr[0], port.cr[1], port.odr, afio.mapr)
        known = self._buffer_states.get(key)
        if known is None:
            if len(self._buffer_states) >= BUFFER_STATES_KEPT:
                self._buffer_states.clear()
            tx_mode = port.mode(BUS_TX_PIN)
            drives = (
                afio.usart1_remapped
                and gpio.is_alternate(tx_mode)
                and tx_mode & 0x4 == 0  # push-pull
                and port.output(BUS_TX_ENABLE) is True
                and port.output(BUS_RX_ENABLE) is False
            )
            listens = port.output(BUS_RX_ENABLE) is True and port.output(BUS_TX_ENABLE) is False
            known = self._buffer_states[key] = (drives, listens)
        return known

    def _bus_tx(self, byte: int, start: float, end: float, baud: float) -> None:
        self._bus_byte(byte, start, end, baud, self._buffer_drives())

    def _bus_tx_run(self, data: list[int], starts: list[float], frame: float, baud: float) -> None:
        """USART1's ``on_tx_run``: the bytes it started in C since the model last looked,
        as :meth:`_bus_tx` takes them one by one. The buffer's pins are the same for all:
        a write that could change them stops the CPU for the model, which hands these on
        first (mcu_gpio.h)."""
        drives = self._buffer_drives()
        tx, stats = self._tx_bytes, self.bus_stats
        for byte, start in zip(data, starts, strict=True):
            if drives and tx and start == self._tx_end and baud == self._tx_baud:
                tx.append(byte)  # right behind the one before (a bus is there: tx holds bytes)
                self._tx_end = start + frame
                stats.sent += 1
            else:
                self._bus_byte(byte, start, start + frame, baud, drives)

    def _bus_byte(self, byte: int, start: float, end: float, baud: float, drives: bool) -> None:
        if not drives:
            self.bus_stats.blocked += 1
        bus = self.bus
        if bus is None:
            return
        if drives:
            self.bus_stats.sent += 1
            if start == self._tx_end and baud == self._tx_baud and self._tx_bytes:
                self._tx_bytes.append(byte)  # right behind the one before: the same frame
                self._tx_end = end
                return
        self._flush_bus_tx()
        if start > bus.now:
            bus.run_until(start)  # the bus's events due by the byte's start run first
        if drives:
            if bus.baudrate != baud:
                bus.baudrate = baud
            self._tx_bytes.append(byte)
            self._tx_start, self._tx_end, self._tx_baud = start, end, baud
        self._plan_bus()

    def _flush_bus_tx(self, _t: float = 0.0) -> None:
        """Give the bus the master's bytes USART1 has sent since it was last given some,
        back to back from the first one's start (where the bus's clock stands): in one
        write rather than a byte at a time, which is the same on the wire (the servos hear
        a packet when its last byte is in) and spares the bus most of its work. Done
        before the bus runs past the first one's start (:meth:`_run_bus`) and when USART1
        has nothing more to send (``_t``: when)."""
        data = self._tx_bytes
        if not data:
            return
        bus = self.bus
        assert bus is not None
        self._settle_rx()  # the bytes heard so far are read before the wire changes
        bus.master_write(bytes(data))
        data.clear()
        self._plan_bus()

    def _plan_bus(self) -> None:
        """Keep one event at the bus's next event and one at the next byte's arrival."""
        bus = self.bus
        assert bus is not None
        scheduler = self.mcu.scheduler
        self._settle_rx()
        t = bus.next_sounding_time() if self.world_steps_wait else bus.next_event_time()
        arrival = self._hand_rx(t) if self.mcu.usart1.timed_in_c else None
        if t is not None and t > bus.master_tx_done + REPLY_HORIZON_S:
            t = None  # nothing the firmware can hear: it runs later, in order
        if self._bus_step is not None and (t is None or self._bus_step.time != t):
            self._bus_step.cancel()
            self._bus_step = None
        if t is not None and self._bus_step is None:
            self._bus_step = scheduler.at(max(t, self.mcu.now()), self._step_bus)
        if not self.mcu.usart1.timed_in_c:
            arrival = bus.next_master_arrival(1) if bus.master_in_waiting() == 0 else bus.now
        if self._arrival is not None and (arrival is None or self._arrival.time != arrival):
            self._arrival.cancel()
            self._arrival = None
        if arrival is not None and self._arrival is None:
            self._arrival = scheduler.at(max(arrival, self.mcu.now()), self._deliver)

    def _hand_rx(self, bus_event: float | None) -> float | None:
        """Hand USART1's receiver, in C, the bytes on their way from the servos that
        nothing can change before they arrive: before the bus's next event that may put
        bytes on the wire (``bus_event``) and before a master byte the bus has not been
        given (the first one the firmware sends after them stops the CPU for the model,
        mcu_usart.c).
        Returns when the first byte not handed arrives (None: none), for :meth:`_deliver`."""
        bus, usart1 = self.bus, self.mcu.usart1
        assert bus is not None
        usart1.forget_expected()  # handed again from where the bus stands
        before = math.inf if bus_event is None else bus_event
        if self._tx_bytes and self._tx_start < before:
            before = self._tx_start
        data, times, after = bus.master_coming(before, lib.MCU_USART_RXQ)
        if data:
            usart1.expect(data, times)
        return after

    def _settle_rx(self) -> None:
        """Read from the bus the bytes USART1 took in C since the last look, and count
        them (each was heard, or arrived with PB5 low)."""
        fast = self.mcu.usart1.fast
        n = fast.rx_taken - self._rx_taken
        if not n:
            return
        heard = fast.rx_heard - self._rx_heard
        self._rx_taken, self._rx_heard = fast.rx_taken, fast.rx_heard
        bus = self.bus
        assert bus is not None
        if fast.rx_taken_at > bus.now:
            bus.run_until(fast.rx_taken_at)  # nothing sounding is due before (_hand_rx)
        bus.master_read(n)
        self.bus_stats.received += heard
        self.bus_stats.deaf += n - heard

    def _run_bus(self, t: float) -> None:
        """Run the bus until ``t``, given the bytes USART1 has sent first if ``t`` is past
        their start (a bus event due at their start, or before, leaves them be: given
        then, the bytes of a packet still on its way would reach the bus a few at a
        time)."""
        bus = self.bus
        assert bus is not None
        if self._tx_bytes and t > self._tx_start:
            self._flush_bus_tx()
        if t > bus.now:
            bus.run_until(t)

    def _step_bus(self, t: float) -> None:
        self._bus_step = None
        self._run_bus(t)
        self._plan_bus()

    def _deliver(self, t: float) -> None:
        self._arrival = None
        bus = self.bus
        assert bus is not None
        self._settle_rx()
        self._run_bus(t)
        data = bus.master_read(1)
        if data:
            if self._receiver_listens():
                self.mcu.usart1.receive(data[0])
                self.bus_stats.received += 1
            else:
                self.bus_stats.deaf += 1
        self._plan_bus()

    # -- running ---------------------------------------------------------------------------------

    def now(self) -> float:
        return self.mcu.now()

    def run_until(self, t: float) -> None:
        """Run the board (chip and bus) until time ``t`` (seconds). The bus stops at the
        start of a packet USART1 is still sending (the rest of it follows it there)."""
        self.mcu.run_until(t)
        if self.bus is not None:
            self._run_bus(min(t, self._tx_start) if self._tx_bytes else t)
            self._plan_bus()

    def run_for(self, seconds: float) -> None:
        self.run_until(self.now() + seconds)
