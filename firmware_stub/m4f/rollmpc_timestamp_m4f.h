/**
 * @file rollmpc_timestamp_m4f.h
 * @brief Cycle counter for ROLLMPC_TIMESTAMP on a Cortex-M4 (DWT CYCCNT).
 *
 * Force-included when the generated sources are compiled (-include), so that
 * rollmpc_last_info()->solve_ticks holds the solve time in CPU cycles. The counter is
 * enabled by rollctl_hal_init().
 */
#ifndef ROLLMPC_TIMESTAMP_M4F_H
#define ROLLMPC_TIMESTAMP_M4F_H
#include <stdint.h>
#define ROLLMPC_TIMESTAMP() (*(volatile uint32_t *)0xE0001004u)
#endif
