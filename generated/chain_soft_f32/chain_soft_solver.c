/**
 * @file chain_soft_solver.c
 * @brief Hildreth-family dual QP solver (Lam et al., IFAC 2020, section 3.2) with an
 *        exact active-set polish.
 *
 * Problem (eq. 5-6): min 1/2 U'EU + U'F s.t. M U <= gamma, with rows M_r = sign_r a(q_r)'
 * on a quantity q_r (an input U_i, or a predicted output (Gamma U)_k). The dual Hessian
 * H = M E^-1 M' is read through its structure (hq()), never stored densely.
 *
 * Variants are compile-time switches (chain_soft_config.h):
 *  - REDUCED=0, WARM=0, omega=1: Hildreth (Alg. 1), Gauss-Seidel on all rows, cold start.
 *  - REDUCED=0, WARM=1, omega>1: Hildreth+ (SOR, warm start, precomputed data).
 *  - REDUCED=1: Hildreth+' (mini-Hildreth on rows with K < sigma), plus the correction
 *    the paper lacks: after each solve every row is re-checked and violated rows join.
 *  - POLISH_FIRST=1: before any sweep, polish from the previous optimal active set (or
 *    from the rows the unconstrained solution violates); sweep only if that fails.
 *  - POLISH=1: every POLISH_EVERY sweeps, the rows with positive multipliers are taken as
 *    the working set and solved exactly -- in primal form (Cholesky of E_FF) when only
 *    input bounds are in it, else in dual form (Cholesky of H_WW) -- then corrected by
 *    dropping negative multipliers and adding violated rows until KKT holds.
 *
 * Every sum runs sequentially in a fixed order with no fused multiply-add, so the NumPy
 * reference (rollmpc_codegen.reference.solver) reproduces every output bit for bit.
 */
#include <math.h>
#include "chain_soft_internal.h"

#define R_ CHAIN_SOFT_R

/*
 * Work units (docs/solver.md, "Work budget"): about one multiply-add with its loads. Each
 * costly function adds its closed-form cost to ws->work once per call (never per loop
 * iteration); the same formulas bound a unit of work before it starts (afford()), so the
 * work of a solve never exceeds CHAIN_SOFT_SOLVER_WORK_BUDGET. The NumPy reference charges the
 * same numbers at the same places (rollmpc_codegen/qp/work.py: these formulas).
 */
#define OUT_OF_WORK (-2) /* a solver part stopped: the budget cannot afford its next unit */

/* One read of H through hq(): the Woodbury sum of nt terms, twice for a Δu quantity. */
static uint32_t hq_work(const chain_soft_mode_data *md)
{
    return ((uint32_t)md->nt + 4u) * 1u;
}

/* predict_outputs(): the Markov sum of every output over the stages before it. */
static uint32_t predict_work(const chain_soft_mode_data *md)
{
    const uint32_t stages = (uint32_t)md->nyq / (uint32_t)md->ny;
    return (uint32_t)md->ny * (uint32_t)md->nu * stages * (stages + 1u) / 2u
        + (uint32_t)md->nyq;
}

/*
 * A check of every row at a point (violated_outside(), most_violated()): the certificate,
 * the prediction it may need, and the rows.
 */
static uint32_t scan_work(const chain_soft_mode_data *md)
{
    return 3u * (uint32_t)md->m + (uint32_t)md->n + predict_work(md);
}

/*
 * correct() over `count` rows: n-long columns for at most min(2 count, n) input and
 * min(count, nyq) output quantities, and the Woodbury term.
 */
static uint32_t correct_work(const chain_soft_mode_data *md, int count)
{
    const uint32_t n = (uint32_t)md->n, nt = (uint32_t)md->nt, c = (uint32_t)count;
    const uint32_t nin = (2u * c < n) ? 2u * c : n;
    const uint32_t nout = (c < (uint32_t)md->nyq) ? c : (uint32_t)md->nyq;
    return c + 2u * n + (uint32_t)md->nyq + n * (nin + nout + nt) + nt * nin;
}

/* One Gauss-Seidel sweep over `count` rows. */
static uint32_t sweep_work(const chain_soft_mode_data *md, int count)
{
    const uint32_t c = (uint32_t)count;
    return c * c * hq_work(md) + 8u * c;
}

/* finish() and the slacks of the plan: always paid, so every check reserves it. */
static uint32_t finish_work(const chain_soft_mode_data *md)
{
    return 2u * (uint32_t)md->n + 2u * (uint32_t)md->m;
}

/*
 * Can the budget still pay for `need` units (and the final finish())? Every unit of work
 * asks before it starts, so ws->work + finish_work() never passes the budget (the
 * generator checks that the unconstrained step leaves room); ws->work_limit is the
 * budget, or less while the shifted guess runs (P_qp_solve()).
 */
static int afford(const chain_soft_work *ws, const chain_soft_mode_data *md, uint32_t need)
{
    const uint32_t used = ws->work + finish_work(md);
    return used <= ws->work_limit && need <= ws->work_limit - used;
}

/* Cholesky factorisation of order n (n^3/6 multiply-adds, a division per entry). */
static uint32_t chol_work(int n)
{
    const uint32_t u = (uint32_t)n;
    return u * u * u / 6u + 2u * u * u + 4u * u;
}

/* One triangular solve of order n. */
static uint32_t tri_work(int n)
{
    const uint32_t u = (uint32_t)n;
    return u * u / 2u + 4u * u;
}

/* chol_rank_one() on a trailing block of order n: a rotation per column. */
static uint32_t rank_one_work(int n)
{
    const uint32_t u = (uint32_t)n;
    return 3u * u * u / 2u + 10u * u;
}

/* chol_delete() of row k from order n: the rows below move up, then one rank-one update. */
static uint32_t delete_work(int k, int n)
{
    const uint32_t a = (uint32_t)n, b = (uint32_t)k;
    return (a * a - b * b) / 2u + a + rank_one_work((n - 1 - k > 0) ? n - 1 - k : 0);
}

/* factor_working_set() of nw rows: their H entries, then the factorisation. */
static uint32_t factor_work(const chain_soft_mode_data *md, int nw)
{
    const uint32_t u = (uint32_t)nw;
    return u * (u + 1u) / 2u * hq_work(md) + chol_work(nw);
}

/* append_row() at position nw: the column H_Wp and its diagonal, a forward solve. */
static uint32_t append_work(const chain_soft_mode_data *md, int nw)
{
    return ((uint32_t)nw + 1u) * hq_work(md) + tri_work(nw) + (uint32_t)nw;
}

/*
 * primal_solve() on nw bound inputs and free_multipliers() after it: the Cholesky of the
 * smaller of (S^-1)_BB and S_FF at 3/4 of a unit per operation; its solves for the nt + 1
 * right-hand sides, the terminal Schur complement and the n x nb (or n x nf) products at
 * 1/3: these dense loops run that much faster per operation than H reads (qp/work.py).
 */
static uint32_t primal_work(const chain_soft_mode_data *md, int nw)
{
    const int n = md->n, nt = md->nt, k = (nw < n - nw) ? nw : n - nw;
    const uint32_t u = (uint32_t)k, un = (uint32_t)n, ut = (uint32_t)nt;
    const uint32_t loops = u * u / 2u + 2u * (ut + 1u) * tri_work(k) + ut * ut * u / 2u
        + 2u * tri_work(nt) + 3u * ut * un + 2u * un * (u + ut) + (uint32_t)nw * (un + ut);
    return (9u * (chol_work(k) + chol_work(nt)) + 4u * loops) / 12u;
}

/* One step of add_to_set() on nw rows: two triangular solves, then a row leaves, switches
 * state or joins. */
static uint32_t add_step_work(int nw)
{
    const uint32_t leave = delete_work(0, nw), flip = rank_one_work(nw);
    return 2u * tri_work(nw) + 5u * (uint32_t)nw + ((leave > flip) ? leave : flip);
}

/* Element (a, b) of Hq = [[E^-1, E^-1 G'], [G E^-1, G E^-1 G']] (quantities a, b). */
static chain_soft_real hq(const chain_soft_mode_data *md, int a, int b)
{
    const int n = md->n;
    if (a < n) {
        if (b < n) {
            /* Woodbury: E^-1 = S^-1 - Ew' Ew */
            const chain_soft_real si = (a >= b) ? md->Sinv_p[CHAIN_SOFT_TRI(a, b)] : md->Sinv_p[CHAIN_SOFT_TRI(b, a)];
            chain_soft_real acc = R_(0.0);
            int o;
            for (o = 0; o < md->nt; ++o) {
                acc += md->Ew[o * n + a] * md->Ew[o * n + b];
            }
            return si - acc;
        }
        return md->EinvGt[a * md->nyq + (b - n)];
    }
    if (b < n) {
        return md->EinvGt[b * md->nyq + (a - n)];
    }
    a -= n;
    b -= n;
    return (a >= b) ? md->GEinvGt_p[CHAIN_SOFT_TRI(a, b)] : md->GEinvGt_p[CHAIN_SOFT_TRI(b, a)];
}

/* H_rs = sign_r sign_s Hq(q_r, q_s). */
static chain_soft_real h_rows(const chain_soft_mode_data *md, int r, int s)
{
    const chain_soft_real h = hq(md, md->row_q[r], md->row_q[s]);
    return (md->row_sign[r] == md->row_sign[s]) ? h : -h;
}

/* S(a, b) from the packed lower triangle. */
static chain_soft_real s_at(const chain_soft_mode_data *md, int a, int b)
{
    return (a >= b) ? md->S_p[CHAIN_SOFT_TRI(a, b)] : md->S_p[CHAIN_SOFT_TRI(b, a)];
}

/*
 * sum_i a_i b_i in four interleaved partial sums (lane i mod 4, the tail into lane 0),
 * combined as (s0 + s1) + (s2 + s3): the same rounding as the reference, and four
 * independent add chains instead of one.
 */
static chain_soft_real dot4(const chain_soft_real *a, const chain_soft_real *b, int len)
{
    chain_soft_real s0 = R_(0.0), s1 = R_(0.0), s2 = R_(0.0), s3 = R_(0.0);
    int i;
    for (i = 0; i + 3 < len; i += 4) {
        s0 += a[i] * b[i];
        s1 += a[i + 1] * b[i + 1];
        s2 += a[i + 2] * b[i + 2];
        s3 += a[i + 3] * b[i + 3];
    }
    for (; i < len; ++i) {
        s0 += a[i] * b[i];
    }
    return (s0 + s1) + (s2 + s3);
}

/*
 * sum_i S(q, i) v_i: dot4 over row q of the packed triangle up to the diagonal, plus the
 * same four-lane sum down column q below it.
 */
