/**
 * @file rollglue.c
 * @brief Portable autopilot glue around a generated roll controller (see rollglue.h).
 *
 * Per sample: (1) input health: age of each input, a frozen attitude, NaN/Inf;
 * (2) while the autopilot flies, the controller's observers follow the plant on the
 * command the autopilot applies (P_observe), so an engage starts from a converged
 * estimate; (3) engaged, the reference ramps from the measured roll at engage to the
 * command and P_step runs; (4) any bad input or solve hands the servos back for that
 * sample and counts a failure; max_failures in a row lock the MPC out until the
 * autopilot withdraws the engage request; (5) deflections are mapped to channels, signed
 * and normalised by each channel's throw.
 */
#include <math.h>
#include <string.h>
#include "rollglue.h"

#if ROLLGLUE_K(_N_OUTPUTS) != 1 || ROLLGLUE_K(_N_SCHEDULE) > 1
#error "rollglue expects a roll controller: one output (roll), at most one schedule (roll rate)"
#endif
#if ROLLGLUE_N_ACT > ROLLGLUE_MAX_CHANNELS
#error "more actuators than addressable output channels"
#endif
/* The scheduling signal the glue feeds, from the generated config header's
 * <PREFIX>_SCHEDULE_SIGNAL_<NAME> (only the design's own signal is defined there, hence
 * -Wundef off while it is read: ArduPilot builds with -Werror=undef): the measured roll
 * rate, the autopilot's airspeed estimate, or nothing (no schedule). */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wundef"
#if ROLLGLUE_K(_N_SCHEDULE) == 1 && ROLLGLUE_K(_SCHEDULE_SIGNAL_ROLL_RATE) == 1
#define ROLLGLUE_SCHEDULE_ROLL_RATE 1
#else
#define ROLLGLUE_SCHEDULE_ROLL_RATE 0
#endif
#if ROLLGLUE_K(_N_SCHEDULE) == 1 && ROLLGLUE_K(_SCHEDULE_SIGNAL_AIRSPEED) == 1
#define ROLLGLUE_SCHEDULE_AIRSPEED 1
#else
#define ROLLGLUE_SCHEDULE_AIRSPEED 0
#endif
#pragma GCC diagnostic pop
/* the last guard: the build tools (PX4's CMake, build_ardupilot.py, firmware.mk) say it in
   one line before compiling (glue_fit.py) */
#if ROLLGLUE_K(_N_SCHEDULE) == 1 && ROLLGLUE_SCHEDULE_ROLL_RATE + ROLLGLUE_SCHEDULE_AIRSPEED != 1
#error "rollglue feeds the roll rate or the airspeed as the schedule: this controller is scheduled on another signal (docs/integration.md)"
#endif
/* the glue's rate is the controller's: 1 / its sample time, to the nearest Hz (a tree
   generated before _SAMPLE_PERIOD_US existed fails here too: regenerate it) */
#if ROLLGLUE_SAMPLE_HZ * ROLLGLUE_K(_SAMPLE_PERIOD_US) + ROLLGLUE_K(_SAMPLE_PERIOD_US) / 2u < 1000000u \
    || ROLLGLUE_SAMPLE_HZ * ROLLGLUE_K(_SAMPLE_PERIOD_US) > 1000000u + ROLLGLUE_K(_SAMPLE_PERIOD_US) / 2u
#error "ROLLGLUE_SAMPLE_HZ is not 1 / the controller's sample time (its _SAMPLE_PERIOD_US)"
#endif
#if ROLLGLUE_SAMPLE_HZ < 1u
#error "the glue steps at a whole number of Hz: a sample time over 1 s is not one"
#endif

#define ROLLGLUE_SAMPLE_S (1.0f / (float)ROLLGLUE_SAMPLE_HZ)

typedef ROLLGLUE_FN(_real) glue_real;

static int in_range_u(uint32_t v, uint32_t lo, uint32_t hi)
{
    return v >= lo && v <= hi;
}

static int in_range_f(float v, float lo, float hi)
{
    return isfinite(v) && v >= lo && v <= hi; /* NaN fails every comparison */
}

