/* Drives the glue core and ArduPilot's unit layer with floating-point exceptions trapped,
 * as ArduPilot's SITL traps them (FE_INVALID, FE_DIVBYZERO, FE_OVERFLOW: SIGFPE aborts):
 * NaN on every channel that is not an aileron, a NaN attitude burst, a NaN airspeed, an
 * engage and a hand-over. Exit 0 when nothing trapped. */
#define _GNU_SOURCE
#include <fenv.h>
#include <math.h>
#include <stdio.h>
#include "rollglue_ap.h"

static rollglue glue;

int main(void)
{
    rollglue_ap_settings s = {25, 25, 20, 5, 30.0f, {0}, {{0}}, 0};
    rollglue_ap_sample in;
    rollglue_input gin;
    rollglue_output out;
    rollglue_params p;
    int k, c, a, engaged = 0;
    feenableexcept(FE_INVALID | FE_DIVBYZERO | FE_OVERFLOW);
    for (a = 0; a < ROLLGLUE_N_ACT; ++a) {
        s.throw_deg[a] = 15.0f;
        s.servo[a][0] = 1 + 4 * a; /* SERVO1, SERVO5 */
    }
    rollglue_init(&glue);
    rollglue_ap_params(&s, &p);
    if (rollglue_set_params(&glue, &p, 16u) != ROLLGLUE_PARAMS_OK) {
        return 2;
    }
    for (k = 1; k <= 400; ++k) {
        const uint64_t now = (uint64_t)k * 10000u;
        const int nan_attitude = k >= 200 && k < 205;
        in.roll_cd = 300;
        in.roll_us = nan_attitude ? 0u : now;
        in.gyro_x_rads = nan_attitude ? NAN : 0.01f * (float)(k % 7);
        in.airspeed_mps = k >= 300 && k < 305 ? NAN : 25.0f;
        in.airspeed_us = now;
        in.roll_cmd_cd = k < 250 ? 1000 : -1000;
        in.cmd_us = now;
        for (c = 0; c < ROLLGLUE_MAX_CHANNELS; ++c) {
            in.applied_scaled[c] = (c == 0 || c == 4) ? 100.0f : NAN;
        }
        in.engage = k > 50;
        rollglue_ap_input(&in, &gin);
        rollglue_step(&glue, &gin, now, &out);
        engaged += out.valid;
        for (c = 0; c < ROLLGLUE_MAX_CHANNELS; ++c) {
            (void)rollglue_ap_scaled(out.value[c]);
        }
    }
    printf("%d engaged samples\n", engaged);
    return engaged > 0 ? 0 : 3;
}