static chain_soft_real s_row_dot(const chain_soft_mode_data *md, int q, const chain_soft_real *v)
{
    const chain_soft_real *sp = md->S_p;
    const chain_soft_real head = dot4(&sp[CHAIN_SOFT_TRI(q, 0)], v, q + 1);
    chain_soft_real s0 = R_(0.0), s1 = R_(0.0), s2 = R_(0.0), s3 = R_(0.0);
    int i = q + 1, off = CHAIN_SOFT_TRI(q + 1, q);
    for (; i + 3 < md->n; i += 4) {
        s0 += sp[off] * v[i];
        off += i + 1;
        s1 += sp[off] * v[i + 1];
        off += i + 2;
        s2 += sp[off] * v[i + 2];
        off += i + 3;
        s3 += sp[off] * v[i + 3];
        off += i + 4;
    }
    for (; i < md->n; ++i) {
        s0 += sp[off] * v[i];
        off += i + 1;
    }
    return head + ((s0 + s1) + (s2 + s3));
}

/*
 * Runs of equal w over the stages 0..N-2: ws->run[0..count) are their first stages and
 * ws->run[count] = N-1. Returns count; *longest is the first longest run (-1 if none).
 */
static int reference_runs(chain_soft_work *ws, const chain_soft_mode_data *md, int *longest)
{
    const int ny = md->ny, last = md->nyq / md->ny - 1;
    int stage, a, j, count = 0, best = -1, best_len = 0;
    for (stage = 0; stage < last; ++stage) {
        int differs = (stage == 0);
        for (a = 0; a < ny && !differs; ++a) {
            const chain_soft_real p = ws->yv[(stage - 1) * ny + a], q = ws->yv[stage * ny + a];
            differs = (p < q) || (p > q);
        }
        if (differs) {
            ws->run[count++] = (int16_t)stage;
        }
    }
    ws->run[count] = (int16_t)last;
    for (j = 0; j < count; ++j) {
        const int len = ws->run[j + 1] - ws->run[j];
        if (len > best_len) {
            best_len = len;
            best = j;
        }
    }
    *longest = best;
    return count;
}

/*
 * th0 = Kx x + E^-1 G' w with w = 2 Omega r (kept in ws->yv, free until the outputs are
 * predicted); px = Phi x (output rows only).
 * The columns of E^-1 G' are summed per run of equal w; the longest run's sum comes from
 * colsum minus the others, so a held reference costs n (nx + 2 ny) instead of n (nx + N ny).
 */
static void unconstrained(chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *x, const chain_soft_real *r)
{
    const int n = md->n, ny = md->ny, nyq = md->nyq, last = md->nyq / md->ny - 1;
    int i, j, k, l, a, stage, nruns, longest, summed;
    for (k = 0; k < nyq; ++k) {
        const int st = k / ny, b = k % ny;
        chain_soft_real acc = R_(0.0);
        for (l = 0; l < ny; ++l) {
            acc += md->Omega2[(st * ny + b) * ny + l] * r[st * ny + l];
        }
        ws->yv[k] = acc;
    }
    nruns = reference_runs(ws, md, &longest);
    summed = last - ((longest >= 0) ? ws->run[longest + 1] - ws->run[longest] : 0);
    for (i = 0; i < n; ++i) {
        const chain_soft_real *row = &md->EinvGt[i * nyq];
        chain_soft_real acc = R_(0.0);
        for (l = 0; l < md->nx; ++l) {
            acc += md->Kx[i * md->nx + l] * x[l];
        }
        for (a = 0; a < ny; ++a) {
            chain_soft_real other = R_(0.0);
            for (j = 0; j < nruns; ++j) {
                if (j != longest) {
                    chain_soft_real sum = R_(0.0);
                    for (stage = ws->run[j]; stage < ws->run[j + 1]; ++stage) {
                        sum += row[stage * ny + a];
                    }
                    acc += ws->yv[ws->run[j] * ny + a] * sum;
                    other += sum;
                }
            }
            if (longest >= 0) {
                acc += ws->yv[ws->run[longest] * ny + a] * (md->colsum[a * n + i] - other);
            }
            acc += row[last * ny + a] * ws->yv[last * ny + a];
        }
        ws->th0[i] = acc;
    }
    ws->work += (uint32_t)nyq * (uint32_t)ny + (uint32_t)n * (uint32_t)md->nx
        + (uint32_t)n * (uint32_t)ny * ((uint32_t)summed + (uint32_t)nruns + 2u);
    if (md->GEinvGt_p != 0) {
        ws->work += (uint32_t)nyq * (uint32_t)md->nx;
        for (k = 0; k < nyq; ++k) {
            chain_soft_real acc = R_(0.0);
            for (l = 0; l < md->nx; ++l) {
                acc += md->Phi[k * md->nx + l] * x[l];
            }
            ws->px[k] = acc;
        }
    }
}

/*
 * yv = Gamma th (block Toeplitz in the Markov parameters).
 * Input (t, b) is spread over every later output in one strided pass, so each output
 * still sums its terms in (t, b) order, as the reference does, with the longest loop
 * innermost.
 */
static void predict_outputs(chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *th)
{
    const int ny = md->ny, nu = md->nu, nyq = md->nyq;
    int k, t, b, j;
    ws->work += predict_work(md);
    for (k = 0; k < nyq; ++k) {
        ws->yv[k] = R_(0.0);
    }
    for (t = 0; t < nyq / ny; ++t) {
        chain_soft_real *y = &ws->yv[t * ny]; /* outputs of stages t.. */
        const int len = nyq - t * ny;
        for (b = 0; b < nu; ++b) {
            const chain_soft_real u = th[t * nu + b];
            const chain_soft_real *mk = &md->markov[b]; /* (stage - t, a) with stride nu */
            for (j = 0; j < len; ++j) {
                y[j] += mk[j * nu] * u;
            }
        }
    }
}

/* Value of row r's quantity at th (yv must hold Gamma th). */
static chain_soft_real row_value(const chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *th, int r)
{
    const int q = md->row_q[r];
    return (q < md->n) ? th[q] : ws->yv[q - md->n];
}

/*
 * 1 if no output row can be violated at th: |(Gamma th)_k| <= out_bound_k max|th| <= gamma_r
 * (out_bound carries the rounding margin), so the N^2/2 prediction can be skipped.
 */
static int outputs_certified(chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *th)
{
    chain_soft_real thmax = R_(0.0), bmax = R_(0.0);
    int i, r;
    ws->work += (uint32_t)md->n + (uint32_t)md->m;
    for (i = 0; i < md->n; ++i) {
        const chain_soft_real v = CHAIN_SOFT_FABS(th[i]);
        thmax = (v > thmax) ? v : thmax;
    }
    for (i = md->nyq - md->ny; i < md->nyq; ++i) { /* out_bound grows along the horizon */
        bmax = (md->out_bound[i] > bmax) ? md->out_bound[i] : bmax;
    }
    if (bmax * thmax <= ws->gam_out_min) {
        return 1; /* the largest bound against the tightest output row */
    }
    for (r = 0; r < md->m; ++r) {
        const int q = md->row_q[r];
        if (q >= md->n && !(md->out_bound[q - md->n] * thmax <= ws->gam[r])) {
            return 0;
        }
    }
    return 1;
}

/* K = gamma - M th0 of the output rows (needs the N^2/2 prediction of th0). */
static void output_slacks(chain_soft_work *ws, const chain_soft_mode_data *md)
{
    int r;
    if (ws->out_slacks_ok) {
        return;
    }
    predict_outputs(ws, md, ws->th0);
    ws->work += (uint32_t)md->m;
    for (r = 0; r < md->m; ++r) {
        const int q = md->row_q[r];
        if (q >= md->n) {
            const chain_soft_real v = ws->yv[q - md->n];
            ws->K[r] = (md->row_sign[r] > 0) ? ws->gam[r] - v : ws->gam[r] + v;
        }
    }
    ws->out_slacks_ok = 1;
}

/*
 * gamma = c + W x for every row and K = gamma - M th0; returns the number with K < 0.
 * When the outputs are certified at th0, their K (all >= 0) is left to output_slacks(),
 * which whatever needs it calls first.
 */
static int slacks(chain_soft_work *ws, const chain_soft_mode_data *md)
{
    int r, count = 0;
    ws->work += 2u * (uint32_t)md->m;
    ws->gam_out_min = CHAIN_SOFT_LAMBDA_LIMIT;
    for (r = 0; r < md->m; ++r) {
        const int q = md->row_q[r];
        chain_soft_real g = md->row_c[r];
        if (q >= md->n) {
            g = (md->row_sign[r] > 0) ? g - ws->px[q - md->n] : g + ws->px[q - md->n];
            ws->gam_out_min = (g < ws->gam_out_min) ? g : ws->gam_out_min;
        } else {
            ws->K[r] = (md->row_sign[r] > 0) ? g - ws->th0[q] : g + ws->th0[q];
            count += (ws->K[r] < R_(0.0));
        }
        ws->gam[r] = g;
    }
    ws->out_slacks_ok = md->GEinvGt_p == 0;
    if (!ws->out_slacks_ok && !outputs_certified(ws, md, ws->th0)) {
        output_slacks(ws, md);
        for (r = 0; r < md->m; ++r) {
            count += (md->row_q[r] >= md->n && ws->K[r] < R_(0.0));
        }
    }
    return count;
}

/*
 * 1 if the output rows need checking at th (not certified); ws->yv then holds Gamma th.
 * 0 if there are none or none can be violated.
 */
static int outputs_to_check(chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *th)
{
    if (md->GEinvGt_p == 0 || outputs_certified(ws, md, th)) {
        return 0;
    }
    predict_outputs(ws, md, th);
    return 1;
}

/*
 * M_r th - gamma_r: the violation of row r at th (positive = violated). inline: called per
 * row in the polish's checks; out of line it cost ~1.5k cycles on the median M4F step.
 */
static inline chain_soft_real row_excess(const chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *th, int r)
{
    const chain_soft_real v = row_value(ws, md, th, r);
    const chain_soft_real g = ws->gam[r];
    return (md->row_sign[r] > 0) ? v - g : -v - g;
}

/* max(1, |gamma_r|): the feasibility tolerance of row r is FEAS_TOL times this. */
static inline chain_soft_real tol_scale(const chain_soft_work *ws, int r)
{
    const chain_soft_real ag = CHAIN_SOFT_FABS(ws->gam[r]);
    return (ag > R_(1.0)) ? ag : R_(1.0);
}

/* Is row r violated at th beyond its tolerance? */
static int row_violated(const chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *th, int r)
{
    return row_excess(ws, md, th, r) > CHAIN_SOFT_SOLVER_FEAS_TOL * tol_scale(ws, r);
}

/*
 * L L' +- v v' on the trailing block of the packed factor l (order n) from row and column
 * `from` on, v holding the vector's entries from..n-1 (overwritten): the rotations of the
 * classic rank-one update, hyperbolic ones for a downdate. No entry of H is read again.
 * Returns -1 when a downdated pivot keeps no more than DEPENDENCE_TOL of its square: the
 * factor is then not valid, and the caller refactors from scratch.
 */