/* Channel (-1 = none, second servos only) and sign of every servo; no channel twice. */
static int check_servos(const rollglue_params *p, uint32_t n_channels)
{
    int i, j;
    const int n = ROLLGLUE_N_ACT * ROLLGLUE_SIDES;
    const int8_t *ch = &p->channel[0][0], *sg = &p->sign[0][0];
    for (i = 0; i < n; ++i) {
        if (ch[i] == -1 && i % ROLLGLUE_SIDES != 0) {
            continue;
        }
        if (ch[i] < 0 || (uint32_t)ch[i] >= n_channels) {
            return ROLLGLUE_PARAMS_CHANNEL;
        }
        for (j = 0; j < i; ++j) {
            if (ch[j] == ch[i]) {
                return ROLLGLUE_PARAMS_SHARED_CHANNEL;
            }
        }
        if (sg[i] != 1 && sg[i] != -1) {
            return ROLLGLUE_PARAMS_SIGN;
        }
    }
    return ROLLGLUE_PARAMS_OK;
}

static int check_actuators(const rollglue_params *p, uint32_t n_channels)
{
    int a;
    for (a = 0; a < ROLLGLUE_N_ACT; ++a) {
        if (!in_range_f(p->throw_deg[a], ROLLGLUE_THROW_MIN_DEG, ROLLGLUE_THROW_MAX_DEG)) {
            return ROLLGLUE_PARAMS_THROW;
        }
    }
    return check_servos(p, n_channels);
}

static int check_params(const rollglue_params *p, uint32_t n_channels)
{
    if (!in_range_u(n_channels, 1u, ROLLGLUE_MAX_CHANNELS)) {
        return ROLLGLUE_PARAMS_N_CHANNELS;
    }
    if (!in_range_u(p->timeout_us, ROLLGLUE_TIMEOUT_MIN_US, ROLLGLUE_TIMEOUT_MAX_US)) {
        return ROLLGLUE_PARAMS_TIMEOUT;
    }
    if (p->frozen_samples > ROLLGLUE_FROZEN_MAX || p->frozen_samples == 1u) {
        return ROLLGLUE_PARAMS_FROZEN; /* one sample is always "identical to itself" */
    }
    if (!in_range_u(p->warmup_samples, ROLLGLUE_WARMUP_MIN, ROLLGLUE_WARMUP_MAX)) {
        return ROLLGLUE_PARAMS_WARMUP;
    }
    if (!in_range_u(p->max_failures, ROLLGLUE_MAX_FAIL_MIN, ROLLGLUE_MAX_FAIL_MAX)) {
        return ROLLGLUE_PARAMS_MAX_FAIL;
    }
    if (!in_range_f(p->ref_slew_dps, 0.0f, ROLLGLUE_SLEW_MAX_DPS)) {
        return ROLLGLUE_PARAMS_SLEW;
    }
    return check_actuators(p, n_channels);
}

void rollglue_init(rollglue *g)
{
    memset(g, 0, sizeof *g);
    ROLLGLUE_FN(_init)(&g->mpc);
    g->tm.state = ROLLGLUE_TRACKING;
}

int rollglue_set_params(rollglue *g, const rollglue_params *p, uint32_t n_channels)
{
    const int result = check_params(p, n_channels);
    if (result == ROLLGLUE_PARAMS_OK) {
        g->params = *p;
        g->n_channels = n_channels;
    }
    return result;
}

static int is_stale(uint64_t sample_us, uint64_t now_us, uint32_t timeout_us)
{
    return sample_us == 0u || sample_us > now_us || now_us - sample_us > timeout_us;
}

/* Bit-identical roll and rate for frozen_samples samples in a row: a hung estimator that
 * keeps re-publishing (fresh timestamps, old values). Real sensor noise never repeats. */
static int is_frozen(rollglue *g, const rollglue_input *in)
{
    const int same = memcmp(&in->roll_deg, &g->last_roll_deg, sizeof(float)) == 0
        && memcmp(&in->roll_rate_dps, &g->last_rate_dps, sizeof(float)) == 0;
    g->last_roll_deg = in->roll_deg;
    g->last_rate_dps = in->roll_rate_dps;
    g->frozen_count = same ? (uint16_t)(g->frozen_count + (g->frozen_count < UINT16_MAX)) : 1u;
    return g->params.frozen_samples != 0u && g->frozen_count >= g->params.frozen_samples;
}

/* The controller's scheduling signal in its own units: the roll rate, or the airspeed
 * scaled from m/s (unused, 0, for a controller without a schedule). */
static float schedule_value(const rollglue_input *in)
{
#if ROLLGLUE_SCHEDULE_AIRSPEED
    return in->airspeed_mps * ROLLGLUE_AIRSPEED_SCALE;
#elif ROLLGLUE_SCHEDULE_ROLL_RATE
    return in->roll_rate_dps;
#else
    (void)in;
    return 0.0f;
#endif
}

