"""An emulated STM32F103RE that runs the exact CM-530 image (``build/cm530/firmware.elf``,
what ``make flash`` sends), with the peripherals the firmware uses modelled at register
level from the reference manual (RM0008) and the ARMv7-M architecture manual.

Why these parts:

* The CPU is ``unicorn`` (PyPI), QEMU's CPU core as a library: it executes Thumb-2 as a
  Cortex-M3 exactly (QEMU's own translator), installs from wheels on every platform the
  project supports, and lets the host map memory-mapped I/O to Python callbacks and hook
  instructions, which is all a register-level model needs. Upstream QEMU has no F103
  machine, and Renode is not installable from the registries these machines reach.
* Not ``qiling``'s MCU models: qiling drives unicorn too, but its STM32 peripherals are
  written from the vendor's header files with their own simplifications (no baud timing,
  USARTs that answer at once, no flash controller timing, an NVIC of its own), bring a
  large dependency tree, and would hide exactly the rules these models are here to check.
  A few hundred lines per peripheral, each tested against the manual, are easier to trust.
* Unicorn has no NVIC; exception entry and return follow the architecture manual in
  :mod:`.cpu`. Time is counted in instructions by a native hook (``snakebot._core``), one
  cycle each, and the peripherals' events are scheduled on that clock (:mod:`.schedule`).

Modules: :mod:`.rcc`, :mod:`.flash`, :mod:`.gpio` (with AFIO), :mod:`.usart`,
:mod:`.systick`, :mod:`.nvic` (NVIC and SCB), :mod:`.iwdg` (the peripherals);
:mod:`.cpu`, :mod:`.machine` (the chip); :mod:`.board` (the CM-530's wiring: USART1 to the
emulated servo bus through the direction pins, USART3 to the PC); :mod:`.image` (which
images it runs); :mod:`.runner` (real time, on a pseudo-terminal).
"""
