/* See mcu_usart.h. The bits and their rules: RM0008 section 27 (and usart.py). */
#include "mcu_usart.h"

#include "mcu_nvic.h"
#include "mcu_systick.h"

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

/* -- the shift register, timed here ------------------------------------------------------- */

static int timed_here(const mcu_fast_io *f)
{
    return f->nvic != 0 && f->shifting && f->frame_s > 0.0;
}

/* The next byte from the far end, when timed here (a negative number if none). */
static double rx_next(const mcu_fast_io *f)
{
    return f->nvic != 0 && f->rx_count ? f->rx_at[f->rx_head] : -1.0;
}

/* Its stop bit is in: as usart.py's receive(), if the receiver listens. */
static void rx_arrive(mcu_fast_io *f)
{
    uint8_t byte = f->rx_byte[f->rx_head];
    f->rx_taken_at = f->rx_at[f->rx_head];
    f->rx_head = (f->rx_head + 1u) % MCU_USART_RXQ;
    f->rx_count--;
    f->rx_taken++;
    if (!f->rx_listens) {
        return;
    }
    f->rx_heard++;
    if (!((f->second & CR1_UE) && (f->second & CR1_RE))) {
        return;
    }
    f->rx_received++;
    if (f->value & RXNE) {
        f->value |= ORE;
        f->rx_overruns++;
    } else {
        f->rdr = byte;
        f->value |= RXNE;
    }
    mcu_usart_update_irq(f);
}

/* SysTick's step to zero, when timed here (a negative number if not). */
static double systick_next(const mcu_counter *c)
{
    const mcu_systick *s = (const mcu_systick *)c->systick;
    return s != 0 && s->nvic != 0 && s->armed ? s->zero_at : -1.0;
}

double mcu_timed_next(const mcu_counter *c)
{
    double next = -1.0;
    for (uint32_t i = 0; i < c->n_timed; i++) {
        const mcu_fast_io *f = (const mcu_fast_io *)c->timed[i];
        if (timed_here(f) && (next < 0.0 || f->shift_end < next)) {
            next = f->shift_end;
        }
        double rx = rx_next(f);
        if (rx >= 0.0 && (next < 0.0 || rx < next)) {
            next = rx;
        }
    }
    double tick = systick_next(c);
    if (tick >= 0.0 && (next < 0.0 || tick < next)) {
        next = tick;
    }
    return next;
}

/* Instructions from now to time t, rounded up as the machine rounds a stop (a millionth
 * of a cycle short counts as there). */
static uint64_t cycles_to(const mcu_counter *c, double t)
{
    double x = (t - mcu_now(c)) * c->hz - 1e-6;
    if (!(x > 0.0)) {
        return 0;
    }
    if (x >= 1.8e19) {
        return UINT64_MAX / 2;
    }
    uint64_t k = (uint64_t)x;
    return (double)k < x ? k + 1 : k;
}

void mcu_timed_plan(mcu_counter *c)
{
    double t = mcu_timed_next(c);
    if (t < 0.0) {
        c->event_count = c->take_next ? c->count : UINT64_MAX;
        return;
    }
    uint64_t k = cycles_to(c, t);
    if (k == 0 && t > mcu_now(c)) {
        k = 1; /* short by a rounding: look again after the next instruction */
    }
    c->event_count = c->count + k;
    if (c->take_next) {
        c->event_count = c->count; /* an exception to take first (mcu_nvic_changed) */
    }
}

/* The shift register is done with its frame (at shift_end): TDR's byte moves in (TXE set,
 * the byte logged for the model), or nothing is waiting and TC is set; as usart.py's
 * _shift_done and _start_shift. */
static void shift_done(mcu_counter *c, mcu_fast_io *f)
{
    double t = f->shift_end;
    if (f->tdr_full && (f->second & CR1_TE)) {
        f->log_byte[f->logged] = (uint8_t)f->tdr;
        f->log_start[f->logged] = t;
        f->logged++;
        c->undrained = 1;
        f->tdr_full = 0;
        f->tdr = 0;
        f->value |= TXE;
        f->shift_end = t + f->frame_s;
    } else {
        f->shifting = 0;
        f->value |= TC;
        if (f->stop_on_idle) {
            f->idle = 1;
            f->idle_at = t;
            c->undrained = 1;
        }
    }
    mcu_usart_update_irq(f);
}

