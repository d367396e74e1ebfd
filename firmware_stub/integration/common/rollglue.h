/**
 * @file rollglue.h
 * @brief Portable autopilot glue around a generated roll controller: input freshness,
 *        bumpless engage and hand-over, failure counting, channel/sign mapping and
 *        output normalisation. Shared by the PX4 module and the ArduPilot patches.
 *
 * Hand-written (not generated). Pure C99, no autopilot types, no heap, no globals: the
 * autopilot adapter converts its units to the ones below once per sample, calls
 * rollglue_step(), and writes rollglue_output.value[] to its servo outputs when
 * rollglue_output.valid is set; otherwise its own controller keeps the servos.
 *
 * Units: degrees, degrees per second, microseconds; servo values normalised to [-1, 1]
 * (+1 = the full throw of the channel in its positive direction).
 *
 * The generated controller is chosen at compile time: ROLLGLUE_PREFIX (default rollmpc),
 * ROLLGLUE_PREFIX_UPPER (ROLLMPC) and ROLLGLUE_HEADER ("rollmpc.h"). It must have one
 * output (the roll angle) and at most one scheduling signal, the roll rate or the
 * airspeed (the config header's <PREFIX>_SCHEDULE_SIGNAL_<NAME> says which); the number
 * of actuators comes from its config header.
 *
 * Call contract: one rollglue per controller, statically allocated (it holds the
 * controller instance, tens of KB); rollglue_init() once; rollglue_set_params() before
 * the first step and whenever parameters change; rollglue_step() once per sample period
 * of the controller, from one thread.
 */
#ifndef ROLLGLUE_H
#define ROLLGLUE_H

#include <stdint.h>

/* A tree of another prefix: the build passes the three macros (PX4's CMakeLists.txt reads
 * them from the tree), or glue_fit.py writes them into rollglue_design.h beside the glue
 * (ArduPilot's flat library, where a library cannot add compiler flags). */
#if !defined(ROLLGLUE_PREFIX) && defined(__has_include)
#if __has_include("rollglue_design.h")
#include "rollglue_design.h"
#endif
#endif
#ifndef ROLLGLUE_PREFIX
#define ROLLGLUE_PREFIX rollmpc
#define ROLLGLUE_PREFIX_UPPER ROLLMPC
#define ROLLGLUE_HEADER "rollmpc.h"
#endif

#define ROLLGLUE_PASTE_(a, b) a##b
#define ROLLGLUE_PASTE(a, b) ROLLGLUE_PASTE_(a, b)
/** A function or type of the generated controller: ROLLGLUE_FN(_step) = rollmpc_step. */
#define ROLLGLUE_FN(name) ROLLGLUE_PASTE(ROLLGLUE_PREFIX, name)
/** A macro of the generated controller: ROLLGLUE_K(_HORIZON) = ROLLMPC_HORIZON. */
#define ROLLGLUE_K(name) ROLLGLUE_PASTE(ROLLGLUE_PREFIX_UPPER, name)

#include ROLLGLUE_HEADER

