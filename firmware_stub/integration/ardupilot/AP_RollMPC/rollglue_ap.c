/**
 * @file rollglue_ap.c
 * @brief ArduPilot's units and timing for the glue core (see rollglue_ap.h).
 */
#include <math.h>
#include "rollglue_ap.h"

#define CENTI 0.01f
#define DEG_PER_RAD 57.2957795f

/* Out-of-range values map to one the glue refuses (never a silent wrap-around). */
static uint16_t narrow_u16(int32_t v)
{
    return (v >= 0 && v <= (int32_t)UINT16_MAX) ? (uint16_t)v : (uint16_t)UINT16_MAX;
}

/* SERVOn number (1-based, 0 = none) -> glue channel (0-based, -1 = none). */
static int8_t servo_channel(int32_t servo)
{
    return (servo >= 0 && servo <= INT8_MAX) ? (int8_t)(servo - 1) : (int8_t)INT8_MAX;
}

void rollglue_ap_params(const rollglue_ap_settings *s, rollglue_params *p)
{
    int a, side;
    const uint16_t timeout_ms = narrow_u16(s->timeout_ms);
    p->timeout_us = (uint32_t)timeout_ms * 1000u;
    p->frozen_samples = narrow_u16(s->frozen_samples);
    p->warmup_samples = narrow_u16(s->warmup_samples);
    p->max_failures = narrow_u16(s->max_failures);
    p->ref_slew_dps = s->slew_dps;
    for (a = 0; a < ROLLGLUE_N_ACT; ++a) {
        p->throw_deg[a] = s->throw_deg[a];
        for (side = 0; side < ROLLGLUE_SIDES; ++side) {
            const int32_t bit = (int32_t)1 << (ROLLGLUE_SIDES * a + side);
            p->channel[a][side] = servo_channel(s->servo[a][side]);
            p->sign[a][side] = (int8_t)((s->reversed & bit) != 0 ? -1 : 1);
        }
    }
}

int rollglue_ap_foreign_channel(const rollglue_params *p, const uint16_t *functions,
                                uint32_t n_channels)
{
    int a, side;
    for (a = 0; a < ROLLGLUE_N_ACT; ++a) {
        for (side = 0; side < ROLLGLUE_SIDES; ++side) {
            const int ch = p->channel[a][side];
            if (ch >= 0 && ((uint32_t)ch >= n_channels
                            || functions[ch] != ROLLGLUE_AP_FUNCTION_AILERON)) {
                return ch;
            }
        }
    }
    return -1;
}

/* NaN is tested with isnan() before any ordered comparison: a comparison with NaN raises
 * FE_INVALID, which ArduPilot's SITL traps (SIGFPE, "Floating point exception - aborting") */
static float normalised(float scaled)
{
    const float v = scaled / ROLLGLUE_AP_SCALED_MAX;
    if (isnan(v)) {
        return v; /* not an aileron channel: unknown */
    }
    return v > 1.0f ? 1.0f : (v < -1.0f ? -1.0f : v);
}

void rollglue_ap_input(const rollglue_ap_sample *s, rollglue_input *in)
{
    int c;
    in->roll_deg = (float)s->roll_cd * CENTI;
    in->roll_us = s->roll_us;
    in->roll_rate_dps = s->gyro_x_rads * DEG_PER_RAD;
    in->rate_us = s->roll_us; /* one AHRS update gives both */
    in->roll_cmd_deg = (float)s->roll_cmd_cd * CENTI;
    in->cmd_us = s->cmd_us;
    in->airspeed_mps = s->airspeed_mps;
    in->airspeed_us = s->airspeed_us;
    for (c = 0; c < ROLLGLUE_MAX_CHANNELS; ++c) {
        in->applied[c] = normalised(s->applied_scaled[c]);
    }
    in->engage = s->engage;
}

float rollglue_ap_scaled(float norm)
{
    const float v = norm * ROLLGLUE_AP_SCALED_MAX;
    if (isnan(v)) {
        return 0.0f;
    }
    if (v < -ROLLGLUE_AP_SCALED_MAX) {
        return -ROLLGLUE_AP_SCALED_MAX;
    }
    return v < ROLLGLUE_AP_SCALED_MAX ? v : ROLLGLUE_AP_SCALED_MAX;
}

uint16_t rollglue_ap_ticks_per_sample(uint32_t loop_rate_hz)
{
    const uint32_t ticks = loop_rate_hz / ROLLGLUE_SAMPLE_HZ;
    if (ticks == 0u || ticks > UINT16_MAX || ticks * ROLLGLUE_SAMPLE_HZ != loop_rate_hz) {
        return 0u;
    }
    return (uint16_t)ticks;
}

int rollglue_ap_sample_due(uint32_t tick, uint16_t ticks_per_sample)
{
    return ticks_per_sample != 0u && tick % ticks_per_sample == 0u;
}
