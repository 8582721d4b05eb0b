/* The emulated STM32F103's instruction counter (snakebot.sim.mcu.cpu): a unicorn code hook
 * that counts every executed instruction and stops the CPU when the count reaches a limit,
 * so the emulator knows the exact time of every register access and can run the CPU up to
 * the next peripheral event and no further. Called by unicorn for each instruction, it has
 * to be native code: a Python callback there would run a hundred times slower.
 * Host-side only: never compiled into the firmware. */
#ifndef SNAKEBOT_MCU_COUNT_H
#define SNAKEBOT_MCU_COUNT_H

#include <stdint.h>

/* cffi:begin */
#define MCU_SITE_WORDS 64 /* the sites' filter: 4096 bits, one per half-word address mod 8 KB */

typedef struct {
    uint64_t count;    /* instructions executed since the machine was made */
    uint64_t limit;    /* stop before the instruction that would make count exceed this */
    void *stop;        /* unicorn's uc_emu_stop, as a plain function address */
    uint32_t stops;    /* times the limit stopped the CPU */
    uint32_t pending;  /* an exception is pending: stop after an instruction that unmasks */
    double t0;         /* the machine's time (s) when count was c0 */
    uint64_t c0;
    double hz;         /* instructions per second (HCLK) */
    /* The image's sites, in the order they were watched: this one hook looks at them (a
     * unicorn hook per site would make unicorn walk every hook on every instruction). */
    const uint32_t *site_address;
    const uint8_t *site_kind;  /* MCU_SITE_WFI or MCU_SITE_AFTER_UNMASK */
    uint32_t sites;
    uint64_t site_bits[MCU_SITE_WORDS]; /* a bit for each site (mcu_watch_site): most
                                         * addresses pass at once, the image's hot loops too */
    void *on_wfi;      /* int (*)(uint64_t address): a wfi is next; nonzero if it stopped the CPU */
    double stop_at;    /* the time the limit stands for (0: stop at the limit whatever the time).
                        * A limit worked out from a time can fall one instruction short of it by
                        * a rounding; with nothing pending, the machine would then find nothing
                        * due, nothing to take, and run one instruction more: the hook runs it
                        * at once instead of stopping. */
    uint32_t running;  /* mcu_run is under way (set there) */
    void *nvic;        /* the mcu_nvic (mcu_nvic.h) that takes what is pending after an
                        * unmask (NULL: the CPU stops there instead) */
    /* Events timed here, in C (mcu_usart.h: a USART's shift register finishing a frame):
     * the hook runs them at the instruction a scheduled event would run at, without
     * stopping the CPU, and a sleeping CPU's wfi jumps to them. */
    uint64_t event_count;  /* the count at which the earliest is due (UINT64_MAX: none) */
    void *timed[2];        /* the mcu_fast_io of each USART timed here */
    uint32_t n_timed;
    void *systick;         /* the mcu_systick timed here (mcu_systick.h), or NULL */
    uint32_t undrained;    /* a timed USART has something to tell its model (mcu_usart.h) */
    uint64_t sleeps;       /* wfi instructions that slept, here or in the model */
    uint32_t take_next;    /* an exception became takeable during the run (mcu_nvic_changed):
                            * the hook takes it before the next instruction */
} mcu_counter;

/* The machine's time (s) when the count is `count`: t0 + (count - c0) / hz. */
double mcu_time_at(const mcu_counter *c, uint64_t count);
/* The machine's time now (s). */
double mcu_now(const mcu_counter *c);

#define MCU_SITE_WFI 1
#define MCU_SITE_AFTER_UNMASK 2

/* A peripheral's registers as the CPU reaches them: one or two registers served here, in C,
 * and everything else by the Python model (read_fallback / write_fallback, ctypes callbacks of
 * unicorn's MMIO signatures). A USART's SR is read (value; a read arms the SR-then-DR
 * sequences in `armed`), the IWDG's KR written (a reload key while `running` notes the
 * time of the feed), on every pass of the firmware's main loop: in Python those accesses
 * would cost more than the rest of the emulation. A USART's CR1 is read here too (the
 * interrupt handler reads it on every byte). */