#ifdef __cplusplus
extern "C" {
#endif

#define ROLLGLUE_N_ACT ROLLGLUE_K(_N_ACTUATORS)
/** Servos per actuator: a pair of ailerons on two channels (left, right) or on one. */
#define ROLLGLUE_SIDES 2
/** Sample rate of the generated controller, Hz: every adapter runs rollglue_step() at it.
 *  By default 1 / the controller's own sample time (its _SAMPLE_PERIOD_US); rollglue.c
 *  refuses an override that is not. */
#ifndef ROLLGLUE_SAMPLE_HZ
#define ROLLGLUE_SAMPLE_HZ (1000000u / ROLLGLUE_K(_SAMPLE_PERIOD_US))
#endif
/** The controller's airspeed unit per m/s: knots by default (c172_roll, `rollmpc fly`:
 *  `units.schedule: kts`); -DROLLGLUE_AIRSPEED_SCALE=1.0f for a design scheduled in m/s. */
#ifndef ROLLGLUE_AIRSPEED_SCALE
#define ROLLGLUE_AIRSPEED_SCALE (3600.0f / 1852.0f)
#endif
/** Servo output channels the glue can address (PX4 uses 8, ArduPilot up to 32). */
#define ROLLGLUE_MAX_CHANNELS 32

/* Parameter ranges, enforced by rollglue_set_params() (the autopilots' parameter
 * definitions repeat them for their ground stations; a test checks they agree). */
#define ROLLGLUE_TIMEOUT_MIN_US 5000u     /**< Half a sample at 100 Hz. */
#define ROLLGLUE_TIMEOUT_MAX_US 100000u   /**< Ten samples at 100 Hz. */
#define ROLLGLUE_FROZEN_MAX 1000u         /**< Samples; 0 disables the check. */
#define ROLLGLUE_WARMUP_MIN 1u
#define ROLLGLUE_WARMUP_MAX 1000u
#define ROLLGLUE_MAX_FAIL_MIN 1u
#define ROLLGLUE_MAX_FAIL_MAX 1000u
#define ROLLGLUE_SLEW_MAX_DPS 360.0f      /**< 0 = the command as a step. */
#define ROLLGLUE_THROW_MIN_DEG 1.0f
#define ROLLGLUE_THROW_MAX_DEG 90.0f

/** Tunable parameters (the autopilot's parameter system feeds them). */
typedef struct {
    uint32_t timeout_us;      /**< Oldest acceptable roll, rate and command sample. */
    uint16_t frozen_samples;  /**< Consecutive bit-identical roll+rate samples that mark
                                   the attitude as frozen; 0 = no check. */
    uint16_t warmup_samples;  /**< Tracked samples (observers fed) before an engage. */
    uint16_t max_failures;    /**< Consecutive failures before a lock-out. */
    float ref_slew_dps;       /**< Reference ramp from the measured roll to the command. */
    /** Output channel of each actuator's servos, 0-based; the second may be -1 (one
     *  servo or a Y-cable drives the pair). */
    int8_t channel[ROLLGLUE_N_ACT][ROLLGLUE_SIDES];
    /** +1 or -1: the normalised value of a servo is sign * deflection / throw. */
    int8_t sign[ROLLGLUE_N_ACT][ROLLGLUE_SIDES];
    float throw_deg[ROLLGLUE_N_ACT];   /**< Deflection at a normalised value of 1. */
} rollglue_params;

/** Result of rollglue_set_params(): the first field found out of range. */
typedef enum {
    ROLLGLUE_PARAMS_OK = 0,
    ROLLGLUE_PARAMS_TIMEOUT = 1,
    ROLLGLUE_PARAMS_FROZEN = 2,
    ROLLGLUE_PARAMS_WARMUP = 3,
    ROLLGLUE_PARAMS_MAX_FAIL = 4,
    ROLLGLUE_PARAMS_SLEW = 5,
    ROLLGLUE_PARAMS_CHANNEL = 6,       /**< Outside [0, n_channels) (or -1 on a first side). */
    ROLLGLUE_PARAMS_SHARED_CHANNEL = 7,/**< Two servos on one channel. */
    ROLLGLUE_PARAMS_SIGN = 8,
    ROLLGLUE_PARAMS_THROW = 9,
    ROLLGLUE_PARAMS_N_CHANNELS = 10    /**< n_channels outside [1, ROLLGLUE_MAX_CHANNELS]. */
} rollglue_params_result;

/** One sample of inputs, in the glue's units. Timestamps: the autopilot's clock, us. */
typedef struct {
    float roll_deg;            /**< Roll angle (right wing down positive). */
    uint64_t roll_us;          /**< When roll_deg was sampled; 0 = never. */
    float roll_rate_dps;       /**< Body roll rate (p). */
    uint64_t rate_us;          /**< When roll_rate_dps was sampled; 0 = never. */
    float roll_cmd_deg;        /**< Commanded roll angle. */
    uint64_t cmd_us;           /**< When the command was last published; 0 = never. */
    /** Airspeed estimate, m/s: the schedule of an airspeed-scheduled controller (checked
     *  for age and NaN only then; any value for the others). */
    float airspeed_mps;
    uint64_t airspeed_us;      /**< When airspeed_mps was estimated; 0 = never. */
    /** Normalised value each channel is driven with this sample by whoever drives it,
     *  NaN where unknown. The first servo of each actuator feeds the observers while
     *  the autopilot flies. */
    float applied[ROLLGLUE_MAX_CHANNELS];
    int engage;                /**< Nonzero: the autopilot hands roll to the MPC. */
} rollglue_input;

/** Why the MPC is not driving the servos (bits of rollglue_telemetry.reasons). */
enum {
    ROLLGLUE_NOT_REQUESTED = 1u << 0,
    ROLLGLUE_STALE_ROLL = 1u << 1,
    ROLLGLUE_STALE_RATE = 1u << 2,
    ROLLGLUE_STALE_CMD = 1u << 3,
    ROLLGLUE_FROZEN = 1u << 4,
    ROLLGLUE_NONFINITE = 1u << 5,     /**< NaN/Inf roll, rate or command. */
    ROLLGLUE_WARMING = 1u << 6,       /**< Observers not yet fed warmup_samples. */
    ROLLGLUE_SOLVER = 1u << 7,        /**< Non-optimal status or non-finite command. */
    ROLLGLUE_LOCKED_OUT = 1u << 8,    /**< max_failures reached: re-request to retry. */
    ROLLGLUE_NO_PARAMS = 1u << 9,     /**< rollglue_set_params() never succeeded. */
    ROLLGLUE_STALE_SCHED = 1u << 10   /**< Airspeed (the schedule) older than the timeout. */
};

/** Engagement state. */
typedef enum {
    ROLLGLUE_TRACKING = 0,  /**< The autopilot flies; the observers follow the plant. */
    ROLLGLUE_ENGAGED = 1,   /**< The MPC drives its channels. */
    ROLLGLUE_LOCKOUT = 2    /**< Failed max_failures times in a row; waits for engage = 0. */
} rollglue_state;

/** Servo commands of one sample. */
typedef struct {
    int valid;                 /**< 1: write value[] to the channels in channel_mask. */
    uint32_t channel_mask;     /**< Channels the MPC owns (bit c = channel c). */
    float value[ROLLGLUE_MAX_CHANNELS];  /**< Normalised [-1, 1] where valid, else NaN. */
    float u_deg[ROLLGLUE_N_ACT];         /**< The controller's deflections (NaN if not valid). */
} rollglue_output;

/** Counters and the last sample's diagnostics (for logs and the ground station). */
typedef struct {
    int state;                 /**< rollglue_state. */
    uint32_t reasons;          /**< ROLLGLUE_* bits of the last sample; 0 when engaged. */
    int status;                /**< Generated controller status of the last solve. */
    int mode;                  /**< Controller mode of the last solve. */
    uint32_t consecutive_failures; /**< Since the last good engaged sample or engage = 0. */
    uint32_t failures;         /**< All failures since init. */
    uint32_t engagements;      /**< Transitions into ROLLGLUE_ENGAGED. */
    uint32_t solve_cycles;     /**< P_TIMESTAMP() ticks of the last solve. */
    uint32_t max_solve_cycles; /**< Largest solve_cycles since init. */
    uint16_t warm_samples;     /**< Consecutive closed-loop observer updates. */
} rollglue_telemetry;

/** Module state. */
typedef struct {
    ROLLGLUE_FN(_ctrl) mpc;    /**< The generated controller instance. */
    ROLLGLUE_FN(_real) ref[ROLLGLUE_K(_HORIZON)];  /**< Reference horizon. */
    rollglue_params params;
    uint32_t n_channels;       /**< Channels of the autopilot output (0: no params yet). */
    float ref_deg;             /**< Head of the reference ramp. */
    float last_roll_deg, last_rate_dps;  /**< For the frozen check. */
    uint16_t frozen_count;
    rollglue_telemetry tm;
} rollglue;

/**
 * @brief Reset everything: controller, counters; state TRACKING, no parameters.
 * @param g Module state (not NULL).
 */
void rollglue_init(rollglue *g);

/**
 * @brief Check and apply parameters.
 * @param g          Module state.
 * @param p          New parameters.
 * @param n_channels Output channels the autopilot has (channel[] must be below it).
 * @return ROLLGLUE_PARAMS_OK, or the first offending field; then nothing changes.
 */
int rollglue_set_params(rollglue *g, const rollglue_params *p, uint32_t n_channels);

/**
 * @brief One sample: checks, observer tracking or a controller step, output mapping.
 * @param g      Module state.
 * @param in     Inputs of this sample.
 * @param now_us The autopilot's clock now, us (same clock as the input timestamps).
 * @param out    Out: the servo commands; valid = 0 hands the servos to the autopilot.
 * @return out->valid.
 */
int rollglue_step(rollglue *g, const rollglue_input *in, uint64_t now_us, rollglue_output *out);

/**
 * @brief Counters and the last sample's diagnostics.
 * @param g Module state.
 * @return Pointer into g.
 */
const rollglue_telemetry *rollglue_get_telemetry(const rollglue *g);

/**
 * @brief sizeof of the public structs, for bindings that declare them (host tests).
 * @param sizes Out: [rollglue, params, input, output, telemetry].
 */
void rollglue_sizes(uint32_t sizes[5]);

#ifdef __cplusplus
}
#endif

#endif /* ROLLGLUE_H */