static uint32_t input_faults(rollglue *g, const rollglue_input *in, uint64_t now_us)
{
    const uint32_t t = g->params.timeout_us;
    uint32_t r = 0u;
    r |= is_stale(in->roll_us, now_us, t) ? (uint32_t)ROLLGLUE_STALE_ROLL : 0u;
    r |= is_stale(in->rate_us, now_us, t) ? (uint32_t)ROLLGLUE_STALE_RATE : 0u;
    r |= is_stale(in->cmd_us, now_us, t) ? (uint32_t)ROLLGLUE_STALE_CMD : 0u;
#if ROLLGLUE_SCHEDULE_AIRSPEED
    r |= is_stale(in->airspeed_us, now_us, t) ? (uint32_t)ROLLGLUE_STALE_SCHED : 0u;
#endif
    r |= is_frozen(g, in) ? (uint32_t)ROLLGLUE_FROZEN : 0u;
    if (!isfinite(in->roll_deg) || !isfinite(in->roll_rate_dps) || !isfinite(in->roll_cmd_deg)
        || !isfinite(schedule_value(in))) {
        r |= ROLLGLUE_NONFINITE;
    }
    return r;
}

/* The applied command of each actuator in degrees, from the channels' normalised values;
 * 0 if a channel's value is unknown. */
static int applied_deflections(const rollglue *g, const rollglue_input *in, glue_real *u)
{
    int a;
    for (a = 0; a < ROLLGLUE_N_ACT; ++a) {
        const float v = in->applied[g->params.channel[a][0]];
        if (!isfinite(v)) {
            return 0;
        }
        u[a] = (glue_real)((float)g->params.sign[a][0] * v * g->params.throw_deg[a]);
    }
    return 1;
}

/* While the autopilot flies: the observers follow the plant on its command. */
static void track(rollglue *g, const rollglue_input *in, uint32_t faults)
{
    glue_real y[1], sched[1], u[ROLLGLUE_N_ACT];
    int status = ROLLGLUE_K(_NONFINITE_INPUT);
    y[0] = (glue_real)in->roll_deg;
    sched[0] = (glue_real)schedule_value(in);
    if ((faults & ~(uint32_t)ROLLGLUE_STALE_CMD) != 0u) {
        y[0] = (glue_real)NAN; /* bad attitude: propagate open loop */
        sched[0] = (glue_real)NAN;
    }
    if (applied_deflections(g, in, u)) {
        status = ROLLGLUE_FN(_observe)(&g->mpc, y, sched, u);
    }
    /* only a sample the observers took whole counts: a clipped innovation
     * (MEASUREMENT_CLIPPED) restarts the warm-up */
    if (status == ROLLGLUE_K(_OPTIMAL)) {
        g->tm.warm_samples = (uint16_t)(g->tm.warm_samples + (g->tm.warm_samples < UINT16_MAX));
    } else {
        g->tm.warm_samples = 0u;
    }
}

static float move_toward(float from, float to, float step)
{
    if (to > from + step) {
        return from + step;
    }
    return to < from - step ? from - step : to;
}

/* r(k+1..k+N): the ramp from ref_deg toward the command at ref_slew_dps (a step if 0). */
static void build_reference(rollglue *g, float cmd_deg)
{
    int k;
    const float step = g->params.ref_slew_dps * ROLLGLUE_SAMPLE_S;
    for (k = 0; k < ROLLGLUE_K(_HORIZON); ++k) {
        g->ref[k] = (glue_real)(step > 0.0f ? move_toward(g->ref_deg, cmd_deg, step * (float)(k + 1))
                                            : cmd_deg);
    }
    g->ref_deg = (float)g->ref[0];
}