#define MCU_USART_RXQ 64 /* bytes the far end sends that can wait for their time here */
#define MCU_USART_LOG 64 /* bytes a USART's shift register timed in C starts between two
                          * looks of its model (a full log stops the CPU) */

typedef struct {
    uint32_t kind;           /* MCU_IO_USART_SR, MCU_IO_IWDG_KR, MCU_IO_SCS or MCU_IO_GPIO */
    uint32_t value;          /* USART: SR, kept current by the model */
    uint32_t armed;          /* USART: bit 0 = error flags, bit 1 = TC (set by an SR read) */
    uint32_t second_offset;  /* a second register read here (a USART's CR1) ... */
    uint32_t second;         /* ... its value, kept current by the model ... */
    uint32_t second_on;      /* ... while this is set (the clock is on; else the model reads) */
    uint32_t running;        /* IWDG: started */
    uint64_t feeds;          /* IWDG: reloads */
    double last_feed;        /* IWDG: time of the last reload (s), valid once feeds > 0 */
    double largest_gap;      /* IWDG: longest time between two reloads (s) */
    mcu_counter *counter;
    void *read_fallback;
    void *write_fallback;
    /* A USART whose interrupt line is wired to the C NVIC (`nvic` set) has more served
     * here, its state kept here for the model too (mcu_usart.h): DR read, DR written while
     * the shift register is busy or the transmitter off, CR1 written with modelled bits
     * that start no idle frame. `value` is SR, `second` CR1. */
    uint32_t tdr;       /* the byte waiting in TDR ... */
    uint32_t tdr_full;  /* ... if one is */
    uint32_t shifting;  /* the shift register is sending (a byte or the idle frame) */
    uint32_t rdr;       /* the byte last received */
    uint32_t line;      /* the interrupt line's level */
    int32_t irq;        /* its NVIC line */
    void *nvic;         /* the mcu_nvic (NULL: the Python model serves all but SR and CR1 reads) */
    /* The shift register timed here (frame_s > 0; the counter's timed events): at the end
     * of each frame TDR's byte moves in (TXE), or TC is set; the bytes that start are
     * logged for the model, which hands them on (on_tx) when it next runs. */
    double shift_end;   /* when the shift register is done with its frame (while shifting) */
    double frame_s;     /* one frame at the programmed rate (s), kept by the model */
    double baud;        /* the rate (bits/s), for the model's on_tx */
    uint32_t stop_on_idle;  /* TC: stop the CPU so the model's on_idle runs at that time */
    uint32_t idle;      /* TC was set here: the model's on_idle is due, at idle_at */
    double idle_at;
    uint32_t logged;    /* bytes started here and not yet handed on by the model */
    uint8_t log_byte[MCU_USART_LOG];
    double log_start[MCU_USART_LOG];
    void *systick;      /* SCS: the mcu_systick whose CSR and CVR reads are served here */
    /* The far end's bytes whose stop bits are known to come at rx_at (a servo's reply on
     * the bus), handed to the receiver here, in order, at those times (the counter's timed
     * events): heard if rx_listens (the board's receive enable) is set then, as the
     * model's receive(); the model reads the counts and the last one's time. */
    uint32_t rx_listens;
    uint32_t rx_head;   /* the next one's index in the ring */
    uint32_t rx_count;  /* how many are still to come */
    uint8_t rx_byte[MCU_USART_RXQ];
    double rx_at[MCU_USART_RXQ];
    uint64_t rx_taken;     /* bytes taken from the queue (heard or not) */
    double rx_taken_at;    /* the last one's time */
    uint64_t rx_heard;     /* taken while rx_listens */
    uint64_t rx_received;  /* heard with the receiver on (UE and RE): receive()'s count */
    uint64_t rx_overruns;  /* of those, lost to a full RDR (ORE) */
    /* A GPIO port (mcu_gpio.h): `value` is ODR, `second_on` its clock */
    uint32_t outputs;      /* the pins that are GPIO outputs (not alternate function) */
    uint32_t python_only;  /* the model serves every write (something listens to the pins) */
    void *rx_usart;        /* the mcu_fast_io whose rx_listens these pins set, or NULL: ... */
    uint32_t listen_high;  /* ... while these pins are outputs driven high ... */
    uint32_t listen_low;   /* ... and these outputs driven low */
    uint32_t pulls;        /* the inputs with a pull-up or pull-down: IDR reads their ODR bit */
    uint32_t driven;       /* the pins driven from outside: the model reads IDR while any is */
} mcu_fast_io;