int mcu_timed_run(mcu_counter *c, double now)
{
    int need = 0;
    for (;;) {
        mcu_fast_io *due = 0, *rx = 0;
        double rx_at = 0.0;
        for (uint32_t i = 0; i < c->n_timed; i++) {
            mcu_fast_io *f = (mcu_fast_io *)c->timed[i];
            if (timed_here(f) && f->shift_end <= now && (due == 0 || f->shift_end < due->shift_end)) {
                due = f;
            }
            double t = rx_next(f);
            if (t >= 0.0 && t <= now && (rx == 0 || t < rx_at)) {
                rx = f;
                rx_at = t;
            }
        }
        if (rx != 0 && (due == 0 || rx_at < due->shift_end)) {
            if (rx->logged && rx_at > rx->log_start[0]) {
                need = 1; /* a byte started since: the model puts it on the wire first */
                break;
            }
            rx_arrive(rx); /* ties: the frames first */
            continue;
        }
        double tick = systick_next(c);
        if (tick >= 0.0 && tick <= now && (due == 0 || tick < due->shift_end)) {
            mcu_systick_zero((mcu_systick *)c->systick); /* ties: the frames first */
            continue;
        }
        if (due == 0) {
            break;
        }
        if (due->logged >= MCU_USART_LOG || due->idle) {
            need = 1; /* the model first hands on what it was told */
            break;
        }
        shift_done(c, due);
        if (due->idle || due->logged >= MCU_USART_LOG) {
            need = 1;
            break;
        }
    }
    mcu_timed_plan(c);
    return need;
}

static void stop_now(mcu_counter *c)
{
    if (c->count < c->limit) {
        c->limit = c->count;
    }
    c->stop_at = 0.0;
}

int mcu_timed_in_hook(void *uc, mcu_counter *c)
{
    uint64_t limit = c->limit;
    double stop_at = c->stop_at;
    if (mcu_timed_run(c, mcu_now(c))) {
        stop_now(c); /* the model looks before this instruction */
        return 0;
    }
    mcu_nvic *n = (mcu_nvic *)c->nvic;
    if (n == 0 || (c->limit == limit && c->stop_at == stop_at)) {
        return 0;
    }
    /* a line the events raised stopped the CPU (mcu_nvic_changed): taken here instead, as
     * after an unmask (or the CPU stops there, inside an IT block) */
    c->limit = limit;
    c->stop_at = stop_at;
    return mcu_nvic_after_unmask(uc, n) > 0;
}

typedef int (*timed_reg_fn)(void *uc, int reg, void *value);

int mcu_timed_sleep(void *uc, mcu_counter *c, uint64_t address)
{
    mcu_nvic *n = (mcu_nvic *)c->nvic;
    if (n == 0 || c->stop_at <= 0.0 || mcu_nvic_takeable(n, 0, -1) >= 0 ||
        mcu_maybe_in_it_block(uc, n->x)) {
        return 0;
    }
    for (;;) {
        double t = mcu_timed_next(c);
        if (t < 0.0 || !(t < c->stop_at)) {
            return 0; /* the machine's next event comes first: the model sleeps */
        }
        double now = mcu_now(c);
        if (t > now) {
            c->t0 += t - now; /* asleep: time jumps to the event */
        }
        double stop_at = c->stop_at;
        int need = mcu_timed_run(c, mcu_now(c));
        c->stop_at = stop_at; /* a line it raised stopped the CPU: taken here instead */
        uint64_t k = cycles_to(c, stop_at);
        c->limit = c->count + (k > 0 ? k : 1);
        if (need) {
            if (mcu_nvic_takeable(n, 0, -1) >= 0) {
                c->sleeps++; /* it slept up to the event that wakes it (a TC the model
                              * looks at): on_wfi then finds it awake and counts nothing */
            }
            return 0;
        }
        if (mcu_nvic_takeable(n, 0, -1) >= 0) {
            break;
        }
    }
    /* woken: the wfi is done (counted, not executed) and what may preempt is taken */
    c->sleeps++;
    uint32_t pc = ((uint32_t)address + 2u) | 1u;
    ((timed_reg_fn)n->x->reg_write)(uc, n->x->frame[6], &pc);
    int taken = mcu_nvic_take(uc, n);
    if (taken > 0) {
        mcu_keep_pc(uc, n->x);
    } else if (taken < 0) {
        stop_now(c);
    }
    return 1;
}
