/**
 * @file chain_rb_controller.c
 * @brief Switched controller: hysteresis scheduler (eq. 3), one observer per mode,
 *        QP solve of the active mode, first-move extraction.
 *
 * All observers run every sample in the paper's predictor form
 * xhat+ = A xhat + B u_j + L (y - C xhat), each driven by the physical commands of its
 * own actuators (0 for an inactive pair) and the shared measurement. The inactive
 * observers therefore stay locked to y and a switch is bumpless.
 */
#include <math.h>
#include "chain_rb_internal.h"
#if CHAIN_RB_GENERATION != 0x474cca90b24b299
#error "chain_rb_controller.c and chain_rb_config.h are of different generations (an interrupted regeneration?): regenerate the whole directory"
#endif

#define R_ CHAIN_RB_R


/* The config's bounds of every mode, which chain_rb_init() restores (+-inf: no rows). */
static const chain_rb_bounds config_bounds[CHAIN_RB_N_MODES] = {
    { { -0.5f, -0.5f, -0.5f, -0.5f }, { 0.5f, 0.5f, 0.5f, 0.5f },
      { -0.600000024f, -0.600000024f, -0.600000024f, -0.600000024f, -HUGE_VALF, -HUGE_VALF },
      { 0.600000024f, 0.600000024f, 0.600000024f, 0.600000024f, 0.600000024f, HUGE_VALF } }
};

/*
 * The range an applied command can have, per actuator: the lowest u_min and the highest
 * u_max of the modes that drive it (context.actuator_range); P_set_bounds() widens it.
 */
static const chain_rb_real actuator_min[CHAIN_RB_N_ACTUATORS] = {
    -0.5f, -0.5f, -0.5f, -0.5f
};
static const chain_rb_real actuator_max[CHAIN_RB_N_ACTUATORS] = {
    0.5f, 0.5f, 0.5f, 0.5f
};

/*
 * u_applied made plausible into u: each entry clipped to its actuator's range. A command
 * beyond it cannot have been applied (a glitch of the servo feedback, a unit mix-up in the
 * glue); taken in full, 1e8 pushed every estimate so far that the clipped innovations
 * never pulled it back. Returns how many entries were clipped.
 */