#define MCU_IO_USART_SR 1
#define MCU_IO_IWDG_KR 2
#define MCU_IO_SCS 3
#define MCU_IO_GPIO 4
#define MCU_SCS_SYSTICK 0x10 /* SysTick's registers from the system control space's base */

uint64_t mcu_io_read(void *uc, uint64_t offset, unsigned size, void *io);
void mcu_io_write(void *uc, uint64_t offset, unsigned size, uint64_t value, void *io);

/* Exception entry and return (ARMv7-M B1.5.6, B1.5.8) on the main stack, done here with
 * unicorn's own functions (their addresses in `api`, register ids from unicorn's Python
 * constants): in Python the register and memory calls of one entry cost more than the
 * handler they start. Which exception, and when: mcu_nvic.h. */
typedef struct {
    void *reg_read_batch;   /* uc_reg_read_batch */
    void *reg_write_batch;  /* uc_reg_write_batch */
    void *mem_read;         /* uc_mem_read */
    void *mem_write;        /* uc_mem_write */
    void *reg_read;         /* uc_reg_read */
    void *reg_write;        /* uc_reg_write */
    void *emu_start;        /* uc_emu_start */
    int frame[8];           /* r0-r3, r12, lr, pc, xpsr: the stacked frame's order */
    int sp;                 /* the main stack pointer's register id */
    uint32_t lowest_sp;     /* the lowest stack pointer an entry saw */
    uint32_t exc_return;    /* the EXC_RETURN value of the last failed return */
    uint32_t handler;       /* the vector of the last entry (kept when it is not Thumb) */
} mcu_exceptions;

#define MCU_EXC_OK 0
#define MCU_EXC_NOT_THUMB 1    /* the vector does not hold a Thumb address */
#define MCU_EXC_BAD_RETURN 2   /* EXC_RETURN other than handler / thread on MSP */
#define MCU_EXC_MEMORY 3       /* unicorn refused a stack or vector access */

/* Push the frame, aligned to 8 bytes (bit 9 of the stacked xPSR), and enter `exception`
 * through the vector table at `vtor`; `ipsr` is the active exception's number (0: thread
 * mode), stacked in xPSR and choosing EXC_RETURN. */
int mcu_exception_enter(void *uc, mcu_exceptions *x, uint32_t exception, uint32_t vtor,
                        uint32_t ipsr);
/* Pop the frame of the branch to EXC_RETURN the CPU just made. */
int mcu_exception_return(void *uc, mcu_exceptions *x);
/* One register (0 if unicorn refuses). */
uint32_t mcu_reg(void *uc, mcu_exceptions *x, int reg);
/* Write PC again on its own, from a code hook that entered an exception: unicorn keeps a
 * PC written by uc_reg_write there (a batch write leaves the hooked instruction's). */
int mcu_keep_pc(void *uc, mcu_exceptions *x);
/* Whether the instruction at PC may sit in an IT block (an IT instruction among the 8
 * halfwords before it; a false yes is harmless): an exception must not be entered there
 * from a hook, where unicorn's copy of the IT state is stale. */
int mcu_maybe_in_it_block(void *uc, mcu_exceptions *x);
/* Run the CPU from its PC for at most `instructions` (the counter's limit); unicorn's
 * status. */
int mcu_run(void *uc, mcu_exceptions *x, mcu_counter *c, uint64_t instructions);

/* Set the filter's bit for a site at `address` (the image's wfi and after-unmask sites). */
void mcu_watch_site(mcu_counter *c, uint32_t address);
/* The code hook on every instruction: counts it, stops the CPU at the limit, and at a
 * watched site calls `on_wfi` or does what mcu_after_unmask does, in the sites' order. */
void mcu_count_instruction(void *uc, uint64_t address, uint32_t size, void *counter);
/* mcu_count_instruction's own address, for unicorn (cffi's lib.mcu_count_instruction is a
 * wrapper that calls it, one call more on every instruction). */
void *mcu_count_hook(void);
void mcu_after_unmask(void *uc, uint64_t address, uint32_t size, void *counter);
/* cffi:end */

#endif
