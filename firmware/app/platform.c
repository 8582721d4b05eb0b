/* Board-independent wiring of the HAL: the USART instances and their interrupt handlers,
 * the start-up order, the watchdog. Board facts come from board.h. */
#include "platform.h"

#include "board.h"
#include "board_api.h"
#include "hal_cpu.h"
#include "hal_io.h"
#include "hal_iwdg.h"
#include "hal_regs.h"
#include "hal_systick.h"

/* NVIC priorities: the bus outranks the PC link (1 Mbps leaves 10 us per byte). */
#define PRIO_BUS 1U
#define PRIO_PC 2U
#define PRIO_SYSTICK 3U

HAL_RING_STORAGE(bus_rx_buf, BOARD_BUS_RX_RING);
HAL_RING_STORAGE(bus_tx_buf, BOARD_BUS_TX_RING);
HAL_RING_STORAGE(pc_rx_buf, BOARD_PC_RX_RING);
HAL_RING_STORAGE(pc_tx_buf, BOARD_PC_TX_RING);

hal_usart_t platform_bus = {
    .base = BOARD_BUS_USART,
    .irq = BOARD_BUS_IRQ,
    .tx_enable = BOARD_BUS_TX_ENABLE_PIN,
    .rx_enable = BOARD_BUS_RX_ENABLE_PIN,
    .rx = HAL_RING_INIT(bus_rx_buf),
    .tx = HAL_RING_INIT(bus_tx_buf),
};

hal_usart_t platform_pc = {
    .base = BOARD_PC_USART,
    .irq = BOARD_PC_IRQ,
    .rx = HAL_RING_INIT(pc_rx_buf),
    .tx = HAL_RING_INIT(pc_tx_buf),
};

static platform_info_t info;

static uint8_t read_reset_cause(void)
{
    uint32_t csr = hal_io_read32(HAL_RCC_CSR);
    hal_io_modify32(HAL_RCC_CSR, 0, HAL_RCC_CSR_RMVF);
    uint8_t cause = 0;
    if (csr & HAL_RCC_CSR_PINRSTF) {
        cause |= PLATFORM_RESET_PIN;
    }
    if (csr & HAL_RCC_CSR_PORRSTF) {
        cause |= PLATFORM_RESET_POWER;
    }
    if (csr & HAL_RCC_CSR_SFTRSTF) {
        cause |= PLATFORM_RESET_SOFTWARE;
    }
    if (csr & HAL_RCC_CSR_IWDGRSTF) {
        cause |= PLATFORM_RESET_WATCHDOG;
    }
    return cause;
}

void platform_init(void)
{
    info.reset_cause = read_reset_cause();
    info.clocks = board_clock_init();
    board_pins_init();
    hal_systick_init(info.clocks.hclk_hz, PRIO_SYSTICK);
    uint32_t bus_pclk = BOARD_BUS_ON_APB2 ? info.clocks.pclk2_hz : info.clocks.pclk1_hz;
    uint32_t pc_pclk = BOARD_PC_ON_APB2 ? info.clocks.pclk2_hz : info.clocks.pclk1_hz;
    hal_usart_init(&platform_bus, bus_pclk, BOARD_BUS_BAUD, PRIO_BUS);
    hal_usart_init(&platform_pc, pc_pclk, BOARD_PC_BAUD, PRIO_PC);
    hal_iwdg_start(BOARD_WATCHDOG_MS);
}

const platform_info_t *platform_info(void)
{
    return &info;
}

#if BOARD_PACE_PC_TX
/* The PC link's transmitter paced to BOARD_PC_BAUD (10 bits a byte), for a USART that
 * takes bytes as fast as they are written: a host that does not read then fills the ring
 * and sees replies dropped, as on the CM-530, instead of the emulator spending its time
 * sending them. Credit in thousandths of a byte; at most a ring's worth is saved up. */
#define PC_BYTES_PER_S (BOARD_PC_BAUD / 10U)
static uint32_t pc_credit;
static uint32_t pc_credit_ms;

static void service_pc(void)
{
    uint32_t now = hal_millis();
    if (now == pc_credit_ms) {
        return; /* no credit since the last pass: less than a byte is saved up */
    }
    pc_credit += (now - pc_credit_ms) * PC_BYTES_PER_S;
    pc_credit_ms = now;
    if (pc_credit > BOARD_PC_TX_RING * 1000UL) {
        pc_credit = BOARD_PC_TX_RING * 1000UL;
    }
    uint32_t bytes = pc_credit / 1000U;
    hal_usart_service_bytes(&platform_pc, bytes);
    pc_credit -= bytes * 1000U;
}
#else
static void service_pc(void)
{
    hal_usart_service(&platform_pc);
}
#endif

void platform_service(void)
{
    hal_usart_service(&platform_bus);
    service_pc();
}

void platform_idle(int idle)
{
    hal_iwdg_feed();
    if (!idle) {
        return;
    }
    /* Only received bytes keep the loop awake. A transmission in progress wakes it by
     * itself: on the F103 each TXE and the final TC interrupt (the handler feeds the next
     * byte, or turns the bus back to receive), on a board whose USART raises neither
     * (QEMU) platform_service() has sent everything already, or the paced PC link waits
     * for SysTick's next millisecond. */
    uint32_t primask = hal_irq_save();
    if (hal_ring_count(&platform_pc.rx) == 0U && hal_ring_count(&platform_bus.rx) == 0U) {
        hal_wait_for_interrupt();
    }
    hal_irq_restore(primask);
}

/* Interrupt handlers: forward into the drivers. */
void SysTick_Handler(void)
{
    hal_systick_isr();
}

#define BUS_HANDLER_IS_USART1 (BOARD_BUS_IRQ == HAL_IRQ_USART1)
#define PC_HANDLER_IS_USART3 (BOARD_PC_IRQ == HAL_IRQ_USART3)
#if !BUS_HANDLER_IS_USART1 || !PC_HANDLER_IS_USART3
#error "platform.c wires the bus to USART1 and the PC link to USART3: extend it for this board"
#endif

void USART1_IRQHandler(void)
{
    hal_usart_isr(&platform_bus);
}

void USART3_IRQHandler(void)
{
    hal_usart_isr(&platform_pc);
}