static int chol_rank_one(chain_soft_real *l, int from, int n, chain_soft_real *v, int downdate)
{
    int i, j;
    for (j = from; j < n; ++j) {
        const chain_soft_real ljj = l[CHAIN_SOFT_TRI(j, j)], vj = v[j];
        const chain_soft_real r2 = downdate ? (ljj - vj) * (ljj + vj) : ljj * ljj + vj * vj;
        chain_soft_real r, c, s, ic;
        int off = CHAIN_SOFT_TRI(j + 1, j); /* column j below the diagonal: stride i + 1 */
        if (downdate && !(r2 > CHAIN_SOFT_SOLVER_DEPENDENCE_TOL * (ljj * ljj))) {
            return -1;
        }
        r = CHAIN_SOFT_SQRT(r2);
        c = r / ljj;
        s = vj / ljj;
        ic = ljj / r;
        l[CHAIN_SOFT_TRI(j, j)] = r;
        for (i = j + 1; i < n; ++i) {
            const chain_soft_real lij = (downdate ? l[off] - s * v[i] : l[off] + s * v[i]) * ic;
            l[off] = lij;
            v[i] = c * v[i] - s * lij;
            off += i + 1;
        }
    }
    return 0;
}

/*
 * Delete row and column k of the factored matrix (order n): the rows below k move up one,
 * dropping their entry k, and that entry (the column below the old pivot) updates the
 * trailing block by rank one. v: scratch of n entries.
 */
static void chol_delete(chain_soft_real *l, int k, int n, chain_soft_real *v)
{
    int i, j, dst = CHAIN_SOFT_TRI(k, 0), src = CHAIN_SOFT_TRI(k + 1, 0);
    for (i = k + 1; i < n; ++i) {
        for (j = 0; j <= i; ++j, ++src) {
            if (j == k) {
                v[i - 1] = l[src];
            } else {
                l[dst++] = l[src];
            }
        }
    }
    (void)chol_rank_one(l, k, n - 1, v, 0); /* an update cannot break down */
}

/*
 * Soft output bounds (rollmpc_codegen/features/soft_constraints.py): a soft row r has the slack
 * s_r = max(0, (lam_r - l1) w), w = 1/(2 l2). In the working set it is tight (s_r = 0,
 * lam_r <= l1, like a hard row) or, flagged in ws->slack_on, slack: M_r th - gamma_r = s_r,
 * which adds w to its diagonal of H_WW and l1 w to its right-hand side.
 * Returns w (0 for a hard row) and its penalty in *l1.
 */
static chain_soft_real soft_of(const chain_soft_mode_data *md, int r, chain_soft_real *l1)
{
    const int q = md->row_q[r];
    int b;
    if (q < md->n) {
        *l1 = R_(0.0);
        return R_(0.0);
    }
    b = 2 * ((q - md->n) % md->ny) + ((md->row_sign[r] > 0) ? 1 : 0);
    *l1 = md->soft_l1[b];
    return md->soft_w[b];
}

/* Slack of working-set row r with multiplier z: (z - l1) w in the slack state, else 0. */
static chain_soft_real slack_in_set(const chain_soft_work *ws, const chain_soft_mode_data *md,
    int r, chain_soft_real z)
{
    chain_soft_real l1;
    const chain_soft_real w = soft_of(md, r, &l1);
    return ws->slack_on[r] ? (z - l1) * w : R_(0.0);
}

/* State of row r joining the working set with multiplier lam: slack when lam > l1. */
static void set_state(chain_soft_work *ws, const chain_soft_mode_data *md, int r,
    chain_soft_real lam)
{
    chain_soft_real l1;
    const chain_soft_real w = soft_of(md, r, &l1);
    ws->slack_on[r] = (uint8_t)((w > R_(0.0) && lam > l1) ? 1 : 0);
}

/*
 * Switch the state of working-set position k (of nw): w joins (slack) or leaves (tight)
 * its diagonal entry of H_WW, so a kept dual factor takes a rank-one update or downdate
 * with sqrt(w) e_k (scratch ws->rhs); a downdate that breaks down leaves no valid factor.
 */
static void switch_row(chain_soft_work *ws, const chain_soft_mode_data *md, int k, int nw)
{
    const int r = ws->wset[k];
    chain_soft_real l1;
    const chain_soft_real w = soft_of(md, r, &l1);
    int i;
    ws->slack_on[r] = (uint8_t)(ws->slack_on[r] ? 0 : 1);
    if (ws->chol_holds == CHAIN_SOFT_CHOL_DUAL) {
        ws->work += rank_one_work(nw - k);
        ws->rhs[k] = CHAIN_SOFT_SQRT(w);
        for (i = k + 1; i < nw; ++i) {
            ws->rhs[i] = R_(0.0);
        }
        if (chol_rank_one(ws->chol, k, nw, ws->rhs, !ws->slack_on[r]) != 0) {
            ws->chol_holds = CHAIN_SOFT_CHOL_NONE;
        }
    }
}

/*
 * Switch the working-set rows whose multiplier crossed l1 (tight -> slack above it,
 * slack -> tight below it); returns how many switched (then solve again), or
 * OUT_OF_WORK when the budget cannot afford the next switch.
 */
static int switch_states(chain_soft_work *ws, const chain_soft_mode_data *md, int nw)
{
    int i, count = 0;
    for (i = 0; i < nw; ++i) {
        const int r = ws->wset[i];
        chain_soft_real l1;
        const chain_soft_real w = soft_of(md, r, &l1);
        if (w > R_(0.0) && (ws->slack_on[r] ? (ws->z[i] < l1) : (ws->z[i] > l1))) {
            if (!afford(ws, md, rank_one_work(nw - i))) {
                return OUT_OF_WORK;
            }
            switch_row(ws, md, i, nw);
            ++count;
        }
    }
    return count;
}

/* Is working-set row r (multiplier z) violated at th beyond its slack and tolerance? */
static int violated_in_set(const chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *th, int r, chain_soft_real z)
{
    return row_excess(ws, md, th, r) - slack_in_set(ws, md, r, z)
        > CHAIN_SOFT_SOLVER_FEAS_TOL * tol_scale(ws, r);
}

/* Slack of row r at multiplier lam: (lam - l1) w when soft and lam > l1, else 0. */
static chain_soft_real multiplier_slack(const chain_soft_mode_data *md, int r, chain_soft_real lam)
{
    chain_soft_real l1;
    const chain_soft_real w = soft_of(md, r, &l1);
    return (w > R_(0.0) && lam > l1) ? (lam - l1) * w : R_(0.0);
}

/*
 * Rows violated at ws->th beyond their slack multiplier_slack() under the sweep
 * multipliers lam (by row), for the sweeps' convergence test.
 */
static int violated_beyond_slack(chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *lam)
{
    const int outputs = outputs_to_check(ws, md, ws->th);
    int r, count = 0;
    for (r = 0; r < md->m; ++r) {
        if (outputs || md->row_q[r] < md->n) {
            const chain_soft_real sl = multiplier_slack(md, r, lam[r]);
            count += (row_excess(ws, md, ws->th, r) - sl > CHAIN_SOFT_SOLVER_FEAS_TOL * tol_scale(ws, r));
        }
    }
    return count;
}

/*
 * th = th0 - E^-1 M_L' mult over the rows L = list[0..count) with a positive multiplier.
 * The multipliers are first summed by quantity, v = M_L' mult (inputs into ws->dv, outputs
 * into ws->yv, a Δu row into its two inputs), then E^-1 v = S^-1 v_in - Ew' (Ew v_in)
 * + E^-1 G' v_out is accumulated in ws->th column by column over the nonzero entries of v
 * (Ew v_in in ws->nu): n (nnz + nt) + nt nnz_in operations, where reading E^-1 M_L' entry
 * by entry cost n |L| reads of E^-1 (nt operations each for an input, twice for a Δu row).
 */
static void correct(chain_soft_work *ws, const chain_soft_mode_data *md, const int16_t *list,
    int count, const chain_soft_real *mult, int mult_by_row)
{
    const int n = md->n, nyq = md->nyq, nt = md->nt;
    int i, j, o;
    ws->work += correct_work(md, count);
    for (i = 0; i < n; ++i) {
        ws->dv[i] = R_(0.0);
        ws->th[i] = R_(0.0);
    }
    for (i = 0; i < nyq; ++i) {
        ws->yv[i] = R_(0.0);
    }
    for (o = 0; o < nt; ++o) {
        ws->nu[o] = R_(0.0);
    }
    for (j = 0; j < count; ++j) {
        const int s = list[j], q = md->row_q[s];
        const chain_soft_real mu = mult_by_row ? mult[s] : mult[j];
        if (mu > R_(0.0)) {
            const chain_soft_real v = (md->row_sign[s] > 0) ? mu : -mu;
            if (q < n) {
                ws->dv[q] += v;
            } else {
                ws->yv[q - n] += v;
            }
        }
    }
    for (j = 0; j < n; ++j) {
        const chain_soft_real v = ws->dv[j];
        if (v < R_(0.0) || v > R_(0.0)) {
            for (i = 0; i < j; ++i) { /* S^-1 is packed lower: row j, then column j */
                ws->th[i] += md->Sinv_p[CHAIN_SOFT_TRI(j, i)] * v;
            }
            for (i = j; i < n; ++i) {
                ws->th[i] += md->Sinv_p[CHAIN_SOFT_TRI(i, j)] * v;
            }
            for (o = 0; o < nt; ++o) {
                ws->nu[o] += md->Ew[o * n + j] * v;
            }
        }
    }
    for (i = 0; i < n; ++i) {
        chain_soft_real acc = ws->th[i];
        for (o = 0; o < nt; ++o) {
            acc -= md->Ew[o * n + i] * ws->nu[o];
        }
        ws->th[i] = acc;
    }
    for (j = 0; j < nyq; ++j) {
        const chain_soft_real v = ws->yv[j];
        if (v < R_(0.0) || v > R_(0.0)) {
            for (i = 0; i < n; ++i) {
                ws->th[i] += md->EinvGt[i * nyq + j] * v;
            }
        }
    }
    for (i = 0; i < n; ++i) {
        ws->th[i] = ws->th0[i] - ws->th[i];
    }
}

/* Rebuild the sorted row list of the sweep set from the membership flags. */
static int build_set(chain_soft_work *ws, const chain_soft_mode_data *md)
{
    int r, count = 0;
    ws->work += (uint32_t)md->m;
    for (r = 0; r < md->m; ++r) {
        if (ws->in_set[r]) {
            ws->set[count++] = (int16_t)r;
        }
    }
    return count;
}

/*
 * One (SOR) Gauss-Seidel sweep of eq. (7) over the set. Returns the squared step
 * norm; sets *diverged when a multiplier exceeds CHAIN_SOFT_LAMBDA_LIMIT.
 */
