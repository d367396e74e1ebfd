/**
 * @file quadatt_controller.c
 * @brief Switched controller: hysteresis scheduler (eq. 3), one observer per mode,
 *        QP solve of the active mode, first-move extraction.
 *
 * All observers run every sample in the paper's predictor form
 * xhat+ = A xhat + B u_j + L (y - C xhat), each driven by the physical commands of its
 * own actuators (0 for an inactive pair) and the shared measurement. The inactive
 * observers therefore stay locked to y and a switch is bumpless.
 */
#include <math.h>
#include "quadatt_internal.h"
#if QUADATT_GENERATION != 0x0de5cde63d20b5f
#error "quadatt_controller.c and quadatt_config.h are of different generations (an interrupted regeneration?): regenerate the whole directory"
#endif

#define R_ QUADATT_R


/*
 * The range an applied command can have, per actuator: the lowest u_min and the highest
 * u_max of the modes that drive it (context.actuator_range).
 */
static const quadatt_real actuator_min[QUADATT_N_ACTUATORS] = {
    -3.0f, -3.0f, -3.0f, -3.0f
};
static const quadatt_real actuator_max[QUADATT_N_ACTUATORS] = {
    3.0f, 3.0f, 3.0f, 3.0f
};

/*
 * u_applied made plausible into u: each entry clipped to its actuator's range. A command
 * beyond it cannot have been applied (a glitch of the servo feedback, a unit mix-up in the
 * glue); taken in full, 1e8 pushed every estimate so far that the clipped innovations
 * never pulled it back. Returns how many entries were clipped.
 */
