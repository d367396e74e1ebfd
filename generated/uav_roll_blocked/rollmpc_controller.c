/**
 * @file rollmpc_controller.c
 * @brief Switched controller: hysteresis scheduler (eq. 3), one observer per mode,
 *        QP solve of the active mode, first-move extraction.
 *
 * All observers run every sample in the paper's predictor form
 * xhat+ = A xhat + B u_j + L (y - C xhat), each driven by the physical commands of its
 * own actuators (0 for an inactive pair) and the shared measurement. The inactive
 * observers therefore stay locked to y and a switch is bumpless.
 */
#include <math.h>
#include "rollmpc_internal.h"
#if ROLLMPC_GENERATION != 0x7fff7b8e801a310
#error "rollmpc_controller.c and rollmpc_config.h are of different generations (an interrupted regeneration?): regenerate the whole directory"
#endif

#define R_ ROLLMPC_R

/*
 * Band scheduler on roll_rate: 3 bands split at the thresholds
 * -16.0, 16.0 (eq. 3 generalised). Band b lies between thresholds b-1 and b.
 * Threshold i is stored as its hysteresis margins: sched_below[i] = threshold - epsilon and
 * sched_above[i] = threshold + epsilon.
 */
static const rollmpc_real sched_below[ROLLMPC_N_SCHED_BANDS - 1] = {
    -16.5, 15.5
};
static const rollmpc_real sched_above[ROLLMPC_N_SCHED_BANDS - 1] = {
    -15.5, 16.5
};
/* Mode of each band (a mode may serve several bands). */
static const int sched_mode[ROLLMPC_N_SCHED_BANDS] = {
    1, 0, 1
};

/**
 * @brief Mode for one sample of the scheduling signal (finite), with hysteresis.
 *
 * The mode becomes band b's mode only when s is inside band b by more than the margin
 * of each of its thresholds (sched_above[b-1] < s < sched_below[b]); within a margin of
 * a threshold the current mode is kept. With two modes in the bands (outside, inside,
 * outside) this is eq. (3) exactly.
 * @param current Mode of the previous sample.
 * @param s       Scheduling signal.
 * @return The mode for this sample.
 */
static int schedule(int current, rollmpc_real s)
{
    int band = 0;
    int next = current;
    while ((band < (ROLLMPC_N_SCHED_BANDS - 1)) && (s > sched_above[band])) {
        ++band; /* firmly above threshold band, hence above every threshold before it */
    }
    if ((band == (ROLLMPC_N_SCHED_BANDS - 1)) || (s < sched_below[band])) {
        next = sched_mode[band];
    }
    return next;
}

/*
 * The range an applied command can have, per actuator: the lowest u_min and the highest
 * u_max of the modes that drive it (context.actuator_range).
 */
static const rollmpc_real actuator_min[ROLLMPC_N_ACTUATORS] = {
    -15.0, -15.0
};
static const rollmpc_real actuator_max[ROLLMPC_N_ACTUATORS] = {
    15.0, 15.0
};

/*
 * u_applied made plausible into u: each entry clipped to its actuator's range. A command
 * beyond it cannot have been applied (a glitch of the servo feedback, a unit mix-up in the
 * glue); taken in full, 1e8 pushed every estimate so far that the clipped innovations
 * never pulled it back. Returns how many entries were clipped.
 */
static int plausible_applied(const rollmpc_ctrl *c, const rollmpc_real *u_applied,
    rollmpc_real *u)
{
    rollmpc_real lo[ROLLMPC_N_ACTUATORS], hi[ROLLMPC_N_ACTUATORS];
    int i, clipped = 0;
    for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
        lo[i] = actuator_min[i];
        hi[i] = actuator_max[i];
    }
    (void)c;
    for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
        u[i] = u_applied[i];
        if (u[i] > hi[i]) {
            u[i] = hi[i];
            ++clipped;
        }
        if (u[i] < lo[i]) { /* lo <= hi: never both */
            u[i] = lo[i];
            ++clipped;
        }
    }
    return clipped;
}

/*
 * One observer update; use_y = 0 propagates open loop (no valid measurement). Each
 * innovation y - C xhat is clipped to +-innovation_limit, so that a spike moves the
 * estimate by a bounded step while a real large change is still followed, slewed.
 * Returns how many innovations were clipped.
 */
