/* CM-530 board set-up: clock and pins. */
#include "board.h"

#include "board_api.h"

hal_clocks_t board_clock_init(void)
{
    return hal_clock_init(BOARD_HSE_HZ, BOARD_PLL_MUL);
}

void board_pins_init(void)
{
    cm530_io_init();
}
