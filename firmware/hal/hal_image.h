/* The image's identity, for the flasher: a block right after the vector table, whose
 * address is also in the vector table's first reserved entry (7), so a tool reading a raw
 * .bin finds it without symbols. Little-endian:
 *
 *     0  magic "SNKI"        4  layout version (HAL_IMAGE_INFO_VERSION)
 *     5  firmware version    6  0 (reserved, u16)
 *     8  image bytes (u32, from the vector table to the end of what is loaded into flash)
 *    12  board name (8 bytes, NUL-padded: BOARD_NAME, "cm530" or "qemu")
 *
 * `snakebot flash` refuses an image without it, for another board, or shorter than it
 * says; code starts after it, so a reset vector pointing at or before it is refused too. */
#ifndef SNAKEBOT_HAL_IMAGE_H
#define SNAKEBOT_HAL_IMAGE_H

#include <stdint.h>

#define HAL_IMAGE_INFO_VERSION 1U
#define HAL_IMAGE_INFO_VECTOR 7U /* the vector table entry holding the block's address */
#define HAL_IMAGE_BOARD_NAME_BYTES 8U

typedef struct {
    char magic[4];
    uint8_t layout_version;
    uint8_t firmware_version;
    uint16_t reserved;
    uint32_t image_bytes;
    char board[HAL_IMAGE_BOARD_NAME_BYTES];
} hal_image_info_t;

/* Defined by the app (firmware/app/image_info.c), placed by the linker script. */
extern const hal_image_info_t hal_image_info;

#endif
