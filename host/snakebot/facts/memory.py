"""The memory maps of the two boards' chips (RM0008 section 3.3 for the CM-530's
STM32F103RE; RM0041 for the STM32F100RB of QEMU's stm32vldiscovery): where flash and RAM
start, the same on every STM32, and how large each chip's are."""

from __future__ import annotations

FLASH_BASE = 0x0800_0000
RAM_BASE = 0x2000_0000

CM530_FLASH_SIZE = 512 * 1024
"""The STM32F103RE's flash."""
CM530_RAM_SIZE = 64 * 1024
"""The STM32F103RE's RAM."""

QEMU_FLASH_SIZE = 128 * 1024
"""The STM32F100RB's flash (QEMU's stm32vldiscovery)."""
QEMU_RAM_SIZE = 8 * 1024
"""The STM32F100RB's RAM."""
