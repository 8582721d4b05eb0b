/* This image's identity block (hal_image.h): the board it was built for and its version,
 * and the check of the image in flash against the CRC-32 the flasher computed. */
#include "board.h"
#include "crc32.h"
#include "ctl_device.h"
#include "ctl_table.h"
#include "hal_image.h"

/* From the linker script: the size of everything loaded into flash and of the flash
 * region it may fill (absolute symbols: their addresses are the values), and where the
 * image starts. */
extern const uint8_t _flash_image_bytes[];
extern const uint8_t _flash_area_bytes[];
extern const uint8_t _flash_image_start[];

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

/* Reads the flash directly, once, on request: about 10 cycles a byte, so a 64 KB image
 * (the most Upload Length can name) takes under 10 ms at 72 MHz, one control tick. */
uint8_t ctl_firmware_check(uint32_t len, uint32_t crc)
{
    if (len == 0U || len > (uint32_t)(uintptr_t)_flash_area_bytes) {
        return CTL_UPLOAD_RESULT_FIRMWARE_BAD_LENGTH;
    }
    if (len != hal_image_info.image_bytes) {
        return CTL_UPLOAD_RESULT_FIRMWARE_LENGTH_MISMATCH;
    }
    if (crc32_compute(_flash_image_start, len) != crc) {
        return CTL_UPLOAD_RESULT_FIRMWARE_CRC_MISMATCH;
    }
    return CTL_UPLOAD_RESULT_OK;
}