static int observe(rollmpc_work *ws, const rollmpc_mode_data *md, rollmpc_real *x,
    const rollmpc_real *y, const rollmpc_real *u_phys, int use_y)
{
    int i, l, a;
    int clipped = 0;
    for (a = 0; a < md->ny; ++a) {
        rollmpc_real acc = R_(0.0);
        for (l = 0; l < md->nx; ++l) {
            acc += md->C[a * md->nx + l] * x[l];
        }
        ws->innov[a] = R_(0.0);
        if (use_y) {
            const rollmpc_real limit = md->innovation_limit[a];
            ws->innov[a] = y[a] - acc;
            if (ws->innov[a] > limit) {
                ws->innov[a] = limit;
                ++clipped;
            }
            if (ws->innov[a] < -limit) { /* limit > 0: never both */
                ws->innov[a] = -limit;
                ++clipped;
            }
        }
    }
    for (i = 0; i < md->nx; ++i) {
        rollmpc_real acc = R_(0.0);
        for (l = 0; l < md->nx; ++l) {
            acc += md->A[i * md->nx + l] * x[l];
        }
        for (l = 0; l < md->nu; ++l) {
            acc += md->B[i * md->nu + l] * u_phys[md->actuator_index[l]];
        }
        if (use_y) {
            for (a = 0; a < md->ny; ++a) {
                acc += md->L[i * md->ny + a] * ws->innov[a];
            }
        }
        ws->xn[i] = acc;
    }
    for (i = 0; i < md->nx; ++i) {
        x[i] = ws->xn[i];
    }
    return clipped;
}

size_t rollmpc_ctrl_size(void)
{
    return sizeof(rollmpc_ctrl);
}

/*
 * No factor of an earlier QP to start from: the work arrays hold no mode's, or another
 * mode's (one set of work arrays serves every mode). A QP starts from the factor the last
 * QP left when that QP was of its mode (solve_mode()): the Hessian is the mode's, only its
 * working set moves.
 */
static void forget_factor(rollmpc_work *ws)
{
    ws->chol_holds = ROLLMPC_CHOL_NONE;
    ws->primal_form = 0;
}

void rollmpc_init(rollmpc_ctrl *c)
{
    int j, i;
    if (c == 0) {
        return;
    }
    c->mode = 0;
    for (j = 0; j < ROLLMPC_N_MODES; ++j) {
        for (i = 0; i < ROLLMPC_NX_MAX; ++i) {
            c->xhat[j][i] = R_(0.0);
        }
        for (i = 0; i < ROLLMPC_M_MAX; ++i) {
            c->lam[j][i] = R_(0.0);
        }
    }
    for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
        c->u_last[i] = R_(0.0);
    }
    for (i = 0; i < ROLLMPC_N_MAX; ++i) {
        c->U[i] = R_(0.0);
    }
    c->plan_mode = (int16_t)c->mode;
    c->plan_age = ROLLMPC_HORIZON; /* no plan yet */
    forget_factor(&c->work);
    c->info.status = ROLLMPC_OPTIMAL;
    c->info.mode = c->mode;
    c->info.iterations = 0;
    c->info.polish_iterations = 0;
    c->info.active = 0;
    c->info.mode_switches = 0;
    c->info.clipped = 0;
    c->info.solve_ticks = 0u;
    c->info.work = 0u;
}

/*
 * Keep the plan in c->U for a later TIME_LIMIT of the same mode (fallback_point()): an
 * optimal plan, or the shifted one a TIME_LIMIT fell back to (a sample older); any other
 * status leaves none. (P_step plans into c->U itself; P_solve_qp into the caller's U.)
 */
static void keep_plan(rollmpc_ctrl *c, int mode, int status, const rollmpc_real *U)
{
    int i;
    if (status == ROLLMPC_OPTIMAL || (status == ROLLMPC_TIME_LIMIT && c->work.from_plan)) {
        for (i = 0; U != c->U && i < rollmpc_modes[mode].n; ++i) {
            c->U[i] = U[i];
        }
        c->plan_age = (int16_t)((status == ROLLMPC_OPTIMAL) ? 0 : c->plan_age + 1);
    } else {
        c->plan_age = ROLLMPC_HORIZON;
    }
    if (status != ROLLMPC_OPTIMAL && status != ROLLMPC_TIME_LIMIT) {
        forget_factor(&c->work); /* a failed sample leaves no warm start: the next is P_init's */
    }
    c->plan_mode = (int16_t)mode;
}

