"""General-purpose I/O ports and the alternate-function remap (RM0008 sections 9.2, 9.4).

A port keeps its configuration (CRL/CRH, four bits a pin: MODE and CNF), its output latch
(ODR, BSRR, BRR) and reads its pins (IDR): an output pin reads what it drives, an input
with pull-up or pull-down reads that level unless something outside drives it
(:meth:`GpioPort.drive`, e.g. a button), a floating input reads what is driven or 0.
Listeners hear every change of an output (:meth:`GpioPort.listen`), which is how the
board sees the bus direction pins. LCKR is not modelled. A port whose clock is off ignores
writes and reads as zero, as on the chip; in strict mode that is an error (the firmware
forgot an enable bit).

AFIO's MAPR holds the USART1 remap (PB6/PB7 instead of PA9/PA10) and the SWJ
configuration (write-only: reads as zero); the other remaps and EVCR/EXTICR are not
modelled.
"""

from __future__ import annotations

from collections.abc import Callable

from snakebot.core import ffi, lib
from snakebot.sim.mcu.errors import UnmodelledAccess
from snakebot.sim.mcu.regs import Peripheral, kept_in

GPIO_BASES = {"A": 0x40010800, "B": 0x40010C00, "C": 0x40011000, "D": 0x40011400}
AFIO_BASE = 0x40010000
CRL, CRH, IDR, ODR, BSRR, BRR, LCKR = range(0, 0x1C, 4)
CR_RESET = 0x4444_4444  # every pin a floating input

# Pin modes (MODE bits 1:0, CNF bits 3:2 of each nibble)
INPUT_ANALOG, INPUT_FLOATING, INPUT_PULL = 0x0, 0x4, 0x8
OUTPUT_PP, OUTPUT_OD, AF_PP, AF_OD = 0x0, 0x4, 0x8, 0xC  # CNF with MODE != 0


def is_output(nibble: int) -> bool:
    return nibble & 0x3 != 0


def is_alternate(nibble: int) -> bool:
    return is_output(nibble) and nibble & 0x8 != 0


OUTPUT_MASKS_KEPT = 16  # configurations whose output and pulled pins are remembered (_masks)
PinListener = Callable[[int, bool], None]
"""Called with (pin, level) when an output pin's level changes."""