static chain_soft_real sweep(chain_soft_work *ws, const chain_soft_mode_data *md,
    chain_soft_real *lam, int count, int *diverged)
{
    const chain_soft_real omega = CHAIN_SOFT_SOLVER_OMEGA;
    chain_soft_real e2 = R_(0.0);
    int jr, js;
    ws->work += sweep_work(md, count);
    for (jr = 0; jr < count; ++jr) {
        const int r = ws->set[jr];
        chain_soft_real acc = R_(0.0), t, wv, nl, d;
        for (js = 0; js < count; ++js) {
            const int s = ws->set[js];
            if (s != r && lam[s] > R_(0.0)) {
                acc += h_rows(md, r, s) * lam[s];
            }
        }
        {
            /* piecewise maximum: above l1 the slack's penalty adds w to the diagonal */
            const chain_soft_real hd = hq(md, md->row_q[r], md->row_q[r]);
            chain_soft_real l1;
            const chain_soft_real w = soft_of(md, r, &l1);
            t = -(ws->K[r] + acc) / hd;
            if (w > R_(0.0) && t > l1) {
                t = (l1 * w - (ws->K[r] + acc)) / (hd + w);
            }
        }
        wv = (R_(1.0) - omega) * lam[r] + omega * t;
        nl = (wv > R_(0.0)) ? wv : R_(0.0);
        d = nl - lam[r];
        e2 += d * d;
        lam[r] = nl;
        if (!(nl <= CHAIN_SOFT_LAMBDA_LIMIT)) {
            *diverged = 1;
        }
    }
    return e2;
}

/*
 * Rows of one kind (outputs = 0: input rows, 1: output rows) violated at th and not
 * flagged in `member` (0: no row is), appended in row order to out; cap + 1 when more
 * than cap.
 */
static int violated_kind(chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *th, const uint8_t *member, int16_t *out, int cap, int outputs)
{
    const int n = md->n;
    int r, nout = 0;
    ws->work += (uint32_t)md->m;
    for (r = 0; r < md->m; ++r) {
        const int q = md->row_q[r];
        chain_soft_real v, g, viol, ag;
        if ((q >= n) != outputs) {
            continue;
        }
        if (member != 0 && member[r]) {
            continue;
        }
        /* row_violated() inline: the tolerance is at least FEAS_TOL, so reject early */
        v = (q < n) ? th[q] : ws->yv[q - n];
        g = ws->gam[r];
        viol = (md->row_sign[r] > 0) ? v - g : -v - g;
        if (!(viol > CHAIN_SOFT_SOLVER_FEAS_TOL)) {
            continue;
        }
        ag = CHAIN_SOFT_FABS(g);
        if (viol > CHAIN_SOFT_SOLVER_FEAS_TOL * (ag > R_(1.0) ? ag : R_(1.0))) {
            if (nout == cap) {
                return cap + 1;
            }
            out[nout++] = (int16_t)r;
        }
    }
    return nout;
}

/*
 * Violated rows at th outside the flagged ones (see violated_kind()): the input rows
 * first; only when none is violated, the output rows (predicted unless certified), so an
 * intermediate point far outside the input box costs no output prediction.
 */
static int violated_outside(chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *th, const uint8_t *member, int16_t *out, int cap)
{
    const int nbox = violated_kind(ws, md, th, member, out, cap, 0);
    if (nbox != 0 || !outputs_to_check(ws, md, th)) {
        return nbox;
    }
    return violated_kind(ws, md, th, member, out, cap, 1);
}

/*
 * Primal solve, free-variable form, in the split form E = S + V'(2P)V: with d = U - th0, d_B = bounds - th0_B and nu the terminal
 * multiplier step,
 *     S_FF d_F + V_F' nu = -S_FB d_B,    V d - (2P)^-1 nu = 0,
 * solved by Cholesky of S_FF and an nt x nt Schur complement. Multipliers come from the
 * gradient g = S d + V' nu as z_k = -sign_k g_{q_k}. Nothing here forms E, whose float
 * entries cannot hold a heavy terminal weight and the stage weights at once.
 * Costs nf^3/6; primal_solve() picks it when at least half the inputs are bound.
 * Writes ws->th (free_multipliers() then gives ws->z); returns -1 if a factorisation
 * breaks down.
 */
static int primal_solve_free(chain_soft_work *ws, const chain_soft_mode_data *md, int nf)
{
    const int n = md->n, nt = md->nt;
    int i, a, c, o, p;
    for (a = 0; a < nf; ++a) {
        const int f = ws->tmp[a];
        ws->rhs[a] = -s_row_dot(md, f, ws->dv); /* dv is 0 on the free inputs here */
        for (c = 0; c <= a; ++c) {
            ws->chol[CHAIN_SOFT_TRI(a, c)] = s_at(md, f, ws->tmp[c]);
        }
        for (o = 0; o < nt; ++o) {
            ws->ycol[o * CHAIN_SOFT_N_MAX + a] = md->V[o * n + f];
        }
    }
    if (nf > 0) {
        if (chain_soft_cholesky(ws->chol, nf) != 0) {
            return -1;
        }
        chain_soft_chol_solve(ws->chol, nf, ws->rhs);
        for (o = 0; o < nt; ++o) {
            chain_soft_chol_solve(ws->chol, nf, &ws->ycol[o * CHAIN_SOFT_N_MAX]);
        }
    }
    if (nt > 0) {
        for (o = 0; o < nt; ++o) {
            chain_soft_real acc;
            for (p = 0; p <= o; ++p) {
                acc = R_(0.0);
                for (a = 0; a < nf; ++a) {
                    acc += md->V[o * n + ws->tmp[a]] * ws->ycol[p * CHAIN_SOFT_N_MAX + a];
                }
                ws->tsmall[CHAIN_SOFT_TRI(o, p)] = acc + md->P2inv[o * nt + p];
            }
            acc = R_(0.0);
            for (a = 0; a < nf; ++a) {
                acc += md->V[o * n + ws->tmp[a]] * ws->rhs[a];
            }
            for (i = 0; i < n; ++i) {
                if (ws->is_bound[i]) {
                    acc += md->V[o * n + i] * ws->dv[i];
                }
            }
            ws->nu[o] = acc;
        }
        if (chain_soft_cholesky(ws->tsmall, nt) != 0) {
            return -1;
        }
        chain_soft_chol_solve(ws->tsmall, nt, ws->nu);
    }
    for (a = 0; a < nf; ++a) {
        const int f = ws->tmp[a];
        chain_soft_real acc = ws->rhs[a];
        for (o = 0; o < nt; ++o) {
            acc -= ws->ycol[o * CHAIN_SOFT_N_MAX + a] * ws->nu[o];
        }
        ws->dv[f] = acc;
        ws->th[f] = ws->th0[f] + acc;
    }
    return 0;
}

/*
 * Multipliers of the free-form solution, z_k = -sign_k g_{q_k} with g = S d + V' nu: the
 * nw x n part of a polish step, so polish() computes them only once the bound inputs make
 * the point feasible.
 */
static void free_multipliers(chain_soft_work *ws, const chain_soft_mode_data *md, int nw)
{
    int a, o;
    for (a = 0; a < nw; ++a) {
        const int r = ws->wset[a], q = md->row_q[r];
        chain_soft_real g = s_row_dot(md, q, ws->dv);
        for (o = 0; o < md->nt; ++o) {
            g += md->V[o * md->n + q] * ws->nu[o];
        }
        ws->z[a] = (md->row_sign[r] > 0) ? -g : g;
    }
}

/*
 * The same solve through S^-1 when few inputs are bound (nb < nf): with beta = g_B (the
 * bound forces) and Uv = V S^-1, T = (2P)^-1 + V S^-1 V':
 *     beta = S^-1_BB^-1 (d_B + Uv_B' nu),   (T - Uv_B S^-1_BB^-1 Uv_B') nu = Uv_B S^-1_BB^-1 d_B,
 *     d = S^-1_{:,B} beta - Uv' nu,         z_k = -sign_k beta_k.
 * Costs nb^3/6 + n nb instead of nf^3/6. ws->tmp holds the bound inputs in working-set
 * order, which is not ascending when a stage has several inputs.
 */
static int primal_solve_bound(chain_soft_work *ws, const chain_soft_mode_data *md, int nw)
{
    const int n = md->n, nt = md->nt;
    int i, a, c, o, p;
    for (a = 0; a < nw; ++a) {
        const int qa = ws->tmp[a];
        for (c = 0; c <= a; ++c) {
            const int qc = ws->tmp[c]; /* S^-1 is packed lower: read (max, min) */
            ws->chol[CHAIN_SOFT_TRI(a, c)] = (qa >= qc) ? md->Sinv_p[CHAIN_SOFT_TRI(qa, qc)]
                                                         : md->Sinv_p[CHAIN_SOFT_TRI(qc, qa)];
        }
        ws->rhs[a] = ws->dv[qa];
        for (o = 0; o < nt; ++o) {
            ws->ycol[o * CHAIN_SOFT_N_MAX + a] = md->Uv[o * n + qa];
        }
    }
    if (chain_soft_cholesky(ws->chol, nw) != 0) {
        return -1;
    }
    chain_soft_chol_solve(ws->chol, nw, ws->rhs);
    for (o = 0; o < nt; ++o) {
        chain_soft_chol_solve(ws->chol, nw, &ws->ycol[o * CHAIN_SOFT_N_MAX]);
    }
    if (nt > 0) {
        for (o = 0; o < nt; ++o) {
            chain_soft_real acc;
            for (p = 0; p <= o; ++p) {
                acc = R_(0.0);
                for (a = 0; a < nw; ++a) {
                    acc += md->Uv[o * n + ws->tmp[a]] * ws->ycol[p * CHAIN_SOFT_N_MAX + a];
                }
                ws->tsmall[CHAIN_SOFT_TRI(o, p)] = md->T[o * nt + p] - acc;
            }
            acc = R_(0.0);
            for (a = 0; a < nw; ++a) {
                acc += md->Uv[o * n + ws->tmp[a]] * ws->rhs[a];
            }
            ws->nu[o] = acc;
        }
        if (chain_soft_cholesky(ws->tsmall, nt) != 0) {
            return -1;
        }
        chain_soft_chol_solve(ws->tsmall, nt, ws->nu);
    }
    for (a = 0; a < nw; ++a) { /* beta = x1 + Y nu, kept in rhs */
        chain_soft_real acc = ws->rhs[a];
        for (o = 0; o < nt; ++o) {
            acc += ws->ycol[o * CHAIN_SOFT_N_MAX + a] * ws->nu[o];
        }
        ws->rhs[a] = acc;
        ws->z[a] = (md->row_sign[ws->wset[a]] > 0) ? -acc : acc;
    }
    for (i = 0; i < n; ++i) {
        if (!ws->is_bound[i]) {
            chain_soft_real acc = R_(0.0);
            for (a = 0; a < nw; ++a) {
                const int q = ws->tmp[a];
                acc += ((i >= q) ? md->Sinv_p[CHAIN_SOFT_TRI(i, q)] : md->Sinv_p[CHAIN_SOFT_TRI(q, i)]) * ws->rhs[a];
            }
            for (o = 0; o < nt; ++o) {
                acc -= md->Uv[o * n + i] * ws->nu[o];
            }
            ws->th[i] = ws->th0[i] + acc;
        }
    }
    return 0;
}

/*
 * Primal solve on a working set of input-bound rows only (wset[0..nw), at most one row
 * per input): U_B at the bounds, d_B = U_B - th0_B, then the cheaper of the two forms.
 * Writes ws->th; returns 1 when ws->z is written too (bound form), 0 when it is left to
 * free_multipliers() (free form), -1 if a factorisation breaks down.
 */
