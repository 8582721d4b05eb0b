/* Flash programming (the STM32F1 flash program/erase controller, FPEC), for keeping the
 * committed gait table across power cycles.
 *
 * Every operation is confined to a region the caller declares (so a bad offset can never
 * erase the bootloader or the running firmware), waits on BSY a bounded number of times,
 * reads back what it wrote, and leaves the controller locked. QEMU's stm32vldiscovery has
 * no flash controller and its flash is ROM: there every write ends in HAL_FLASH_ERR_VERIFY.
 * The driver is tested on the host against a register model (built with -DHAL_HOST_TEST). */
#ifndef SNAKEBOT_HAL_FLASH_H
#define SNAKEBOT_HAL_FLASH_H

#include <stdint.h>

typedef enum {
    HAL_FLASH_OK = 0,
    HAL_FLASH_ERR_RANGE = 1,   /* outside the region, misaligned, or a bad region */
    HAL_FLASH_ERR_LOCKED = 2,  /* the unlock key sequence did not unlock the controller */
    HAL_FLASH_ERR_TIMEOUT = 3, /* BSY stayed set */
    HAL_FLASH_ERR_PROGRAM = 4, /* PGERR: the half-word was not erased before programming */
    HAL_FLASH_ERR_WRPROT = 5,  /* WRPRTERR: the page is write-protected */
    HAL_FLASH_ERR_VERIFY = 6   /* reading back gave something else */
} hal_flash_status_t;

/* Where the driver may write: page-aligned base, size a multiple of the page size. */
typedef struct {
    uint32_t base;
    uint32_t size;
    uint32_t page_size; /* 1024 (F1 low/medium density) or 2048 (high density, the F103RE) */
} hal_flash_region_t;

/* How many times BSY is polled before giving up. A page erase takes 20-40 ms; the CPU
 * stalls on its own instruction fetches meanwhile, so on the chip this bound is rarely
 * approached. */
#ifndef HAL_FLASH_BUSY_POLLS
#define HAL_FLASH_BUSY_POLLS 2000000UL
#endif

/* Erase the pages overlapping [offset, offset + len) of the region, and check they read
 * back erased (all 0xFF). */
hal_flash_status_t hal_flash_erase(const hal_flash_region_t *r, uint32_t offset, uint32_t len);

/* Program `len` bytes at `offset` (even) of the region, half-word by half-word; an odd
 * final byte is padded with 0xFF. The target must be erased. */
hal_flash_status_t hal_flash_write(const hal_flash_region_t *r, uint32_t offset,
                                   const uint8_t *data, uint32_t len);

#endif