static int plausible_applied(const chain_rb_ctrl *c, const chain_rb_real *u_applied,
    chain_rb_real *u)
{
    chain_rb_real lo[CHAIN_RB_N_ACTUATORS], hi[CHAIN_RB_N_ACTUATORS];
    int i, clipped = 0;
    int j;
    for (i = 0; i < CHAIN_RB_N_ACTUATORS; ++i) {
        lo[i] = actuator_min[i];
        hi[i] = actuator_max[i];
    }
    for (j = 0; j < CHAIN_RB_N_MODES; ++j) { /* the live bounds may be wider */
        for (i = 0; i < chain_rb_modes[j].nu; ++i) {
            const int a = chain_rb_modes[j].actuator_index[i];
            lo[a] = (c->bounds[j].u_min[i] < lo[a]) ? c->bounds[j].u_min[i] : lo[a];
            hi[a] = (c->bounds[j].u_max[i] > hi[a]) ? c->bounds[j].u_max[i] : hi[a];
        }
    }
    for (i = 0; i < CHAIN_RB_N_ACTUATORS; ++i) {
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
static int observe(chain_rb_work *ws, const chain_rb_mode_data *md, chain_rb_real *x,
    const chain_rb_real *y, const chain_rb_real *u_phys, int use_y)
{
    int i, l, a;
    int clipped = 0;
    for (a = 0; a < md->ny; ++a) {
        chain_rb_real acc = R_(0.0);
        for (l = 0; l < md->nx; ++l) {
            acc += md->C[a * md->nx + l] * x[l];
        }
        ws->innov[a] = R_(0.0);
        if (use_y) {
            const chain_rb_real limit = md->innovation_limit[a];
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
        chain_rb_real acc = R_(0.0);
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

size_t chain_rb_ctrl_size(void)
{
    return sizeof(chain_rb_ctrl);
}

/*
 * No factor of an earlier QP to start from: the work arrays hold no mode's, or another
 * mode's (one set of work arrays serves every mode). A QP starts from the factor the last
 * QP left when that QP was of its mode (solve_mode()): the Hessian is the mode's, only its
 * working set moves.
 */
static void forget_factor(chain_rb_work *ws)
{
    ws->chol_holds = CHAIN_RB_CHOL_NONE;
    ws->primal_form = 0;
}

void chain_rb_init(chain_rb_ctrl *c)
{
    int j, i;
    if (c == 0) {
        return;
    }
    c->mode = 0;
    for (j = 0; j < CHAIN_RB_N_MODES; ++j) {
        for (i = 0; i < CHAIN_RB_NX_MAX; ++i) {
            c->xhat[j][i] = R_(0.0);
        }
        for (i = 0; i < CHAIN_RB_M_MAX; ++i) {
            c->lam[j][i] = R_(0.0);
        }
    }
    for (i = 0; i < CHAIN_RB_N_ACTUATORS; ++i) {
        c->u_last[i] = R_(0.0);
    }
    for (i = 0; i < CHAIN_RB_N_MAX; ++i) {
        c->U[i] = R_(0.0);
    }
    c->plan_mode = (int16_t)c->mode;
    c->plan_age = CHAIN_RB_HORIZON; /* no plan yet */
    forget_factor(&c->work);
    for (j = 0; j < CHAIN_RB_N_MODES; ++j) {
        c->bounds[j] = config_bounds[j];
    }
    c->work.bounds = c->bounds[c->mode];
    c->info.status = CHAIN_RB_OPTIMAL;
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
static void keep_plan(chain_rb_ctrl *c, int mode, int status, const chain_rb_real *U)
{
    int i;
    if (status == CHAIN_RB_OPTIMAL || (status == CHAIN_RB_TIME_LIMIT && c->work.from_plan)) {
        for (i = 0; U != c->U && i < chain_rb_modes[mode].n; ++i) {
            c->U[i] = U[i];
        }
        c->plan_age = (int16_t)((status == CHAIN_RB_OPTIMAL) ? 0 : c->plan_age + 1);
    } else {
        c->plan_age = CHAIN_RB_HORIZON;
    }
    if (status != CHAIN_RB_OPTIMAL && status != CHAIN_RB_TIME_LIMIT) {
        forget_factor(&c->work); /* a failed sample leaves no warm start: the next is P_init's */
    }
    c->plan_mode = (int16_t)mode;
}

static int solve_mode(chain_rb_ctrl *c, int mode, const chain_rb_real *x,
    const chain_rb_real *r, chain_rb_real *U)
{
    uint32_t t0;
    int status;
    if (c->plan_mode != mode) { /* the last QP was another mode's (keep_plan()) */
        forget_factor(&c->work);
    }
    t0 = CHAIN_RB_TIMESTAMP();
    status = chain_rb_qp_solve(&c->work, c->lam[mode], c->U,
        (c->plan_mode == mode) ? c->plan_age : CHAIN_RB_HORIZON, &chain_rb_modes[mode], x, r,
        U, &c->info.iterations, &c->info.polish_iterations, &c->info.active);
    c->info.solve_ticks = (uint32_t)(CHAIN_RB_TIMESTAMP() - t0);
    keep_plan(c, mode, status, U);
    c->info.status = status;
    c->info.mode = mode;
    c->info.work = c->work.work;
    return status;
}

/* The scheduler's mode for this sample (finite sched); the incoming mode starts cold. */
static void follow_schedule(chain_rb_ctrl *c, const chain_rb_real *sched)
{
    (void)c;
    (void)sched;
}

/*
 * The held command made the active mode's. chain_rb_observe() can switch the mode after
 * the last chain_rb_step(), leaving in u_last the other mode's actuators or values past
 * this mode's input bounds: this mode's actuators keep their last values clamped into its
 * bounds and every other actuator gets 0, so that a held command obeys the same rules as
 * a solved one (an identity after a chain_rb_step() of this mode).
 */
static void hold_for_mode(chain_rb_ctrl *c)
{
    const chain_rb_mode_data *md = &chain_rb_modes[c->mode];
    const chain_rb_bounds *b = &c->bounds[c->mode];
    chain_rb_real held[CHAIN_RB_N_ACTUATORS];
    int i;
    for (i = 0; i < CHAIN_RB_N_ACTUATORS; ++i) {
        held[i] = R_(0.0);
    }
    for (i = 0; i < md->nu; ++i) {
        const chain_rb_real lo = b->u_min[i];
        const chain_rb_real hi = b->u_max[i];
        const chain_rb_real v = c->u_last[md->actuator_index[i]];
        held[md->actuator_index[i]] = (v < lo) ? lo : ((v > hi) ? hi : v);
    }
    for (i = 0; i < CHAIN_RB_N_ACTUATORS; ++i) {
        c->u_last[i] = held[i];
    }
}

int chain_rb_step(chain_rb_ctrl *c, const chain_rb_real *y, const chain_rb_real *sched,
    const chain_rb_real *r, chain_rb_real *u)
{
    int j, i, status, inputs_ok;
    int clipped = 0;
    const chain_rb_mode_data *md;
    if (c == 0 || u == 0) {
        return CHAIN_RB_BAD_ARGUMENT;
    }
    inputs_ok = y != 0 && r != 0 && (CHAIN_RB_N_SCHEDULE == 0 || sched != 0);
    if (!inputs_ok) {
        hold_for_mode(c);
        for (i = 0; i < CHAIN_RB_N_ACTUATORS; ++i) {
            u[i] = c->u_last[i];
        }
        c->info.status = CHAIN_RB_BAD_ARGUMENT;
        return CHAIN_RB_BAD_ARGUMENT;
    }
    if (!chain_rb_all_finite(y, CHAIN_RB_N_OUTPUTS) || !chain_rb_all_finite(sched, CHAIN_RB_N_SCHEDULE)
        || !chain_rb_all_finite(r, CHAIN_RB_HORIZON * CHAIN_RB_N_OUTPUTS)) {
        hold_for_mode(c);
        for (i = 0; i < CHAIN_RB_N_ACTUATORS; ++i) {
            u[i] = c->u_last[i];
        }
        for (j = 0; j < CHAIN_RB_N_MODES; ++j) {
            (void)observe(&c->work, &chain_rb_modes[j], c->xhat[j], y, u, 0);
        }
        c->info.status = CHAIN_RB_NONFINITE_INPUT;
        c->info.iterations = 0;
        c->info.work = 0u;
        c->info.clipped = 0;
        return CHAIN_RB_NONFINITE_INPUT;
    }
    follow_schedule(c, sched);
    md = &chain_rb_modes[c->mode];
    c->work.bounds = c->bounds[c->mode]; /* the solver reads the live bounds here */
    status = solve_mode(c, c->mode, c->xhat[c->mode], r, c->U);
    for (i = 0; i < CHAIN_RB_N_ACTUATORS; ++i) {
        u[i] = R_(0.0);
    }
    for (i = 0; i < md->nu; ++i) {
        u[md->actuator_index[i]] = c->U[i];
    }
    for (j = 0; j < CHAIN_RB_N_MODES; ++j) {
        clipped += observe(&c->work, &chain_rb_modes[j], c->xhat[j], y, u, 1);
    }
    for (i = 0; i < CHAIN_RB_N_ACTUATORS; ++i) {
        c->u_last[i] = u[i];
    }
    c->info.clipped = clipped;
    if (status == CHAIN_RB_OPTIMAL && clipped > 0) {
        status = CHAIN_RB_MEASUREMENT_CLIPPED; /* a solver status wins over the report */
        c->info.status = status;
    }
    return status;
}

int chain_rb_observe(chain_rb_ctrl *c, const chain_rb_real *y,
    const chain_rb_real *sched, const chain_rb_real *u_applied)
{
    chain_rb_real u[CHAIN_RB_N_ACTUATORS];
    int j, use_y, applied_clipped;
    int clipped = 0;
    if (c == 0 || y == 0 || u_applied == 0 || (CHAIN_RB_N_SCHEDULE != 0 && sched == 0)) {
        return CHAIN_RB_BAD_ARGUMENT;
    }
    if (!chain_rb_all_finite(u_applied, CHAIN_RB_N_ACTUATORS)) {
        return CHAIN_RB_NONFINITE_INPUT; /* no input to propagate with: nothing changes */
    }
    applied_clipped = plausible_applied(c, u_applied, u);
    use_y = chain_rb_all_finite(y, CHAIN_RB_N_OUTPUTS) && chain_rb_all_finite(sched, CHAIN_RB_N_SCHEDULE);
    if (use_y) {
        follow_schedule(c, sched);
    }
    for (j = 0; j < CHAIN_RB_N_MODES; ++j) {
        clipped += observe(&c->work, &chain_rb_modes[j], c->xhat[j], y, u, use_y);
    }
    if (!use_y) {
        return CHAIN_RB_NONFINITE_INPUT;
    }
    if (applied_clipped > 0) {
        return CHAIN_RB_APPLIED_CLIPPED; /* the feedback's fault wins over the sensor's */
    }
    return (clipped > 0) ? CHAIN_RB_MEASUREMENT_CLIPPED : CHAIN_RB_OPTIMAL;
}

int chain_rb_solve_qp(chain_rb_ctrl *c, int mode, const chain_rb_real *x,
    const chain_rb_real *r, chain_rb_real *U, int *iterations)
{
    int status, i;
    if (c == 0 || U == 0 || mode < 0 || mode >= CHAIN_RB_N_MODES) {
        return CHAIN_RB_BAD_ARGUMENT;
    }
    if (x == 0 || r == 0 || !chain_rb_all_finite(x, chain_rb_modes[mode].nx)
        || !chain_rb_all_finite(r, CHAIN_RB_HORIZON * CHAIN_RB_N_OUTPUTS)) {
        status = (x == 0 || r == 0) ? CHAIN_RB_BAD_ARGUMENT : CHAIN_RB_NONFINITE_INPUT;
        for (i = 0; i < chain_rb_modes[mode].n; ++i) {
            U[i] = R_(0.0);
        }
        c->info.status = status;
        if (iterations != 0) {
            *iterations = 0;
        }
        return status;
    }
    c->work.bounds = c->bounds[mode]; /* the solver reads the live bounds here */
    status = solve_mode(c, mode, x, r, U);
    if (iterations != 0) {
        *iterations = c->info.iterations;
    }
    return status;
}

/*
 * Status of a new output bound v where the config has configured (+-inf: no rows):
 * a configured bound stays finite, an unconfigured one stays that infinity.
 */
static int output_bound_status(chain_rb_real configured, chain_rb_real v, int upper)
{
    if (isnan(v)) {
        return CHAIN_RB_BAD_BOUNDS;
    }
    if (isfinite(configured)) {
        return isfinite(v) ? CHAIN_RB_OPTIMAL : CHAIN_RB_BAD_BOUNDS;
    }
    if (isfinite(v)) {
        return CHAIN_RB_BOUND_NOT_CONFIGURED;
    }
    return ((v > R_(0.0)) == (upper != 0)) ? CHAIN_RB_OPTIMAL : CHAIN_RB_BAD_BOUNDS;
}

int chain_rb_set_bounds(chain_rb_ctrl *c, int mode, const chain_rb_real *u_min,
    const chain_rb_real *u_max, const chain_rb_real *y_min, const chain_rb_real *y_max)
{
    const chain_rb_mode_data *md;
    chain_rb_bounds *b;
    int i;
    if (c == 0 || mode < 0 || mode >= CHAIN_RB_N_MODES || u_min == 0 || u_max == 0
        || y_min == 0 || y_max == 0) {
        return CHAIN_RB_BAD_ARGUMENT;
    }
    md = &chain_rb_modes[mode];
    for (i = 0; i < md->nu; ++i) {
        if (!(isfinite(u_min[i]) && isfinite(u_max[i]) && u_min[i] < u_max[i]
              && u_min[i] <= R_(0.0) && u_max[i] >= R_(0.0))) {
            return CHAIN_RB_BAD_BOUNDS;
        }
    }
    for (i = 0; i < md->ny; ++i) {
        int status = output_bound_status(config_bounds[mode].y_min[i], y_min[i], 0);
        if (status == CHAIN_RB_OPTIMAL) {
            status = output_bound_status(config_bounds[mode].y_max[i], y_max[i], 1);
        }
        if (status == CHAIN_RB_OPTIMAL && !(y_min[i] < y_max[i])) {
            status = CHAIN_RB_BAD_BOUNDS;
        }
        if (status != CHAIN_RB_OPTIMAL) {
            return status;
        }
    }
    b = &c->bounds[mode];
    for (i = 0; i < md->nu; ++i) {
        b->u_min[i] = u_min[i];
        b->u_max[i] = u_max[i];
    }
    for (i = 0; i < md->ny; ++i) {
        b->y_min[i] = y_min[i];
        b->y_max[i] = y_max[i];
    }
    if (mode == c->mode) {
        hold_for_mode(c); /* the held command obeys the new input bounds too */
    }
    return CHAIN_RB_OPTIMAL;
}

int chain_rb_get_bounds(const chain_rb_ctrl *c, int mode, chain_rb_real *u_min,
    chain_rb_real *u_max, chain_rb_real *y_min, chain_rb_real *y_max)
{
    int i;
    if (c == 0 || mode < 0 || mode >= CHAIN_RB_N_MODES || u_min == 0 || u_max == 0
        || y_min == 0 || y_max == 0) {
        return CHAIN_RB_BAD_ARGUMENT;
    }
    for (i = 0; i < chain_rb_modes[mode].nu; ++i) {
        u_min[i] = c->bounds[mode].u_min[i];
        u_max[i] = c->bounds[mode].u_max[i];
    }
    for (i = 0; i < chain_rb_modes[mode].ny; ++i) {
        y_min[i] = c->bounds[mode].y_min[i];
        y_max[i] = c->bounds[mode].y_max[i];
    }
    return CHAIN_RB_OPTIMAL;
}

const chain_rb_info *chain_rb_last_info(const chain_rb_ctrl *c)
{
    return (c != 0) ? &c->info : 0; /* a NULL instance has no diagnostics, not a crash */
}

const char *chain_rb_status_message(int status)
{
    switch (status) {
    case CHAIN_RB_OPTIMAL: return "optimal";
    case CHAIN_RB_MAX_ITER: return "iteration cap reached";
    case CHAIN_RB_INACCURATE: return "converged by delta but constraints violated";
    case CHAIN_RB_INFEASIBLE: return "infeasible: constraints cannot all hold (proven, or multipliers diverged)";
    case CHAIN_RB_NONFINITE_INPUT: return "non-finite input; last command held";
    case CHAIN_RB_NUMERICAL: return "non-finite intermediate result; safe fallback";
    case CHAIN_RB_BAD_ARGUMENT: return "bad argument";
    case CHAIN_RB_BAD_BOUNDS: return "bad bounds; nothing changed";
    case CHAIN_RB_BOUND_NOT_CONFIGURED: return "bound not in the config (no constraint rows); nothing changed";
    case CHAIN_RB_TIME_LIMIT: return "work budget reached; best command so far";
    case CHAIN_RB_MEASUREMENT_CLIPPED: return "optimal; an implausible measurement was clipped";
    case CHAIN_RB_APPLIED_CLIPPED: return "an applied command beyond its actuator's range was clipped";
    default: return "unknown status";
    }
}