static int primal_solve(chain_soft_work *ws, const chain_soft_mode_data *md, int nw)
{
    const int n = md->n;
    int i, nf = 0;
    ws->chol_holds = CHAIN_SOFT_CHOL_NONE; /* ws->chol is about to hold a primal factor */
    for (i = 0; i < n; ++i) {
        ws->is_bound[i] = 0;
        ws->dv[i] = R_(0.0);
    }
    for (i = 0; i < nw; ++i) {
        const int r = ws->wset[i], q = md->row_q[r];
        if (ws->is_bound[q]) {
            return -1; /* both bounds of one input: not a valid working set */
        }
        ws->is_bound[q] = 1;
        ws->th[q] = (md->row_sign[r] > 0) ? md->row_c[r] : -md->row_c[r];
        ws->dv[q] = ws->th[q] - ws->th0[q];
    }
    if (nw < n - nw) {
        for (i = 0; i < nw; ++i) {
            ws->tmp[i] = md->row_q[ws->wset[i]];
        }
        return (primal_solve_bound(ws, md, nw) == 0) ? 1 : -1;
    }
    for (i = 0; i < n; ++i) {
        if (!ws->is_bound[i]) {
            ws->tmp[nf++] = (int16_t)i;
        }
    }
    return primal_solve_free(ws, md, nf);
}

/*
 * L = chol(H_WW) for W = wset[0..nw) (plus w on the diagonal of slack soft rows) into
 * ws->chol, from scratch: the fallback whenever the kept factor may not be valid. Sets
 * ws->chol_holds; -1 if a pivot breaks down.
 */
static int factor_working_set(chain_soft_work *ws, const chain_soft_mode_data *md, int nw)
{
    int i, j;
    ws->work += factor_work(md, nw);
    for (i = 0; i < nw; ++i) {
        for (j = 0; j <= i; ++j) {
            ws->chol[CHAIN_SOFT_TRI(i, j)] = h_rows(md, ws->wset[i], ws->wset[j]);
        }
        if (ws->slack_on[ws->wset[i]]) {
            chain_soft_real l1;
            ws->chol[CHAIN_SOFT_TRI(i, i)] += soft_of(md, ws->wset[i], &l1);
        }
    }
    if (chain_soft_cholesky_from(ws->chol, 0, nw) != 0) {
        ws->chol_holds = CHAIN_SOFT_CHOL_NONE;
        return -1;
    }
    ws->chol_holds = CHAIN_SOFT_CHOL_DUAL;
    return 0;
}

/*
 * y = L^-1 H_Wp in place on ws->rhs (holding H_Wp on entry), and the pivot hpp - y'y that
 * row p would have in the factor of W + p (hpp: its diagonal entry).
 */
static chain_soft_real factor_pivot(chain_soft_work *ws, int nw, chain_soft_real hpp)
{
    int i;
    chain_soft_real zeta = hpp;
    ws->work += tri_work(nw) + (uint32_t)nw;
    chain_soft_chol_lsolve(ws->chol, nw, ws->rhs);
    for (i = 0; i < nw; ++i) {
        zeta -= ws->rhs[i] * ws->rhs[i];
    }
    return zeta;
}

/* Row nw of the factor: y = L^-1 H_Wp from ws->rhs and the pivot sqrt(zeta). */
static void factor_append(chain_soft_work *ws, int nw, chain_soft_real zeta)
{
    int i;
    for (i = 0; i < nw; ++i) {
        ws->chol[CHAIN_SOFT_TRI(nw, i)] = ws->rhs[i];
    }
    ws->chol[CHAIN_SOFT_TRI(nw, nw)] = CHAIN_SOFT_SQRT(zeta);
}

/*
 * Row p joins the working set at position nw, tight. A kept dual factor gains its row
 * (one forward solve with H_Wp) unless its pivot is below the dependence tolerance; then
 * the next dual solve refactors from scratch.
 */
static void append_row(chain_soft_work *ws, const chain_soft_mode_data *md, int p, int nw)
{
    int i;
    ws->wset[nw] = (int16_t)p;
    ws->in_set[p] = 1;
    ws->slack_on[p] = 0;
    if (ws->chol_holds == CHAIN_SOFT_CHOL_DUAL) {
        const chain_soft_real hpp = hq(md, md->row_q[p], md->row_q[p]);
        chain_soft_real zeta;
        ws->work += ((uint32_t)nw + 1u) * hq_work(md);
        for (i = 0; i < nw; ++i) {
            ws->rhs[i] = h_rows(md, ws->wset[i], p);
        }
        zeta = factor_pivot(ws, nw, hpp);
        if (zeta > CHAIN_SOFT_SOLVER_DEPENDENCE_TOL * hpp) {
            factor_append(ws, nw, zeta);
        } else {
            ws->chol_holds = CHAIN_SOFT_CHOL_NONE;
        }
    }
}

/*
 * Working-set position k leaves (wset and z shift down); a kept dual factor loses its row
 * and column by a rank-one update of the rows below (chol_delete(), scratch ws->rhs).
 */
static void remove_row(chain_soft_work *ws, int k, int *nw)
{
    int i;
    ws->in_set[ws->wset[k]] = 0;
    ws->slack_on[ws->wset[k]] = 0;
    if (ws->chol_holds == CHAIN_SOFT_CHOL_DUAL) {
        ws->work += delete_work(k, *nw);
        chol_delete(ws->chol, k, *nw, ws->rhs);
    }
    for (i = k; i + 1 < *nw; ++i) {
        ws->wset[i] = ws->wset[i + 1];
        ws->z[i] = ws->z[i + 1];
    }
    --*nw;
}

/*
 * Dual solve on a general working set: z = -H_WW^-1 K_W, th = th0 - E^-1 M_W' z, with the
 * kept factor when ws->chol holds it, else factored from scratch. Returns 0, -1 if the
 * factorisation breaks down, or OUT_OF_WORK.
 */
static int dual_solve(chain_soft_work *ws, const chain_soft_mode_data *md, int nw)
{
    int i;
    const uint32_t need = (ws->out_slacks_ok ? 0u : (uint32_t)md->m + predict_work(md))
        + ((ws->chol_holds == CHAIN_SOFT_CHOL_DUAL) ? 0u : factor_work(md, nw)) + 2u * tri_work(nw);
    if (!afford(ws, md, need)) {
        return OUT_OF_WORK;
    }
    output_slacks(ws, md);
    for (i = 0; i < nw; ++i) {
        ws->z[i] = -ws->K[ws->wset[i]];
        if (ws->slack_on[ws->wset[i]]) {
            chain_soft_real l1;
            const chain_soft_real w = soft_of(md, ws->wset[i], &l1);
            ws->z[i] += l1 * w;
        }
    }
    if (ws->chol_holds != CHAIN_SOFT_CHOL_DUAL && factor_working_set(ws, md, nw) != 0) {
        return -1;
    }
    ws->work += 2u * tri_work(nw);
    chain_soft_chol_solve(ws->chol, nw, ws->z);
    return 0;
}

/* Working set from the rows with positive multipliers among list[0..count); -1 if > n. */
static int seed_from_multipliers(chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *lam, const int16_t *list, int count)
{
    int j, nw = 0;
    ws->chol_holds = CHAIN_SOFT_CHOL_NONE; /* a new working set: no factor of it yet */
    ws->work += (uint32_t)count;
    for (j = 0; j < count; ++j) {
        const int r = list ? list[j] : j;
        if (lam[r] > R_(0.0)) {
            if (nw == md->w_cap) {
                return -1;
            }
            set_state(ws, md, r, lam[r]);
            ws->wset[nw++] = (int16_t)r;
        }
    }
    return nw;
}

/*
 * Working set from the previous active set (optimal, or where a TIME_LIMIT stopped)
 * shifted one stage along the horizon (row r joins when its next-stage row was active):
 * the receding-horizon guess; -1 if more than the working set holds.
 */
static int seed_shifted(chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *lam)
{
    int r, nw = 0;
    ws->chol_holds = CHAIN_SOFT_CHOL_NONE;
    ws->work += (uint32_t)md->m;
    for (r = 0; r < md->m; ++r) {
        if (lam[md->row_next[r]] > R_(0.0)) {
            if (nw == md->w_cap) {
                return -1;
            }
            set_state(ws, md, r, lam[md->row_next[r]]);
            ws->wset[nw++] = (int16_t)r;
        }
    }
    return nw;
}

/* Working set from the rows violated by the unconstrained solution (K < 0); -1 if > n. */
static int seed_from_violated(chain_soft_work *ws, const chain_soft_mode_data *md)
{
    int r, nw = 0;
    ws->chol_holds = CHAIN_SOFT_CHOL_NONE;
    ws->work += (uint32_t)md->m;
    for (r = 0; r < md->m; ++r) {
        if ((ws->out_slacks_ok || md->row_q[r] < md->n) && ws->K[r] < R_(0.0)) {
            if (nw == md->w_cap) {
                return -1;
            }
            ws->slack_on[r] = 0;
            ws->wset[nw++] = (int16_t)r;
        }
    }
    return nw;
}

/*
 * Drop the working-set rows with negative multipliers (remove_row(), from the last
 * position down). Returns 0 if none was dropped, 1 if some were (solve again), -1 if the
 * working set is to be given up: emptied, or a guess (see polish()) that would lose more
 * than half of its rows; OUT_OF_WORK if the budget cannot afford the deletions.
 */
static int drop_negative(chain_soft_work *ws, const chain_soft_mode_data *md, int *nw, int guess)
{
    int i, keep = 0;
    for (i = 0; i < *nw; ++i) {
        keep += (ws->z[i] >= R_(0.0));
    }
    if (keep == *nw) {
        return 0;
    }
    if (keep == 0 || (guess && 2 * keep < *nw)) {
        return -1;
    }
    if (ws->chol_holds == CHAIN_SOFT_CHOL_DUAL
        && !afford(ws, md, ((uint32_t)*nw - (uint32_t)keep) * delete_work(0, *nw))) {
        return OUT_OF_WORK;
    }
    for (i = *nw - 1; i >= 0; --i) {
        if (!(ws->z[i] >= R_(0.0))) {
            remove_row(ws, i, nw);
        }
    }
    return 1;
}

/* Are the working-set rows all input bounds (the primal form's working sets)? */
static int box_only(const chain_soft_work *ws, const chain_soft_mode_data *md, int nw)
{
    int i, box = 1;
    for (i = 0; i < nw; ++i) {
        box = box && md->row_q[ws->wset[i]] < md->n;
    }
    return box;
}

/* Do the working-set rows hold (within the feasibility tolerance) at ws->th? */
static int working_set_holds(chain_soft_work *ws, const chain_soft_mode_data *md, int nw)
{
    int i;
    const int outputs = outputs_to_check(ws, md, ws->th);
    for (i = 0; i < nw; ++i) {
        const int r = ws->wset[i];
        if ((outputs || md->row_q[r] < md->n) && violated_in_set(ws, md, ws->th, r, ws->z[i])) {
            return 0;
        }
    }
    return 1;
}

