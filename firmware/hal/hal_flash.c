/* Flash program/erase controller of the STM32F1 (PM0075, RM0008 section 3.3). */
#include "hal_flash.h"

#include <stdbool.h>

#include "hal_io.h"
#include "hal_regs.h"

#define SR_ERRORS (HAL_FLASH_SR_PGERR | HAL_FLASH_SR_WRPRTERR)

static bool region_ok(const hal_flash_region_t *r, uint32_t offset, uint32_t len)
{
    if (r == 0 || r->page_size == 0U || (r->page_size & (r->page_size - 1U)) != 0U ||
        (r->base & (r->page_size - 1U)) != 0U || (r->size & (r->page_size - 1U)) != 0U) {
        return false;
    }
    return offset <= r->size && len <= r->size - offset;
}

static hal_flash_status_t wait_idle(void)
{
    for (uint32_t n = 0; n < HAL_FLASH_BUSY_POLLS; n++) {
        if ((hal_io_read32(HAL_FLASH_SR) & HAL_FLASH_SR_BSY) == 0U) {
            return HAL_FLASH_OK;
        }
    }
    return HAL_FLASH_ERR_TIMEOUT;
}

/* After an operation: BSY clear, then the error flags decide; flags are cleared. */
static hal_flash_status_t finish(void)
{
    hal_flash_status_t st = wait_idle();
    uint32_t sr = hal_io_read32(HAL_FLASH_SR);
    hal_io_write32(HAL_FLASH_SR, SR_ERRORS | HAL_FLASH_SR_EOP); /* write 1 to clear */
    if (st != HAL_FLASH_OK) {
        return st;
    }
    if (sr & HAL_FLASH_SR_WRPRTERR) {
        return HAL_FLASH_ERR_WRPROT;
    }
    if (sr & HAL_FLASH_SR_PGERR) {
        return HAL_FLASH_ERR_PROGRAM;
    }
    return HAL_FLASH_OK;
}

static hal_flash_status_t unlock(void)
{
    if (hal_io_read32(HAL_FLASH_CR) & HAL_FLASH_CR_LOCK) {
        hal_io_write32(HAL_FLASH_KEYR, HAL_FLASH_KEY1);
        hal_io_write32(HAL_FLASH_KEYR, HAL_FLASH_KEY2);
        if (hal_io_read32(HAL_FLASH_CR) & HAL_FLASH_CR_LOCK) {
            return HAL_FLASH_ERR_LOCKED;
        }
    }
    hal_flash_status_t st = wait_idle();
    /* Stale error flags from someone else's operation must not be blamed on ours. */
    hal_io_write32(HAL_FLASH_SR, SR_ERRORS | HAL_FLASH_SR_EOP);
    return st;
}

static void lock(void)
{
    hal_io_modify32(HAL_FLASH_CR, HAL_FLASH_CR_PG | HAL_FLASH_CR_PER, HAL_FLASH_CR_LOCK);
}

static hal_flash_status_t erase_page(const hal_flash_region_t *r, uint32_t addr)
{
    hal_io_modify32(HAL_FLASH_CR, HAL_FLASH_CR_PG, HAL_FLASH_CR_PER);
    hal_io_write32(HAL_FLASH_AR, addr);
    hal_io_modify32(HAL_FLASH_CR, 0, HAL_FLASH_CR_STRT);
    hal_flash_status_t st = finish();
    hal_io_modify32(HAL_FLASH_CR, HAL_FLASH_CR_PER, 0);
    if (st != HAL_FLASH_OK) {
        return st;
    }
    for (uint32_t a = addr; a < addr + r->page_size; a += 2U) {
        if (hal_io_read16(a) != 0xFFFFU) {
            return HAL_FLASH_ERR_VERIFY;
        }
    }
    return HAL_FLASH_OK;
}

hal_flash_status_t hal_flash_erase(const hal_flash_region_t *r, uint32_t offset, uint32_t len)
{
    if (!region_ok(r, offset, len)) {
        return HAL_FLASH_ERR_RANGE;
    }
    if (len == 0U) {
        return HAL_FLASH_OK;
    }
    hal_flash_status_t st = unlock();
    uint32_t first = offset & ~(r->page_size - 1U);
    for (uint32_t page = first; st == HAL_FLASH_OK && page < offset + len; page += r->page_size) {
        st = erase_page(r, r->base + page);
    }
    lock();
    return st;
}

static hal_flash_status_t program_halfword(uint32_t addr, uint16_t value)
{
    if (value == 0xFFFFU && hal_io_read16(addr) == 0xFFFFU) {
        return HAL_FLASH_OK; /* already what an erased cell holds */
    }
    hal_io_modify32(HAL_FLASH_CR, HAL_FLASH_CR_PER, HAL_FLASH_CR_PG);
    hal_io_write16(addr, value);
    hal_flash_status_t st = finish();
    hal_io_modify32(HAL_FLASH_CR, HAL_FLASH_CR_PG, 0);
    if (st == HAL_FLASH_OK && hal_io_read16(addr) != value) {
        st = HAL_FLASH_ERR_VERIFY;
    }
    return st;
}

hal_flash_status_t hal_flash_write(const hal_flash_region_t *r, uint32_t offset,
                                   const uint8_t *data, uint32_t len)
{
    if (!region_ok(r, offset, len) || (offset & 1U) != 0U || (data == 0 && len != 0U)) {
        return HAL_FLASH_ERR_RANGE;
    }
    if (len == 0U) {
        return HAL_FLASH_OK;
    }
    /* An odd length pads its last half-word: that byte must lie in the region too. */
    if ((len & 1U) != 0U && offset + len + 1U > r->size) {
        return HAL_FLASH_ERR_RANGE;
    }
    hal_flash_status_t st = unlock();
    for (uint32_t i = 0; st == HAL_FLASH_OK && i < len; i += 2U) {
        uint16_t lo = data[i];
        uint16_t hi = (i + 1U < len) ? data[i + 1U] : 0xFFU;
        st = program_halfword(r->base + offset + i, (uint16_t)(lo | (hi << 8)));
    }
    lock();
    return st;
}
