/* ROBOTIS CM-530: STM32F103RE (512 KB flash, 64 KB RAM), 8 MHz crystal.
 * Sources: ROBOTIS e-Manual and example code; docs/hardware.md has the wiring. The memory
 * layout must agree with cm530.ld. */
#ifndef SNAKEBOT_BOARD_H
#define SNAKEBOT_BOARD_H

#include "hal_regs.h"

#define BOARD_NAME "cm530"
#define BOARD_ID CTL_BOARD_CM530 /* the Board register's value (enum in ctl_table.h) */

/* Clock: HSE 8 MHz x9 = 72 MHz; APB1 36 MHz (USART3), APB2 72 MHz (USART1). */
#define BOARD_HSE_HZ 8000000UL
#define BOARD_PLL_MUL 9U

/* Memory. The ROBOTIS bootloader owns 0x08000000-0x08002FFF and jumps to BOARD_APP_BASE. */
#define BOARD_APP_BASE 0x08003000UL
#define BOARD_RAM_SIZE (64UL * 1024UL)
/* Bytes a gait table may take (Table Capacity on the Program page), and the RAM arena that
 * holds the active table and the staging area side by side (ctl_set_tables): an upload of
 * up to 16 KB always fits beside a playing table; a larger one beside a larger playing
 * table is refused until playback stops (protocol/controller.md). */
#define BOARD_TABLE_CAPACITY 32768U
#define BOARD_TABLE_ARENA (48U * 1024U)
#define BOARD_FLASH_PAGE_SIZE 2048UL
/* Flash map (cm530.ld agrees), from the top: 0x08078000-0x0807FFFF is free (it kept the
 * table while tables were 2 KB; the library and the limits stayed where they were, so a
 * firmware update keeps them). The 4 KB at 0x08077000 keep the robot's limits (two slots
 * of one page each). */
#define BOARD_HAS_FLASH_STORE 1
#define BOARD_LIMITS_STORE_BASE 0x08077000UL
#define BOARD_LIMITS_STORE_SIZE (4UL * 1024UL)
/* Below them, the gait library (app/store_lib.h): its directory (two slots of one page),
 * then STORE_LIB_SLOTS + 1 = 9 data areas of one table capacity each (32 KB), ending where
 * the limits begin. */
#define BOARD_HAS_FLASH_LIBRARY 1
#define BOARD_LIB_DIR_BASE 0x0802E000UL
#define BOARD_LIB_DIR_SIZE (4UL * 1024UL)
#define BOARD_LIB_AREA_SIZE ((unsigned long)BOARD_TABLE_CAPACITY)
/* Below the library, the committed gait table (app/store.c, kept out of the image by
 * cm530.ld): two store_slots slots of a capacity plus one page (the record's header) each,
 * 68 KB, at 0x0801D000. */
#define BOARD_STORE_SIZE (2UL * (BOARD_TABLE_CAPACITY + BOARD_FLASH_PAGE_SIZE))
#define BOARD_STORE_BASE (BOARD_LIB_DIR_BASE - BOARD_STORE_SIZE)

#include "cm530_io.h" /* bus and PC-link USARTs and pins */

/* Buttons, active low with the pull-ups on, in the Buttons register's bit order: U PC11,
 * D PC10, L PA15, R PA14, START PB3. R is left out ({0, 0}): PA14 is SWCLK, readable only
 * with SWD off, and SWD stays on for a debugger. PA15 and PB3 are JTAG pins that
 * cm530_io_init frees. */
#define BOARD_BUTTON_PINS                                                                  \
    {{HAL_GPIOC_BASE, 11}, {HAL_GPIOC_BASE, 10}, {HAL_GPIOA_BASE, 15}, {0U, 0U},            \
     {HAL_GPIOB_BASE, 3}}
/* LEDs, active low, in the LEDs register's bit order: AUX PB12, MANAGE PB13, PROGRAM PB14 show
 * the library slot picked (binary), PLAY PB15 that a gait plays. */
#define BOARD_LED_PINS                                                                     \
    {{HAL_GPIOB_BASE, 12}, {HAL_GPIOB_BASE, 13}, {HAL_GPIOB_BASE, 14}, {HAL_GPIOB_BASE, 15}}

/* Ring sizes (powers of two). A whole Protocol 1.0 packet is at most 250 bytes. */
#define BOARD_BUS_RX_RING 512
#define BOARD_BUS_TX_RING 512
#define BOARD_PC_RX_RING 512
#define BOARD_PC_TX_RING 512
/* The USART's own baud timing paces the PC link's transmitter. */
#define BOARD_PACE_PC_TX 0

/* Independent watchdog timeout (LSI-based, approximate). */
#define BOARD_WATCHDOG_MS 500UL

/* Control tick: player, safety and one bus schedule (SYNC_WRITE + one telemetry READ). */
#define BOARD_CONTROL_TICK_MS 10U
/* The bus master's reply window: BUS_SUGGESTED_TIMEOUT_US (AX-12 default return delay). */
#define BOARD_BUS_REPLY_TIMEOUT_US 1500UL

#endif