/*
 * Iterative refinement of a dual solve whose point misses its own working set: with
 * multipliers ~1e9 (float), th = th0 - E^-1 M_W' z cancels most digits. The residual
 * e = M_W th - gamma_W is small, so z += H_WW^-1 e (ws->chol holds the factor) and
 * a new th lose far fewer. Up to two rounds; 0 once the working set holds, no multiplier
 * is negative and no other row is violated, else -1 (or OUT_OF_WORK).
 */
static int refine_dual(chain_soft_work *ws, const chain_soft_mode_data *md, int nw)
{
    int round, i;
    if (!afford(ws, md, 2u * (2u * tri_work(nw) + correct_work(md, nw) + 2u * scan_work(md))
                        + (uint32_t)md->m)) {
        return OUT_OF_WORK;
    }
    for (round = 0; round < 2; ++round) {
        int negative = 0;
        if (md->GEinvGt_p != 0) {
            predict_outputs(ws, md, ws->th);
        }
        for (i = 0; i < nw; ++i) {
            ws->rhs[i] = row_excess(ws, md, ws->th, ws->wset[i]);
            ws->rhs[i] -= slack_in_set(ws, md, ws->wset[i], ws->z[i]);
        }
        ws->work += 2u * tri_work(nw);
        chain_soft_chol_solve(ws->chol, nw, ws->rhs);
        for (i = 0; i < nw; ++i) {
            ws->z[i] += ws->rhs[i];
            negative += (ws->z[i] < R_(0.0));
        }
        if (negative != 0) {
            return -1; /* a sign changed: not this working set's point */
        }
        i = switch_states(ws, md, nw);
        if (i != 0) {
            return (i == OUT_OF_WORK) ? OUT_OF_WORK : -1; /* a slack state changed */
        }
        correct(ws, md, ws->wset, nw, ws->z, 0);
        if (working_set_holds(ws, md, nw)) {
            return (violated_outside(ws, md, ws->th, ws->in_set, ws->tmp, 0) == 0) ? 0 : -1;
        }
    }
    return -1;
}

/* lam = the working set's multipliers, 0 elsewhere: the next sample's warm start. */
static void keep_working_set(const chain_soft_work *ws, const chain_soft_mode_data *md,
    chain_soft_real *lam, int nw)
{
    int i;
    for (i = 0; i < md->m; ++i) {
        lam[i] = R_(0.0);
    }
    for (i = 0; i < nw; ++i) {
        lam[ws->wset[i]] = ws->z[i];
    }
}

/* The polish converged: the working set and its multipliers become the warm start. */
static int accept(chain_soft_work *ws, const chain_soft_mode_data *md, chain_soft_real *lam,
    int nw, int *active)
{
    ws->work += (uint32_t)md->m;
    keep_working_set(ws, md, lam, nw);
    *active = nw;
    return 0;
}

/*
 * Where polish() stopped when the budget ran out (code OUT_OF_WORK): its working set
 * wset[0..nw), the first `known` of them with their multipliers in z. Returns code.
 */
static int stopped(chain_soft_work *ws, int nw, int known, int code)
{
    if (code == OUT_OF_WORK) {
        ws->stop_rows = nw;
        ws->stop_known = known;
    }
    return code;
}

/*
 * A TIME_LIMIT in polish(): lam keeps the working set where it stopped as the next
 * sample's warm start, closer than the one it started from: the rows with a positive
 * multiplier among those solved for, and the rows that joined since with a token one
 * (they joined tight).
 */
static void keep_progress(chain_soft_work *ws, const chain_soft_mode_data *md,
    chain_soft_real *lam)
{
    int i;
    for (i = 0; i < ws->stop_rows; ++i) {
        ws->z[i] = (i >= ws->stop_known) ? R_(1.0e-30) : ((ws->z[i] > R_(0.0)) ? ws->z[i] : R_(0.0));
    }
    keep_working_set(ws, md, lam, ws->stop_rows);
}

/*
 * Exact solve on the working set W = wset[0..nw), primal when W holds only input bounds,
 * dual otherwise; violated rows join (appended: wset is in joining order), rows with
 * negative multipliers leave, repeat (the primal form adds violated rows before it
 * computes multipliers). The dual form keeps its factor of H_WW across the corrections
 * (and takes the one dual_active_set() hands over): rows join and leave it by updates.
 * A guessed working set (guess = 1: the shifted warm start) is abandoned as soon as more
 * than half of it has negative multipliers: the operating point moved, and the caller's
 * next seed is cheaper than unwinding it row block by row block. Returns 0 with ws->th
 * optimal and lam set to the exact multipliers, -1 (lam untouched), or OUT_OF_WORK when
 * the budget cannot afford the next step (where: stopped()).
 */
static int polish(chain_soft_work *ws, const chain_soft_mode_data *md, chain_soft_real *lam,
    int nw, int guess, int *iterations, int *active)
{
    int i, it, code, known = 0; /* known: the first wset rows whose z is their multiplier */
    if (nw <= 0 || nw > md->w_cap) {
        return -1;
    }
    if (!afford(ws, md, (uint32_t)md->m)) {
        return stopped(ws, nw, 0, OUT_OF_WORK);
    }
    ws->work += (uint32_t)md->m;
    for (i = 0; i < md->m; ++i) {
        ws->in_set[i] = 0; /* in_set flags the working set from here on */
    }
    for (i = 0; i < nw; ++i) {
        ws->in_set[ws->wset[i]] = 1;
    }
    for (it = 0; it < CHAIN_SOFT_SOLVER_POLISH_MAX; ++it) {
        int nadd;
        ++*iterations;
        if (box_only(ws, md, nw)) {
            /* primal: bound rows first; the multipliers only at a feasible point */
            if (!afford(ws, md, primal_work(md, nw) + scan_work(md) + (uint32_t)md->m)) {
                return stopped(ws, nw, known, OUT_OF_WORK);
            }
            ws->work += primal_work(md, nw);
            code = primal_solve(ws, md, nw);
            if (code < 0) {
                return -1;
            }
            known = (code == 1) ? nw : 0;
            nadd = violated_outside(ws, md, ws->th, ws->in_set, ws->tmp, md->w_cap - nw);
            if (nadd == 0) {
                if (code == 0) {
                    free_multipliers(ws, md, nw);
                }
                known = nw;
                code = drop_negative(ws, md, &nw, guess);
                if (code != 0) {
                    if (code < 0) {
                        return stopped(ws, nw, known, code);
                    }
                    known = nw;
                    continue;
                }
                return accept(ws, md, lam, nw, active);
            }
        } else {
            code = dual_solve(ws, md, nw);
            if (code != 0) {
                return stopped(ws, nw, known, code);
            }
            known = nw;
            code = switch_states(ws, md, nw);
            if (code != 0) {
                if (code < 0) {
                    return stopped(ws, nw, known, code);
                }
                continue;
            }
            code = drop_negative(ws, md, &nw, guess);
            if (code != 0) {
                if (code < 0) {
                    return stopped(ws, nw, known, code);
                }
                known = nw;
                continue;
            }
            if (!afford(ws, md, correct_work(md, nw) + 2u * scan_work(md) + (uint32_t)md->m)) {
                return stopped(ws, nw, known, OUT_OF_WORK);
            }
            correct(ws, md, ws->wset, nw, ws->z, 0);
            nadd = violated_outside(ws, md, ws->th, ws->in_set, ws->tmp, md->w_cap - nw);
            if (nadd == 0) {
                /* a (near-)singular H_WW, e.g. parallel rows of an infeasible QP, can give
                 * multipliers whose point misses its own working set: not optimal */
                code = working_set_holds(ws, md, nw) ? 0 : refine_dual(ws, md, nw);
                return (code == 0) ? accept(ws, md, lam, nw, active) : stopped(ws, nw, known, code);
            }
        }
        if (nadd > md->w_cap - nw) {
            return -1;
        }
        if (ws->chol_holds == CHAIN_SOFT_CHOL_DUAL
            && !afford(ws, md, (uint32_t)nadd * append_work(md, nw + nadd))) {
            return stopped(ws, nw, known, OUT_OF_WORK);
        }
        for (i = 0; i < nadd; ++i) {
            append_row(ws, md, ws->tmp[i], nw++);
        }
    }
    return -1;
}

/* rows added per scan of every row: the scan and the corrected point are paid once for
 * them, each checked again (in dual terms) before it joins */
#define ADD_BATCH 4
/*
 * The rows most violated at th (violation relative to max(1, |gamma_r|)) among the rows
 * not in the working set (in_set flags), at most ADD_BATCH of them, most violated first
 * (the lower row first among equals), into ws->tmp; returns how many (0: none is
 * violated beyond the tolerance).
 */
static int most_violated(chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *th)
{
    const int outputs = outputs_to_check(ws, md, th);
    chain_soft_real worst[ADD_BATCH];
    int r, j, count = 0;
    ws->work += 2u * (uint32_t)md->m;
    for (r = 0; r < md->m; ++r) {
        if (!ws->in_set[r] && (outputs || md->row_q[r] < md->n)) {
            const chain_soft_real viol = row_excess(ws, md, th, r);
            const chain_soft_real scale = tol_scale(ws, r);
            if (viol > CHAIN_SOFT_SOLVER_FEAS_TOL * scale) {
                const chain_soft_real rel = viol / scale;
                for (j = count; j > 0 && rel > worst[j - 1]; --j) {
                    if (j < ADD_BATCH) {
                        worst[j] = worst[j - 1];
                        ws->tmp[j] = ws->tmp[j - 1];
                    }
                }
                if (j < ADD_BATCH) {
                    worst[j] = rel;
                    ws->tmp[j] = (int16_t)r;
                    count += (count < ADD_BATCH);
                }
            }
        }
    }
    return count;
}

/*
 * Make the violated row p active (Goldfarb-Idnani): raise its multiplier t while the
 * working-set rows stay tight, their multipliers moving by -t H_WW^-1 H_Wp. A row whose
 * multiplier reaches 0 first leaves the set and the step repeats; once p's violation
 * reaches 0 it joins. A row p dependent on the set (zeta = H_pp - H_pW H_WW^-1 H_Wp ~ 0)
 * can only move the others; if none can move, the QP is infeasible (Farkas). The factor
 * L = chol(H_WW) is kept by updates: p appends its row, a leaving row is deleted.
 * Soft rows switch state where their multiplier crosses l1 (a breakpoint of the step,
 * like a row leaving): a tight row rising to l1 turns slack, a slack row falling to l1
 * turns tight; p itself turns slack at l1, after which its slack absorbs part of its
 * violation (w joins zeta), so a soft p is never dependent.
 * With `recheck` (p was chosen at an earlier point), p is skipped unless its violation
 * -K_p - H_pW z is still beyond the tolerance. Returns 0 when p joined, 2 when skipped, 1
 * for infeasible, -1 on the step cap or a breakdown, or OUT_OF_WORK before a step the
 * budget cannot afford (z has moved, p not joined).
 */
