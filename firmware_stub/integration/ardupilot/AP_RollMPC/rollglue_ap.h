/**
 * @file rollglue_ap.h
 * @brief ArduPilot's units and timing for the glue core (rollglue.h), in plain C so the
 *        host tests cover them: centidegrees, rad/s and +/-4500 servo units to and from
 *        the glue's degrees and normalised values; SERVOn numbers and parameter values to
 *        rollglue_params; the main-loop ticks of one controller sample.
 *
 * Hand-written (not generated). The C++ adapter (AP_RollMPC.cpp) is its only caller on a
 * vehicle; nothing here knows an ArduPilot type.
 *
 * Conventions (ArduPlane's own): roll and roll command in centidegrees, right wing down
 * positive; body roll rate in rad/s; an aileron servo function's scaled output in
 * [-4500, 4500], positive rolls right, with the mirror of the left and right servos left to
 * each SERVOn_REVERSED. The glue's sign of a servo is an extra reversal on top of that
 * (RMPC_REV, default none).
 */
#ifndef ROLLGLUE_AP_H
#define ROLLGLUE_AP_H

#include <stdint.h>
#include "rollglue.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Scaled range of an aileron function (SRV_Channel::aux_servo_function_setup: set_angle(4500)). */
#define ROLLGLUE_AP_SCALED_MAX 4500.0f
/** SRV_Channel::k_aileron: the only servo function the MPC may drive. */
#define ROLLGLUE_AP_FUNCTION_AILERON 4u

/** The RMPC_* parameter values as ArduPilot stores them, before any range check. */
typedef struct {
    int32_t timeout_ms;
    int32_t frozen_samples;
    int32_t warmup_samples;
    int32_t max_failures;
    float slew_dps;
    float throw_deg[ROLLGLUE_N_ACT];
    /** SERVOn output numbers (1-based, as in the SERVOn_* parameters); 0 = none. */
    int32_t servo[ROLLGLUE_N_ACT][ROLLGLUE_SIDES];
    int32_t reversed;          /**< Bit (2 a + s): servo s of actuator a reversed. */
} rollglue_ap_settings;

/** One sample in ArduPilot's units. Timestamps: AP_HAL::micros64(); 0 = none yet. */
typedef struct {
    int32_t roll_cd;           /**< AP_AHRS::roll_sensor. */
    uint64_t roll_us;          /**< IMU sample behind the attitude; 0 when the AHRS is unhealthy. */
    float gyro_x_rads;         /**< AP_AHRS::get_gyro().x (bias-corrected). */
    float airspeed_mps;        /**< AP_AHRS::airspeed_EAS(), NaN without an estimate. */
    uint64_t airspeed_us;      /**< When it was estimated; 0 = none. */
    int32_t roll_cmd_cd;       /**< nav_roll_cd (Plane), the attitude target (Copter). */
    uint64_t cmd_us;           /**< When the vehicle last computed the command. */
    /** Scaled output each servo channel got in the latest loop; NaN where not an aileron. */
    float applied_scaled[ROLLGLUE_MAX_CHANNELS];
    int engage;                /**< The vehicle lets the MPC fly roll now. */
} rollglue_ap_sample;

/**
 * @brief Parameter values -> glue parameters. Values that do not fit a field become one the
 *        glue refuses (never a silent wrap-around); the ranges themselves are the glue's.
 * @param s Parameter values.
 * @param p Out: parameters for rollglue_set_params().
 */
void rollglue_ap_params(const rollglue_ap_settings *s, rollglue_params *p);

/**
 * @brief The servo channel (0-based) of the first servo whose SERVOn_FUNCTION is not Aileron.
 * @param p          Parameters accepted by rollglue_set_params().
 * @param functions  SERVOn_FUNCTION of each channel.
 * @param n_channels Entries in functions.
 * @return -1 if every servo of the mapping is an Aileron channel.
 */
int rollglue_ap_foreign_channel(const rollglue_params *p, const uint16_t *functions,
                                uint32_t n_channels);

/**
 * @brief One sample in ArduPilot's units -> the glue's input (degrees, deg/s, normalised).
 * @param s  The sample.
 * @param in Out: input for rollglue_step().
 */
void rollglue_ap_input(const rollglue_ap_sample *s, rollglue_input *in);

/**
 * @brief Normalised servo value -> ArduPilot scaled units, clamped to +/-4500 (0 for NaN).
 * @param norm Normalised value, [-1, 1].
 * @return Scaled value for SRV_Channel::pwm_from_scaled_value().
 */
float rollglue_ap_scaled(float norm);

/**
 * @brief Main-loop ticks per controller sample: SCHED_LOOP_RATE must be a whole multiple
 *        of ROLLGLUE_SAMPLE_HZ, else the sample period would not be the controller's.
 * @param loop_rate_hz The scheduler's loop rate.
 * @return Ticks per sample, or 0 when the loop rate is not a multiple (the MPC stays off).
 */
uint16_t rollglue_ap_ticks_per_sample(uint32_t loop_rate_hz);

/**
 * @brief Whether a controller sample falls on this main-loop tick (decimation of a
 *        loop-rate caller, e.g. AC_CustomControl on Copter).
 * @param tick             AP_Scheduler::ticks32().
 * @param ticks_per_sample rollglue_ap_ticks_per_sample(); 0 never samples.
 * @return Nonzero on every ticks_per_sample-th tick.
 */
int rollglue_ap_sample_due(uint32_t tick, uint16_t ticks_per_sample);

#ifdef __cplusplus
}
#endif

#endif /* ROLLGLUE_AP_H */
