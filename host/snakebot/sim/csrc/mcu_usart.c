/* See mcu_usart.h. The bits and their rules: RM0008 section 27 (and usart.py). */
#include "mcu_usart.h"

#include "mcu_nvic.h"

#define SR 0x0u
#define DR 0x4u
#define CR1 0xCu
#define PE (1u << 0)
#define FE (1u << 1)
#define NE (1u << 2)
#define ORE (1u << 3)
#define IDLE (1u << 4)
#define RXNE (1u << 5)
#define TC (1u << 6)
#define TXE (1u << 7)
#define CR1_RE (1u << 2)
#define CR1_TE (1u << 3)
#define CR1_RXNEIE (1u << 5)
#define CR1_TCIE (1u << 6)
#define CR1_TXEIE (1u << 7)
#define CR1_UE (1u << 13)
#define CR1_MODELLED (CR1_RE | CR1_TE | CR1_RXNEIE | CR1_TCIE | CR1_TXEIE | CR1_UE)
#define ARMED_ERRORS 1u /* an SR read: the next DR read clears the error flags */
#define ARMED_TC 2u     /* an SR read: the next DR write clears TC */

static int sending(uint32_t cr1)
{
    return (cr1 & CR1_UE) && (cr1 & CR1_TE);
}

void mcu_usart_update_irq(mcu_fast_io *f)
{
    uint32_t cr1 = f->second, sr = f->value;
    uint32_t level = ((cr1 & CR1_TXEIE) && (sr & TXE)) || ((cr1 & CR1_TCIE) && (sr & TC)) ||
                     ((cr1 & CR1_RXNEIE) && (sr & (RXNE | ORE)));
    if (level != f->line || level) {
        f->line = level;
        mcu_nvic_set_line((mcu_nvic *)f->nvic, f->irq, (int)level);
    }
}

int mcu_usart_read(mcu_fast_io *f, uint64_t offset, unsigned size, uint64_t *value)
{
    if (f->nvic == 0 || !f->second_on || size != 4 || offset != DR) {
        return 0;
    }
    f->value &= ~RXNE;
    if (f->armed & ARMED_ERRORS) {
        f->armed &= ~ARMED_ERRORS;
        f->value &= ~(ORE | NE | FE | PE | IDLE);
    }
    mcu_usart_update_irq(f);
    *value = f->rdr;
    return 1;
}

int mcu_usart_write(mcu_fast_io *f, uint64_t offset, unsigned size, uint64_t value)
{
    if (f->nvic == 0 || !f->second_on || size != 4) {
        return 0;
    }
    if (offset == DR && (f->shifting || !sending(f->second))) {
        uint32_t after_sr_read = f->armed & ARMED_TC;
        f->armed &= ~ARMED_TC;
        if (after_sr_read) {
            f->value &= ~TC;
        }
        if (sending(f->second)) { /* behind the byte being sent */
            if (!f->tdr_full) {
                f->tdr_full = 1;
                f->value &= ~TXE;
            }
            f->tdr = (uint32_t)value & 0xFFu; /* TDR full already: the byte before is lost */
        } /* else nothing is sent: the byte is lost */
        mcu_usart_update_irq(f);
        return 1;
    }
    if (offset == CR1 && !(value & ~(uint64_t)CR1_MODELLED & 0xFFFFu)) {
        uint32_t cr1 = (uint32_t)value & 0x3FFFu;
        if (sending(cr1) && !sending(f->second) && !f->shifting) {
            return 0; /* TE set: the model sends an idle frame first */
        }
        f->second = cr1;
        mcu_usart_update_irq(f);
        return 1;
    }
    return 0;
}