static int add_to_set(chain_soft_work *ws, const chain_soft_mode_data *md, int p, int recheck,
    int *nw, int *steps)
{
    const chain_soft_real hpp = hq(md, md->row_q[p], md->row_q[p]);
    chain_soft_real lp = R_(0.0);
    chain_soft_real l1p;
    const chain_soft_real wp = soft_of(md, p, &l1p);
    int p_on = 0; /* p's multiplier passed l1: its slack grows with it */
    int i;
    if (!afford(ws, md, ((uint32_t)*nw + 1u) * hq_work(md))) {
        return OUT_OF_WORK;
    }
    ws->work += ((uint32_t)*nw + 1u) * hq_work(md);
    for (i = 0; i < *nw; ++i) { /* H_Wp, read once for every step of this add */
        ws->hcol[i] = h_rows(md, ws->wset[i], p);
    }
    if (recheck) { /* chosen at an earlier point: still violated at this one? */
        chain_soft_real viol = -ws->K[p];
        for (i = 0; i < *nw; ++i) {
            viol -= ws->hcol[i] * ws->z[i];
        }
        if (!(viol > CHAIN_SOFT_SOLVER_FEAS_TOL * tol_scale(ws, p))) {
            return 2;
        }
    }
    for (;;) {
        chain_soft_real zeta, viol = -ws->K[p] - hpp * lp, tblock = R_(0.0), t;
        int k = -1, dependent;
        int event = 0; /* at tblock: 0 row k leaves, 1 row k switches state, 2 p turns slack */
        if (++*steps > CHAIN_SOFT_SOLVER_ACTIVE_SET_MAX) {
            return -1;
        }
        if (!afford(ws, md, add_step_work(*nw))) {
            return OUT_OF_WORK;
        }
        ws->work += tri_work(*nw) + 4u * (uint32_t)*nw;
        for (i = 0; i < *nw; ++i) { /* y = L^-1 H_Wp (rhs), d = L'^-1 y (dv) */
            ws->rhs[i] = ws->hcol[i];
            viol -= ws->rhs[i] * ws->z[i];
        }
        zeta = factor_pivot(ws, *nw, hpp);
        for (i = 0; i < *nw; ++i) {
            ws->dv[i] = ws->rhs[i];
        }
        chain_soft_chol_ltsolve(ws->chol, *nw, ws->dv);
        for (i = 0; i < *nw; ++i) { /* first multiplier to reach 0 or to cross l1 */
            const int r = ws->wset[i];
            chain_soft_real l1, ratio = R_(-1.0);
            const chain_soft_real w = soft_of(md, r, &l1);
            int ev = 0;
            if (ws->dv[i] > R_(0.0)) { /* z_i falls: a slack row to l1, a tight row to 0 */
                ev = ws->slack_on[r];
                ratio = (ev ? ws->z[i] - l1 : ws->z[i]) / ws->dv[i];
            } else if (ws->dv[i] < R_(0.0) && w > R_(0.0) && !ws->slack_on[r]) {
                ev = 1; /* a tight soft row rises to l1 */
                ratio = (l1 - ws->z[i]) / -ws->dv[i];
            }
            if (ws->dv[i] > R_(0.0) || ev) {
                ratio = (ratio > R_(0.0)) ? ratio : R_(0.0);
                if (k < 0 || ratio < tblock) {
                    k = i;
                    tblock = ratio;
                    event = ev;
                }
            }
        }
        if (p_on) {
            zeta += wp; /* the slack takes wp of every unit of p's multiplier */
            viol -= (lp - l1p) * wp;
        } else if (wp > R_(0.0)) {
            const chain_soft_real tp = (l1p > lp) ? l1p - lp : R_(0.0);
            if (k < 0 || tp < tblock) {
                k = *nw; /* no row: p's multiplier reaches l1 */
                tblock = tp;
                event = 2;
            }
        }
        dependent = *nw == md->w_cap || !(zeta > CHAIN_SOFT_SOLVER_DEPENDENCE_TOL * hpp);
        if (dependent && k < 0) {
            return 1;
        }
        t = dependent ? tblock : viol / zeta;
        if (!dependent) {
            if (k >= 0 && tblock < t) {
                t = tblock;
            } else {
                k = -1; /* the full step: p becomes tight */
            }
        }
        for (i = 0; i < *nw; ++i) {
            ws->z[i] -= t * ws->dv[i];
        }
        lp += t;
        if (k < 0) {
            factor_append(ws, *nw, zeta);
            ws->wset[*nw] = (int16_t)p;
            ws->z[*nw] = lp;
            ws->in_set[p] = 1;
            ws->slack_on[p] = (uint8_t)p_on;
            ++*nw;
            return 0;
        }
        if (event == 2) {
            p_on = 1;
            continue;
        }
        if (event == 1) { /* row k's diagonal gains or loses w: update, else refactor */
            switch_row(ws, md, k, *nw);
            if (ws->chol_holds != CHAIN_SOFT_CHOL_DUAL) {
                if (!afford(ws, md, factor_work(md, *nw))) {
                    return OUT_OF_WORK;
                }
                if (factor_working_set(ws, md, *nw) != 0) {
                    return -1;
                }
            }
            continue;
        }
        remove_row(ws, k, nw);
        for (i = k; i < *nw; ++i) {
            ws->hcol[i] = ws->hcol[i + 1];
        }
    }
}

/*
 * The warm start of dual_active_set(): the working set where the shifted guess' polish
 * stopped (wset[0..from), its factor as ws->chol_holds says), or with from < 0 the
 * previous working set shifted one stage (seed_shifted(): optimal, or where a TIME_LIMIT
 * stopped), made dual feasible by solving on it, switching the soft states whose
 * multipliers cross l1 and dropping the rows with negative multipliers until none is;
 * ws->th is then its point. Returns its size (0: no seed, or it broke down or emptied:
 * start cold) or OUT_OF_WORK (where: stopped()).
 */
static int resume_working_set(chain_soft_work *ws, const chain_soft_mode_data *md,
    const chain_soft_real *lam, int from, int *steps)
{
    int i, round, code, nw = (from >= 0) ? from : seed_shifted(ws, md, lam);
    for (i = 0; i < nw; ++i) {
        ws->in_set[ws->wset[i]] = 1;
    }
    for (round = 0; nw > 0 && round < CHAIN_SOFT_SOLVER_POLISH_MAX; ++round) {
        int known;
        ++*steps;
        code = dual_solve(ws, md, nw);
        known = (code == 0) ? nw : 0;
        code = (code == 0) ? switch_states(ws, md, nw) : code;
        code = (code == 0) ? drop_negative(ws, md, &nw, 0) : code;
        if (code == OUT_OF_WORK) {
            return stopped(ws, nw, known, OUT_OF_WORK);
        }
        if (code == 0) {
            if (!afford(ws, md, correct_work(md, nw))) {
                return stopped(ws, nw, nw, OUT_OF_WORK);
            }
            correct(ws, md, ws->wset, nw, ws->z, 0);
            return nw;
        }
        if (code < 0) {
            break;
        }
    }
    for (i = 0; i < nw; ++i) { /* start cold */
        ws->in_set[ws->wset[i]] = 0;
        ws->slack_on[ws->wset[i]] = 0;
    }
    ws->chol_holds = CHAIN_SOFT_CHOL_DUAL; /* the factor of the empty working set */
    return 0;
}

/*
 * Dual active-set solve (Goldfarb-Idnani) from the warm start (resume_working_set(), from
 * where the shifted guess stopped if from >= 0) or the unconstrained optimum: add the
 * most violated rows until none is, keeping the multipliers
 * >= 0 and the working set linearly independent, so it finishes where the polish fails
 * (dependent active sets, working sets the shifted guess and the violated rows do not
 * reach). Its working set then goes to polish() for the exact solve and KKT check -- also
 * after a claim of infeasibility, because far from the origin (multipliers ~1e9 in float)
 * th = th0 - E^-1 M' z loses the digits the primal form keeps; with it goes the factor of
 * H_WW, which the polish keeps, and lam takes its multipliers (the next sample's warm
 * start if the budget runs out). Returns 0 (optimal, as polish()), 1 (infeasible: ws->th
 * is then th0), -1 (step cap, breakdown, or the polish rejects the set) or OUT_OF_WORK
 * (ws->th the last point reached, lam its working set).
 */
static int dual_active_set(chain_soft_work *ws, const chain_soft_mode_data *md,
    chain_soft_real *lam, int from, int *iterations, int *active)
{
    int i, nw = 0, steps = 0, code = 0;
    for (i = 0; i < md->n; ++i) {
        ws->th[i] = ws->th0[i]; /* the command until the dual active set has a point */
    }
    if (!afford(ws, md, (ws->out_slacks_ok ? 0u : (uint32_t)md->m + predict_work(md))
                        + 2u * (uint32_t)md->m)) {
        if (from >= 0) {
            keep_progress(ws, md, lam); /* where the shifted guess stopped */
        }
        return OUT_OF_WORK;
    }
    output_slacks(ws, md);
    ws->work += (uint32_t)md->m;
    for (i = 0; i < md->m; ++i) {
        ws->in_set[i] = 0;
        ws->slack_on[i] = (from >= 0) ? ws->slack_on[i] : 0; /* the guess' states stay */
    }
    if (from < 0) {
        ws->chol_holds = CHAIN_SOFT_CHOL_DUAL; /* the factor of the empty working set */
    }
    if (from >= 0 || CHAIN_SOFT_SOLVER_WARM_START) {
        nw = resume_working_set(ws, md, lam, from, &steps);
        if (nw == OUT_OF_WORK) { /* lam: the warm start as far as it got */
            keep_progress(ws, md, lam);
            *iterations += steps;
            return OUT_OF_WORK;
        }
    }
    for (;;) {
        int p, c;
        if (!afford(ws, md, scan_work(md) + (uint32_t)md->m)) {
            code = OUT_OF_WORK;
            break;
        }
        p = most_violated(ws, md, ws->th);
        if (p == 0) {
            break;
        }
        for (c = 0; c < p && code == 0; ++c) { /* 2: no longer violated, skipped */
            code = add_to_set(ws, md, ws->tmp[c], c > 0, &nw, &steps);
            code = (code == 2) ? 0 : code;
        }
        if (code != 0) {
            break;
        }
        if (!afford(ws, md, correct_work(md, nw))) {
            code = OUT_OF_WORK;
            break;
        }
        correct(ws, md, ws->wset, nw, ws->z, 0);
    }
    *iterations += steps;
    if (nw == 0 && code != OUT_OF_WORK) { /* code 0: violations of th0 within the tolerance only */
        return (code == 0) ? accept(ws, md, lam, 0, active) : code;
    }
    /* the next sample's warm start, until polish() replaces it (its cost is part of the
     * finish() every check reserves: finish() then leaves lam as it is) */
    keep_working_set(ws, md, lam, nw);
    i = (code == OUT_OF_WORK) ? OUT_OF_WORK : polish(ws, md, lam, nw, 0, iterations, active);
    if (i == OUT_OF_WORK) {
        *active = nw;
    }
    if (i == 0 || i == OUT_OF_WORK) {
        return i;
    }
    if (code == 1) {
        for (i = 0; i < md->n; ++i) {
            ws->th[i] = ws->th0[i];
        }
    }
    return (code == 1) ? 1 : -1;
}

