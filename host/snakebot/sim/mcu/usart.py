"""USART in asynchronous mode, 8 data bits, no parity, 1 stop bit (RM0008 section 27).

The transmitter has the data register (TDR) and a shift register: a byte written to DR
moves to the shift register at once if it is idle (TXE stays set), else waits in TDR (TXE
clear) until the shift register has sent the one before. A byte takes 10 bit times at the
programmed rate (``pclk / BRR``); TC is set when the shift register has sent its byte and
TDR is empty. Enabling the transmitter (TE) first sends an idle frame, as the chip does.
TC is cleared by reading SR then writing DR, or by writing 0 to it; RXNE by reading DR or
writing 0; reading SR then DR clears ORE, NE, FE and PE. Each sequence is tracked on its
own (a receive handler's DR read between the SR read and the DR write does not keep TC
set), which is how the firmware's interrupt handler uses them. A byte that arrives while RXNE
is still set is lost and sets ORE. The interrupt line is the OR of TXEIE&TXE, TCIE&TC and
RXNEIE&(RXNE|ORE). Other modes (9 bits, parity, 2 stop bits, DMA, hardware flow control,
half-duplex by HDSEL, LIN, smartcard, IrDA) are unmodelled, so an error in strict mode.

On the chip (its line wired to the C NVIC) the registers the firmware's interrupt handlers
reach for every byte are served in C from the state this model keeps in ``fast``
(mcu_usart.h): SR, DR and CR1 reads, a DR write behind the byte being sent, a CR1 write that
starts no idle frame; and once the machine times it there (:meth:`Usart.time_in_c`), the
shift register's frames end in C too, at the instruction this model's event would run at
(TXE and the next byte, or TC), the bytes that start logged for :meth:`Usart.drain` to
hand on. This model serves the rest (a shift register it starts, the far end).

Bytes leave through ``on_tx(byte, start, end, baud)`` as their start bit goes out (a frame
timed in C: when the model next runs, before anything else the machine does) and
``on_idle(t)`` tells when the transmitter has nothing more to send (TC is set); bytes
arrive through :meth:`Usart.receive` (one byte whose stop bit is in now) or
:meth:`Usart.feed` (bytes the far end sends back to back at the programmed rate).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

from snakebot.core import ffi, lib
from snakebot.sim.mcu.regs import Clock, Peripheral, kept_in
from snakebot.sim.mcu.schedule import Event, Scheduler

SR, DR, BRR, CR1, CR2, CR3, GTPR = range(0, 0x1C, 4)
PE, FE, NE, ORE, IDLE, RXNE, TC, TXE = (1 << n for n in range(8))
SR_RESET = TXE | TC
SR_CLEAR_BY_ZERO = RXNE | TC | (1 << 8) | (1 << 9)  # RXNE, TC, LBD, CTS
CR1_SBK, CR1_RWU, CR1_RE, CR1_TE, CR1_IDLEIE = 1 << 0, 1 << 1, 1 << 2, 1 << 3, 1 << 4
CR1_RXNEIE, CR1_TCIE, CR1_TXEIE, CR1_PEIE = 1 << 5, 1 << 6, 1 << 7, 1 << 8
CR1_M, CR1_UE = 1 << 12, 1 << 13
CR1_PCE = CR1_PEIE << 2  # parity control enable, bit 10
CR1_MODELLED = CR1_RE | CR1_TE | CR1_RXNEIE | CR1_TCIE | CR1_TXEIE | CR1_UE
BITS_PER_FRAME = 10

TxSink = Callable[[int, float, float, float], None]
TxRunSink = Callable[[list[int], list[float], float, float], None]
"""Called with (bytes, their starts, one frame (s), baud): the bytes the shift register
timed in C started since the model last looked, in order, handed on at once."""


class Usart(Peripheral):
    """One USART at ``base``. ``pclk()``: its bus clock (Hz); ``irq(level)``: its NVIC
    line; ``clock_on()``: its RCC enable."""

    def __init__(
        self,
        name: str,
        base: int,
        *,
        scheduler: Scheduler,
        now: Clock,
        pclk: Callable[[], int],
        irq: Callable[[bool], None],
        clock_on: Callable[[], bool],
        on_tx: TxSink | None = None,
        strict: bool = True,
        nvic_line: tuple[object, int] | None = None,
    ) -> None:
        super().__init__(base, strict=strict)
        self.name = name
        self.scheduler = scheduler
        self.now = now
        self.pclk = pclk
        self.irq = irq
        self.clock_on = clock_on
        self._on_tx = on_tx
        self._on_tx_run: TxRunSink | None = None
        self._on_idle: Callable[[float], None] | None = None
        self._counter: object = None  # the machine's mcu_counter once timed in C
        self.sent = 0
        self._received = 0  # by receive(); the rest by the bytes expected in C
        self._overruns = 0
        self.lost = 0  # bytes the far end sent while no rate was programmed (BRR unset)
        self.fast = ffi.new("mcu_fast_io *")  # SR as the CPU reads it (in C, see mcu_count.h)
        self.fast.kind = lib.MCU_IO_USART_SR
        self.fast.second_offset = CR1  # read by the interrupt handler on every byte
        if nvic_line is not None:  # its line wired to the C NVIC: more served in C
            self.fast.nvic, self.fast.irq = nvic_line
        self._inbox: deque[int] = deque()
        self._feeding: Event | None = None
        self._shift_end: Event | None = None
        self.reset()

    def reset(self) -> None:
        for event in (self._shift_end, self._feeding):
            if event is not None:
                event.cancel()
        self._shift_end = self._feeding = None
        self.fast.shifting = self.fast.logged = self.fast.idle = self.fast.rx_count = 0
        self._inbox.clear()
        self.sr = SR_RESET
        self.rdr = 0
        self.tdr = None
        self.brr = 0
        self.cr1 = self.cr2 = self.cr3 = 0
        self.fast.armed = 0  # bit 0: a DR read clears the error flags; bit 1: a DR write TC
        self.fast.second_on = 0
        self.fast.line = 0
        self.irq(False)

    # -- the state, kept in ``fast`` (C serves some accesses from there) --------------------

    sr = kept_in("fast", "value")
    cr1 = kept_in("fast", "second")
    rdr = kept_in("fast", "rdr")

    @property
    def tdr(self) -> int | None:
        """The byte waiting in TDR, if one is."""
        return int(self.fast.tdr) if self.fast.tdr_full else None

    @tdr.setter
    def tdr(self, value: int | None) -> None:
        self.fast.tdr_full = value is not None
        self.fast.tdr = value or 0

    # -- rates ----------------------------------------------------------------------------

    @property
    def baud(self) -> float:
        """The programmed rate (bits per second; 0 when BRR is not set)."""
        return self.pclk() / self.brr if self.brr >= 16 else 0.0

    def frame_s(self) -> float:
        baud = self.baud
        return BITS_PER_FRAME / baud if baud else float("inf")

    @property
    def transmitting(self) -> bool:
        return bool(self.fast.shifting)

    @property
    def shift_end(self) -> float | None:
        """When the shift register is done with what it sends (None: idle)."""
        if not self.fast.shifting:
            return None
        return self.fast.shift_end if self._shift_end is None else self._shift_end.time

    # -- timed in C -----------------------------------------------------------------------

    def time_in_c(self, counter: object) -> None:
        """Let the machine's instruction counter ``counter`` (an ``mcu_counter``) time the
        shift register's frames, in C (the line must be wired to the C NVIC; None: this
        model times the frames it starts from now on)."""
        self._counter = counter
        self.rate_changed()

    def rate_changed(self) -> None:
        """BRR or the bus clock changed: the frames timed in C take the new rate."""
        baud = self.baud
        self.fast.baud = baud
        self.fast.frame_s = BITS_PER_FRAME / baud if baud else float("inf")

    @property
    def on_tx(self) -> TxSink | None:
        """Called with each byte as its start bit goes out."""
        return self._on_tx

    @on_tx.setter
    def on_tx(self, fn: TxSink | None) -> None:
        self._on_tx, self._on_tx_run = fn, None  # a run is handed on byte by byte to it

    @property
    def on_tx_run(self) -> TxRunSink | None:
        """Takes the bytes a drain hands on, in one call (see :meth:`hand_on_runs`)."""
        return self._on_tx_run

    def hand_on_runs(self, on_tx: TxSink, on_tx_run: TxRunSink) -> None:
        """``on_tx``, and ``on_tx_run`` that takes the bytes a drain hands on in one call
        as ``on_tx`` would take them one by one (until ``on_tx`` is set again)."""
        self._on_tx, self._on_tx_run = on_tx, on_tx_run

    @property
    def on_idle(self) -> Callable[[float], None] | None:
        """Called with the time when the transmitter has nothing more to send (TC)."""
        return self._on_idle

    @on_idle.setter
    def on_idle(self, fn: Callable[[float], None] | None) -> None:
        self._on_idle = fn
        self.fast.stop_on_idle = fn is not None  # timed in C: the CPU stops for it

    def drain(self) -> None:
        """Hand on what the shift register timed in C did since the last drain: each byte
        it started (``on_tx_run`` with them all, or ``on_tx`` for each, in order) and then
        its TC (``on_idle``)."""
        fast = self.fast
        n = fast.logged
        if n:
            fast.logged = 0
            self.sent += n
            frame, baud = fast.frame_s, fast.baud
            on_tx, on_tx_run = self._on_tx, self._on_tx_run
            if on_tx_run is not None:
                on_tx_run(ffi.unpack(fast.log_byte, n), ffi.unpack(fast.log_start, n), frame, baud)
            elif on_tx is not None:
                starts = ffi.unpack(fast.log_start, n)  # one call, not one per element
                for byte, start in zip(ffi.unpack(fast.log_byte, n), starts, strict=True):
                    on_tx(byte, start, start + frame, baud)
        if fast.idle:
            fast.idle = 0
            if self._on_idle is not None:
                self._on_idle(fast.idle_at)

    # -- the far end ------------------------------------------------------------------------

    @property
    def received(self) -> int:
        """Bytes the receiver took in (the receiver on)."""
        return self._received + int(self.fast.rx_received)

    @property
    def overruns(self) -> int:
        """Bytes lost to a full RDR (ORE)."""
        return self._overruns + int(self.fast.rx_overruns)

    @property
    def timed_in_c(self) -> bool:
        """The machine's counter times this USART's events (see :meth:`time_in_c`)."""
        return self._counter is not None and bool(self.fast.nvic)

    def expect(self, data: bytes, times: list[float]) -> int:
        """The far end's ``data``, each byte's stop bit in at its time in ``times`` (in
        order, after the ones expected already): the receiver takes them in C at those
        times, heard as by :meth:`receive` while ``fast.rx_listens`` is set (only when
        :attr:`timed_in_c`). Returns how many fitted (the queue holds MCU_USART_RXQ)."""
        fast = self.fast
        room = lib.MCU_USART_RXQ - fast.rx_count
        n = min(len(data), room)
        at = (fast.rx_head + fast.rx_count) % lib.MCU_USART_RXQ
        for byte, t in zip(data[:n], times[:n], strict=True):
            fast.rx_byte[at] = byte
            fast.rx_at[at] = t
            at = (at + 1) % lib.MCU_USART_RXQ
        fast.rx_count += n
        lib.mcu_timed_plan(self._counter)
        return n

    def forget_expected(self) -> None:
        """Drop the expected bytes still to come (the far end's plans changed)."""
        self.fast.rx_count = 0

    def receive(self, byte: int) -> None:
        """A byte's stop bit has arrived now."""
        if not (self.cr1 & CR1_UE and self.cr1 & CR1_RE):
            return
        self._received += 1
        if self.sr & RXNE:
            self.sr |= ORE
            self._overruns += 1
        else:
            self.rdr = byte
            self.sr |= RXNE
        self._update_irq()

    def feed(self, data: bytes) -> None:
        """The far end sends ``data`` back to back at the programmed rate, after whatever
        it is still sending. Bytes that come while no rate is programmed (BRR unset, as
        from reset until the firmware sets the USART up) are lost, as on the chip, whose
        receiver cannot frame them: they are counted in :attr:`lost`."""
        self._inbox.extend(data)
        if self._feeding is None:
            self._feed_next(self.now())

    def _feed_next(self, t: float) -> None:
        """Schedule the next byte of the inbox one frame after ``t``, or lose the inbox
        when there is no rate to time it by."""
        if not self._inbox:
            return
        frame = self.frame_s()
        if frame == float("inf"):
            self.lost += len(self._inbox)
            self._inbox.clear()
            return
        self._feeding = self.scheduler.at(t + frame, self._feed_one)

    def _feed_one(self, t: float) -> None:
        self._feeding = None
        if self._inbox:
            self.receive(self._inbox.popleft())
        self._feed_next(t)

    @property
    def inbox(self) -> int:
        """Bytes the far end has still to send."""
        return len(self._inbox)

    # -- the transmitter --------------------------------------------------------------------

    def _start_shift(self, byte: int | None, t: float) -> None:
        """The shift register starts sending ``byte`` (None: an idle frame) at ``t``."""
        baud = self.baud  # frame_s, with the rate worked out once
        frame = BITS_PER_FRAME / baud if baud else float("inf")
        end = t + frame
        if byte is not None:
            self.sent += 1
            if self._on_tx is not None:
                self._on_tx(byte, t, end, baud)
        fast = self.fast
        fast.shifting = 1
        if self.timed_in_c:
            fast.baud, fast.frame_s, fast.shift_end = baud, frame, end
            lib.mcu_timed_plan(self._counter)
        else:
            self._shift_end = self.scheduler.at(end, self._shift_done)

    def _shift_done(self, t: float) -> None:
        self._shift_end = None
        self.fast.shifting = 0
        if self.tdr is not None and self.cr1 & CR1_TE:
            byte, self.tdr = self.tdr, None
            self.sr |= TXE
            self._start_shift(byte, t)
        else:
            self.sr |= TC
            if self._on_idle is not None:
                self._on_idle(t)
        self._update_irq()

    # -- registers ----------------------------------------------------------------------------

    def _gate(self) -> bool:
        if self.clock_on():
            return True
        self.unknown(0, 4, None)  # with the clock off: the chip ignores it
        return False

    def read(self, offset: int, size: int) -> int:
        if not self.word_only(offset, size, None) or not self._gate():
            return 0
        if offset == SR:
            self.fast.armed = 3
            return self.sr
        if offset == DR:
            self.sr &= ~RXNE
            if self.fast.armed & 1:
                self.fast.armed &= ~1
                self.sr &= ~(ORE | NE | FE | PE | IDLE)
            self._update_irq()
            return self.rdr
        if offset == BRR:
            return self.brr
        if offset == CR1:
            return self.cr1
        if offset == CR2:
            return self.cr2
        if offset == CR3:
            return self.cr3
        return self.unknown(offset, size, None)

    def write(self, offset: int, size: int, value: int) -> None:
        if not self.word_only(offset, size, value) or not self._gate():
            return
        if offset == SR:
            self.sr &= value | ~SR_CLEAR_BY_ZERO
        elif offset == DR:
            after_sr_read = bool(self.fast.armed & 2)
            self.fast.armed &= ~2
            self._write_dr(value & 0x1FF, after_sr_read)
        elif offset == BRR:
            self.brr = value & 0xFFFF
            self.rate_changed()
        elif offset == CR1:
            self._write_cr1(value)
        elif offset in (CR2, CR3):
            if value & 0xFFFF:
                self.unknown(offset, size, value)  # stop bits, clock, DMA, flow control
            if offset == CR2:
                self.cr2 = value & 0xFFFF
            else:
                self.cr3 = value & 0xFFFF
        else:
            self.unknown(offset, size, value)
        self._update_irq()

    def _write_cr1(self, value: int) -> None:
        if value & ~CR1_MODELLED & 0xFFFF:
            self.unknown(CR1, 4, value)
        old = self.cr1
        self.cr1 = value & 0x3FFF
        if self.cr1 & CR1_UE and self.cr1 & CR1_TE and not (old & CR1_UE and old & CR1_TE):
            if not self.fast.shifting:
                self._start_shift(None, self.now())  # TE set: an idle frame first

    def _write_dr(self, value: int, after_sr_read: bool) -> None:
        if after_sr_read:
            self.sr &= ~TC
        if not (self.cr1 & CR1_UE and self.cr1 & CR1_TE):
            return  # nothing is sent; the byte is lost
        if not self.fast.shifting:
            self._start_shift(value & 0xFF, self.now())
        elif self.tdr is None:
            self.tdr = value & 0xFF
            self.sr &= ~TXE
        # TDR full: the chip overwrites it; the byte before is lost
        else:
            self.tdr = value & 0xFF

    def clock_changed(self) -> None:
        """The RCC's enable bits were written: CR1 is read in C only while the clock is
        on."""
        self.fast.second_on = self.clock_on()

    def _update_irq(self) -> None:
        fast = self.fast
        fast.second_on = self.clock_on()
        if fast.nvic:
            lib.mcu_usart_update_irq(fast)
            return
        cr1, sr = self.cr1, self.sr
        level = bool(
            (cr1 & CR1_TXEIE and sr & TXE)
            or (cr1 & CR1_TCIE and sr & TC)
            or (cr1 & CR1_RXNEIE and sr & (RXNE | ORE))
        )
        if level != fast.line or level:
            fast.line = level
            self.irq(level)
