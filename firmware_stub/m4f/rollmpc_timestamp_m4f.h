/**
 * @file rollmpc_timestamp_m4f.h
 * @brief ROLLMPC_TIMESTAMP() = the DWT cycle counter (integration/common/rollglue_cycles.h).
 *
 * Force-included when the generated sources are compiled (-include), so that
 * rollmpc_last_info()->solve_ticks holds the solve time in CPU cycles. The counter is
 * enabled by rollctl_hal_init().
 */
#ifndef ROLLMPC_TIMESTAMP_M4F_H
#define ROLLMPC_TIMESTAMP_M4F_H
#include "../integration/common/rollglue_cycles.h"
#define ROLLMPC_TIMESTAMP() ROLLGLUE_CYCLES()
#endif