/*
 * Clamp th into the input bounds (or fall back) and write U; returns the final status.
 * Only OPTIMAL and TIME_LIMIT keep lam: the exact multipliers, or the working set a
 * TIME_LIMIT reached, which the next sample continues from.
 */
static int finish(chain_soft_work *ws, const chain_soft_mode_data *md, chain_soft_real *lam,
    int status, chain_soft_real *U)
{
    const chain_soft_real *src = ws->th;
    int i, th_ok = 1, th0_ok = 1;
    ws->work += finish_work(md);
    for (i = 0; i < md->n; ++i) {
        th_ok = th_ok && isfinite(ws->th[i]);
        th0_ok = th0_ok && isfinite(ws->th0[i]);
    }
    if (!th_ok) {
        status = CHAIN_SOFT_NUMERICAL;
        src = th0_ok ? ws->th0 : 0;
    }
    for (i = 0; i < md->n; ++i) {
        const chain_soft_real lo = md->u_min[i % md->nu], hi = md->u_max[i % md->nu];
        const chain_soft_real v = src ? src[i] : R_(0.0);
        U[i] = (v < lo) ? lo : ((v > hi) ? hi : v);
    }
    if (status != CHAIN_SOFT_OPTIMAL && status != CHAIN_SOFT_TIME_LIMIT) {
        for (i = 0; i < md->m; ++i) {
            lam[i] = R_(0.0); /* no sticky warm start after a failed sample */
        }
    }
    ws->slack_max = R_(0.0); /* the slacks of the plan: 0 unless optimal */
    ws->slack_rows = 0;
    for (i = 0; status == CHAIN_SOFT_OPTIMAL && i < md->m; ++i) {
        const chain_soft_real sl = multiplier_slack(md, i, lam[i]);
        if (sl > R_(0.0)) {
            ws->slack_max = (sl > ws->slack_max) ? sl : ws->slack_max;
            ++ws->slack_rows;
        }
    }
    return status;
}

/*
 * The budget ran out before the dual active set: the command is the clamped th0 and, if
 * a polish stopped (polished = 1), lam its working set (keep_progress()).
 */
static int time_limit_at_th0(chain_soft_work *ws, const chain_soft_mode_data *md,
    chain_soft_real *lam, int polished, chain_soft_real *U)
{
    int i;
    for (i = 0; i < md->n; ++i) {
        ws->th[i] = ws->th0[i];
    }
    if (polished) {
        keep_progress(ws, md, lam);
    }
    return finish(ws, md, lam, CHAIN_SOFT_TIME_LIMIT, U);
}

/**
 * @brief Solve one mode's QP (internal; see chain_soft_solve_qp()).
 * @param ws Work arrays.
 * @param lam Warm-start multipliers of the mode [m], updated.
 * @param md Mode data.
 * @param x State estimate [nx].
 * @param r Reference [N ny].
 * @param U Out: input sequence [n].
 * @param iterations Out: dual sweeps.
 * @param polish_iterations Out: polish corrections.
 * @param active Out: rows in the final active set.
 * @return A chain_soft_status code.
 */
int chain_soft_qp_solve(chain_soft_work *ws, chain_soft_real *lam, const chain_soft_mode_data *md,
    const chain_soft_real *x, const chain_soft_real *r, chain_soft_real *U, int *iterations,
    int *polish_iterations, int *active)
{
    int i, count, total = 0, status = CHAIN_SOFT_MAX_ITER, resume = -1;
    *iterations = 0;
    *polish_iterations = 0;
    *active = 0;
    ws->work = 0u;
    ws->work_limit = CHAIN_SOFT_SOLVER_WORK_BUDGET;
    unconstrained(ws, md, x, r);
    for (i = 0; i < md->n; ++i) {
        ws->th[i] = ws->th0[i];
    }
    if (slacks(ws, md) == 0) {
        for (i = 0; i < md->m; ++i) {
            lam[i] = R_(0.0);
        }
        return finish(ws, md, lam, CHAIN_SOFT_OPTIMAL, U);
    }
    /* Polish first: from the previous active set (warm start), then from the rows the
     * unconstrained solution violates; what follows runs only if both fail. The shifted
     * guess, in the dual form, may spend a third of what the budget has left: the dual
     * active set then continues from where it stopped. With a warm start, the violated rows are polished
     * only in the primal form: in the dual form the resumed dual active set costs less
     * than a factor of H_WW over every violated row (which breaks down on dependent rows). */
    count = 0; /* rows of the warm start */
    if (CHAIN_SOFT_SOLVER_WARM_START) {
        if (!afford(ws, md, (uint32_t)md->m)) {
            return time_limit_at_th0(ws, md, lam, 0, U);
        }
        count = seed_shifted(ws, md, lam);
        if (CHAIN_SOFT_SOLVER_ACTIVE_SET && !box_only(ws, md, count)) {
            ws->work_limit = ws->work + (CHAIN_SOFT_SOLVER_WORK_BUDGET - ws->work) / 3u;
        }
        i = polish(ws, md, lam, count, 1, polish_iterations, active);
        ws->work_limit = CHAIN_SOFT_SOLVER_WORK_BUDGET;
        if (i == 0) {
            return finish(ws, md, lam, CHAIN_SOFT_OPTIMAL, U);
        }
        if (i == OUT_OF_WORK) {
            if (!CHAIN_SOFT_SOLVER_ACTIVE_SET) {
                return time_limit_at_th0(ws, md, lam, 1, U);
            }
            resume = ws->stop_rows; /* the dual active set takes over from there */
        }
    }
    if (resume < 0) {
        if (!afford(ws, md, (uint32_t)md->m)) {
            return time_limit_at_th0(ws, md, lam, 0, U);
        }
        i = seed_from_violated(ws, md);
        if (count <= 0 || !CHAIN_SOFT_SOLVER_ACTIVE_SET || box_only(ws, md, i)) {
            i = polish(ws, md, lam, i, 0, polish_iterations, active);
            if (i == 0) {
                return finish(ws, md, lam, CHAIN_SOFT_OPTIMAL, U);
            }
            if (i == OUT_OF_WORK) {
                return time_limit_at_th0(ws, md, lam, 1, U);
            }
        }
    }
    /* Before any sweep: the dual active-set solve, which also proves infeasibility. */
    i = dual_active_set(ws, md, lam, resume, polish_iterations, active);
    if (i >= 0) {
        return finish(ws, md, lam, (i == 0) ? CHAIN_SOFT_OPTIMAL : CHAIN_SOFT_INFEASIBLE, U);
    }
    if (i == OUT_OF_WORK) {
        return finish(ws, md, lam, CHAIN_SOFT_TIME_LIMIT, U); /* at its last point */
    }
    if (!afford(ws, md, 3u * (uint32_t)md->m + (uint32_t)md->n
                        + (ws->out_slacks_ok ? 0u : predict_work(md)))) {
        return time_limit_at_th0(ws, md, lam, 0, U);
    }
    output_slacks(ws, md);
    for (i = 0; i < md->n; ++i) {
        ws->th[i] = ws->th0[i];
    }
    for (i = 0; i < md->m; ++i) {
        ws->in_set[i] = (uint8_t)(CHAIN_SOFT_SOLVER_REDUCED ? (ws->K[i] < CHAIN_SOFT_SOLVER_SIGMA) : 1);
        if (!CHAIN_SOFT_SOLVER_WARM_START || !ws->in_set[i]) {
            lam[i] = R_(0.0);
        }
    }
    count = build_set(ws, md);
    for (;;) {
        int t, converged = 0, diverged = 0, nviol, added = 0, out = 0;
        const int chunk = CHAIN_SOFT_SOLVER_POLISH ? CHAIN_SOFT_SOLVER_POLISH_EVERY : CHAIN_SOFT_SOLVER_MAX_ITER;
        /* after the chunk: the corrected point, then the polish (which checks for itself)
         * or the row checks */
        const uint32_t after = correct_work(md, count) + (uint32_t)count;
        for (t = 0; t < chunk && total < CHAIN_SOFT_SOLVER_MAX_ITER; ++t) {
            chain_soft_real e2;
            out = !afford(ws, md, sweep_work(md, count) + after);
            if (out) {
                break;
            }
            e2 = sweep(ws, md, lam, count, &diverged);
            ++total;
            if (diverged) {
                break;
            }
            if (e2 < CHAIN_SOFT_SOLVER_DELTA) {
                converged = 1;
                break;
            }
        }
        if (out) {
            status = CHAIN_SOFT_TIME_LIMIT; /* ws->th: the last corrected point */
            break;
        }
        if (diverged) {
            status = CHAIN_SOFT_INFEASIBLE;
            break;
        }
        correct(ws, md, ws->set, count, lam, 1);
        i = polish(ws, md, lam, seed_from_multipliers(ws, md, lam, ws->set, count), 0,
                   polish_iterations, active);
        if (i == 0) {
            status = CHAIN_SOFT_OPTIMAL;
            break;
        }
        if (i == OUT_OF_WORK
            || !afford(ws, md, correct_work(md, count) + 2u * scan_work(md) + 2u * (uint32_t)md->m)) {
            for (i = 0; i < md->n; ++i) { /* the polish overwrote the sweeps' point */
                ws->th[i] = ws->th0[i];
            }
            status = CHAIN_SOFT_TIME_LIMIT;
            break;
        }
        for (i = 0; i < md->m; ++i) { /* the polish flagged its working set in in_set */
            ws->in_set[i] = 0;
        }
        for (i = 0; i < count; ++i) {
            ws->in_set[ws->set[i]] = 1;
        }
        correct(ws, md, ws->set, count, lam, 1);
        nviol = violated_beyond_slack(ws, md, lam);
        if (CHAIN_SOFT_SOLVER_REDUCED && nviol != 0) {
            /* every violated row joins: predict the outputs unless certified */
            const int outputs = outputs_to_check(ws, md, ws->th);
            for (i = 0; i < md->m; ++i) {
                if (!ws->in_set[i] && (outputs || md->row_q[i] < md->n)
                    && row_violated(ws, md, ws->th, i)) {
                    ws->in_set[i] = 1;
                    ++added;
                }
            }
        }
        if (converged && nviol == 0) {
            status = CHAIN_SOFT_OPTIMAL;
            break;
        }
        if (total >= CHAIN_SOFT_SOLVER_MAX_ITER) {
            status = CHAIN_SOFT_MAX_ITER;
            break;
        }
        if (converged && added == 0) {
            status = CHAIN_SOFT_INACCURATE;
            break;
        }
        if (added != 0) {
            count = build_set(ws, md);
        }
    }
    if (*active == 0) {
        for (i = 0; i < md->m; ++i) {
            *active += (lam[i] > R_(0.0));
        }
    }
    *iterations = total;
    return finish(ws, md, lam, status, U);
}
