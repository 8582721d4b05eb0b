/* This image's identity block (hal_image.h): the board it was built for and its version. */
#include "board.h"
#include "ctl_table.h"
#include "hal_image.h"

/* The size of everything loaded into flash, from the linker script (an absolute symbol:
 * its address is the value). */
extern const uint8_t _flash_image_bytes[];

typedef char board_name_fits[sizeof BOARD_NAME <= HAL_IMAGE_BOARD_NAME_BYTES + 1U ? 1 : -1];

__attribute__((section(".image_info"), used))
const hal_image_info_t hal_image_info = {
    .magic = {'S', 'N', 'K', 'I'},
    .layout_version = HAL_IMAGE_INFO_VERSION,
    .firmware_version = CTL_FIRMWARE_VERSION_VALUE,
    .reserved = 0,
    .image_bytes = (uint32_t)(uintptr_t)_flash_image_bytes,
    .board = BOARD_NAME,
};
