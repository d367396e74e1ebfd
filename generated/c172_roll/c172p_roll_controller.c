/**
 * @file c172p_roll_controller.c
 * @brief Switched controller: hysteresis scheduler (eq. 3), one observer per mode,
 *        QP solve of the active mode, first-move extraction.
 *
 * All observers run every sample in the paper's predictor form
 * xhat+ = A xhat + B u_j + L (y - C xhat), each driven by the physical commands of its
 * own actuators (0 for an inactive pair) and the shared measurement. The inactive
 * observers therefore stay locked to y and a switch is bumpless.
 */
#include <math.h>
#include "c172p_roll_internal.h"
#if C172P_ROLL_GENERATION != 0xdd0bb146b0d2e07
#error "c172p_roll_controller.c and c172p_roll_config.h are of different generations (an interrupted regeneration?): regenerate the whole directory"
#endif

#define R_ C172P_ROLL_R

/*
 * Band scheduler on airspeed: 3 bands split at the thresholds
 * 80.0, 100.0 (eq. 3 generalised). Band b lies between thresholds b-1 and b.
 * Threshold i is stored as its hysteresis margins: sched_below[i] = threshold - epsilon and
 * sched_above[i] = threshold + epsilon.
 */
static const c172p_roll_real sched_below[C172P_ROLL_N_SCHED_BANDS - 1] = {
    78.0, 98.0
};
static const c172p_roll_real sched_above[C172P_ROLL_N_SCHED_BANDS - 1] = {
    82.0, 102.0
};
/* Mode of each band (a mode may serve several bands). */
static const int sched_mode[C172P_ROLL_N_SCHED_BANDS] = {
    0, 1, 2
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
static int schedule(int current, c172p_roll_real s)
{
    int band = 0;
    int next = current;
    while ((band < (C172P_ROLL_N_SCHED_BANDS - 1)) && (s > sched_above[band])) {
        ++band; /* firmly above threshold band, hence above every threshold before it */
    }
    if ((band == (C172P_ROLL_N_SCHED_BANDS - 1)) || (s < sched_below[band])) {
        next = sched_mode[band];
    }
    return next;
}

/*
 * The range an applied command can have, per actuator: the lowest u_min and the highest
 * u_max of the modes that drive it (context.actuator_range).
 */
static const c172p_roll_real actuator_min[C172P_ROLL_N_ACTUATORS] = {
    -19.98
};
static const c172p_roll_real actuator_max[C172P_ROLL_N_ACTUATORS] = {
    14.98
};

/*
 * u_applied made plausible into u: each entry clipped to its actuator's range. A command
 * beyond it cannot have been applied (a glitch of the servo feedback, a unit mix-up in the
 * glue); taken in full, 1e8 pushed every estimate so far that the clipped innovations
 * never pulled it back. Returns how many entries were clipped.
 */
static int plausible_applied(const c172p_roll_ctrl *c, const c172p_roll_real *u_applied,
    c172p_roll_real *u)
{
    c172p_roll_real lo[C172P_ROLL_N_ACTUATORS], hi[C172P_ROLL_N_ACTUATORS];
    int i, clipped = 0;
    for (i = 0; i < C172P_ROLL_N_ACTUATORS; ++i) {
        lo[i] = actuator_min[i];
        hi[i] = actuator_max[i];
    }
    (void)c;
    for (i = 0; i < C172P_ROLL_N_ACTUATORS; ++i) {
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
static int observe(c172p_roll_work *ws, const c172p_roll_mode_data *md, c172p_roll_real *x,
    const c172p_roll_real *y, const c172p_roll_real *u_phys, int use_y)
{
    int i, l, a;
    int clipped = 0;
    for (a = 0; a < md->ny; ++a) {
        c172p_roll_real acc = R_(0.0);
        for (l = 0; l < md->nx; ++l) {
            acc += md->C[a * md->nx + l] * x[l];
        }
        ws->innov[a] = R_(0.0);
        if (use_y) {
            const c172p_roll_real limit = md->innovation_limit[a];
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
        c172p_roll_real acc = R_(0.0);
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

size_t c172p_roll_ctrl_size(void)
{
    return sizeof(c172p_roll_ctrl);
}

/*
 * No factor of an earlier QP to start from: the work arrays hold no mode's, or another
 * mode's (one set of work arrays serves every mode). A QP starts from the factor the last
 * QP left when that QP was of its mode (solve_mode()): the Hessian is the mode's, only its
 * working set moves.
 */
static void forget_factor(c172p_roll_work *ws)
{
    ws->chol_holds = C172P_ROLL_CHOL_NONE;
    ws->primal_form = 0;
}

void c172p_roll_init(c172p_roll_ctrl *c)
{
    int j, i;
    if (c == 0) {
        return;
    }
    c->mode = 1;
    for (j = 0; j < C172P_ROLL_N_MODES; ++j) {
        for (i = 0; i < C172P_ROLL_NX_MAX; ++i) {
            c->xhat[j][i] = R_(0.0);
        }
        for (i = 0; i < C172P_ROLL_M_MAX; ++i) {
            c->lam[j][i] = R_(0.0);
        }
    }
    for (i = 0; i < C172P_ROLL_N_ACTUATORS; ++i) {
        c->u_last[i] = R_(0.0);
    }
    for (i = 0; i < C172P_ROLL_N_MAX; ++i) {
        c->U[i] = R_(0.0);
    }
    c->plan_mode = (int16_t)c->mode;
    c->plan_age = C172P_ROLL_HORIZON; /* no plan yet */
    forget_factor(&c->work);
    c->info.status = C172P_ROLL_OPTIMAL;
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
static void keep_plan(c172p_roll_ctrl *c, int mode, int status, const c172p_roll_real *U)
{
    int i;
    if (status == C172P_ROLL_OPTIMAL || (status == C172P_ROLL_TIME_LIMIT && c->work.from_plan)) {
        for (i = 0; U != c->U && i < c172p_roll_modes[mode].n; ++i) {
            c->U[i] = U[i];
        }
        c->plan_age = (int16_t)((status == C172P_ROLL_OPTIMAL) ? 0 : c->plan_age + 1);
    } else {
        c->plan_age = C172P_ROLL_HORIZON;
    }
    if (status != C172P_ROLL_OPTIMAL && status != C172P_ROLL_TIME_LIMIT) {
        forget_factor(&c->work); /* a failed sample leaves no warm start: the next is P_init's */
    }
    c->plan_mode = (int16_t)mode;
}

static int solve_mode(c172p_roll_ctrl *c, int mode, const c172p_roll_real *x,
    const c172p_roll_real *r, c172p_roll_real *U)
{
    uint32_t t0;
    int status;
    if (c->plan_mode != mode) { /* the last QP was another mode's (keep_plan()) */
        forget_factor(&c->work);
    }
    t0 = C172P_ROLL_TIMESTAMP();
    status = c172p_roll_qp_solve(&c->work, c->lam[mode], c->U,
        (c->plan_mode == mode) ? c->plan_age : C172P_ROLL_HORIZON, &c172p_roll_modes[mode], x, r,
        U, &c->info.iterations, &c->info.polish_iterations, &c->info.active);
    c->info.solve_ticks = (uint32_t)(C172P_ROLL_TIMESTAMP() - t0);
    keep_plan(c, mode, status, U);
    c->info.status = status;
    c->info.mode = mode;
    c->info.work = c->work.work;
    return status;
}

/* The scheduler's mode for this sample (finite sched); the incoming mode starts cold. */
static void follow_schedule(c172p_roll_ctrl *c, const c172p_roll_real *sched)
{
    int i;
    const int j = schedule(c->mode, sched[0]);
    if (j != c->mode) {
        for (i = 0; i < C172P_ROLL_M_MAX; ++i) {
            c->lam[j][i] = R_(0.0); /* stale multipliers of the incoming mode: cold start */
        }
        c->plan_age = C172P_ROLL_HORIZON; /* and no plan of its own to fall back to */
        c->mode = j;
        ++c->info.mode_switches;
    }
}

/*
 * The held command made the active mode's. c172p_roll_observe() can switch the mode after
 * the last c172p_roll_step(), leaving in u_last the other mode's actuators or values past
 * this mode's input bounds: this mode's actuators keep their last values clamped into its
 * bounds and every other actuator gets 0, so that a held command obeys the same rules as
 * a solved one (an identity after a c172p_roll_step() of this mode).
 */
static void hold_for_mode(c172p_roll_ctrl *c)
{
    const c172p_roll_mode_data *md = &c172p_roll_modes[c->mode];
    c172p_roll_real held[C172P_ROLL_N_ACTUATORS];
    int i;
    for (i = 0; i < C172P_ROLL_N_ACTUATORS; ++i) {
        held[i] = R_(0.0);
    }
    for (i = 0; i < md->nu; ++i) {
        const c172p_roll_real lo = md->u_min[i];
        const c172p_roll_real hi = md->u_max[i];
        const c172p_roll_real v = c->u_last[md->actuator_index[i]];
        held[md->actuator_index[i]] = (v < lo) ? lo : ((v > hi) ? hi : v);
    }
    for (i = 0; i < C172P_ROLL_N_ACTUATORS; ++i) {
        c->u_last[i] = held[i];
    }
}

int c172p_roll_step(c172p_roll_ctrl *c, const c172p_roll_real *y, const c172p_roll_real *sched,
    const c172p_roll_real *r, c172p_roll_real *u)
{
    int j, i, status, inputs_ok;
    int clipped = 0;
    const c172p_roll_mode_data *md;
    if (c == 0 || u == 0) {
        return C172P_ROLL_BAD_ARGUMENT;
    }
    inputs_ok = y != 0 && r != 0 && (C172P_ROLL_N_SCHEDULE == 0 || sched != 0);
    if (!inputs_ok) {
        hold_for_mode(c);
        for (i = 0; i < C172P_ROLL_N_ACTUATORS; ++i) {
            u[i] = c->u_last[i];
        }
        c->info.status = C172P_ROLL_BAD_ARGUMENT;
        return C172P_ROLL_BAD_ARGUMENT;
    }
    if (!c172p_roll_all_finite(y, C172P_ROLL_N_OUTPUTS) || !c172p_roll_all_finite(sched, C172P_ROLL_N_SCHEDULE)
        || !c172p_roll_all_finite(r, C172P_ROLL_HORIZON * C172P_ROLL_N_OUTPUTS)) {
        hold_for_mode(c);
        for (i = 0; i < C172P_ROLL_N_ACTUATORS; ++i) {
            u[i] = c->u_last[i];
        }
        for (j = 0; j < C172P_ROLL_N_MODES; ++j) {
            (void)observe(&c->work, &c172p_roll_modes[j], c->xhat[j], y, u, 0);
        }
        c->info.status = C172P_ROLL_NONFINITE_INPUT;
        c->info.iterations = 0;
        c->info.work = 0u;
        c->info.clipped = 0;
        return C172P_ROLL_NONFINITE_INPUT;
    }
    follow_schedule(c, sched);
    md = &c172p_roll_modes[c->mode];
    status = solve_mode(c, c->mode, c->xhat[c->mode], r, c->U);
    for (i = 0; i < C172P_ROLL_N_ACTUATORS; ++i) {
        u[i] = R_(0.0);
    }
    for (i = 0; i < md->nu; ++i) {
        u[md->actuator_index[i]] = c->U[i];
    }
    for (j = 0; j < C172P_ROLL_N_MODES; ++j) {
        clipped += observe(&c->work, &c172p_roll_modes[j], c->xhat[j], y, u, 1);
    }
    for (i = 0; i < C172P_ROLL_N_ACTUATORS; ++i) {
        c->u_last[i] = u[i];
    }
    c->info.clipped = clipped;
    if (status == C172P_ROLL_OPTIMAL && clipped > 0) {
        status = C172P_ROLL_MEASUREMENT_CLIPPED; /* a solver status wins over the report */
        c->info.status = status;
    }
    return status;
}

int c172p_roll_observe(c172p_roll_ctrl *c, const c172p_roll_real *y,
    const c172p_roll_real *sched, const c172p_roll_real *u_applied)
{
    c172p_roll_real u[C172P_ROLL_N_ACTUATORS];
    int j, use_y, applied_clipped;
    int clipped = 0;
    if (c == 0 || y == 0 || u_applied == 0 || (C172P_ROLL_N_SCHEDULE != 0 && sched == 0)) {
        return C172P_ROLL_BAD_ARGUMENT;
    }
    if (!c172p_roll_all_finite(u_applied, C172P_ROLL_N_ACTUATORS)) {
        return C172P_ROLL_NONFINITE_INPUT; /* no input to propagate with: nothing changes */
    }
    applied_clipped = plausible_applied(c, u_applied, u);
    use_y = c172p_roll_all_finite(y, C172P_ROLL_N_OUTPUTS) && c172p_roll_all_finite(sched, C172P_ROLL_N_SCHEDULE);
    if (use_y) {
        follow_schedule(c, sched);
    }
    for (j = 0; j < C172P_ROLL_N_MODES; ++j) {
        clipped += observe(&c->work, &c172p_roll_modes[j], c->xhat[j], y, u, use_y);
    }
    if (!use_y) {
        return C172P_ROLL_NONFINITE_INPUT;
    }
    if (applied_clipped > 0) {
        return C172P_ROLL_APPLIED_CLIPPED; /* the feedback's fault wins over the sensor's */
    }
    return (clipped > 0) ? C172P_ROLL_MEASUREMENT_CLIPPED : C172P_ROLL_OPTIMAL;
}

int c172p_roll_solve_qp(c172p_roll_ctrl *c, int mode, const c172p_roll_real *x,
    const c172p_roll_real *r, c172p_roll_real *U, int *iterations)
{
    int status, i;
    if (c == 0 || U == 0 || mode < 0 || mode >= C172P_ROLL_N_MODES) {
        return C172P_ROLL_BAD_ARGUMENT;
    }
    if (x == 0 || r == 0 || !c172p_roll_all_finite(x, c172p_roll_modes[mode].nx)
        || !c172p_roll_all_finite(r, C172P_ROLL_HORIZON * C172P_ROLL_N_OUTPUTS)) {
        status = (x == 0 || r == 0) ? C172P_ROLL_BAD_ARGUMENT : C172P_ROLL_NONFINITE_INPUT;
        for (i = 0; i < c172p_roll_modes[mode].n; ++i) {
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

const c172p_roll_info *c172p_roll_last_info(const c172p_roll_ctrl *c)
{
    return (c != 0) ? &c->info : 0; /* a NULL instance has no diagnostics, not a crash */
}

const char *c172p_roll_status_message(int status)
{
    switch (status) {
    case C172P_ROLL_OPTIMAL: return "optimal";
    case C172P_ROLL_MAX_ITER: return "iteration cap reached";
    case C172P_ROLL_INACCURATE: return "converged by delta but constraints violated";
    case C172P_ROLL_INFEASIBLE: return "infeasible: constraints cannot all hold (proven, or multipliers diverged)";
    case C172P_ROLL_NONFINITE_INPUT: return "non-finite input; last command held";
    case C172P_ROLL_NUMERICAL: return "non-finite intermediate result; safe fallback";
    case C172P_ROLL_BAD_ARGUMENT: return "bad argument";
    case C172P_ROLL_TIME_LIMIT: return "work budget reached; best command so far";
    case C172P_ROLL_MEASUREMENT_CLIPPED: return "optimal; an implausible measurement was clipped";
    case C172P_ROLL_APPLIED_CLIPPED: return "an applied command beyond its actuator's range was clipped";
    default: return "unknown status";
    }
}
