/**
 * @file rollctl.c
 * @brief Roll-control module: reference horizon, rollmpc_step(), failsafe.
 *
 * Hand-written example integration (see rollctl.h for the call contract).
 */
#include <math.h>
#include "rollctl.h"
#include "rollctl_hal.h"

#if ROLLMPC_N_OUTPUTS != 1 || ROLLMPC_N_SCHEDULE > 1
#error "rollctl expects a single-output roll controller (roll angle; roll rate schedule)"
#endif
#if ROLLMPC_N_SCHEDULE == 1
#if ROLLMPC_SCHEDULE_SIGNAL_ROLL_RATE != 1
#error "rollctl feeds the roll rate as the scheduling signal: this controller is scheduled on another signal"
#endif
#endif
#if ROLLCTL_RATE_HZ * ROLLMPC_SAMPLE_PERIOD_US + ROLLMPC_SAMPLE_PERIOD_US / 2u < 1000000u \
    || ROLLCTL_RATE_HZ * ROLLMPC_SAMPLE_PERIOD_US > 1000000u + ROLLMPC_SAMPLE_PERIOD_US / 2u
#error "ROLLCTL_RATE_HZ is not 1 / the controller's sample time (ROLLMPC_SAMPLE_PERIOD_US)"
#endif

static rollmpc_real clamp_servo(rollmpc_real v)
{
    if (!isfinite(v)) {
        return ROLLMPC_R(0.0);
    }
    if (v > ROLLCTL_SERVO_LIMIT_DEG) {
        return ROLLCTL_SERVO_LIMIT_DEG;
    }
    return v < -ROLLCTL_SERVO_LIMIT_DEG ? -ROLLCTL_SERVO_LIMIT_DEG : v;
}

void rollctl_init(rollctl *rc)
{
    int i;
    rollmpc_init(&rc->mpc);
    for (i = 0; i < ROLLMPC_HORIZON * ROLLMPC_N_OUTPUTS; ++i) {
        rc->ref[i] = ROLLMPC_R(0.0);
    }
    for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
        rc->u[i] = ROLLMPC_R(0.0);
        rc->u_good[i] = ROLLMPC_R(0.0);
    }
    rc->steps = 0u;
    rc->failsafe_events = 0u;
    rc->last_status = ROLLMPC_OPTIMAL;
    rc->last_cycles = 0u;
    rc->max_cycles = 0u;
}

/* r(k+1..k+N): the preview where given (held at its last sample), else the command held.
 * The preview may alias rc->ref: entry k is read before entries >= k are written. */
static void build_reference(rollctl *rc, const rollctl_input *in)
{
    int k;
    const int n = (in->preview != 0 && in->preview_len > 0) ? in->preview_len : 0;
    for (k = 0; k < ROLLMPC_HORIZON; ++k) {
        rc->ref[k] = n == 0 ? in->roll_cmd_deg : in->preview[k < n ? k : n - 1];
    }
}

int rollctl_step(rollctl *rc, const rollctl_input *in, uint32_t (*cycles_now)(void))
{
    rollmpc_real y[1], sched[1];
    uint32_t t0 = 0u;
    int i, status, finite = 1;
    build_reference(rc, in);
    /* a missing sample goes in as NaN: the controller holds its command and runs its
     * observers open loop (ROLLMPC_NONFINITE_INPUT) */
    y[0] = in->imu_valid ? in->roll_deg : (rollmpc_real)NAN;
    sched[0] = in->imu_valid ? in->roll_rate_dps : (rollmpc_real)NAN;
    if (cycles_now != 0) {
        t0 = cycles_now();
    }
    status = rollmpc_step(&rc->mpc, y, sched, rc->ref, rc->u);
    if (cycles_now != 0) {
        rc->last_cycles = cycles_now() - t0;
        if (rc->last_cycles > rc->max_cycles) {
            rc->max_cycles = rc->last_cycles;
        }
    }
    for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
        finite = finite && isfinite(rc->u[i]);
    }
    if (ROLLMPC_STATUS_PLAN_USABLE(status) && finite) {
        for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
            rc->u_good[i] = rc->u[i];
        }
    } else {
        /* failsafe: hold the last good command, within the servo limits */
        ++rc->failsafe_events;
        for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
            rc->u[i] = clamp_servo(rc->u_good[i]);
        }
    }
    rc->last_status = status;
    ++rc->steps;
    return status;
}

void rollctl_run_once(rollctl *rc)
{
    rollctl_input in;
    in.roll_deg = ROLLMPC_R(0.0);
    in.roll_rate_dps = ROLLMPC_R(0.0);
    in.imu_valid = rollctl_hal_read_imu(&in.roll_deg, &in.roll_rate_dps);
    in.roll_cmd_deg = rollctl_hal_roll_command();
    /* the preview is read straight into the reference buffer (see build_reference) */
    in.preview_len = rollctl_hal_roll_preview(rc->ref, ROLLMPC_HORIZON);
    in.preview = in.preview_len > 0 ? rc->ref : 0;
    (void)rollctl_step(rc, &in, rollctl_hal_cycles);
    rollctl_hal_write_servos(rc->u, ROLLMPC_N_ACTUATORS);
    rollctl_hal_telemetry(rc);
}