static int solve(rollglue *g, const rollglue_input *in, rollglue_output *out)
{
    glue_real y[1], sched[1], u[ROLLGLUE_N_ACT];
    int a, s, finite = 1;
    const ROLLGLUE_FN(_info) *info;
    y[0] = (glue_real)in->roll_deg;
    sched[0] = (glue_real)schedule_value(in);
    build_reference(g, in->roll_cmd_deg);
    g->tm.status = ROLLGLUE_FN(_step)(&g->mpc, y, sched, g->ref, u);
    info = ROLLGLUE_FN(_last_info)(&g->mpc);
    g->tm.mode = info->mode;
    g->tm.solve_cycles = info->solve_ticks;
    if (info->solve_ticks > g->tm.max_solve_cycles) {
        g->tm.max_solve_cycles = info->solve_ticks;
    }
    for (a = 0; a < ROLLGLUE_N_ACT; ++a) {
        finite = finite && isfinite(u[a]);
    }
    if (!ROLLGLUE_K(_STATUS_PLAN_USABLE)(g->tm.status) || !finite) {
        return 0;
    }
    for (a = 0; a < ROLLGLUE_N_ACT; ++a) {
        const float v = (float)u[a] / g->params.throw_deg[a];
        const float norm = v > 1.0f ? 1.0f : (v < -1.0f ? -1.0f : v);
        out->u_deg[a] = (float)u[a];
        for (s = 0; s < ROLLGLUE_SIDES; ++s) {
            if (g->params.channel[a][s] >= 0) {
                out->value[g->params.channel[a][s]] = (float)g->params.sign[a][s] * norm;
            }
        }
    }
    return 1;
}

static void clear_output(const rollglue *g, rollglue_output *out)
{
    int c, a, s;
    out->valid = 0;
    out->channel_mask = 0u;
    for (c = 0; c < ROLLGLUE_MAX_CHANNELS; ++c) {
        out->value[c] = NAN;
    }
    for (a = 0; a < ROLLGLUE_N_ACT; ++a) {
        out->u_deg[a] = NAN;
        for (s = 0; s < ROLLGLUE_SIDES && g->n_channels != 0u; ++s) {
            if (g->params.channel[a][s] >= 0) {
                out->channel_mask |= 1u << (uint32_t)g->params.channel[a][s];
            }
        }
    }
}

/* A bad sample while engaged (or on the engage attempt): hand over, count, maybe lock out. */
static void fail(rollglue *g, uint32_t reason)
{
    g->tm.reasons |= reason;
    ++g->tm.failures;
    ++g->tm.consecutive_failures;
    g->tm.warm_samples = 0u; /* the observers saw a command that was not applied */
    g->tm.state = g->tm.consecutive_failures >= g->params.max_failures ? ROLLGLUE_LOCKOUT
                                                                       : ROLLGLUE_TRACKING;
}

int rollglue_step(rollglue *g, const rollglue_input *in, uint64_t now_us, rollglue_output *out)
{
    uint32_t faults;
    clear_output(g, out);
    if (g->n_channels == 0u) {
        g->tm.reasons = ROLLGLUE_NO_PARAMS;
        return 0;
    }
    faults = input_faults(g, in, now_us);
    g->tm.reasons = faults;
    if (!in->engage) {
        g->tm.reasons |= ROLLGLUE_NOT_REQUESTED;
        g->tm.consecutive_failures = 0u; /* a new request starts a new count */
        g->tm.state = ROLLGLUE_TRACKING;
    }
    if (g->tm.state == ROLLGLUE_ENGAGED && faults != 0u) {
        fail(g, 0u); /* stale, frozen or NaN input: the autopilot takes over at once */
    }
    if (g->tm.state != ROLLGLUE_ENGAGED) {
        track(g, in, faults);
        if (g->tm.state == ROLLGLUE_LOCKOUT) {
            g->tm.reasons |= ROLLGLUE_LOCKED_OUT;
            return 0;
        }
        if (g->tm.warm_samples < g->params.warmup_samples) {
            g->tm.reasons |= ROLLGLUE_WARMING;
        }
        if (g->tm.reasons != 0u) {
            return 0;
        }
        g->ref_deg = in->roll_deg; /* bumpless: the reference starts at the measured roll */
        g->tm.state = ROLLGLUE_ENGAGED;
        ++g->tm.engagements;
    }
    if (!solve(g, in, out)) {
        fail(g, ROLLGLUE_SOLVER);
        clear_output(g, out);
        return 0;
    }
    g->tm.consecutive_failures = 0u;
    out->valid = 1;
    return 1;
}

const rollglue_telemetry *rollglue_get_telemetry(const rollglue *g)
{
    return &g->tm;
}

void rollglue_sizes(uint32_t sizes[5])
{
    sizes[0] = (uint32_t)sizeof(rollglue);
    sizes[1] = (uint32_t)sizeof(rollglue_params);
    sizes[2] = (uint32_t)sizeof(rollglue_input);
    sizes[3] = (uint32_t)sizeof(rollglue_output);
    sizes[4] = (uint32_t)sizeof(rollglue_telemetry);
}
