/**
 * @file rollctl_hal.h
 * @brief Hardware abstraction used by the roll-control module (rollctl.c, app_main.c).
 *
 * Two implementations: host/rollctl_hal_host.c (a text protocol on stdin/stdout, for
 * closing the loop against the simulated plant) and m4f/rollctl_hal_m4f.c (STM32F4-class
 * Cortex-M4F: SysTick at 100 Hz, DWT cycle counter; sensor and servo drivers are board
 * specific and left as clearly marked stubs).
 */
#ifndef ROLLCTL_HAL_H
#define ROLLCTL_HAL_H

#include <stdint.h>
#include "rollctl.h"

#ifdef __cplusplus
extern "C" {
#endif

/** @brief Start the timebase and the drivers. */
void rollctl_hal_init(void);

/**
 * @brief Wait for the next 10 ms tick.
 * @return 1 to run a sample, 0 to stop (host: end of input; never on the target).
 */
int rollctl_hal_wait_tick(void);

/**
 * @brief Latest IMU sample.
 * @param roll_deg Out: roll angle, deg.
 * @param roll_rate_dps Out: roll rate, deg/s.
 * @return 1 if the sample is valid and fresh, 0 otherwise.
 */
int rollctl_hal_read_imu(rollmpc_real *roll_deg, rollmpc_real *roll_rate_dps);

/**
 * @brief Commanded roll angle, deg.
 * @return The command of this sample.
 */
rollmpc_real rollctl_hal_roll_command(void);

/**
 * @brief Optional reference preview r(k+1..k+n), deg.
 * @param preview Out: up to max_len samples.
 * @param max_len Capacity of preview.
 * @return Samples written (0: no preview, hold the command).
 */
int rollctl_hal_roll_preview(rollmpc_real *preview, int max_len);

/**
 * @brief Write the aileron deflections, deg, one per physical actuator (inner, outer).
 * @param deflection_deg Commands [n].
 * @param n ROLLMPC_N_ACTUATORS.
 */
void rollctl_hal_write_servos(const rollmpc_real *deflection_deg, int n);

/**
 * @brief Free-running cycle counter (DWT CYCCNT on the target).
 * @return Counter value; differences are valid across one wrap.
 */
uint32_t rollctl_hal_cycles(void);

/**
 * @brief Publish the module's diagnostics once per sample.
 * @param rc Module state after the sample.
 */
void rollctl_hal_telemetry(const rollctl *rc);

#ifdef __cplusplus
}
#endif

#endif /* ROLLCTL_HAL_H */
