/**
 * @file app_main.c
 * @brief Firmware stub main loop: one roll-control sample per 10 ms tick.
 *
 * The same file runs on the host (the HAL reads samples from stdin and stops at the
 * end of input) and on the Cortex-M4F (SysTick tick; never returns).
 */
#include "rollctl.h"
#include "rollctl_hal.h"

/* Static: the module holds the controller instance (tens of KB), never on the stack. */
static rollctl rollctl_state;

/**
 * @brief Start the HAL and the module, then run a sample at every tick.
 * @return 0 when the HAL stops the loop (host only).
 */
int main(void)
{
    rollctl_hal_init();
    rollctl_init(&rollctl_state);
    while (rollctl_hal_wait_tick()) {
        rollctl_run_once(&rollctl_state);
    }
    return 0;
}
