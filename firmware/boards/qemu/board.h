/* The CM-530 firmware laid out for QEMU's stm32vldiscovery machine (qemu-system-arm 7.2,
 * hw/arm/stm32vldiscovery.c and hw/arm/stm32f100_soc.c): an STM32F100 with 128 KB flash
 * and 8 KB RAM whose USART1/2/3 sit at the F103 addresses with the F103 interrupt numbers
 * (37/38/39) and are wired to -serial 0/1/2. What QEMU models and what it does not:
 *  - USART (the stm32f2xx model): RXNE raises the interrupt; TXE and TC are always set and
 *    raise none (QEMU 7.2), so transmission is driven by hal_usart_service(); BRR ignored.
 *  - RCC, GPIO, AFIO, IWDG and the flash interface are "unimplemented devices": writes are
 *    ignored, reads return 0. The clock driver times out on HSERDY/PLLRDY and falls back
 *    to the HSI; the watchdog is a no-op (a hung loop is not caught here); flash is ROM.
 *  - The core (and SysTick) runs at a fixed 24 MHz whatever RCC is told.
 * A boot stub at 0x08000000 (stub.c) enters the image at 0x08003000 as the ROBOTIS
 * bootloader does, so what runs is the relocated CM-530 layout. Must agree with qemu.ld. */
#ifndef SNAKEBOT_BOARD_H
#define SNAKEBOT_BOARD_H

#include "hal_regs.h"

#define BOARD_NAME "qemu"
#define BOARD_ID CTL_BOARD_QEMU /* the Board register's value (enum in ctl_table.h) */

#define BOARD_HSE_HZ 8000000UL
#define BOARD_PLL_MUL 9U
/* QEMU's stm32vldiscovery SYSCLK (fixed). */
#define BOARD_EMULATED_HCLK_HZ 24000000UL

#define BOARD_STUB_BASE 0x08000000UL
#define BOARD_APP_BASE 0x08003000UL
#define BOARD_RAM_SIZE (8UL * 1024UL)
/* Bytes a gait table may take: the 8 KB of RAM hold the staging area and the active
 * table side by side (the arena, ctl_set_tables) at this size, and no more. */
#define BOARD_TABLE_CAPACITY 2048U
#define BOARD_TABLE_ARENA (2U * BOARD_TABLE_CAPACITY)
#define BOARD_FLASH_PAGE_SIZE 1024UL
/* No flash controller in QEMU: the committed table lives in RAM only. */
#define BOARD_HAS_FLASH_STORE 0

/* The CM-530's USARTs and pins: QEMU has its USARTs at the same addresses. */
#include "../cm530/cm530_io.h"

#define BOARD_BUS_RX_RING 128
#define BOARD_BUS_TX_RING 128
#define BOARD_PC_RX_RING 256
#define BOARD_PC_TX_RING 256
/* QEMU's USART has no baud timing: the PC link's transmitter is paced in software
 * (platform.c), so replies leave at the rate the CM-530's wire carries them. */
#define BOARD_PACE_PC_TX 1

#define BOARD_WATCHDOG_MS 500UL

/* Control tick: player, safety and one bus schedule (SYNC_WRITE + one telemetry READ). */
#define BOARD_CONTROL_TICK_MS 10U
/* The bus master's reply window: generous, since the emulated servos answer from another
 * process on a machine that may be busy. */
#define BOARD_BUS_REPLY_TIMEOUT_US 30000UL

#endif