static int solve_mode(rollmpc_ctrl *c, int mode, const rollmpc_real *x,
    const rollmpc_real *r, rollmpc_real *U)
{
    uint32_t t0;
    int status;
    if (c->plan_mode != mode) { /* the last QP was another mode's (keep_plan()) */
        forget_factor(&c->work);
    }
    t0 = ROLLMPC_TIMESTAMP();
    status = rollmpc_qp_solve(&c->work, c->lam[mode], c->U,
        (c->plan_mode == mode) ? c->plan_age : ROLLMPC_HORIZON, &rollmpc_modes[mode], x, r,
        U, &c->info.iterations, &c->info.polish_iterations, &c->info.active);
    c->info.solve_ticks = (uint32_t)(ROLLMPC_TIMESTAMP() - t0);
    keep_plan(c, mode, status, U);
    c->info.status = status;
    c->info.mode = mode;
    c->info.work = c->work.work;
    return status;
}

/* The scheduler's mode for this sample (finite sched); the incoming mode starts cold. */
static void follow_schedule(rollmpc_ctrl *c, const rollmpc_real *sched)
{
    int i;
    const int j = schedule(c->mode, sched[0]);
    if (j != c->mode) {
        for (i = 0; i < ROLLMPC_M_MAX; ++i) {
            c->lam[j][i] = R_(0.0); /* stale multipliers of the incoming mode: cold start */
        }
        c->plan_age = ROLLMPC_HORIZON; /* and no plan of its own to fall back to */
        c->mode = j;
        ++c->info.mode_switches;
    }
}

/*
 * The held command made the active mode's. rollmpc_observe() can switch the mode after
 * the last rollmpc_step(), leaving in u_last the other mode's actuators or values past
 * this mode's input bounds: this mode's actuators keep their last values clamped into its
 * bounds and every other actuator gets 0, so that a held command obeys the same rules as
 * a solved one (an identity after a rollmpc_step() of this mode).
 */
static void hold_for_mode(rollmpc_ctrl *c)
{
    const rollmpc_mode_data *md = &rollmpc_modes[c->mode];
    rollmpc_real held[ROLLMPC_N_ACTUATORS];
    int i;
    for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
        held[i] = R_(0.0);
    }
    for (i = 0; i < md->nu; ++i) {
        const rollmpc_real lo = md->u_min[i];
        const rollmpc_real hi = md->u_max[i];
        const rollmpc_real v = c->u_last[md->actuator_index[i]];
        held[md->actuator_index[i]] = (v < lo) ? lo : ((v > hi) ? hi : v);
    }
    for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
        c->u_last[i] = held[i];
    }
}

int rollmpc_step(rollmpc_ctrl *c, const rollmpc_real *y, const rollmpc_real *sched,
    const rollmpc_real *r, rollmpc_real *u)
{
    int j, i, status, inputs_ok;
    int clipped = 0;
    const rollmpc_mode_data *md;
    if (c == 0 || u == 0) {
        return ROLLMPC_BAD_ARGUMENT;
    }
    inputs_ok = y != 0 && r != 0 && (ROLLMPC_N_SCHEDULE == 0 || sched != 0);
    if (!inputs_ok) {
        hold_for_mode(c);
        for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
            u[i] = c->u_last[i];
        }
        c->info.status = ROLLMPC_BAD_ARGUMENT;
        return ROLLMPC_BAD_ARGUMENT;
    }
    if (!rollmpc_all_finite(y, ROLLMPC_N_OUTPUTS) || !rollmpc_all_finite(sched, ROLLMPC_N_SCHEDULE)
        || !rollmpc_all_finite(r, ROLLMPC_HORIZON * ROLLMPC_N_OUTPUTS)) {
        hold_for_mode(c);
        for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
            u[i] = c->u_last[i];
        }
        for (j = 0; j < ROLLMPC_N_MODES; ++j) {
            (void)observe(&c->work, &rollmpc_modes[j], c->xhat[j], y, u, 0);
        }
        c->info.status = ROLLMPC_NONFINITE_INPUT;
        c->info.iterations = 0;
        c->info.work = 0u;
        c->info.clipped = 0;
        return ROLLMPC_NONFINITE_INPUT;
    }
    follow_schedule(c, sched);
    md = &rollmpc_modes[c->mode];
    status = solve_mode(c, c->mode, c->xhat[c->mode], r, c->U);
    for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
        u[i] = R_(0.0);
    }
    for (i = 0; i < md->nu; ++i) {
        u[md->actuator_index[i]] = c->U[i];
    }
    for (j = 0; j < ROLLMPC_N_MODES; ++j) {
        clipped += observe(&c->work, &rollmpc_modes[j], c->xhat[j], y, u, 1);
    }
    for (i = 0; i < ROLLMPC_N_ACTUATORS; ++i) {
        c->u_last[i] = u[i];
    }
    c->info.clipped = clipped;
    if (status == ROLLMPC_OPTIMAL && clipped > 0) {
        status = ROLLMPC_MEASUREMENT_CLIPPED; /* a solver status wins over the report */
        c->info.status = status;
    }
    return status;
}

