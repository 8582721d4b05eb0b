/* The CM-530's I/O wiring: which USART serves the Dynamixel bus and which the PC link, on
 * which pins. One copy for every board that runs the CM-530 firmware: cm530 itself, and
 * qemu, which lays the same firmware out for QEMU's machine (whose USARTs sit at the same
 * addresses; it ignores the pin set-up). */
#ifndef SNAKEBOT_CM530_IO_H
#define SNAKEBOT_CM530_IO_H

#include "hal_regs.h"

/* Dynamixel bus: USART1 remapped to PB6 (TX) / PB7 (RX), half duplex through a buffer:
 * PB4 high enables the transmitter, PB5 high the receiver. */
#define BOARD_BUS_USART HAL_USART1_BASE
#define BOARD_BUS_IRQ HAL_IRQ_USART1
#define BOARD_BUS_ON_APB2 1
#define BOARD_BUS_BAUD 1000000UL
#define BOARD_BUS_TX_ENABLE_PIN {HAL_GPIOB_BASE, 4}
#define BOARD_BUS_RX_ENABLE_PIN {HAL_GPIOB_BASE, 5}

/* PC link: USART3 on PB10 (TX) / PB11 (RX), through the board's USB-serial port. */
#define BOARD_PC_USART HAL_USART3_BASE
#define BOARD_PC_IRQ HAL_IRQ_USART3
#define BOARD_PC_ON_APB2 0
#define BOARD_PC_BAUD 57600UL

/* Clocks the bus and PC-link USARTs and GPIOB, frees PB4 from JTAG, remaps USART1 and
 * sets up the four USART pins. */
void cm530_io_init(void);

#endif