class GpioPort(Peripheral):
    """One port (``letter`` A..D); ``clock_on()`` says whether its RCC enable is set."""

    def __init__(self, letter: str, clock_on: Callable[[], bool], *, strict: bool = True) -> None:
        super().__init__(GPIO_BASES[letter], strict=strict)
        self.letter = letter
        self.name = f"GPIO{letter}"
        self.clock_on = clock_on
        self._listeners: list[PinListener] = []
        self._output_masks: dict[tuple[int, int], tuple[int, int]] = {}  # _masks by CRL, CRH
        self._external: dict[int, bool] = {}  # pins driven from outside (drive)
        self.fast = ffi.new("mcu_fast_io *")  # ODR, and its writes served in C (mcu_gpio.h)
        self.fast.kind = lib.MCU_IO_GPIO
        self.reset()

    def reset(self) -> None:
        self.cr = [CR_RESET, CR_RESET]
        self.odr = 0
        self._pins_changed()

    odr = kept_in("fast", "value")  # C writes it too (mcu_gpio.h)

    def link_receive_enable(self, usart_fast: object, high: int, low: int) -> None:
        """Keep ``usart_fast.rx_listens`` (an ``mcu_fast_io`` of a USART) set while pin
        ``high`` is an output driven high and pin ``low`` one driven low."""
        fast = self.fast
        fast.rx_usart, fast.listen_high, fast.listen_low = usart_fast, 1 << high, 1 << low
        self._pins_changed()

    def clock_changed(self) -> None:
        """The RCC's enable bits were written: C serves writes only while the clock is on."""
        self.fast.second_on = self.clock_on()

    def _pins_changed(self) -> None:
        self.fast.outputs, self.fast.pulls = self._masks()
        lib.mcu_gpio_changed(self.fast)

    def listen(self, listener: PinListener) -> None:
        self._listeners.append(listener)
        self.fast.python_only = 1  # every write through write(), which tells the listeners

    def mode(self, pin: int) -> int:
        """The pin's four configuration bits (CNF:MODE)."""
        return (self.cr[pin // 8] >> (4 * (pin % 8))) & 0xF

    def drive(self, pin: int, level: bool | None) -> None:
        """Something outside drives ``pin`` to ``level`` (None: lets go)."""
        if level is None:
            self._external.pop(pin, None)
        else:
            self._external[pin] = level
        self.fast.driven = sum(1 << p for p in self._external)  # C leaves IDR to idr()

    def output(self, pin: int) -> bool | None:
        """The level the port drives on ``pin`` as a GPIO output (None: not a GPIO output)."""
        nibble = self.mode(pin)
        if not is_output(nibble) or is_alternate(nibble):
            return None
        return bool(self.odr >> pin & 1)

    def level(self, pin: int) -> bool:
        nibble = self.mode(pin)
        if is_output(nibble) and not is_alternate(nibble):
            return bool(self.odr >> pin & 1)
        if pin in self._external:
            return self._external[pin]
        if nibble == INPUT_PULL:
            return bool(self.odr >> pin & 1)  # ODR picks pull-up (1) or pull-down (0)
        return False

    def idr(self) -> int:
        outputs, pulls = self._masks()
        value = self.odr & (outputs | pulls)  # what an output drives, the pull ODR picks
        for pin, level in self._external.items():  # driven from outside, unless an output
            bit = 1 << pin
            if not outputs & bit:
                value = value | bit if level else value & ~bit
        return value

    def _gate(self, offset: int, value: int | None) -> bool:
        if self.clock_on():
            return True
        if self.strict:
            what = "read" if value is None else f"write of 0x{value:X}"
            raise UnmodelledAccess(
                f"{self.name}: {what} at offset 0x{offset:02X} with the port's clock off "
                f"(RCC_APB2ENR IOP{self.letter}EN): the chip ignores it"
            )
        return False

    def read(self, offset: int, size: int) -> int:
        if not self.word_only(offset, size, None) or not self._gate(offset, None):
            return 0
        if offset in (CRL, CRH):
            return self.cr[offset // 4]
        if offset == IDR:
            return self.idr()
        if offset == ODR:
            return self.odr
        return self.unknown(offset, size, None)

    def write(self, offset: int, size: int, value: int) -> None:
        if not self.word_only(offset, size, value) or not self._gate(offset, value):
            return
        before_mask, before = self._outputs()
        if offset in (CRL, CRH):
            self.cr[offset // 4] = value
        elif offset == ODR:
            self.odr = value & 0xFFFF
        elif offset == BSRR:  # set wins over reset for the same pin
            self.odr = (self.odr & ~(value >> 16) | value) & 0xFFFF
        elif offset == BRR:
            self.odr &= ~value & 0xFFFF
        elif offset == IDR:
            return  # read-only
        else:
            self.unknown(offset, size, value)
            return
        self.clock_changed()
        self._pins_changed()
        if not self._listeners:
            return
        mask, levels = self._outputs()
        changed = mask & (levels ^ before | ~before_mask)
        while changed:
            low = changed & -changed
            changed ^= low
            pin = low.bit_length() - 1
            for listener in self._listeners:
                listener(pin, bool(levels & low))

    def _outputs(self) -> tuple[int, int]:
        """(pins that are GPIO outputs, their levels) as bit masks."""
        mask = self._masks()[0]
        return mask, self.odr & mask

    def _masks(self) -> tuple[int, int]:
        """(pins that are GPIO outputs, inputs with a pull) as bit masks, worked out once
        for each configuration."""
        cr = self.cr
        key = (cr[0], cr[1])
        masks = self._output_masks.get(key)
        if masks is None:
            outputs = pulls = 0
            for pin in range(16):
                nibble = cr[pin // 8] >> (4 * (pin % 8)) & 0xF
                if is_output(nibble) and not is_alternate(nibble):
                    outputs |= 1 << pin
                elif nibble == INPUT_PULL:
                    pulls |= 1 << pin
            if len(self._output_masks) >= OUTPUT_MASKS_KEPT:
                self._output_masks.clear()
            masks = self._output_masks[key] = (outputs, pulls)
        return masks


MAPR_USART1_REMAP = 1 << 2
MAPR_SWJ_MASK = 0x7 << 24
MAPR_MODELLED = MAPR_USART1_REMAP | MAPR_SWJ_MASK
EVCR, MAPR = 0x00, 0x04


class Afio(Peripheral):
    """The remap register; ``clock_on()`` says whether AFIOEN is set."""

    name = "AFIO"

    def __init__(self, clock_on: Callable[[], bool], *, strict: bool = True) -> None:
        super().__init__(AFIO_BASE, strict=strict)
        self.clock_on = clock_on
        self.reset()

    def reset(self) -> None:
        self.mapr = 0
        self.swj = 0

    @property
    def usart1_remapped(self) -> bool:
        return bool(self.mapr & MAPR_USART1_REMAP)

    def read(self, offset: int, size: int) -> int:
        if not self.word_only(offset, size, None):
            return 0
        if offset == MAPR:
            return self.mapr if self.clock_on() else 0
        return self.unknown(offset, size, None)

    def write(self, offset: int, size: int, value: int) -> None:
        if not self.word_only(offset, size, value):
            return
        if offset != MAPR:
            self.unknown(offset, size, value)
            return
        if not self.clock_on():
            if self.strict:
                raise UnmodelledAccess(
                    "AFIO: MAPR written with its clock off (RCC_APB2ENR AFIOEN): the chip "
                    "ignores it"
                )
            return
        if value & ~MAPR_MODELLED:
            self.unknown(offset, size, value)
        self.mapr = value & MAPR_USART1_REMAP  # SWJ_CFG is write-only
        self.swj = (value & MAPR_SWJ_MASK) >> 24