int rollmpc_observe(rollmpc_ctrl *c, const rollmpc_real *y,
    const rollmpc_real *sched, const rollmpc_real *u_applied)
{
    rollmpc_real u[ROLLMPC_N_ACTUATORS];
    int j, use_y, applied_clipped;
    int clipped = 0;
    if (c == 0 || y == 0 || u_applied == 0 || (ROLLMPC_N_SCHEDULE != 0 && sched == 0)) {
        return ROLLMPC_BAD_ARGUMENT;
    }
    if (!rollmpc_all_finite(u_applied, ROLLMPC_N_ACTUATORS)) {
        return ROLLMPC_NONFINITE_INPUT; /* no input to propagate with: nothing changes */
    }
    applied_clipped = plausible_applied(c, u_applied, u);
    use_y = rollmpc_all_finite(y, ROLLMPC_N_OUTPUTS) && rollmpc_all_finite(sched, ROLLMPC_N_SCHEDULE);
    if (use_y) {
        follow_schedule(c, sched);
    }
    for (j = 0; j < ROLLMPC_N_MODES; ++j) {
        clipped += observe(&c->work, &rollmpc_modes[j], c->xhat[j], y, u, use_y);
    }
    if (!use_y) {
        return ROLLMPC_NONFINITE_INPUT;
    }
    if (applied_clipped > 0) {
        return ROLLMPC_APPLIED_CLIPPED; /* the feedback's fault wins over the sensor's */
    }
    return (clipped > 0) ? ROLLMPC_MEASUREMENT_CLIPPED : ROLLMPC_OPTIMAL;
}

int rollmpc_solve_qp(rollmpc_ctrl *c, int mode, const rollmpc_real *x,
    const rollmpc_real *r, rollmpc_real *U, int *iterations)
{
    int status, i;
    if (c == 0 || U == 0 || mode < 0 || mode >= ROLLMPC_N_MODES) {
        return ROLLMPC_BAD_ARGUMENT;
    }
    if (x == 0 || r == 0 || !rollmpc_all_finite(x, rollmpc_modes[mode].nx)
        || !rollmpc_all_finite(r, ROLLMPC_HORIZON * ROLLMPC_N_OUTPUTS)) {
        status = (x == 0 || r == 0) ? ROLLMPC_BAD_ARGUMENT : ROLLMPC_NONFINITE_INPUT;
        for (i = 0; i < rollmpc_modes[mode].n; ++i) {
            U[i] = R_(0.0);
        }
        c->info.status = status;
        if (iterations != 0) {
            *iterations = 0;
        }
        return status;
    }
    status = solve_mode(c, mode, x, r, U);
    if (iterations != 0) {
        *iterations = c->info.iterations;
    }
    return status;
}

const rollmpc_info *rollmpc_last_info(const rollmpc_ctrl *c)
{
    return (c != 0) ? &c->info : 0; /* a NULL instance has no diagnostics, not a crash */
}

const char *rollmpc_status_message(int status)
{
    switch (status) {
    case ROLLMPC_OPTIMAL: return "optimal";
    case ROLLMPC_MAX_ITER: return "iteration cap reached";
    case ROLLMPC_INACCURATE: return "converged by delta but constraints violated";
    case ROLLMPC_INFEASIBLE: return "infeasible: constraints cannot all hold (proven, or multipliers diverged)";
    case ROLLMPC_NONFINITE_INPUT: return "non-finite input; last command held";
    case ROLLMPC_NUMERICAL: return "non-finite intermediate result; safe fallback";
    case ROLLMPC_BAD_ARGUMENT: return "bad argument";
    case ROLLMPC_TIME_LIMIT: return "work budget reached; best command so far";
    case ROLLMPC_MEASUREMENT_CLIPPED: return "optimal; an implausible measurement was clipped";
    case ROLLMPC_APPLIED_CLIPPED: return "an applied command beyond its actuator's range was clipped";
    default: return "unknown status";
    }
}