static int plausible_applied(const quadatt_ctrl *c, const quadatt_real *u_applied,
    quadatt_real *u)
{
    quadatt_real lo[QUADATT_N_ACTUATORS], hi[QUADATT_N_ACTUATORS];
    int i, clipped = 0;
    for (i = 0; i < QUADATT_N_ACTUATORS; ++i) {
        lo[i] = actuator_min[i];
        hi[i] = actuator_max[i];
    }
    (void)c;
    for (i = 0; i < QUADATT_N_ACTUATORS; ++i) {
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
static int observe(quadatt_work *ws, const quadatt_mode_data *md, quadatt_real *x,
    const quadatt_real *y, const quadatt_real *u_phys, int use_y)
{
    int i, l, a;
    int clipped = 0;
    for (a = 0; a < md->ny; ++a) {
        quadatt_real acc = R_(0.0);
        for (l = 0; l < md->nx; ++l) {
            acc += md->C[a * md->nx + l] * x[l];
        }
        ws->innov[a] = R_(0.0);
        if (use_y) {
            const quadatt_real limit = md->innovation_limit[a];
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
        quadatt_real acc = R_(0.0);
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

size_t quadatt_ctrl_size(void)
{
    return sizeof(quadatt_ctrl);
}

/*
 * No factor of an earlier QP to start from: the work arrays hold no mode's, or another
 * mode's (one set of work arrays serves every mode). A QP starts from the factor the last
 * QP left when that QP was of its mode (solve_mode()): the Hessian is the mode's, only its
 * working set moves.
 */
static void forget_factor(quadatt_work *ws)
{
    ws->chol_holds = QUADATT_CHOL_NONE;
    ws->primal_form = 0;
}

void quadatt_init(quadatt_ctrl *c)
{
    int j, i;
    if (c == 0) {
        return;
    }
    c->mode = 0;
    for (j = 0; j < QUADATT_N_MODES; ++j) {
        for (i = 0; i < QUADATT_NX_MAX; ++i) {
            c->xhat[j][i] = R_(0.0);
        }
        for (i = 0; i < QUADATT_M_MAX; ++i) {
            c->lam[j][i] = R_(0.0);
        }
    }
    for (i = 0; i < QUADATT_N_ACTUATORS; ++i) {
        c->u_last[i] = R_(0.0);
    }
    for (i = 0; i < QUADATT_N_MAX; ++i) {
        c->U[i] = R_(0.0);
    }
    c->plan_mode = (int16_t)c->mode;
    c->plan_age = QUADATT_HORIZON; /* no plan yet */
    forget_factor(&c->work);
    c->info.status = QUADATT_OPTIMAL;
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
static void keep_plan(quadatt_ctrl *c, int mode, int status, const quadatt_real *U)
{
    int i;
    if (status == QUADATT_OPTIMAL || (status == QUADATT_TIME_LIMIT && c->work.from_plan)) {
        for (i = 0; U != c->U && i < quadatt_modes[mode].n; ++i) {
            c->U[i] = U[i];
        }
        c->plan_age = (int16_t)((status == QUADATT_OPTIMAL) ? 0 : c->plan_age + 1);
    } else {
        c->plan_age = QUADATT_HORIZON;
    }
    if (status != QUADATT_OPTIMAL && status != QUADATT_TIME_LIMIT) {
        forget_factor(&c->work); /* a failed sample leaves no warm start: the next is P_init's */
    }
    c->plan_mode = (int16_t)mode;
}

static int solve_mode(quadatt_ctrl *c, int mode, const quadatt_real *x,
    const quadatt_real *r, quadatt_real *U)
{
    uint32_t t0;
    int status;
    if (c->plan_mode != mode) { /* the last QP was another mode's (keep_plan()) */
        forget_factor(&c->work);
    }
    t0 = QUADATT_TIMESTAMP();
    status = quadatt_qp_solve(&c->work, c->lam[mode], c->U,
        (c->plan_mode == mode) ? c->plan_age : QUADATT_HORIZON, &quadatt_modes[mode], x, r,
        U, &c->info.iterations, &c->info.polish_iterations, &c->info.active);
    c->info.solve_ticks = (uint32_t)(QUADATT_TIMESTAMP() - t0);
    keep_plan(c, mode, status, U);
    c->info.status = status;
    c->info.mode = mode;
    c->info.work = c->work.work;
    return status;
}

/* The scheduler's mode for this sample (finite sched); the incoming mode starts cold. */
static void follow_schedule(quadatt_ctrl *c, const quadatt_real *sched)
{
    (void)c;
    (void)sched;
}

/*
 * The held command made the active mode's. quadatt_observe() can switch the mode after
 * the last quadatt_step(), leaving in u_last the other mode's actuators or values past
 * this mode's input bounds: this mode's actuators keep their last values clamped into its
 * bounds and every other actuator gets 0, so that a held command obeys the same rules as
 * a solved one (an identity after a quadatt_step() of this mode).
 */
static void hold_for_mode(quadatt_ctrl *c)
{
    const quadatt_mode_data *md = &quadatt_modes[c->mode];
    quadatt_real held[QUADATT_N_ACTUATORS];
    int i;
    for (i = 0; i < QUADATT_N_ACTUATORS; ++i) {
        held[i] = R_(0.0);
    }
    for (i = 0; i < md->nu; ++i) {
        const quadatt_real lo = md->u_min[i];
        const quadatt_real hi = md->u_max[i];
        const quadatt_real v = c->u_last[md->actuator_index[i]];
        held[md->actuator_index[i]] = (v < lo) ? lo : ((v > hi) ? hi : v);
    }
    for (i = 0; i < QUADATT_N_ACTUATORS; ++i) {
        c->u_last[i] = held[i];
    }
}

int quadatt_step(quadatt_ctrl *c, const quadatt_real *y, const quadatt_real *sched,
    const quadatt_real *r, quadatt_real *u)
{
    int j, i, status, inputs_ok;
    int clipped = 0;
    const quadatt_mode_data *md;
    if (c == 0 || u == 0) {
        return QUADATT_BAD_ARGUMENT;
    }
    inputs_ok = y != 0 && r != 0 && (QUADATT_N_SCHEDULE == 0 || sched != 0);
    if (!inputs_ok) {
        hold_for_mode(c);
        for (i = 0; i < QUADATT_N_ACTUATORS; ++i) {
            u[i] = c->u_last[i];
        }
        c->info.status = QUADATT_BAD_ARGUMENT;
        return QUADATT_BAD_ARGUMENT;
    }
    if (!quadatt_all_finite(y, QUADATT_N_OUTPUTS) || !quadatt_all_finite(sched, QUADATT_N_SCHEDULE)
        || !quadatt_all_finite(r, QUADATT_HORIZON * QUADATT_N_OUTPUTS)) {
        hold_for_mode(c);
        for (i = 0; i < QUADATT_N_ACTUATORS; ++i) {
            u[i] = c->u_last[i];
        }
        for (j = 0; j < QUADATT_N_MODES; ++j) {
            (void)observe(&c->work, &quadatt_modes[j], c->xhat[j], y, u, 0);
        }
        c->info.status = QUADATT_NONFINITE_INPUT;
        c->info.iterations = 0;
        c->info.work = 0u;
        c->info.clipped = 0;
        return QUADATT_NONFINITE_INPUT;
    }
    follow_schedule(c, sched);
    md = &quadatt_modes[c->mode];
    status = solve_mode(c, c->mode, c->xhat[c->mode], r, c->U);
    for (i = 0; i < QUADATT_N_ACTUATORS; ++i) {
        u[i] = R_(0.0);
    }
    for (i = 0; i < md->nu; ++i) {
        u[md->actuator_index[i]] = c->U[i];
    }
    for (j = 0; j < QUADATT_N_MODES; ++j) {
        clipped += observe(&c->work, &quadatt_modes[j], c->xhat[j], y, u, 1);
    }
    for (i = 0; i < QUADATT_N_ACTUATORS; ++i) {
        c->u_last[i] = u[i];
    }
    c->info.clipped = clipped;
    if (status == QUADATT_OPTIMAL && clipped > 0) {
        status = QUADATT_MEASUREMENT_CLIPPED; /* a solver status wins over the report */
        c->info.status = status;
    }
    return status;
}

int quadatt_observe(quadatt_ctrl *c, const quadatt_real *y,
    const quadatt_real *sched, const quadatt_real *u_applied)
{
    quadatt_real u[QUADATT_N_ACTUATORS];
    int j, use_y, applied_clipped;
    int clipped = 0;
    if (c == 0 || y == 0 || u_applied == 0 || (QUADATT_N_SCHEDULE != 0 && sched == 0)) {
        return QUADATT_BAD_ARGUMENT;
    }
    if (!quadatt_all_finite(u_applied, QUADATT_N_ACTUATORS)) {
        return QUADATT_NONFINITE_INPUT; /* no input to propagate with: nothing changes */
    }
    applied_clipped = plausible_applied(c, u_applied, u);
    use_y = quadatt_all_finite(y, QUADATT_N_OUTPUTS) && quadatt_all_finite(sched, QUADATT_N_SCHEDULE);
    if (use_y) {
        follow_schedule(c, sched);
    }
    for (j = 0; j < QUADATT_N_MODES; ++j) {
        clipped += observe(&c->work, &quadatt_modes[j], c->xhat[j], y, u, use_y);
    }
    if (!use_y) {
        return QUADATT_NONFINITE_INPUT;
    }
    if (applied_clipped > 0) {
        return QUADATT_APPLIED_CLIPPED; /* the feedback's fault wins over the sensor's */
    }
    return (clipped > 0) ? QUADATT_MEASUREMENT_CLIPPED : QUADATT_OPTIMAL;
}

int quadatt_solve_qp(quadatt_ctrl *c, int mode, const quadatt_real *x,
    const quadatt_real *r, quadatt_real *U, int *iterations)
{
    int status, i;
    if (c == 0 || U == 0 || mode < 0 || mode >= QUADATT_N_MODES) {
        return QUADATT_BAD_ARGUMENT;
    }
    if (x == 0 || r == 0 || !quadatt_all_finite(x, quadatt_modes[mode].nx)
        || !quadatt_all_finite(r, QUADATT_HORIZON * QUADATT_N_OUTPUTS)) {
        status = (x == 0 || r == 0) ? QUADATT_BAD_ARGUMENT : QUADATT_NONFINITE_INPUT;
        for (i = 0; i < quadatt_modes[mode].n; ++i) {
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

const quadatt_info *quadatt_last_info(const quadatt_ctrl *c)
{
    return (c != 0) ? &c->info : 0; /* a NULL instance has no diagnostics, not a crash */
}

const char *quadatt_status_message(int status)
{
    switch (status) {
    case QUADATT_OPTIMAL: return "optimal";
    case QUADATT_MAX_ITER: return "iteration cap reached";
    case QUADATT_INACCURATE: return "converged by delta but constraints violated";
    case QUADATT_INFEASIBLE: return "infeasible: constraints cannot all hold (proven, or multipliers diverged)";
    case QUADATT_NONFINITE_INPUT: return "non-finite input; last command held";
    case QUADATT_NUMERICAL: return "non-finite intermediate result; safe fallback";
    case QUADATT_BAD_ARGUMENT: return "bad argument";
    case QUADATT_TIME_LIMIT: return "work budget reached; best command so far";
    case QUADATT_MEASUREMENT_CLIPPED: return "optimal; an implausible measurement was clipped";
    case QUADATT_APPLIED_CLIPPED: return "an applied command beyond its actuator's range was clipped";
    default: return "unknown status";
    }
}
