/**
 * @file rollctl.h
 * @brief Roll-control module of the firmware stub: runs the generated "rollmpc"
 *        controller at 100 Hz between an IMU and two aileron servo pairs.
 *
 * Hand-written example integration (not generated). Units are the controller's own:
 * degrees and degrees per second; conversions from autopilot units (radians,
 * centidegrees, normalised setpoints) belong in the autopilot glue, never here or in
 * the generated code.
 *
 * Call contract: one rollctl per controller, statically allocated; rollctl_init() once;
 * rollctl_step() (or rollctl_run_once() with a HAL) once per 10 ms sample, from one
 * thread. Stack: the module adds ~100 B to the generated controller's worst path
 * (rollmpc report: stack_bytes).
 */
#ifndef ROLLCTL_H
#define ROLLCTL_H

#include <stdint.h>
#include "rollmpc.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Control rate: 1 / sample_time of the generated controller (rollctl.c checks an override). */
#ifndef ROLLCTL_RATE_HZ
#define ROLLCTL_RATE_HZ (1000000u / ROLLMPC_SAMPLE_PERIOD_US)
#endif

/** Servo travel in degrees (the actuator bounds of the YAML config, +/-). */
#ifndef ROLLCTL_SERVO_LIMIT_DEG
#define ROLLCTL_SERVO_LIMIT_DEG ROLLMPC_R(15.0)
#endif

/** One sample of the module's inputs (controller units). */
typedef struct {
    rollmpc_real roll_deg;       /**< IMU roll angle, deg. */
    rollmpc_real roll_rate_dps;  /**< IMU roll rate, deg/s (the scheduling signal). */
    int imu_valid;               /**< 0: the IMU sample is missing or stale. */
    rollmpc_real roll_cmd_deg;   /**< Commanded roll, held over the horizon. */
    const rollmpc_real *preview; /**< Optional r(k+1..k+preview_len), deg; NULL = none. */
    int preview_len;             /**< Samples in preview (held at its end). */
} rollctl_input;

/** Module state: the controller instance, the reference buffer and the failsafe. */
typedef struct {
    rollmpc_ctrl mpc;                                        /**< Generated controller. */
    rollmpc_real ref[ROLLMPC_HORIZON * ROLLMPC_N_OUTPUTS];   /**< Reference horizon. */
    rollmpc_real u[ROLLMPC_N_ACTUATORS];      /**< Servo command of the last sample, deg. */
    rollmpc_real u_good[ROLLMPC_N_ACTUATORS]; /**< Last command of an optimal solve, deg. */
    uint32_t steps;            /**< Samples run since init. */
    uint32_t failsafe_events;  /**< Samples whose status was not optimal. */
    int last_status;           /**< rollmpc_status of the last sample. */
    uint32_t last_cycles;      /**< Cycles of the last rollmpc_step() (HAL counter). */
    uint32_t max_cycles;       /**< Largest last_cycles since init. */
} rollctl;

/**
 * @brief Reset the module and the controller; servo commands 0.
 * @param rc Module state (not NULL).
 */
void rollctl_init(rollctl *rc);

/**
 * @brief One control sample: reference horizon, rollmpc_step(), failsafe.
 *
 * On a non-optimal status (including a missing IMU sample, passed on as NaN) the last
 * good command is held, clamped to +/-ROLLCTL_SERVO_LIMIT_DEG, and failsafe_events counts.
 *
 * @param rc  Module state.
 * @param in  Inputs of this sample.
 * @param cycles_now Cycle counter read before and after the solve (may be NULL).
 * @return The rollmpc_status of rollmpc_step().
 */
int rollctl_step(rollctl *rc, const rollctl_input *in, uint32_t (*cycles_now)(void));

/**
 * @brief Read the HAL (IMU, command, preview), run rollctl_step(), write the servos and
 *        the telemetry. Call once per tick of rollctl_hal_wait_tick().
 * @param rc Module state.
 */
void rollctl_run_once(rollctl *rc);

#ifdef __cplusplus
}
#endif

#endif /* ROLLCTL_H */
