/**
 * @file rollmpc_solver.c
 * @brief Hildreth-family dual QP solver (Lam et al., IFAC 2020, section 3.2) with an
 *        exact active-set polish.
 *
 * Problem (eq. 5-6): min 1/2 U'EU + U'F s.t. M U <= gamma, with rows M_r = sign_r a(q_r)'
 * on a quantity q_r (an input U_i, or a predicted output (Gamma U)_k). The dual Hessian
 * H = M E^-1 M' is read through its structure (hq()), never stored densely.
 *
 * Variants are compile-time switches (rollmpc_config.h):
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
 * Every sum runs sequentially in a fixed order with no fused multiply-add, so the
 * generator's NumPy reference reproduces every output bit for bit (rollmpc_README.md,
 * "Bit for bit").
 */
#include <math.h>
#include "rollmpc_internal.h"
#if ROLLMPC_GENERATION != 0x7fff7b8e801a310
#error "rollmpc_solver.c and rollmpc_config.h are of different generations (an interrupted regeneration?): regenerate the whole directory"
#endif

#define R_ ROLLMPC_R

/*
 * Work units (rollmpc_README.md, "Work budget"): about one multiply-add with its
 * loads. Each costly function adds its closed-form cost to ws->work once per call (never
 * per loop iteration); the same formulas bound a unit of work before it starts (afford()),
 * so the work of a solve never exceeds ROLLMPC_SOLVER_WORK_BUDGET. The generator
 * declares each formula once: the NumPy reference charges the same numbers at the same
 * places. The constants in capitals are the README's.
 */
#define OUT_OF_WORK (-2) /* a solver part stopped: the budget cannot afford its next unit */
#define OUT_OF_WORK_AT_TH0 (-3) /* the dual active set stopped so before a point of its own */

/*
 * One read of H through hq(): the Woodbury sum of nt terms, `factor` times (2 with Δu
 * rows: a Δu quantity is a difference of reads).
 */
static uint32_t hq_work(const rollmpc_mode_data *md)
{
    return ((uint32_t)md->nt + 4u) * 1u;
}

/*
 * predict_outputs(): the Markov sum of each output with rows over the stages before it, at
 * PREDICT_UNITS_PER_OP of a unit per multiply-add, and a unit per output.
 */
static uint32_t predict_work(const rollmpc_mode_data *md)
{
    const uint32_t stages = (uint32_t)md->nyq / (uint32_t)md->ny;
    return (uint32_t)md->ny_pred * (uint32_t)md->nu * stages * (stages + 1u) / 2u * 3u / 5u +
        (uint32_t)md->nyq;
}

/*
 * What outputs_certified() charges before it reads a row: th's n values (the ny output
 * bounds of the last stage ride with them) and the nzq signal bounds.
 */
static uint32_t certificate_read_work(const rollmpc_mode_data *md)
{
    return (uint32_t)md->n;
}

/*
 * The most outputs_certified() charges: certificate_read_work() and, when the largest
 * bound does not clear every row at once, the rows up to the first it cannot clear.
 */
static uint32_t certificate_work(const rollmpc_mode_data *md)
{
    return certificate_read_work(md) + (uint32_t)md->m;
}

/*
 * A check of every row at a point (violated_outside(), most_violated()): the certificate,
 * the prediction it may need, and the rows.
 */
static uint32_t scan_work(const rollmpc_mode_data *md)
{
    return 2u * (uint32_t)md->m + certificate_work(md) + predict_work(md);
}

/*
 * correct() over `count` rows whose multipliers reach `nin` input and `nout` output
 * quantities: an n-long column each, and the Woodbury term.
 */
static uint32_t correct_cost(const rollmpc_mode_data *md, int count, uint32_t nin, uint32_t nout)
{
    const uint32_t n = (uint32_t)md->n;
    const uint32_t nt = (uint32_t)md->nt;
    return (uint32_t)count + 2u * n + (uint32_t)md->nyq + n * (nin + nout + nt) + nt * nin;
}

/*
 * The most correct() can cost over `count` rows (what afford() asks for): at most min(2
 * count, n) input and min(count, nyq) output quantities; it charges correct_cost() of the
 * quantities it met.
 */
static uint32_t correct_work(const rollmpc_mode_data *md, int count)
{
    const uint32_t nin = (2u * (uint32_t)count < (uint32_t)md->n) ? 2u * (uint32_t)count :
        (uint32_t)md->n;
    const uint32_t nout = ((uint32_t)count < (uint32_t)md->nyq) ? (uint32_t)count :
        (uint32_t)md->nyq;
    return correct_cost(md, count, nin, nout);
}

/* One Gauss-Seidel sweep over `count` rows. */
static uint32_t sweep_work(const rollmpc_mode_data *md, int count)
{
    return (uint32_t)count * (uint32_t)count * hq_work(md) + 8u * (uint32_t)count;
}

/*
 * 1 in a mode with soft rows (its working set holds their slack rows: w_cap > n), else 0
 * (w_cap is absent, 0, in a build without soft rows).
 */
static uint32_t soft_mode(const rollmpc_mode_data *md)
{
    return (((0u < (uint32_t)md->n + 1u) ? 0u : (uint32_t)md->n + 1u > (uint32_t)md->n) ? (0u <
        (uint32_t)md->n + 1u) ? 0u : (uint32_t)md->n + 1u : (uint32_t)md->n) -
        (uint32_t)md->n;
}

/*
 * finish(): the finite check and clamp of the plan, the multipliers cleared after a failed
 * sample and, in a mode with soft rows, the plan's slacks; always paid, so every check
 * reserves it.
 */
static uint32_t finish_work(const rollmpc_mode_data *md)
{
    return 2u * (uint32_t)md->n + (uint32_t)md->m / 2u + soft_mode(md) * (uint32_t)md->m;
}

/*
 * Can the budget still pay for `need` units (and the final finish())? Every unit of work
 * asks before it starts, so ws->work + finish_work() never passes the budget (the
 * generator checks that the unconstrained step leaves room); ws->work_limit is the
 * budget, or less while the shifted guess runs (P_qp_solve()). A granted unit pays
 * UNIT_CALL_WORK at once: the calls, checks and copies around its operations,
 * which its formula does not count and which dominate the small units of a small QP.
 */
#define UNIT_CALL_WORK 15u
static int afford(rollmpc_work *ws, const rollmpc_mode_data *md, uint32_t need)
{
    const uint32_t used = ws->work + finish_work(md) + UNIT_CALL_WORK;
    if (used <= ws->work_limit && need <= ws->work_limit - used) {
        ws->work += UNIT_CALL_WORK;
        return 1;
    }
    return 0;
}

/*
 * The operations of a Cholesky factorisation of order n (n^3/6 multiply-adds, a division
 * per entry).
 */
static uint32_t chol_ops(int n)
{
    return (uint32_t)n * (uint32_t)n * (uint32_t)n / 6u + 2u * (uint32_t)n * (uint32_t)n + 4u *
        (uint32_t)n;
}

/* The operations of one triangular solve of order n. */
static uint32_t tri_ops(int n)
{
    return (uint32_t)n * (uint32_t)n / 2u + 4u * (uint32_t)n;
}

/*
 * A Cholesky factorisation of order n, at CHOL_UNITS_PER_OP of a unit per operation: the
 * dense kernels of linalg.c run faster per operation than a unit.
 */
static uint32_t chol_work(int n)
{
    return chol_ops(n) * 2u / 5u;
}

/* One triangular solve of order n, at TRI_UNITS_PER_OP of a unit per operation. */
static uint32_t tri_work(int n)
{
    return tri_ops(n) * 3u / 5u;
}

/* chol_rank_one() on a trailing block of order n: a rotation per column. */
static uint32_t rank_one_work(int n)
{
    return 3u * (uint32_t)n * (uint32_t)n / 2u + 10u * (uint32_t)n;
}

/* chol_delete() of row k from order n: the rows below move up, then one rank-one update. */
static uint32_t delete_work(int k, int n)
{
    return ((uint32_t)n * (uint32_t)n - (uint32_t)k * (uint32_t)k) / 2u + (uint32_t)n +
        rank_one_work((n - 1 - k > 0) ? n - 1 - k : 0);
}

/* chol_delete() of the primal factor's row k from order n, carrying Y's nt columns. */
static uint32_t primal_delete_work(int k, int n, int nt)
{
    return delete_work(k, n) + 4u * (uint32_t)nt * ((uint32_t)n - (uint32_t)k);
}

/* factor_working_set() of nw rows: their H entries, then the factorisation. */
static uint32_t factor_work(const rollmpc_mode_data *md, int nw)
{
    return (uint32_t)nw * ((uint32_t)nw + 1u) / 2u * hq_work(md) + chol_work(nw);
}

/* append_row() at position nw: the column H_Wp and its diagonal, a forward solve. */
static uint32_t append_work(const rollmpc_mode_data *md, int nw)
{
    return ((uint32_t)nw + 1u) * hq_work(md) + tri_work(nw) + (uint32_t)nw;
}

/*
 * free_multipliers() on nw rows, charged when it runs: a free-form polish computes them
 * only at a feasible point, not after every correction.
 */
static uint32_t multipliers_work(const rollmpc_mode_data *md, int nw)
{
    return 3u * (uint32_t)nw * ((uint32_t)md->n + (uint32_t)md->nt) / 6u;
}

/* What polish() still spends after a primal solve: its check of every row and accept(). */
static uint32_t primal_reserve(const rollmpc_mode_data *md)
{
    return scan_work(md) + (uint32_t)md->m;
}

/*
 * guess_reversed() on `rows` rows: each multiplier row by row costs about twice one from
 * free_multipliers()'s symmetric product on the M4F.
 */
static uint32_t guess_sample_work(const rollmpc_mode_data *md, int rows)
{
    return multipliers_work(md, 2 * rows);
}

/*
 * trim_guess() on a guess of nw rows at most: its scans of the guess (twice) and of every
 * row.
 */
static uint32_t trim_work(const rollmpc_mode_data *md, int nw)
{
    return (uint32_t)md->m + 2u * (uint32_t)nw;
}

/*
 * primal_solve() with a factor of order k whose rows (and Y's) from `start` are factored
 * again (0: a new factor): its Cholesky at PRIMAL_SIXTHS_PER_OP[0], the nt forward solves
 * of Y's new rows at FORWARD_UNITS_PER_OP, the two solves of the right-hand side as
 * tri_work(), the rows of A, the terminal Schur complement and its solves, the products
 * and PRIMAL_INPUT_OPS per input (the passes over the inputs) at PRIMAL_SIXTHS_PER_OP[1],
 * and PRIMAL_CALL_UNITS per call. The free form's product -S_FB d_B is what it does: k (n
 * - k) multiply-adds, nt (n - k) for V_B d_B, n for the point, and PRIMAL_CALL_OPS per
 * free row and run of bound inputs (`bound_runs`: sparse_rows_dot() calls
 * packed_range_dot() for each); its multipliers are charged by free_multipliers()
 * (multipliers_work()). The bound form's product S^-1_FB beta - Uv_F' nu is what it does
 * too: (k + nt) multiply-adds for each free row (up to three rows more: gather_dot4() sums
 * four rows a call, the last repeated), 2 n to gather the bound inputs and walk the list,
 * and PRIMAL_CALL_OPS per call.
 */
static uint32_t primal_work(const rollmpc_mode_data *md, int k, int start, int bound_form,
    int bound_runs)
{
    const uint32_t n = (uint32_t)md->n;
    const uint32_t nt = (uint32_t)md->nt;
    const uint32_t factor = chol_ops(k) - chol_ops(start) + chol_ops(md->nt);
    const uint32_t products = bound_form ? 4u * ((n - (uint32_t)k + 3u) / 4u) * ((uint32_t)k +
        nt) + 4u * ((n - (uint32_t)k + 3u) / 4u) + 2u * n : ((uint32_t)k
        + nt) * (n - (uint32_t)k) + n + 4u * (uint32_t)k *
        (uint32_t)bound_runs;
    const uint32_t loops = ((uint32_t)k * (uint32_t)k - (uint32_t)start * (uint32_t)start) / 2u
        + nt * nt * (uint32_t)k / 2u + 2u * tri_ops(md->nt) + 3u * nt * n +
        products + 8u * n;
    const uint32_t y_rows = nt * (tri_ops(k) - tri_ops(start));
    return (2u * factor + 3u * loops) / 6u + y_rows * 2u / 5u + 2u * tri_work(k) + 200u;
}

/* independent_rows() on nw rows, at most: each appended to all the rows before it. */
static uint32_t independent_work(const rollmpc_mode_data *md, int nw)
{
    uint32_t w = 0u;
    int k;
    for (k = 0; k < nw; ++k) {
        w += append_work(md, k);
    }
    return w;
}

/*
 * One step of add_to_set() on nw rows: two triangular solves, then a row leaves, switches
 * state or joins.
 */
static uint32_t add_step_work(int nw)
{
    const uint32_t leave = delete_work(0, nw);
    const uint32_t flip = rank_one_work(nw);
    return 2u * tri_work(nw) + 5u * (uint32_t)nw + ((leave > flip) ? leave : flip);
}

/*
 * What the dual active set still spends to accept its final working set at its scanned
 * point without polish(): the output certificate and converged().
 */
static uint32_t final_check_work(const rollmpc_mode_data *md)
{
    return certificate_work(md) + (uint32_t)md->m;
}

/*
 * v signed as row r is (+1: an upper bound row, -1: a lower one), wherever a row's sign
 * selects v or -v; v times the product of two rows' signs. The product is a multiply by
 * +-1 (exact), not a select: the working set's signs are mixed, and on the host a branch
 * on them was mispredicted often enough to cost 4-5 % of thermal_zones_rate's worst QP
 * (measured on the host).
 */
static inline rollmpc_real by_sign(const rollmpc_mode_data *md, int r, rollmpc_real v)
{
    return (md->row_sign[r] > 0) ? v : -v;
}

static inline rollmpc_real by_signs(const rollmpc_mode_data *md, int r, int s, rollmpc_real v)
{
    const int sign = md->row_sign[r] * md->row_sign[s];
    return (rollmpc_real)sign * v;
}

/* E^-1(a, b) for inputs a, b < n, in Woodbury form: E^-1 = S^-1 - Ew' Ew. */
static inline rollmpc_real einv(const rollmpc_mode_data *md, int a, int b)
{
    const int n = md->n;
    const int hi = (a >= b) ? a : b, lo = (a >= b) ? b : a; /* an index select, not a branch */
    const rollmpc_real si = md->Sinv_p[ROLLMPC_TRI(hi, lo)];
    rollmpc_real acc = R_(0.0);
    int o;
    for (o = 0; o < md->nt; ++o) {
        acc += md->Ew[o * n + a] * md->Ew[o * n + b];
    }
    return si - acc;
}

/*
 * Hq(n + k, b): output k against quantity b, from G E^-1 (EinvGt's row b, column k) or
 * G E^-1 G'.
 */
static inline rollmpc_real hq_output(const rollmpc_mode_data *md, int k, int b)
{
    const int n = md->n, nyq = md->nyq;
    if (b < n) {
        return md->EinvGt[b * nyq + k];
    }
    b -= n;
    return (k >= b) ? md->GEinvGt_p[ROLLMPC_TRI(k, b)] : md->GEinvGt_p[ROLLMPC_TRI(b, k)];
}

/* Element (a, b) of Hq = [[E^-1, E^-1 G'], [G E^-1, G E^-1 G']] (quantities a, b). */
static rollmpc_real hq(const rollmpc_mode_data *md, int a, int b)
{
    const int n = md->n;
    if (a < n) {
        if (b < n) {
            return einv(md, a, b);
        }
        return md->EinvGt[a * md->nyq + (b - n)];
    }
    return hq_output(md, a - n, b);
}

/* H_rs = sign_r sign_s Hq(q_r, q_s). */
static rollmpc_real h_rows(const rollmpc_mode_data *md, int r, int s)
{
    const rollmpc_real h = hq(md, md->row_q[r], md->row_q[s]);
    return by_signs(md, r, s, h);
}

/* H_Wp a column at a time: the polish's and the dual active set's reads (no data, same values) */
/*
 * col[i] = E^-1(i, b) over the inputs i, or with `less` col[i] -= E^-1(i, b): einv()'s
 * operations, walking S^-1's row b and then its column b.
 */
static void einv_column(const rollmpc_mode_data *md, int b, int less, rollmpc_real *col)
{
    const int n = md->n;
    const rollmpc_real *ewb = &md->Ew[b]; /* Ew[o * n + b] = ewb[o * n] */
    int i, o, k = ROLLMPC_TRI(b, 0);
    for (i = 0; i < n; ++i) {
        rollmpc_real acc = R_(0.0), e;
        for (o = 0; o < md->nt; ++o) {
            acc += md->Ew[o * n + i] * ewb[o * n];
        }
        e = md->Sinv_p[k] - acc;
        col[i] = less ? col[i] - e : e;
        k += (i < b) ? 1 : i + 1; /* TRI(b, i + 1) while i < b, then TRI(i + 1, b) */
    }
}

/*
 * Column b of Hq over the n inputs, col[i] = Hq(i, b) formed as hq() forms it (a Δu
 * quantity b as the difference of two columns). One pass over the inputs: the column
 * repays itself once enough input and Δu rows read it (h_column()).
 */
static void hq_input_column(const rollmpc_mode_data *md, int b, rollmpc_real *col)
{
    const int n = md->n;
    int i;
    if (b < n) {
        einv_column(md, b, 0, col);
        return;
    }
    for (i = 0; i < n; ++i) {
        col[i] = md->EinvGt[i * md->nyq + (b - n)];
    }
}

/*
 * H_rp with p's input column col (hq_input_column()): an input or Δu row r reads col, an
 * output row hq_output().
 */
static rollmpc_real h_from_column(const rollmpc_mode_data *md, int r, int p, const rollmpc_real *col)
{
    const int a = md->row_q[r];
    rollmpc_real h;
    if (a >= md->n) { /* an output: not in p's input column */
        h = hq_output(md, a - md->n, md->row_q[p]);
    } else {
        h = col[a];
    }
    return by_signs(md, r, p, h);
}

/*
 * The E^-1 entries that reading H_Wp entry by entry forms per input entry of p's
 * quantity, over the rows wset[0..nw): one per input row (h_column() weighs them against the n of a column).
 */
static int einv_reads(const rollmpc_mode_data *md, const int16_t *wset, int nw)
{
    int i, reads = 0;
    for (i = 0; i < nw; ++i) {
        const int q = md->row_q[wset[i]];
        reads += (q < md->n);
    }
    return reads;
}

/*
 * Whether forming a column of n entries pays for rows that would form `reads` entries of
 * E^-1 one by one (einv_reads()): from n / 2 on (of 1/4, 3/8, 1/2, 3/4 and 1, the fewest
 * cycles on the emulated M4F).
 */
static int column_pays(const rollmpc_mode_data *md, int reads)
{
    return 2 * reads >= md->n;
}

/*
 * H_Wp = h_rows(wset[i], p) into out[0..nw): through p's input column in col (n reals of
 * scratch) where the rows' einv_reads() (`reads`, or counted here when negative) make it
 * pay (column_pays()), else entry by entry. Same values either way.
 */
static void h_column(const rollmpc_mode_data *md, const int16_t *wset, int nw, int p,
    int reads, rollmpc_real *col, rollmpc_real *out)
{
    int i;
    if (column_pays(md, (reads < 0) ? einv_reads(md, wset, nw) : reads)) {
        hq_input_column(md, md->row_q[p], col);
        for (i = 0; i < nw; ++i) {
            out[i] = h_from_column(md, wset[i], p, col);
        }
    } else {
        for (i = 0; i < nw; ++i) {
            out[i] = h_rows(md, wset[i], p);
        }
    }
}

/* a run of bound inputs shorter than this is summed inline, not by a call; bound inputs
 * in runs shorter than this on average are summed by columns (sparse_rows_dot(), the
 * free form's product) */
#define SHORT_RUN 4

/*
 * (M x)_q for a symmetric M stored as its packed lower triangle (row q up to the
 * diagonal, column q below it) is one sequential sum over j = 0..n-1 of M(q, j) x_j. Every
 * function here forms that sum in that order: over a range of j (packed_range_dot()), over
 * the support of a sparse x only (the terms left out are exact zeros, so the sum is the
 * same to the bit), or for every q at once (sym_product()). The NumPy reference sums the
 * dense row (rollmpc_README.md, "Bit for bit").
 */

/*
 * acc + sum_{j=lo}^{hi-1} M(q, j) x_j, one term at a time (four per loop trip).
 * Cost: hi - lo multiply-adds.
 */
static rollmpc_real packed_range_dot(const rollmpc_real *mp, int q, const rollmpc_real *x,
    int lo, int hi, rollmpc_real acc)
{
    const int mid = (hi < q + 1) ? hi : q + 1;
    int j = lo;
    if (j < mid) { /* row q, contiguous */
        const rollmpc_real *m = &mp[ROLLMPC_TRI(q, j)], *v = &x[j], *end = &x[mid];
        for (; end - v >= 4; v += 4, m += 4) {
            acc += m[0] * v[0];
            acc += m[1] * v[1];
            acc += m[2] * v[2];
            acc += m[3] * v[3];
        }
        while (v != end) {
            acc += *m++ * *v++;
        }
        j = mid;
    }
    if (j < hi) { /* column q below the diagonal: row j starts j + 1 after row j - 1 */
        const rollmpc_real *m = &mp[ROLLMPC_TRI(j, q)];
        for (; j + 3 < hi; j += 4) {
            const rollmpc_real *m1 = m + j + 1, *m2 = m1 + j + 2, *m3 = m2 + j + 3;
            acc += *m * x[j];
            acc += *m1 * x[j + 1];
            acc += *m2 * x[j + 2];
            acc += *m3 * x[j + 3];
            m = m3 + j + 4;
        }
        for (; j < hi; ++j) {
            acc += *m * x[j];
            m += j + 1;
        }
    }
    return acc;
}

/*
 * acc0 += sum_{j=lo}^{hi-1} M(q0, j) x_j and acc1 likewise for row q1, both ranges inside
 * the rows' stored parts (hi <= q0 + 1 <= q1 + 1): each x_j read serves both sums.
 * Cost: 2 (hi - lo) multiply-adds.
 */
static void packed_range_dot2(const rollmpc_real *mp, int q0, int q1, const rollmpc_real *x,
    int lo, int hi, rollmpc_real *acc0, rollmpc_real *acc1)
{
    const rollmpc_real *m0 = &mp[ROLLMPC_TRI(q0, lo)], *m1 = &mp[ROLLMPC_TRI(q1, lo)];
    const rollmpc_real *v = &x[lo], *end = &x[hi];
    rollmpc_real s0 = *acc0, s1 = *acc1;
    if ((hi - lo) & 1) {
        const rollmpc_real xv = *v++;
        s0 += *m0++ * xv;
        s1 += *m1++ * xv;
    }
    for (; v != end; v += 2, m0 += 2, m1 += 2) {
        const rollmpc_real xa = v[0], xb = v[1];
        s0 += m0[0] * xa;
        s1 += m1[0] * xa;
        s0 += m0[1] * xb;
        s1 += m1[1] * xb;
    }
    *acc0 = s0;
    *acc1 = s1;
}

/*
 * acc[b] += sum_{j=lo}^{hi-1} M(rows[b], j) x_j for b < 4, every range inside its row's
 * stored part (hi <= rows[b] + 1): each x_j read serves four sums.
 * Cost: 4 (hi - lo) multiply-adds.
 */
static void packed_range_dot4(const rollmpc_real *mp, const int16_t *rows, const rollmpc_real *x,
    int lo, int hi, rollmpc_real *acc)
{
    const rollmpc_real *m0 = &mp[ROLLMPC_TRI(rows[0], lo)], *m1 = &mp[ROLLMPC_TRI(rows[1], lo)];
    const rollmpc_real *m2 = &mp[ROLLMPC_TRI(rows[2], lo)], *m3 = &mp[ROLLMPC_TRI(rows[3], lo)];
    const rollmpc_real *v = &x[lo], *end = &x[hi];
    rollmpc_real s0 = acc[0], s1 = acc[1], s2 = acc[2], s3 = acc[3];
    while (v != end) {
        const rollmpc_real xv = *v++;
        s0 += *m0++ * xv;
        s1 += *m1++ * xv;
        s2 += *m2++ * xv;
        s3 += *m3++ * xv;
    }
    acc[0] = s0;
    acc[1] = s1;
    acc[2] = s2;
    acc[3] = s3;
}

/*
 * out[t] = M(qa, q0 + t dir) for t < len (dir = 1 or -1): a run of consecutive columns of
 * row qa, from row qa up to the diagonal and from column qa below it, with no index
 * reads. Cost: len copies.
 */
static void packed_gather(const rollmpc_real *mp, int qa, int q0, int dir, int len,
    rollmpc_real *out)
{
    int t = 0, q = q0;
    const rollmpc_real *m;
    if (dir > 0) {
        if (q0 <= qa) { /* row qa: q0 .. min(qa, q0 + len - 1) */
            const int in_row = (qa - q0 + 1 < len) ? qa - q0 + 1 : len;
            for (m = &mp[ROLLMPC_TRI(qa, q0)]; t < in_row; ++t) {
                out[t] = m[t];
            }
            q += in_row;
        }
        for (m = &mp[ROLLMPC_TRI(q, qa)]; t < len; ++t) { /* column qa, rows q > qa */
            out[t] = *m;
            m += ++q;
        }
        return;
    }
    if (q0 > qa) { /* descending: column qa first, rows q0 .. qa + 1 */
        const int in_col = (q0 - qa < len) ? q0 - qa : len;
        for (m = &mp[ROLLMPC_TRI(q, qa)]; t < in_col; ++t) {
            out[t] = *m;
            m -= q--;
        }
    }
    for (m = &mp[ROLLMPC_TRI(qa, q)]; t < len; ++t) { /* then row qa, backwards */
        out[t] = *m--;
    }
}

/*
 * out[t] = M(qa, list[t]) for t < len: entries of row qa at listed columns, for a stretch
 * of short runs, where packed_gather()'s call per run and row would cost more than the
 * copies. Cost: len copies and index reads.
 */
static void packed_gather_listed(const rollmpc_real *mp, int qa, const int16_t *list,
    int len, rollmpc_real *out)
{
    const rollmpc_real *row = &mp[ROLLMPC_TRI(qa, 0)];
    int t;
    for (t = 0; t < len; ++t) {
        const int q = list[t];
        out[t] = (q <= qa) ? row[q] : mp[ROLLMPC_TRI(q, qa)];
    }
}

/* (M x)_q over all j. Cost: n multiply-adds. */
static rollmpc_real s_row_dot(const rollmpc_real *mp, int n, int q, const rollmpc_real *x)
{
    return packed_range_dot(mp, q, x, 0, n, R_(0.0));
}

/*
 * g[0] = (M x)_q and g[1] = (M x)_(q+1) over all j: the rows up to q side by side, then
 * the columns below q + 1, whose entries M(j, q), M(j, q + 1) are neighbours in row j.
 * Cost: 2 n multiply-adds.
 */
static void s_row_dot2(const rollmpc_real *mp, int n, int q, const rollmpc_real *x,
    rollmpc_real *g)
{
    rollmpc_real s0 = R_(0.0), s1 = R_(0.0);
    const rollmpc_real *m;
    int j;
    packed_range_dot2(mp, q, q + 1, x, 0, q + 1, &s0, &s1);
    s1 += mp[ROLLMPC_TRI(q + 1, q + 1)] * x[q + 1];
    s0 += mp[ROLLMPC_TRI(q + 1, q)] * x[q + 1];
    m = &mp[ROLLMPC_TRI(q + 2, q)];
    for (j = q + 2; j < n; ++j) {
        const rollmpc_real xv = x[j];
        s0 += m[0] * xv;
        s1 += m[1] * xv;
        m += j + 1;
    }
    g[0] = s0;
    g[1] = s1;
}

/*
 * g[b] = (M x)_(q+b) for b < 4 over all j: the rows up to q side by side
 * (packed_range_dot4()), the 3 x 3 corner j = q + 1 .. q + 3 term by term, then the
 * columns below q + 3, whose entries M(j, q .. q + 3) are neighbours in row j.
 * Cost: 4 n multiply-adds.
 */
static void s_row_dot4(const rollmpc_real *mp, int n, int q, const rollmpc_real *x,
    rollmpc_real *g)
{
    const int16_t rows[4] = { (int16_t)q, (int16_t)(q + 1), (int16_t)(q + 2), (int16_t)(q + 3) };
    rollmpc_real s0, s1, s2, s3;
    const rollmpc_real *m;
    int j, b;
    for (b = 0; b < 4; ++b) {
        g[b] = R_(0.0);
    }
    packed_range_dot4(mp, rows, x, 0, q + 1, g);
    for (j = q + 1; j < q + 4; ++j) { /* row j holds M(j, q .. j), column j the rest */
        for (b = 0; b < 4; ++b) {
            const int r = q + b;
            g[b] += mp[(r < j) ? ROLLMPC_TRI(j, r) : ROLLMPC_TRI(r, j)] * x[j];
        }
    }
    s0 = g[0];
    s1 = g[1];
    s2 = g[2];
    s3 = g[3];
    m = &mp[ROLLMPC_TRI(q + 4, q)];
    for (j = q + 4; j < n; ++j) {
        const rollmpc_real xv = x[j];
        s0 += m[0] * xv;
        s1 += m[1] * xv;
        s2 += m[2] * xv;
        s3 += m[3] * xv;
        m += j + 1;
    }
    g[0] = s0;
    g[1] = s1;
    g[2] = s2;
    g[3] = s3;
}

/*
 * out[a] += M(rows[a], j) x_j, then M(rows[a], j + 1) x_(j+1) when pair, for every row:
 * one or two columns of M read down the rows (row j up to the diagonal, column j below
 * it), each row's terms in increasing j as a walk along the row would add them.
 * Cost: nrows (1 + pair) multiply-adds.
 */
static void packed_columns_axpy(const rollmpc_real *mp, int j, int pair, const rollmpc_real *x,
    const int16_t *rows, int nrows, rollmpc_real *out)
{
    const rollmpc_real *row_j = &mp[ROLLMPC_TRI(j, 0)], *row_j1 = row_j + j + 1;
    const rollmpc_real x0 = x[j];
    int a;
    if (!pair) {
        for (a = 0; a < nrows; ++a) {
            const int q = rows[a];
            out[a] += ((q <= j) ? row_j[q] : mp[ROLLMPC_TRI(q, j)]) * x0;
        }
        return;
    }
    {
        const rollmpc_real x1 = x[j + 1];
        for (a = 0; a < nrows; ++a) {
            const int q = rows[a];
            rollmpc_real acc = out[a];
            if (q <= j) {
                acc += row_j[q] * x0;
                acc += row_j1[q] * x1;
            } else {
                const rollmpc_real *m = &mp[ROLLMPC_TRI(q, j)]; /* M(q, j + 1) next */
                acc += m[0] * x0;
                acc += m[1] * x1;
            }
            out[a] = acc;
        }
    }
}

/*
 * out[a] = (M x)_{rows[a]} for a < nrows, x zero outside the support given by the
 * ascending list[0..count) (the free form's bound inputs). The support is walked once,
 * run by run, each run added to every row: to four or two rows at a time where the run
 * lies in their stored parts; with by_columns (the caller's choice where the runs are
 * short: scattered bound inputs) a column or two at a time down the rows instead, which
 * adds each row's terms in the same order (the same sums to the bit) without a call or a
 * test per row and run.
 * Cost: nrows |support| multiply-adds.
 */
static void sparse_rows_dot(const rollmpc_real *mp, const int16_t *rows, int nrows,
    const rollmpc_real *x, const int16_t *list, int count, int by_columns,
    rollmpc_real *out)
{
    int a, i = 0, lo, hi;
    for (a = 0; a < nrows; ++a) {
        out[a] = R_(0.0);
    }
    while (i < count) { /* the run of consecutive entries from list[i] */
        lo = list[i];
        hi = lo + 1;
        for (++i; i < count && list[i] == hi; ++i) {
            ++hi;
        }
        for (; by_columns && lo < hi; lo += 2) {
            packed_columns_axpy(mp, lo, lo + 1 < hi, x, rows, nrows, out);
        }
        a = 0;
        while (lo < hi && a < nrows) {
            if (a + 3 < nrows && rows[a] >= hi - 1 && rows[a + 1] >= hi - 1
                && rows[a + 2] >= hi - 1 && rows[a + 3] >= hi - 1) {
                packed_range_dot4(mp, &rows[a], x, lo, hi, &out[a]);
                a += 4;
            } else
            if (a + 1 < nrows && rows[a] >= hi - 1 && rows[a + 1] >= hi - 1) {
                packed_range_dot2(mp, rows[a], rows[a + 1], x, lo, hi, &out[a], &out[a + 1]);
                a += 2;
            } else if (hi - lo < SHORT_RUN) { /* a short run: no call */
                const int q = rows[a];
                rollmpc_real acc = out[a];
                int j;
                for (j = lo; j < hi; ++j) {
                    acc += mp[(j <= q) ? ROLLMPC_TRI(q, j) : ROLLMPC_TRI(j, q)] * x[j];
                }
                out[a] = acc;
                ++a;
            } else {
                out[a] = packed_range_dot(mp, rows[a], x, lo, hi, out[a]);
                ++a;
            }
        }
    }
}

/*
 * g = M x for every row, each g_q the sequential sum over j: row q (j <= q) as a dot
 * product, and j > q from the rows below, added in increasing j as they are reached; four
 * rows at a time (then two, then one), so each element of M read serves two products and
 * each x_j and g_j read serves eight.
 * Cost: n^2 multiply-adds over n (n + 1) / 2 reads of M.
 */
static void sym_product(const rollmpc_real *mp, int n, const rollmpc_real *x,
    rollmpc_real *g)
{
    int i = 0;
    for (; i + 3 < n; i += 4) {
        const rollmpc_real *r0 = &mp[ROLLMPC_TRI(i, 0)], *r1 = r0 + i + 1, *r2 = r1 + i + 2;
        const rollmpc_real *r3 = r2 + i + 3, *xj = x;
        const rollmpc_real x0 = x[i], x1 = x[i + 1], x2 = x[i + 2], x3 = x[i + 3];
        rollmpc_real s0 = R_(0.0), s1 = R_(0.0), s2 = R_(0.0), s3 = R_(0.0), *gj = g, *end = g + i;
        while (gj != end) {
            const rollmpc_real a0 = *r0++, a1 = *r1++, a2 = *r2++, a3 = *r3++, v = *xj++;
            s0 += a0 * v;
            s1 += a1 * v;
            s2 += a2 * v;
            s3 += a3 * v;
            *gj = (((*gj + a0 * x0) + a1 * x1) + a2 * x2) + a3 * x3;
            ++gj;
        }
        /* the 4 x 4 diagonal block: row parts up to the diagonal, then column terms */
        s0 += r0[0] * x0;
        s1 = (s1 + r1[0] * x0) + r1[1] * x1;
        s2 = ((s2 + r2[0] * x0) + r2[1] * x1) + r2[2] * x2;
        s3 = (((s3 + r3[0] * x0) + r3[1] * x1) + r3[2] * x2) + r3[3] * x3;
        g[i] = ((s0 + r1[0] * x1) + r2[0] * x2) + r3[0] * x3;
        g[i + 1] = (s1 + r2[1] * x2) + r3[1] * x3;
        g[i + 2] = s2 + r3[2] * x3;
        g[i + 3] = s3;
    }
    for (; i < n; ++i) {
        const rollmpc_real *r0 = &mp[ROLLMPC_TRI(i, 0)];
        const rollmpc_real x0 = x[i];
        rollmpc_real s0 = R_(0.0);
        int j;
        for (j = 0; j < i; ++j) {
            s0 += r0[j] * x[j];
            g[j] += r0[j] * x0;
        }
        g[i] = s0 + r0[i] * x0;
    }
}

/*
 * out[i] = sum_l M[i nc + l] v[l] for i < rows (M row-major), each a sequential sum from
 * 0 as the reference's seqsum_rows(); four rows per trip share each load of v.
 */
static void matvec_rows(const rollmpc_real *M, int rows, int nc, const rollmpc_real *v,
    rollmpc_real *out)
{
    int i, l;
    for (i = 0; i + 3 < rows; i += 4) {
        const rollmpc_real *m0 = &M[i * nc], *m1 = m0 + nc, *m2 = m1 + nc, *m3 = m2 + nc;
        rollmpc_real s0 = R_(0.0), s1 = R_(0.0), s2 = R_(0.0), s3 = R_(0.0);
        for (l = 0; l < nc; ++l) {
            const rollmpc_real vl = v[l];
            s0 += m0[l] * vl;
            s1 += m1[l] * vl;
            s2 += m2[l] * vl;
            s3 += m3[l] * vl;
        }
        out[i] = s0;
        out[i + 1] = s1;
        out[i + 2] = s2;
        out[i + 3] = s3;
    }
    for (; i < rows; ++i) {
        const rollmpc_real *m0 = &M[i * nc];
        rollmpc_real s0 = R_(0.0);
        for (l = 0; l < nc; ++l) {
            s0 += m0[l] * v[l];
        }
        out[i] = s0;
    }
}

/*
 * Runs of equal w over the stages 0..N-2: ws->lists.run[0..count) are their first stages and
 * ws->lists.run[count] = N-1. Returns count; *longest is the first longest run (-1 if none).
 */
static int reference_runs(rollmpc_work *ws, const rollmpc_mode_data *md, int *longest)
{
    const int ny = md->ny, last = md->nyq / md->ny - 1;
    const rollmpc_real *w = ws->yv;
    int k = 0, j, count = 0, best = -1, best_len = 0;
    if (last > 0) {
        ws->lists.run[count++] = 0;
    }
    while (k < (last - 1) * ny) { /* w_k of stage k / ny against the same output a stage later */
        if (w[k] < w[k + ny] || w[k] > w[k + ny]) {
            const int stage = k / ny + 1;
            ws->lists.run[count++] = (int16_t)stage;
            k = stage * ny; /* on to the next pair of stages */
        } else {
            ++k;
        }
    }
    ws->lists.run[count] = (int16_t)last;
    for (j = 0; j < count; ++j) {
        const int len = ws->lists.run[j + 1] - ws->lists.run[j];
        if (len > best_len) {
            best_len = len;
            best = j;
        }
    }
    *longest = best;
    return count;
}

/*
 * g[from ny] + ... + g[(to - 1) ny], in stage order from 0; four terms per loop trip when
 * the stages are neighbours (one output) and the target's frames allow it (WIDE_KERNELS).
 */
static rollmpc_real stage_sum(const rollmpc_real *g, int from, int to, int ny)
{
    rollmpc_real sum = R_(0.0);
    const rollmpc_real *p = &g[from * ny], *end = &g[to * ny];
#if ROLLMPC_WIDE_KERNELS
    if (ny == 1) {
        for (; end - p >= 4; p += 4) {
            sum += p[0];
            sum += p[1];
            sum += p[2];
            sum += p[3];
        }
    }
#endif
    for (; p != end; p += ny) {
        sum += *p;
    }
    return sum;
}

/*
 * For output a, the runs other than the longest (nruns > 1): th0_i += w_j s_ij in run
 * order, s_ij the sum of row i's columns (stage, a) of E^-1 G' over run j, and
 * coef_i = colsum_(a,i) - sum_j s_ij, the longest run's column sum.
 */
static void other_runs(rollmpc_work *ws, const rollmpc_mode_data *md, int a, int nruns,
    int longest, rollmpc_real *coef)
{
    const int n = md->n, ny = md->ny, nyq = md->nyq;
    const rollmpc_real *g = &md->EinvGt[a], *w = &ws->yv[a]; /* g[i nyq + stage ny] */
    int i, j;
    for (i = 0; i < n; ++i, g += nyq) {
        rollmpc_real acc = ws->th0[i], other = R_(0.0);
        for (j = 0; j < nruns; ++j) {
            if (j != longest) {
                const rollmpc_real sum = stage_sum(g, ws->lists.run[j], ws->lists.run[j + 1],
                    ny);
                acc += w[ws->lists.run[j] * ny] * sum;
                other += sum;
            }
        }
        ws->th0[i] = acc;
        coef[i] = md->colsum[a * n + i] - other;
    }
}

/*
 * th0 = Kx x + E^-1 G' w with w = 2 Omega r (kept in ws->yv, free until the outputs are
 * predicted); px = Phi x (output rows only).
 * The columns of E^-1 G' are summed per run of equal w; the longest run's sum comes from
 * colsum minus the others, so a held reference costs n (nx + 2 ny) instead of n (nx + N ny).
 * Each th0_i takes its terms in the reference's order: Kx x, then per output a the other
 * runs, the longest and the last stage, with the loop over i innermost. ws->th, which the
 * caller then sets to th0, holds the longest run's sums when there are other runs.
 */
static void unconstrained(rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *x, const rollmpc_real *r)
{
    const int n = md->n, ny = md->ny, nyq = md->nyq, last = md->nyq / md->ny - 1;
    int i, k, l, a, b, nruns, longest, summed;
    for (k = 0, b = 0; k < nyq; ++k) { /* b = k % ny: row b of stage k / ny's block 2 Omega */
        const rollmpc_real *om = &md->Omega2[k * ny], *rs = &r[k - b];
        rollmpc_real acc = R_(0.0);
        for (l = 0; l < ny; ++l) {
            acc += om[l] * rs[l];
        }
        ws->yv[k] = acc;
        b = (b + 1 < ny) ? b + 1 : 0;
    }
    nruns = reference_runs(ws, md, &longest);
    summed = last - ((longest >= 0) ? ws->lists.run[longest + 1] - ws->lists.run[longest] : 0);
    matvec_rows(md->Kx, n, md->nx, x, ws->th0);
    for (a = 0; a < ny; ++a) {
        const rollmpc_real w_last = ws->yv[last * ny + a];
        const rollmpc_real w_long = (longest >= 0)
            ? ws->yv[ws->lists.run[longest] * ny + a] : R_(0.0);
        const rollmpc_real *g = &md->EinvGt[last * ny + a]; /* g[i nyq]: the last stage */
        const rollmpc_real *coef = &md->colsum[a * n]; /* one run: colsum - 0 = colsum */
        if (nruns > 1) {
            other_runs(ws, md, a, nruns, longest, ws->th);
            coef = ws->th;
        }
        for (i = 0; i < n; ++i, g += nyq) {
            rollmpc_real acc = ws->th0[i];
            if (longest >= 0) {
                acc += w_long * coef[i];
            }
            ws->th0[i] = acc + *g * w_last;
        }
    }
    ws->work += (uint32_t)nyq * (uint32_t)ny + (uint32_t)n * (uint32_t)md->nx
        + (uint32_t)n * (uint32_t)ny * ((uint32_t)summed + (uint32_t)nruns + 2u);
    if (md->GEinvGt_p != 0) {
        ws->work += (uint32_t)nyq * (uint32_t)md->nx;
        matvec_rows(md->Phi, nyq, md->nx, x, ws->px);
    }
}

/*
 * yv = Gamma T th: the Markov sum over the stages, stage t reading its block's input.
 * Each output sums its terms in (t, b) order, as the reference does: output a of stage s
 * is row a of md->markov_by_output (lags descending) from lag s down, times th from
 * stage 0, one contiguous dot product (stage t reading its block's
 * inputs). Only the outputs md->pred_out[0..ny_pred) are predicted, those with
 * constraint rows: no row reads the others, which stay 0.
 */
static void predict_outputs(rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *th)
{
    const int ny = md->ny, nu = md->nu, nyq = md->nyq, npred = md->ny_pred;
    const int row_len = (nyq / ny) * nu; /* N nu */
    int s, i, j;
    ws->work += predict_work(md);
    if (npred != ny) {
        for (s = 0; s < nyq; ++s) {
            ws->yv[s] = R_(0.0);
        }
    }
    for (s = 0; s < nyq / ny; ++s) {
        const int len = (s + 1) * nu; /* inputs of stages 0..s */
        const int first = row_len - len; /* lag s in each row of markov_by_output */
        for (i = 0; i + 1 < npred; i += 2) { /* two outputs of the stage share th's reads */
            const int a0 = (npred == ny) ? i : md->pred_out[i];
            const int a1 = (npred == ny) ? i + 1 : md->pred_out[i + 1];
            const rollmpc_real *m0 = &md->markov_by_output[a0 * row_len + first];
            const rollmpc_real *m1 = &md->markov_by_output[a1 * row_len + first];
            rollmpc_real acc0 = R_(0.0), acc1 = R_(0.0);
            int t, b;
            for (t = 0, j = 0; t <= s; ++t) {
                const rollmpc_real *u = &th[md->stage_block[t] * nu];
                for (b = 0; b < nu; ++b, ++j) {
                    acc0 += m0[j] * u[b];
                    acc1 += m1[j] * u[b];
                }
            }
            ws->yv[s * ny + a0] = acc0;
            ws->yv[s * ny + a1] = acc1;
        }
        if (i < npred) { /* an odd last output alone */
            const int a0 = (npred == ny) ? i : md->pred_out[i];
            const rollmpc_real *m0 = &md->markov_by_output[a0 * row_len + first];
            rollmpc_real acc0 = R_(0.0);
            int t, b;
            for (t = 0, j = 0; t <= s; ++t) {
                const rollmpc_real *u = &th[md->stage_block[t] * nu];
                for (b = 0; b < nu; ++b, ++j) {
                    acc0 += m0[j] * u[b];
                }
            }
            ws->yv[s * ny + a0] = acc0;
        }
    }
}

/* Value of row r's quantity at th (yv must hold Gamma th). */
static rollmpc_real row_value(const rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *th, int r)
{
    const int q = md->row_q[r];
    return (q < md->n) ? th[q] : ws->yv[q - md->n];
}

/*
 * 1 if no output row can be violated at th: |(Gamma th)_k| <= out_bound_k max|th| <= gamma_r
 * (out_bound carries the rounding margin), so the N^2/2 prediction can be skipped.
 * Charged by what it reads: th, the signal bounds and the predicted rows up to the first
 * it cannot clear (certificate_work() is the most; the ny bounds of the last stage ride
 * with th).
 */
static int outputs_certified(rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *th)
{
    const int16_t *rows = &md->scan_rows[md->m_box]; /* the predicted rows */
    const int count = md->m - md->m_box;
    rollmpc_real thmax = R_(0.0), bmax = R_(0.0);
    int i;
    ws->work += certificate_read_work(md);
    for (i = 0; i < md->n; ++i) {
        const rollmpc_real v = ROLLMPC_FABS(th[i]);
        thmax = (v > thmax) ? v : thmax;
    }
    for (i = md->nyq - md->ny; i < md->nyq; ++i) { /* out_bound grows along the horizon */
        bmax = (md->out_bound[i] > bmax) ? md->out_bound[i] : bmax;
    }
    if (bmax * thmax <= ws->gam_out_min) {
        return 1; /* the largest bound against the tightest output row */
    }
    for (i = 0; i < count; ++i) { /* the output and signal rows only, ascending */
        const int r = rows[i], q = md->row_q[r];
        if (!(md->out_bound[q - md->n] * thmax <= ws->gam[r])) {
            break;
        }
    }
    ws->work += (uint32_t)((i < count) ? i + 1 : i);
    return i >= count;
}

/* K = gamma - M th0 of the output rows (needs the N^2/2 prediction of th0). */
static void output_slacks(rollmpc_work *ws, const rollmpc_mode_data *md)
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
            const rollmpc_real v = ws->yv[q - md->n];
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
static int slacks(rollmpc_work *ws, const rollmpc_mode_data *md)
{
    const int16_t *row_q = md->row_q;
    const int8_t *row_sign = md->row_sign;
    const rollmpc_real *px = ws->px, *th0 = ws->th0;
    rollmpc_real *gam = ws->gam, *K = ws->K, out_min = ROLLMPC_LAMBDA_LIMIT;
    int r, count = 0;
    ws->work += 2u * (uint32_t)md->m;
    for (r = 0; r < md->m; ++r) {
        const int q = row_q[r];
        rollmpc_real g = md->row_c[r];
        if (q >= md->n) {
            const rollmpc_real p = px[q - md->n];
            g = (row_sign[r] > 0) ? g - p : g + p;
            out_min = (g < out_min) ? g : out_min;
        } else {
            const rollmpc_real v = th0[q];
            const rollmpc_real k = (row_sign[r] > 0) ? g - v : g + v;
            K[r] = k;
            count += (k < R_(0.0));
        }
        gam[r] = g;
    }
    ws->gam_out_min = out_min;
    ws->out_slacks_ok = md->GEinvGt_p == 0;
    if (!ws->out_slacks_ok && !outputs_certified(ws, md, ws->th0)) {
        output_slacks(ws, md);
        for (r = 0; r < md->m; ++r) {
            count += (md->row_q[r] >= md->n && ws->K[r] < R_(0.0));
        }
    }
    return count;
}

/* 1 if there are output rows and outputs_certified() cannot clear them at th. */
static int outputs_uncertified(rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *th)
{
    return md->GEinvGt_p != 0 && !outputs_certified(ws, md, th);
}

/*
 * 1 if the output rows need checking at th (not certified); ws->yv then holds Gamma th.
 * 0 if there are none or none can be violated.
 */
static int outputs_to_check(rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *th)
{
    if (!outputs_uncertified(ws, md, th)) {
        return 0;
    }
    predict_outputs(ws, md, th);
    return 1;
}

/*
 * M_r th - gamma_r: the violation of row r at th (positive = violated). inline: called per
 * row in the polish's checks; out of line it cost ~1.5k cycles on the median M4F step.
 */
static inline rollmpc_real row_excess(const rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *th, int r)
{
    const rollmpc_real v = row_value(ws, md, th, r);
    const rollmpc_real g = ws->gam[r];
    return by_sign(md, r, v) - g;
}

/* max(1, |gamma_r|): the feasibility tolerance of row r is FEAS_TOL times this. */
static inline rollmpc_real tol_scale(const rollmpc_work *ws, int r)
{
    const rollmpc_real ag = ROLLMPC_FABS(ws->gam[r]);
    return (ag > R_(1.0)) ? ag : R_(1.0);
}

/* Is row r violated at th beyond its tolerance? */
static int row_violated(const rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *th, int r)
{
    return row_excess(ws, md, th, r) > ROLLMPC_SOLVER_FEAS_TOL * tol_scale(ws, r);
}

/*
 * The dependence test of every pivot of the dual factor (a joining row's, a factor from
 * scratch's, a downdate's): 1 when its square keeps more than DEPENDENCE_TOL of the row's
 * diagonal entry, i.e. the row is independent of the rows before it.
 */
static int pivot_independent(rollmpc_real square, rollmpc_real diagonal)
{
    return square > ROLLMPC_SOLVER_DEPENDENCE_TOL * diagonal;
}

/*
 * L L' +- v v' on the trailing block of the packed factor l (order n) from row and column
 * `from` on, v holding the vector's entries from..n-1 (overwritten): the rotations of the
 * classic rank-one update, hyperbolic ones for a downdate. No entry of H is read again.
 * `carry` (ncarry columns of stride N_MAX, or none) are solves y = L^-1 b that the same
 * rotations carry along (chol_delete()): column o's entry n holds the extra one.
 * Returns -1 when a downdated pivot keeps no more than DEPENDENCE_TOL of its square: the
 * factor is then not valid, and the caller refactors from scratch.
 */
static int chol_rank_one(rollmpc_real *l, int from, int n, rollmpc_real *v, int downdate,
    rollmpc_real *carry, int ncarry)
{
    int i, j, o;
    for (j = from; j < n; ++j) {
        const rollmpc_real ljj = l[ROLLMPC_TRI(j, j)], vj = v[j];
        const rollmpc_real r2 = downdate ? (ljj - vj) * (ljj + vj) : ljj * ljj + vj * vj;
        rollmpc_real r, c, s, ic;
        int off = ROLLMPC_TRI(j + 1, j); /* column j below the diagonal: stride i + 1 */
        if (downdate && !pivot_independent(r2, ljj * ljj)) {
            return -1;
        }
        r = ROLLMPC_SQRT(r2);
        c = r / ljj;
        s = vj / ljj;
        ic = ljj / r;
        l[ROLLMPC_TRI(j, j)] = r;
        for (i = j + 1; i < n; ++i) {
            const rollmpc_real lij = (downdate ? l[off] - s * v[i] : l[off] + s * v[i]) * ic;
            l[off] = lij;
            v[i] = c * v[i] - s * lij;
            off += i + 1;
        }
        for (o = 0; o < ncarry; ++o) { /* entry j of the solve, as an entry of column j */
            rollmpc_real *y = &carry[o * ROLLMPC_N_MAX];
            const rollmpc_real yj = (downdate ? y[j] - s * y[n] : y[j] + s * y[n]) * ic;
            y[j] = yj;
            y[n] = c * y[n] - s * yj;
        }
    }
    return 0;
}

/*
 * Delete row and column k of the factored matrix (order n): the rows below k move up one,
 * dropping their entry k, and that entry (the column below the old pivot) updates the
 * trailing block by rank one. v: scratch of n entries. The solves `carry` (ncarry
 * columns of stride N_MAX, L^-1 b for right-hand sides b) become those of b without entry
 * k: their entries below k move up and the same rotations take entry k out.
 */
static void chol_delete(rollmpc_real *l, int k, int n, rollmpc_real *v,
    rollmpc_real *carry, int ncarry)
{
    int i, j, o, dst = ROLLMPC_TRI(k, 0), src = ROLLMPC_TRI(k + 1, 0);
    for (i = k + 1; i < n; ++i) {
        for (j = 0; j <= i; ++j, ++src) {
            if (j == k) {
                v[i - 1] = l[src];
            } else {
                l[dst++] = l[src];
            }
        }
    }
    for (o = 0; o < ncarry; ++o) { /* entry k to the end, where the rotations read it */
        rollmpc_real *y = &carry[o * ROLLMPC_N_MAX];
        const rollmpc_real yk = y[k];
        for (i = k + 1; i < n; ++i) {
            y[i - 1] = y[i];
        }
        y[n - 1] = yk;
    }
    (void)chol_rank_one(l, k, n - 1, v, 0, carry, ncarry); /* an update cannot break down */
}

/*
 * th += S^-1 e_j v, then S^-1 e_(j+1) w, and nu += Ew e_j v, then Ew e_(j+1) w: each entry
 * takes the two terms in that order, as two passes one column after the other would give
 * it, in one pass (S^-1 packed lower: rows j and j + 1 above the diagonal block, then
 * columns j and j + 1, neighbours in every row below it).
 */
static void add_sinv_pair(rollmpc_work *ws, const rollmpc_mode_data *md, int j,
    rollmpc_real v, rollmpc_real w)
{
    const int n = md->n;
    const rollmpc_real *rj = &md->Sinv_p[ROLLMPC_TRI(j, 0)], *rk = rj + j + 1;
    int i, o, off = ROLLMPC_TRI(j + 2, j);
    for (i = 0; i < j; ++i) {
        ws->th[i] += rj[i] * v;
        ws->th[i] += rk[i] * w;
    }
    ws->th[j] += rj[j] * v;
    ws->th[j] += rk[j] * w;
    ws->th[j + 1] += rk[j] * v;
    ws->th[j + 1] += rk[j + 1] * w;
    for (i = j + 2; i < n; ++i) {
        ws->th[i] += md->Sinv_p[off] * v;
        ws->th[i] += md->Sinv_p[off + 1] * w;
        off += i + 1;
    }
    for (o = 0; o < md->nt; ++o) {
        ws->nu[o] += md->Ew[o * n + j] * v;
        ws->nu[o] += md->Ew[o * n + j + 1] * w;
    }
}

/* correct()'s ``how``: mult[j] of list[j], or mult[row]; a step from ws->th (below). */
#define CORRECT_BY_LIST 0
#define CORRECT_BY_ROW 1
#define CORRECT_STEP 2

/*
 * th = th0 - E^-1 M_L' mult over the rows L = list[0..count) with a positive multiplier.
 * With CORRECT_STEP, th = th + E^-1 M_L' mult instead, over every nonzero multiplier: a
 * step of iterative refinement, which adds E^-1 M_L' times the small change of the
 * multipliers (negated) to the point, not their large total to th0 (refine_dual()).
 * The multipliers are first summed by quantity, v = M_L' mult (inputs into ws->dv, outputs
 * into ws->yv, a Δu row into its two inputs), then E^-1 v = S^-1 v_in - Ew' (Ew v_in)
 * + E^-1 G' v_out is accumulated in ws->th column by column over the nonzero entries of v
 * (Ew v_in in ws->nu): n (nnz + nt) + nt nnz_in operations, where reading E^-1 M_L' entry
 * by entry cost n |L| reads of E^-1 (nt operations each for an input, twice for a Δu row).
 */
static void correct(rollmpc_work *ws, const rollmpc_mode_data *md, const int16_t *list,
    int count, const rollmpc_real *mult, int how)
{
    const int n = md->n, nyq = md->nyq, nt = md->nt, from_th = (how == CORRECT_STEP);
    int i, j, o;
    uint32_t nin = 0u, nout = 0u; /* the quantities met: the work charged */
    for (i = 0; i < n; ++i) {
        ws->dv[i] = R_(0.0);
        if (!from_th) {
            ws->th[i] = R_(0.0);
        }
    }
    for (i = 0; i < nyq; ++i) {
        ws->yv[i] = R_(0.0);
    }
    for (o = 0; o < nt; ++o) {
        ws->nu[o] = R_(0.0);
    }
    for (j = 0; j < count; ++j) {
        const int s = list[j], q = md->row_q[s];
        const rollmpc_real mu = (how == CORRECT_BY_ROW) ? mult[s] : mult[j];
        if (mu > R_(0.0) || (from_th && mu < R_(0.0))) {
            const rollmpc_real v = by_sign(md, s, mu);
            if (q < n) {
                ws->dv[q] += v;
            } else {
                ws->yv[q - n] += v;
            }
        }
    }
    for (j = 0; j < n; ++j) {
        const rollmpc_real v = ws->dv[j];
        if (v < R_(0.0) || v > R_(0.0)) {
            const rollmpc_real w = (j + 1 < n) ? ws->dv[j + 1] : R_(0.0);
            if (w < R_(0.0) || w > R_(0.0)) { /* columns j and j + 1 in one pass */
                nin += 2u;
                add_sinv_pair(ws, md, j, v, w);
                ++j;
                continue;
            }
            ++nin;
            for (i = 0; i < j; ++i) { /* S^-1 is packed lower: row j, then column j */
                ws->th[i] += md->Sinv_p[ROLLMPC_TRI(j, i)] * v;
            }
            for (i = j; i < n; ++i) {
                ws->th[i] += md->Sinv_p[ROLLMPC_TRI(i, j)] * v;
            }
            for (o = 0; o < nt; ++o) {
                ws->nu[o] += md->Ew[o * n + j] * v;
            }
        }
    }
    for (i = 0; i < n; ++i) {
        rollmpc_real acc = ws->th[i];
        for (o = 0; o < nt; ++o) {
            acc -= md->Ew[o * n + i] * ws->nu[o];
        }
        ws->th[i] = acc;
    }
    for (j = 0; j < nyq; ++j) {
        const rollmpc_real v = ws->yv[j];
        if (v < R_(0.0) || v > R_(0.0)) {
            ++nout;
            for (i = 0; i < n; ++i) {
                ws->th[i] += md->EinvGt[i * nyq + j] * v;
            }
        }
    }
    if (!from_th) {
        for (i = 0; i < n; ++i) {
            ws->th[i] = ws->th0[i] - ws->th[i];
        }
    }
    ws->work += correct_cost(md, count, nin, nout);
}

/* Rebuild the sorted row list of the sweep set from the membership flags. */
static int build_set(rollmpc_work *ws, const rollmpc_mode_data *md)
{
    int r, count = 0;
    ws->work += (uint32_t)md->m;
    for (r = 0; r < md->m; ++r) {
        if (ws->in_set[r]) {
            ws->lists.set[count++] = (int16_t)r;
        }
    }
    return count;
}

/*
 * One (SOR) Gauss-Seidel sweep of eq. (7) over the set. Returns the squared step
 * norm; sets *diverged when a multiplier exceeds ROLLMPC_LAMBDA_LIMIT.
 */
static rollmpc_real sweep(rollmpc_work *ws, const rollmpc_mode_data *md,
    rollmpc_real *lam, int count, int *diverged)
{
    const rollmpc_real omega = ROLLMPC_SOLVER_OMEGA;
    rollmpc_real e2 = R_(0.0);
    int jr, js;
    ws->work += sweep_work(md, count);
    for (jr = 0; jr < count; ++jr) {
        const int r = ws->lists.set[jr];
        rollmpc_real acc = R_(0.0), t, wv, nl, d;
        for (js = 0; js < count; ++js) {
            const int s = ws->lists.set[js];
            if (s != r && lam[s] > R_(0.0)) {
                acc += h_rows(md, r, s) * lam[s];
            }
        }
        t = -(ws->K[r] + acc) / hq(md, md->row_q[r], md->row_q[r]);
        wv = (R_(1.0) - omega) * lam[r] + omega * t;
        nl = (wv > R_(0.0)) ? wv : R_(0.0);
        d = nl - lam[r];
        e2 += d * d;
        lam[r] = nl;
        if (!(nl <= ROLLMPC_LAMBDA_LIMIT)) {
            *diverged = 1;
        }
    }
    return e2;
}

/*
 * Rows of one kind (outputs = 0: input and Δu rows, 1: output rows) violated at th and
 * not flagged in `member` (0: no row is), appended in row order to out; cap + 1 when more
 * than cap. Charged m, a scan of every row, whichever kind it reads.
 */
static int violated_kind(rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *th, const uint8_t *member, int16_t *out, int cap, int outputs)
{
    const int m = md->m;
    const rollmpc_real *gam = ws->gam;
    const rollmpc_real *values = outputs ? ws->yv : th; /* of quantity q at q - base */
    const int base = outputs ? md->n : 0;
    /* this kind's rows, ascending (md->scan_rows): the other kind is not even read */
    const int16_t *rows = outputs ? &md->scan_rows[md->m_box] : md->scan_rows;
    const int count = outputs ? m - md->m_box : md->m_box;
    int i, nout = 0;
    ws->work += (uint32_t)m;
    for (i = 0; i < count; ++i) {
        const int r = rows[i];
        rollmpc_real v, g, viol, ag;
        /* row_violated() inline: the tolerance is at least FEAS_TOL, so reject early */
        v = values[md->row_q[r] - base];
        g = gam[r];
        viol = by_sign(md, r, v) - g;
        if (!(viol > ROLLMPC_SOLVER_FEAS_TOL)) {
            continue;
        }
        ag = ROLLMPC_FABS(g);
        if (!(viol > ROLLMPC_SOLVER_FEAS_TOL * (ag > R_(1.0) ? ag : R_(1.0)))) {
            continue;
        }
        if (member != 0 && member[r]) {
            continue;
        }
        if (nout == cap) {
            return cap + 1;
        }
        out[nout++] = (int16_t)r;
    }
    return nout;
}

/*
 * Violated rows at th outside the flagged ones (see violated_kind()): the input rows
 * first; only when none is violated, the output rows (predicted unless certified), so an
 * intermediate point far outside the input box costs no output prediction.
 */
static int violated_outside(rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *th, const uint8_t *member, int16_t *out, int cap)
{
    const int nbox = violated_kind(ws, md, th, member, out, cap, 0);
    if (nbox != 0 || !outputs_to_check(ws, md, th)) {
        return nbox;
    }
    return violated_kind(ws, md, th, member, out, cap, 1);
}

/*
 * The primal solve works on one of two forms (E = S + V'(2P)V split, d = U - th0):
 *  - free form (FORM_FREE): Cholesky L of S_FF over the free inputs F;
 *  - bound form (FORM_BOUND): Cholesky L of (S^-1)_BB over the bound inputs B.
 * Consecutive solves differ by a few inputs, so the factor is kept and updated:
 * its rows follow an order that keeps the rows of the last full factorisation first (the
 * head) and the inputs that joined since at the end, in joining order (the tail; see
 * primal_order()). An input that joins factors only its own row (the row-oriented
 * Cholesky computes row i from the rows above it alone). The row of one that leaves is
 * deleted by a rank-one update of the rows below it, Y carried along (primal_deletes(),
 * chol_delete()), when that costs less than factoring those rows again from its
 * position; else they are factored again. The NumPy reference keeps the factor as the C
 * does and mirrors both, bit for bit. Whatever else writes ws->chol in between (the dual
 * solves) makes the next primal solve factor from scratch.
 *
 * ws->input_role[i] flags input i (ROLE_*) and, for a tail row, holds its generation:
 * 1 for the inputs that joined at the first update, one more at each update that appends
 * inputs. ws->primal_rows[0..primal_k) are the factor's rows in order, the first
 * ws->primal_head of them its head; with ws->primal_form they describe the factor of the
 * previous primal solve, of this QP or of the mode's last one (the matrices are the mode's:
 * a shifted working set keeps most of its inputs; primal_form = FORM_NONE when the last QP
 * was another mode's, see forget_factor()). The order is kept, not derived again from the
 * roles: an update keeps the previous rows that stay, in their order, and appends the
 * inputs that join, so it reads the previous rows once and the inputs once. The factor is
 * intact while ws->chol_holds is CHOL_PRIMAL: every other writer of ws->chol changes it.
 */
enum { ROLE_BOUND = 1, ROLE_HEAD = 2, ROLE_TAIL = 4 }; /* bound now; in the head, tail */
enum { ROLE_GEN_ONE = 8, ROLE_GEN_MAX = 31 }; /* a tail row's generation: role / 8 */
enum { FORM_NONE = 0, FORM_FREE = 1, FORM_BOUND = 2 };

/*
 * Six times the multiply-adds of a primal solve with a factor of order k whose rows from
 * p on are factored: the rows of A, their Cholesky, Y's rows, the two
 * solves and the k (n - k) product with the other inputs (-S_FB d_B, or S^-1_FB beta).
 * The same in both forms; the choice between updating and refactoring compares it.
 * (Six times: every term is then an integer product, with no 64-bit division, which
 * the M4F would call libgcc for.)
 */
static int64_t primal_cost(const rollmpc_mode_data *md, int64_t k, int64_t p)
{
    const int64_t n = md->n, nt = md->nt;
    const int64_t factor = (k * k * k - k - p * p * p + p) + 3 * (k * (k + 1) - p * (p + 1));
    const int64_t solves = 3 * nt * (k * k - k - p * p + p) + 6 * (k * k - k);
    return factor + solves + 6 * k * (n - k);
}

/*
 * The order of a new primal factor on nw bound inputs of n: the bound form's (nw) when
 * fewer are bound than free, else the free form's (primal_solve() picks the form so).
 */
static int factor_order(int nw, int n)
{
    return (nw < n - nw) ? nw : n - nw;
}

/* Is an input of this role a row of a factor of this form (bound inputs, or free ones)? */
static int in_form(int role, int form)
{
    return ((role & ROLE_BOUND) != 0) == (form == FORM_BOUND);
}

/* The generation of a tail row (0 for the others). */
static int role_gen(int role)
{
    return (int)((unsigned)role / ROLE_GEN_ONE); /* a shift: a role is never negative */
}

/*
 * Compare the factor of the previous solve (form ws->primal_form, rows ws->primal_rows)
 * with the nw bound inputs of n now: returns the order k of the updated factor (the
 * inputs of that form), sets *from to the first row that changes (the first to leave, in
 * the factor's order, or else the first to join, after every kept row), *head to the rows
 * its head keeps, *newest to the last generation of the tail rows it keeps and *joined
 * to the inputs that join. Cost: a role read per previous row.
 */
static int primal_diff(const rollmpc_work *ws, int nw, int n, int *from, int *head,
    int *newest, int *joined)
{
    const int form = ws->primal_form, k_old = ws->primal_k, heads = ws->primal_head;
    const int k = (form == FORM_BOUND) ? nw : n - nw;
    int pos, kept = 0, leave = -1;
    *head = 0;
    *newest = 0;
    for (pos = 0; pos < k_old; ++pos) {
        const int role = ws->input_role[ws->primal_rows[pos]];
        if (in_form(role, form)) {
            const int g = role_gen(role); /* 0 in the head */
            ++kept;
            *head += pos < heads;
            *newest = (g > *newest) ? g : *newest;
        } else {
            leave = (leave < 0) ? pos : leave;
        }
    }
    *from = (leave < 0) ? k_old : leave;
    *joined = k - kept;
    return k;
}

/*
 * The rows of the factor in order into ws->tmp[0..k) and ws->primal_rows: a new factor
 * (!update) has them all as its head, in descending inputs in the free form and ascending
 * in the bound form: in an MPC plan the inputs that saturate come first along the
 * horizon, so the inputs next to the saturated ones, where the working set changes, come
 * last. An update keeps the previous rows that stay in their order (the head's rows that
 * stay, then the tail's by generation, each generation in the head's order) and appends
 * the inputs that join as generation newest + 1, in the head's order. The other inputs
 * follow in ws->tmp[k..n), ascending. Sets the roles to match and ws->primal_form,
 * ws->primal_head, ws->primal_k.
 */
static void primal_order(rollmpc_work *ws, int n, int form, int update, int k, int head,
    int newest)
{
    const int down = form == FORM_FREE, stride = down ? -1 : 1;
    const int join_role = update ? ROLE_TAIL | ((newest + 1) * ROLE_GEN_ONE) : ROLE_HEAD;
    int i, kept = 0, rest = k, at;
    if (update) {
        for (i = 0; i < ws->primal_k; ++i) {
            const int q = ws->primal_rows[i];
            if (in_form(ws->input_role[q], form)) {
                ws->tmp[kept++] = (int16_t)q;
            }
        }
    }
    at = down ? k - 1 : kept; /* the rows that join (all of a new factor's) */
    for (i = 0; i < n; ++i) {
        const int role = ws->input_role[i], bound = role & ROLE_BOUND;
        if (!in_form(role, form)) {
            ws->tmp[rest++] = (int16_t)i;
            ws->input_role[i] = (uint8_t)bound;
        } else if (!update || (role & (ROLE_HEAD | ROLE_TAIL)) == 0) {
            const int joined = bound | join_role;
            ws->tmp[at] = (int16_t)i;
            at += stride;
            ws->input_role[i] = (uint8_t)joined;
        } else {
            /* a kept row: in its place from the previous order, its role unchanged */
        }
    }
    for (i = 0; i < k; ++i) {
        ws->primal_rows[i] = ws->tmp[i];
    }
    ws->primal_form = (int16_t)form;
    ws->primal_head = (int16_t)head;
    ws->primal_k = (int16_t)k;
}

/*
 * The rows of the previous factor (order k_old, in ws->primal_rows) whose inputs left the form,
 * deleted from the last up by chol_delete(), Y's columns carried (apply), or only costed
 * (!apply). Returns their work.
 */
static uint32_t primal_deletes(rollmpc_work *ws, const rollmpc_mode_data *md, int k_old,
    int apply)
{
    const int form = ws->primal_form;
    int pos, k = k_old;
    uint32_t work = 0u;
    for (pos = k_old - 1; pos >= 0; --pos) {
        if (!in_form(ws->input_role[ws->primal_rows[pos]], form)) {
            work += primal_delete_work(pos, k, md->nt);
            if (apply) {
                chol_delete(ws->chol, pos, k, ws->rhs, ws->ycol, md->nt);
            }
            --k;
        }
    }
    return work;
}

/* Are the working-set rows all input bounds (the primal form's working sets)? */
static int box_only(const rollmpc_work *ws, const rollmpc_mode_data *md, int nw)
{
    int i, box = 1;
    for (i = 0; i < nw; ++i) {
        box = box && md->row_q[ws->wset[i]] < md->n;
    }
    return box;
}

/*
 * The length of the run of consecutive inputs (ascending or descending: *dir = 1 or -1)
 * at rows[c] of rows[0..k).
 */
static int input_run(const int16_t *rows, int c, int k, int *dir)
{
    const int q0 = rows[c];
    int len = 1;
    *dir = 1;
    if (c + 1 < k && (rows[c + 1] == q0 + 1 || rows[c + 1] == q0 - 1)) {
        *dir = rows[c + 1] - q0;
        while (c + len < k && rows[c + len] == q0 + len * *dir) {
            ++len;
        }
    }
    return len;
}

/*
 * The bound form's d_F needs (S^-1 beta)_f for every free input f, with beta zero outside
 * the k bound inputs. The bound inputs are gathered once, ascending, with their beta; each
 * four free rows then walk that short list, four sums per list entry read, with no
 * call or test per run of bound inputs however they are scattered. Each row's terms are
 * added in increasing j, as the dense sum adds them (the terms left out are exact zeros:
 * the same sums to the bit as the NumPy reference's dense row).
 */

/*
 * The inputs whose role has ROLE_BOUND, ascending, into list[0..k), and x at each into
 * xs[0..k). Returns k. Cost: n flag reads.
 */
static int gather_bound(const uint8_t *role, int n, const rollmpc_real *x, int16_t *list,
    rollmpc_real *xs)
{
    int q, k = 0;
    for (q = 0; q < n; ++q) {
        if ((role[q] & ROLE_BOUND) != 0) {
            list[k] = (int16_t)q;
            xs[k] = x[q];
            ++k;
        }
    }
    return k;
}

/*
 * out[rows[b]] = sum_t M(rows[b], list[t]) xs[t] for b < take (<= 4), over the ascending
 * list[0..count) of entries other than the rows (ascending, the last repeated up to four:
 * the same sum again), `lo` of them below rows[0] and `hi` below rows[3]: row q holds
 * M(q, j) for j <= q, column q (entry q of row j) the rest. Below every row the four rows
 * are read along, above every row four entries of one row j; only the few entries among
 * the rows choose per row. Cost: 4 count multiply-adds.
 */
static void gather_dot4(const rollmpc_real *mp, const int16_t *rows, const int16_t *list,
    const rollmpc_real *xs, int count, int lo, int hi, int take, rollmpc_real *out)
{
    const uint32_t q0 = (uint32_t)rows[0], q1 = (uint32_t)rows[1], q2 = (uint32_t)rows[2];
    const uint32_t q3 = (uint32_t)rows[3];
    const rollmpc_real *r0 = &mp[ROLLMPC_TRI(q0, 0u)], *r1 = &mp[ROLLMPC_TRI(q1, 0u)];
    const rollmpc_real *r2 = &mp[ROLLMPC_TRI(q2, 0u)], *r3 = &mp[ROLLMPC_TRI(q3, 0u)];
    rollmpc_real a0 = R_(0.0), a1 = R_(0.0), a2 = R_(0.0), a3 = R_(0.0);
    int t = 0;
    for (; t < lo; ++t) { /* j below every row: along the four rows */
        const uint32_t j = (uint32_t)list[t];
        const rollmpc_real x = xs[t];
        a0 += r0[j] * x;
        a1 += r1[j] * x;
        a2 += r2[j] * x;
        a3 += r3[j] * x;
    }
    for (; t < hi; ++t) { /* j among the rows: along a row above j, down one below it */
        const uint32_t j = (uint32_t)list[t];
        const rollmpc_real *row_j = &mp[ROLLMPC_TRI(j, 0u)];
        const rollmpc_real x = xs[t];
        a0 += ((j < q0) ? r0[j] : row_j[q0]) * x;
        a1 += ((j < q1) ? r1[j] : row_j[q1]) * x;
        a2 += ((j < q2) ? r2[j] : row_j[q2]) * x;
        a3 += ((j < q3) ? r3[j] : row_j[q3]) * x;
    }
    for (; t < count; ++t) { /* j above every row: four entries of row j */
        const uint32_t j = (uint32_t)list[t];
        const rollmpc_real *row_j = &mp[ROLLMPC_TRI(j, 0u)];
        const rollmpc_real x = xs[t];
        a0 += row_j[q0] * x;
        a1 += row_j[q1] * x;
        a2 += row_j[q2] * x;
        a3 += row_j[q3] * x;
    }
    out[q0] = a0; /* take >= 1 */
    if (take > 1) {
        out[q1] = a1;
    }
    if (take > 2) {
        out[q2] = a2;
    }
    if (take > 3) {
        out[q3] = a3;
    }
}

/*
 * out[q] = (M x)_q for each q of the ascending rows[0..nrows), none of them in the list:
 * x zero outside the ascending list[0..k), its values in xs. Four rows a call of
 * gather_dot4(), the last repeated past the end; each call's list entries split where
 * they pass its first and last row. Cost: 4 ceil(nrows / 4) k multiply-adds.
 */
static void gather_product(const rollmpc_real *mp, const int16_t *list,
    const rollmpc_real *xs, int k, const int16_t *rows, int nrows, rollmpc_real *out)
{
    int i, lo = 0;
    for (i = 0; i < nrows; i += 4) {
        const int take = (nrows - i < 4) ? nrows - i : 4;
        int16_t rows4[4];
        int b, hi;
        for (b = 0; b < 4; ++b) {
            rows4[b] = rows[i + ((b < take) ? b : take - 1)];
        }
        for (; lo < k && list[lo] < rows4[0]; ++lo) {
        }
        for (hi = lo; hi < k && list[hi] < rows4[3]; ++hi) {
        }
        gather_dot4(mp, rows4, list, xs, k, lo, hi, take, out);
        lo = hi;
    }
}

/* Runs shorter than this are gathered by listed columns (packed_gather_listed()). */
enum { GATHER_RUN_MIN = 4 };

/*
 * Rows from..k-1 of the factor L (ws->chol) of S_FF (free form) or (S^-1)_BB (bound
 * form) in the order of ws->tmp, and the same rows of Y = L^-1 V_F' or L^-1 Uv_B'
 * (ws->ycol), the rows above being kept, when ws->chol_holds proves both intact (the dual
 * active set uses ycol too); else every row.
 * -1 if a pivot breaks down (the factor is then forgotten).
 */
static int primal_factor(rollmpc_work *ws, const rollmpc_mode_data *md, int k, int from)
{
    const int n = md->n, nt = md->nt, bound = ws->primal_form == FORM_BOUND;
    const rollmpc_real *packed = bound ? md->Sinv_p : md->S_p;
    const rollmpc_real *cols = bound ? md->Uv : md->V;
    rollmpc_real *l = ws->chol;
    int a, c = 0, o, start = (ws->chol_holds == ROLLMPC_CHOL_PRIMAL) ? from : 0;
    while (c < k) { /* A's rows start..k-1: columns c..c+len-1 of each, up to its diagonal */
        int dir, len = input_run(ws->tmp, c, k, &dir), run;
        if (len >= GATHER_RUN_MIN) { /* a run of consecutive inputs: no index reads */
            for (a = (start > c) ? start : c; a < k; ++a) {
                packed_gather(packed, ws->tmp[a], ws->tmp[c], dir,
                              (a - c + 1 < len) ? a - c + 1 : len, &l[ROLLMPC_TRI(a, c)]);
            }
        } else { /* a stretch of short runs (a tail by generation): by listed columns */
            while (c + len < k && (run = input_run(ws->tmp, c + len, k, &dir)) < GATHER_RUN_MIN) {
                len += run;
            }
            for (a = (start > c) ? start : c; a < k; ++a) {
                packed_gather_listed(packed, ws->tmp[a], &ws->tmp[c],
                                     (a - c + 1 < len) ? a - c + 1 : len,
                                     &l[ROLLMPC_TRI(a, c)]);
            }
        }
        c += len;
    }
    if (rollmpc_cholesky_from(l, start, k) != 0) {
        ws->primal_form = FORM_NONE;
        ws->chol_holds = ROLLMPC_CHOL_NONE;
        return -1;
    }
    ws->chol_holds = ROLLMPC_CHOL_PRIMAL;
    for (o = 0; o < nt; ++o) {
        rollmpc_real *y = &ws->ycol[o * ROLLMPC_N_MAX];
        for (a = start; a < k; ++a) {
            y[a] = cols[o * n + ws->tmp[a]];
        }
        rollmpc_chol_lsolve_from(l, start, k, y);
    }
    return 0;
}

/*
 * The terminal multiplier step of both forms, from Y (ws->ycol) and y0 = L^-1 r (ws->rhs):
 * free form (P2inv + Y'Y) nu = Y'y0 + V_B d_B, bound form (T - Y'Y) nu = Y'y0; then
 * w = y0 -/+ Y nu into ws->rhs (free/bound). -1 if the nt x nt factor breaks down.
 */
static int terminal_step(rollmpc_work *ws, const rollmpc_mode_data *md, int k)
{
    const int n = md->n, nt = md->nt, free_form = ws->primal_form == FORM_FREE;
    int a, i, o, p;
    if (nt == 0) {
        return 0;
    }
    for (o = 0; o < nt; ++o) {
        const rollmpc_real *yo = &ws->ycol[o * ROLLMPC_N_MAX];
        rollmpc_real acc;
        for (p = 0; p <= o; ++p) {
            const rollmpc_real *yp = &ws->ycol[p * ROLLMPC_N_MAX];
            acc = R_(0.0);
            for (a = 0; a < k; ++a) {
                acc += yo[a] * yp[a];
            }
            ws->tsmall[ROLLMPC_TRI(o, p)] = free_form ? acc + md->P2inv[o * nt + p]
                                                          : md->T[o * nt + p] - acc;
        }
        acc = R_(0.0);
        for (a = 0; a < k; ++a) {
            acc += yo[a] * ws->rhs[a];
        }
        for (i = k; free_form && i < n; ++i) { /* the bound inputs, ascending */
            acc += md->V[o * n + ws->tmp[i]] * ws->dv[ws->tmp[i]];
        }
        ws->nu[o] = acc;
    }
    if (rollmpc_cholesky(ws->tsmall, nt) != 0) {
        return -1;
    }
    rollmpc_chol_solve(ws->tsmall, nt, ws->nu);
    for (a = 0; a < k; ++a) {
        rollmpc_real acc = ws->rhs[a];
        for (o = 0; o < nt; ++o) {
            const rollmpc_real t = ws->ycol[o * ROLLMPC_N_MAX + a] * ws->nu[o];
            acc = free_form ? acc - t : acc + t;
        }
        ws->rhs[a] = acc;
    }
    return 0;
}

/*
 * Free form: with d_B = bounds - th0_B and nu the terminal multiplier step,
 *     S_FF d_F + V_F' nu = -S_FB d_B,    V d - (2P)^-1 nu = 0,
 * through y0 = L^-1 (-S_FB d_B), the terminal step, and d_F = L'^-1 (y0 - Y nu).
 * Multipliers come later (free_multipliers()), from g = S d + V' nu.
 */
static int primal_solve_free(rollmpc_work *ws, const rollmpc_mode_data *md, int k,
    int by_columns)
{
    const rollmpc_real *l = ws->chol;
    int a;
    /* -S_FB d_B: dv is 0 on the free inputs here, so the sums run over B = tmp[k..n) */
    sparse_rows_dot(md->S_p, ws->tmp, k, ws->dv, &ws->tmp[k], md->n - k, by_columns, ws->rhs);
    for (a = 0; a < k; ++a) {
        ws->rhs[a] = -ws->rhs[a];
    }
    rollmpc_chol_lsolve(l, k, ws->rhs);
    if (terminal_step(ws, md, k) != 0) {
        return -1;
    }
    ws->th_solved = 1; /* nothing below can fail */
    rollmpc_chol_ltsolve(l, k, ws->rhs);
    for (a = 0; a < k; ++a) {
        const int f = ws->tmp[a];
        ws->dv[f] = ws->rhs[a];
        ws->th[f] = ws->th0[f] + ws->rhs[a];
    }
    return 0;
}

/* Row r's multiplier from g = (S d)_q: -/+ (g + V_q' nu) by the row's side. */
static rollmpc_real signed_multiplier(const rollmpc_work *ws, const rollmpc_mode_data *md,
    int r, rollmpc_real g)
{
    const int q = md->row_q[r];
    int o;
    for (o = 0; o < md->nt; ++o) {
        g += md->V[o * md->n + q] * ws->nu[o];
    }
    return -by_sign(md, r, g);
}

/*
 * Multipliers of the free-form solution, z_k = -sign_k g_{q_k} with g = S d + V' nu: the
 * nw x n part of a polish step, so polish() computes them only once the bound inputs make
 * the point feasible. With more than 3/4 of the inputs bound, g = S d for every input at
 * once (sym_product() into ws->rhs, free after the solve) reads S half as often; the
 * sums are the same.
 */
static void free_multipliers(rollmpc_work *ws, const rollmpc_mode_data *md, int nw)
{
    const int n = md->n, all = 4 * nw > 3 * n;
    int a, ready = 0; /* rows whose g came with a row above */
    ws->work += multipliers_work(md, nw); /* granted by the primal_solve() before */
    if (all) {
        sym_product(md->S_p, n, ws->dv, ws->rhs);
    }
    for (a = 0; a < nw; ++a) {
        const int r = ws->wset[a], q = md->row_q[r];
        rollmpc_real g;
        if (all) {
            g = ws->rhs[q];
        } else if (ready) {
            g = ws->rhs[a];
            --ready;
        } else if (a + 3 < nw && md->row_q[ws->wset[a + 1]] == q + 1
                   && md->row_q[ws->wset[a + 2]] == q + 2 && md->row_q[ws->wset[a + 3]] == q + 3) {
            s_row_dot4(md->S_p, n, q, ws->dv, &ws->rhs[a]); /* this row and the next three */
            g = ws->rhs[a];
            ready = 3;
        } else if (a + 1 < nw && md->row_q[ws->wset[a + 1]] == q + 1) {
            s_row_dot2(md->S_p, n, q, ws->dv, &ws->rhs[a]); /* this row and the next */
            g = ws->rhs[a];
            ready = 1;
        } else {
            g = s_row_dot(md->S_p, n, q, ws->dv);
        }
        ws->z[a] = signed_multiplier(ws, md, r, g);
    }
}

/*
 * Bound form, through S^-1 (few bound inputs): with beta = g_B (the bound forces),
 * Uv = V S^-1, T = (2P)^-1 + V S^-1 V' and L L' = (S^-1)_BB,
 *     beta = L'^-1 (y0 + Y nu),  y0 = L^-1 d_B,  (T - Y'Y) nu = Y'y0,
 *     d_F = S^-1_FB beta - Uv_F' nu,  z_k = -sign_k beta_k.
 * ws->tmp[0..k) holds B in factor order, ws->tmp[k..n) the free inputs; on return
 * tmp[0..k) holds B ascending and rhs[0..k) their beta.
 */
static int primal_solve_bound(rollmpc_work *ws, const rollmpc_mode_data *md, int nw)
{
    const int n = md->n, nt = md->nt, k = nw;
    const rollmpc_real *l = ws->chol;
    int i, a, o;
    for (a = 0; a < k; ++a) {
        ws->rhs[a] = ws->dv[ws->tmp[a]];
    }
    rollmpc_chol_lsolve(l, k, ws->rhs);
    if (terminal_step(ws, md, k) != 0) {
        return -1;
    }
    ws->th_solved = 1; /* nothing below can fail */
    rollmpc_chol_ltsolve(l, k, ws->rhs);
    for (a = 0; a < k; ++a) { /* beta, by input: d_B is no longer needed */
        ws->dv[ws->tmp[a]] = ws->rhs[a];
    }
    for (i = 0; i < nw; ++i) {
        const int r = ws->wset[i];
        const rollmpc_real beta = ws->dv[md->row_q[r]];
        ws->z[i] = -by_sign(md, r, beta);
    }
    /* d_F = S^-1_FB beta - Uv_F' nu over the free inputs (tmp[k..n), ascending): beta (in
     * dv) is zero outside B, gathered ascending into tmp[0..k) and rhs[0..k) (the factor's
     * order there is no longer needed: the next solve reads it from the roles); the
     * product lands in th on the free inputs, which the point overwrites */
    (void)gather_bound(ws->input_role, n, ws->dv, ws->tmp, ws->rhs);
    gather_product(md->Sinv_p, ws->tmp, ws->rhs, k, &ws->tmp[k], n - k, ws->th);
    for (i = k; i < n; ++i) {
        const int f = ws->tmp[i];
        rollmpc_real acc = ws->th[f];
        for (o = 0; o < nt; ++o) {
            acc -= md->Uv[o * n + f] * ws->nu[o];
        }
        ws->th[f] = ws->th0[f] + acc;
    }
    return 0;
}

/* Four roles as one word, role b of the four in bits 8b..8b+7 (a compiler merges the four
 * loads, or stores, into one where it can, on any target). */
static uint32_t role_word(const uint8_t *role)
{
    return (uint32_t)role[0] | ((uint32_t)role[1] << 8) | ((uint32_t)role[2] << 16)
        | ((uint32_t)role[3] << 24);
}

static void set_role_word(uint8_t *role, uint32_t w)
{
    role[0] = (uint8_t)w;
    role[1] = (uint8_t)(w >> 8);
    role[2] = (uint8_t)(w >> 16);
    role[3] = (uint8_t)(w >> 24);
}

/*
 * ROLE_BOUND on exactly the inputs of wset[0..nw), and d = 0 on every input (the bound
 * ones get theirs once the solve is granted). Returns the pairs of neighbouring bound
 * inputs (the bound inputs form nw - pairs runs), or -1 if an input has both bounds (not
 * a valid working set). It runs at every correction: the flags are cleared four roles at
 * a time (role_word(), ROLE_BOUND being bit 0 of each), and the pairs counted in one pass
 * over the roles rather than by two neighbour tests per row. (Counting the pairs by words
 * too took polish()'s host frame 16 B past its stack budget.)
 */
static int mark_bound_inputs(rollmpc_work *ws, const rollmpc_mode_data *md, int nw)
{
    const int n = md->n;
    uint8_t *role = ws->input_role;
    int i = 0, pairs = 0;
    for (; i + 4 <= n; i += 4) {
        set_role_word(&role[i], role_word(&role[i]) & ~0x01010101u); /* ROLE_BOUND of each */
    }
    for (; i < n; ++i) {
        role[i] = (uint8_t)(role[i] & ~ROLE_BOUND);
    }
    for (i = 0; i < n; ++i) {
        ws->dv[i] = R_(0.0);
    }
    for (i = 0; i < nw; ++i) {
        const int q = md->row_q[ws->wset[i]];
        if (role[q] & ROLE_BOUND) {
            return -1;
        }
        role[q] = (uint8_t)(role[q] | ROLE_BOUND);
    }
    for (i = 1; i < n; ++i) {
        pairs += role[i - 1] & role[i] & ROLE_BOUND;
    }
    return pairs;
}

/*
 * Primal solve on a working set of input-bound rows only (wset[0..nw), at most one row
 * per input): U_B at the bounds, d_B = U_B - th0_B, then the factor of the previous solve
 * updated, or a new one in the form of smaller order, whichever costs fewer
 * multiply-adds (primal_cost()). Charges its work (primal_work(): the rows it factors
 * again) once afford() grants it and `reserve` more.
 * Writes ws->th; returns 1 when ws->z is written too (bound form), 0 when it is left to
 * free_multipliers() (free form), -1 if a factorisation breaks down, OUT_OF_WORK (the
 * factor and its rows unchanged) when the budget cannot pay.
 */
static int primal_solve(rollmpc_work *ws, const rollmpc_mode_data *md, int nw,
    uint32_t reserve)
{
    const int n = md->n;
    int i, k, head, newest = 0, from = 0, form = (nw < n - nw) ? FORM_BOUND : FORM_FREE;
    int update = 0, joined = 0, by_columns;
    const int adjacent = mark_bound_inputs(ws, md, nw); /* nw - adjacent runs */
    if (adjacent < 0) {
        return -1;
    }
    by_columns = nw < SHORT_RUN * (nw - adjacent); /* runs of bound inputs short on average */
    k = factor_order(nw, n);
    head = k;
    /* the previous factor, unless it would grow to every input (a new one is then cheaper)
     * or its tail has used up the generations (a new one starts them again) */
    if (ws->primal_form != FORM_NONE && ((ws->primal_form == FORM_FREE) ? nw > 0 : nw < n)) {
        int k_up, head_up;
        k_up = primal_diff(ws, nw, n, &from, &head_up, &newest, &joined);
        update = newest < ROLE_GEN_MAX && (ws->primal_form == form
            || primal_cost(md, k_up, from) <= primal_cost(md, k, 0));
        if (update) {
            form = ws->primal_form;
            k = k_up;
            head = head_up;
        }
    }
    if (!update) {
        from = 0;
    }
    {
        const int intact = ws->chol_holds == ROLLMPC_CHOL_PRIMAL, runs = nw - adjacent;
        const int bound_form = form == FORM_BOUND;
        int k_old = 0; /* > 0: rows leave by chol_delete() */
        uint32_t cost = primal_work(md, k, intact ? from : 0, bound_form, runs);
        /* the free form's multipliers are charged by free_multipliers(), granted here */
        const uint32_t later = bound_form ? 0u : multipliers_work(md, nw);
        if (update && intact && from < k - joined) {
            /* rows leave from inside the kept factor: deleting them by updates keeps the
             * rows below them, when that costs less than factoring those again */
            const int kept = k - joined, k_prev = ws->primal_k;
            const uint32_t by_update = primal_deletes(ws, md, k_prev, 0)
                + primal_work(md, k, kept, bound_form, runs);
            if (by_update < cost) {
                cost = by_update;
                k_old = k_prev;
                from = kept;
            }
        }
        if (!afford(ws, md, cost + later + reserve)) {
            return OUT_OF_WORK;
        }
        ws->work += cost;
        if (k_old > 0) {
            (void)primal_deletes(ws, md, k_old, 1);
        }
    }
    /* the bound inputs at their bounds only now: out of work, ws->th is still the caller's
     * last point, which TIME_LIMIT returns (the reference's th on entry); from here until
     * the solve succeeds, ws->th is no solved point */
    ws->th_solved = 0;
    for (i = 0; i < nw; ++i) {
        const int r = ws->wset[i], q = md->row_q[r];
        ws->th[q] = by_sign(md, r, md->row_c[r]);
        ws->dv[q] = ws->th[q] - ws->th0[q];
    }
    primal_order(ws, n, form, update, k, head, newest);
    if (primal_factor(ws, md, k, from) != 0) {
        return -1;
    }
    if (form == FORM_BOUND) {
        return (primal_solve_bound(ws, md, nw) == 0) ? 1 : -1;
    }
    return primal_solve_free(ws, md, k, by_columns);
}

/*
 * L = chol(H_WW) for W = wset[0..nw) (plus w on the diagonal of slack soft rows) into
 * ws->chol, from scratch: the fallback whenever the kept factor may not be valid. H_WW's
 * leading columns are read a column at a time while that pays (column_pays()), the rest
 * entry by entry. Sets ws->chol_holds; -1 if a pivot breaks down: not positive, or
 * (as a joining row's, append_row()) L_jj^2 not above DEPENDENCE_TOL times its diagonal
 * entry. Rows that repeat rows before them (a delay plant's output rows are its input
 * rows) leave pivots of a few roundoffs that a bare Cholesky takes as positive; a set
 * "full" of such rows would then pass for a vertex and prove a feasible QP infeasible.
 */
static int factor_working_set(rollmpc_work *ws, const rollmpc_mode_data *md, int nw)
{
    int i, j = 0, k, reads = einv_reads(md, ws->wset, nw);
    ws->work += factor_work(md, nw);
    while (j < nw && column_pays(md, reads)) { /* column j through h_column(), scratch dv, rhs */
        h_column(md, &ws->wset[j], nw - j, ws->wset[j], reads, ws->dv, ws->rhs);
        for (i = j; i < nw; ++i) {
            ws->chol[ROLLMPC_TRI(i, j)] = ws->rhs[i - j];
        }
        reads -= einv_reads(md, &ws->wset[j], 1);
        ++j;
    }
    for (i = j; i < nw; ++i) { /* the rest, too few input rows for a column: row by row */
        for (k = j; k <= i; ++k) {
            ws->chol[ROLLMPC_TRI(i, k)] = h_rows(md, ws->wset[i], ws->wset[k]);
        }
    }
    for (j = 0; j < nw; ++j) { /* the diagonal (w included), for the dependence test */
        ws->rhs[j] = ws->chol[ROLLMPC_TRI(j, j)];
    }
    ws->chol_holds = ROLLMPC_CHOL_NONE;
    ws->chol_rows = 0;
    if (rollmpc_cholesky_from(ws->chol, 0, nw) != 0) {
        return -1;
    }
    for (j = 0; j < nw; ++j) { /* rows above a dependent one do not read it: they stand */
        const rollmpc_real ljj = ws->chol[ROLLMPC_TRI(j, j)];
        if (!pivot_independent(ljj * ljj, ws->rhs[j])) {
            ws->chol_rows = j;
            return -1;
        }
    }
    ws->chol_holds = ROLLMPC_CHOL_DUAL;
    ws->chol_n = nw;
    return 0;
}

/*
 * y = L^-1 H_Wp in place on ws->rhs (holding H_Wp on entry from row `from` on, y above it:
 * rows of the factor and of H_Wp that have not changed since it was solved), and the
 * pivot hpp - y'y that row p would have in the factor of W + p (hpp: its diagonal entry).
 * Charged as a whole solve whatever `from` is.
 */
static rollmpc_real factor_pivot(rollmpc_work *ws, int from, int nw,
    rollmpc_real hpp)
{
    int i;
    rollmpc_real zeta = hpp;
    ws->work += tri_work(nw) + (uint32_t)nw;
    rollmpc_chol_lsolve_from(ws->chol, from, nw, ws->rhs);
    for (i = 0; i < nw; ++i) {
        zeta -= ws->rhs[i] * ws->rhs[i];
    }
    return zeta;
}

/* Row nw of the factor (of wset[0..nw], the caller's row nw): y = L^-1 H_Wp from
 * ws->rhs and the pivot sqrt(zeta). */
static void factor_append(rollmpc_work *ws, int nw, rollmpc_real zeta)
{
    int i;
    for (i = 0; i < nw; ++i) {
        ws->chol[ROLLMPC_TRI(nw, i)] = ws->rhs[i];
    }
    ws->chol[ROLLMPC_TRI(nw, nw)] = ROLLMPC_SQRT(zeta);
    ws->chol_n = nw + 1;
}

/*
 * Row p joins the working set at position nw, tight (or slack: `slack`, soft rows only). A
 * kept dual factor gains its row (one forward solve with H_Wp) unless its pivot is below
 * the dependence tolerance; then the next dual solve refactors from scratch.
 */
static void append_row(rollmpc_work *ws, const rollmpc_mode_data *md, int p, int nw,
    int slack)
{
    ws->wset[nw] = (int16_t)p;
    ws->in_set[p] = 1;
    (void)slack;
    if (ws->chol_holds == ROLLMPC_CHOL_DUAL) {
        rollmpc_real hpp = hq(md, md->row_q[p], md->row_q[p]), zeta;
        ws->work += ((uint32_t)nw + 1u) * hq_work(md);
        /* scratch ycol: the primal factor's Y is not held */
        h_column(md, ws->wset, nw, p, -1, ws->ycol, ws->rhs);
        zeta = factor_pivot(ws, 0, nw, hpp);
        if (pivot_independent(zeta, hpp)) {
            factor_append(ws, nw, zeta);
        } else {
            ws->chol_holds = ROLLMPC_CHOL_NONE;
        }
    }
}

/* Row r is out of the working set: not flagged in it, its slack (if soft) off. */
static void forget_row(rollmpc_work *ws, int r)
{
    ws->in_set[r] = 0;
}

/*
 * The rows of wset[0..nw) in order, each kept when its pivot on the rows kept before it
 * exceeds the dependence tolerance times its diagonal (plus w for a slack row), the others
 * leaving (forget_row()); their factor into ws->chol. Returns how many are kept: where a
 * factor from scratch broke down, a linearly independent working set to resume from. Its
 * first ws->chol_rows rows, factored before the breakdown with the sums an append makes,
 * are kept as they are.
 */
static int independent_rows(rollmpc_work *ws, const rollmpc_mode_data *md, int nw)
{
    int i, kept = ws->chol_rows;
    ws->chol_holds = ROLLMPC_CHOL_DUAL;
    ws->chol_n = kept;
    for (i = kept; i < nw; ++i) {
        const int p = ws->wset[i];
        rollmpc_real hpp = hq(md, md->row_q[p], md->row_q[p]), zeta;
        ws->work += ((uint32_t)kept + 1u) * hq_work(md);
        h_column(md, ws->wset, kept, p, -1, ws->ycol, ws->rhs);
        zeta = factor_pivot(ws, 0, kept, hpp);
        if (pivot_independent(zeta, hpp)) {
            factor_append(ws, kept, zeta);
            ws->wset[kept++] = (int16_t)p;
        } else {
            forget_row(ws, p);
        }
    }
    return kept;
}

/*
 * Working-set position k leaves (wset and z shift down); a kept dual factor loses its row
 * and column by a rank-one update of the rows below (chol_delete(), scratch ws->rhs).
 */
static void remove_row(rollmpc_work *ws, int k, int *nw)
{
    int i;
    forget_row(ws, ws->wset[k]);
    if (ws->chol_holds == ROLLMPC_CHOL_DUAL) {
        ws->work += delete_work(k, *nw);
        chol_delete(ws->chol, k, *nw, ws->rhs, NULL, 0);
        ws->chol_n = *nw - 1;
    }
    for (i = k; i + 1 < *nw; ++i) {
        ws->wset[i] = ws->wset[i + 1];
        ws->z[i] = ws->z[i + 1];
    }
    --*nw;
}

/* What dual_solve() on nw rows may spend, their factor kept (`factored`) or not. */
static uint32_t dual_solve_work(const rollmpc_work *ws, const rollmpc_mode_data *md,
    int nw, int factored)
{
    return (ws->out_slacks_ok ? 0u : (uint32_t)md->m + predict_work(md))
        + (factored ? 0u : factor_work(md, nw)) + 2u * tri_work(nw);
}

/*
 * Dual solve on a general working set: z = -H_WW^-1 K_W, th = th0 - E^-1 M_W' z, with the
 * kept factor when ws->chol holds it, else factored from scratch. Returns 0, -1 if the
 * factorisation breaks down, or OUT_OF_WORK.
 */
static int dual_solve(rollmpc_work *ws, const rollmpc_mode_data *md, int nw)
{
    int i;
    if (!afford(ws, md, dual_solve_work(ws, md, nw, ws->chol_holds == ROLLMPC_CHOL_DUAL))) {
        return OUT_OF_WORK;
    }
    output_slacks(ws, md);
    for (i = 0; i < nw; ++i) {
        ws->z[i] = -ws->K[ws->wset[i]];
    }
    if (ws->chol_holds != ROLLMPC_CHOL_DUAL && factor_working_set(ws, md, nw) != 0) {
        return -1;
    }
    ws->work += 2u * tri_work(nw);
    rollmpc_chol_solve(ws->chol, nw, ws->z);
    return 0;
}

/*
 * Do the working-set rows hold (within the feasibility tolerance) at ws->th? predicted:
 * violated_outside() has just predicted the outputs at ws->th into ws->yv (it found no
 * violated row), so only whether they need checking is decided again (outputs_uncertified(),
 * n + m), not the N^2/2 prediction. tight: the rows must also be tight within the
 * tolerance and no multiplier negative (final_set_holds()).
 */
static int working_set_holds(rollmpc_work *ws, const rollmpc_mode_data *md, int nw,
    int predicted, int tight)
{
    int i;
    const int outputs = predicted ? outputs_uncertified(ws, md, ws->th)
                                  : outputs_to_check(ws, md, ws->th);
    for (i = 0; i < nw; ++i) {
        const int r = ws->wset[i];
        const int checked = outputs || md->row_q[r] < md->n;
        if ((tight != 0) && !checked) {
            return 0; /* cleared by the certificate: inside its bound, not tight */
        }
        if (checked) {
            if (row_violated(ws, md, ws->th, r)) {
                return 0;
            }
            if (tight) { /* and not slack beyond the tolerance, its multiplier not negative */
                const rollmpc_real e = row_excess(ws, md, ws->th, r);
                if (ws->z[i] < R_(0.0) || e < -ROLLMPC_SOLVER_FEAS_TOL * tol_scale(ws, r)) {
                    return 0;
                }
            }
        }
    }
    return 1;
}

/*
 * Iterative refinement of a dual solve whose point misses its own working set: with
 * large multipliers (~1e9 from a terminal weight, or ~1e3 against a far unconstrained
 * optimum, in float), th = th0 - E^-1 M_W' z cancels most digits. The residual
 * e = M_W th - gamma_W is small, so d = H_WW^-1 e (ws->chol holds the factor), z += d and
 * th -= E^-1 M_W' d: the step moves th by a small vector, where forming th from th0 again
 * would cancel the same digits (a brushed motor's current loop braking at its current
 * limit held its 8 rows only to 1e-3). Up to two rounds; 0 once the working set holds,
 * no multiplier is negative and no other row is violated; 1 when the set holds but a row
 * outside it is violated (ws->th the refined point); else -1 (or OUT_OF_WORK).
 */
static int refine_dual(rollmpc_work *ws, const rollmpc_mode_data *md, int nw)
{
    int pass, i;
    if (!afford(ws, md, 2u * (2u * tri_work(nw) + correct_work(md, nw) + 2u * scan_work(md))
                        + (uint32_t)md->m)) {
        return OUT_OF_WORK;
    }
    for (pass = 0; pass < 2; ++pass) {
        int negative = 0;
        if (md->GEinvGt_p != 0) {
            predict_outputs(ws, md, ws->th);
        }
        for (i = 0; i < nw; ++i) {
            ws->rhs[i] = row_excess(ws, md, ws->th, ws->wset[i]);
        }
        ws->work += 2u * tri_work(nw);
        rollmpc_chol_solve(ws->chol, nw, ws->rhs);
        for (i = 0; i < nw; ++i) {
            ws->z[i] += ws->rhs[i];
            ws->rhs[i] = -ws->rhs[i]; /* th += E^-1 M_W' (-d) below */
            negative += (ws->z[i] < R_(0.0));
        }
        if (negative != 0) {
            return -1; /* a sign changed: not this working set's point */
        }
        correct(ws, md, ws->wset, nw, ws->rhs, CORRECT_STEP);
        if (working_set_holds(ws, md, nw, 0, 0)) {
            return (violated_outside(ws, md, ws->th, ws->in_set, ws->tmp, 0) == 0) ? 0 : 1;
        }
    }
    return -1;
}

/* Does the unconstrained solution violate row r (K < 0; seed_from_violated()'s rows)? */
static inline int violated_at_th0(const rollmpc_work *ws, const rollmpc_mode_data *md, int r)
{
    return (ws->out_slacks_ok || md->row_q[r] < md->n) && ws->K[r] < R_(0.0);
}

/*
 * A new working set: a dual factor belongs to the old one; a primal factor describes
 * inputs, not rows (polish_primal.c.j2), and stays.
 */
static void new_working_set(rollmpc_work *ws)
{
    if (ws->chol_holds == ROLLMPC_CHOL_DUAL) {
        ws->chol_holds = ROLLMPC_CHOL_NONE;
    }
}

/* Working set from the rows with positive multipliers among list[0..count); -1 if > n. */
static int seed_from_multipliers(rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *lam, const int16_t *list, int count)
{
    int j, nw = 0;
    new_working_set(ws);
    ws->work += (uint32_t)count;
    for (j = 0; j < count; ++j) {
        const int r = list ? list[j] : j;
        if (lam[r] > R_(0.0)) {
            if (nw == md->n) {
                return -1;
            }
            ws->wset[nw++] = (int16_t)r;
        }
    }
    return nw;
}


/* Clears in_set on the `count` rows of `rows`, or on every row (count < 0). */
static void clear_flags(rollmpc_work *ws, const rollmpc_mode_data *md, const int16_t *rows,
    int count)
{
    int i;
    if (count < 0) {
        for (i = 0; i < md->m; ++i) {
            ws->in_set[i] = 0u;
        }
        return;
    }
    for (i = 0; i < count; ++i) {
        ws->in_set[rows[i]] = 0u;
    }
}

/*
 * The guess of seed_shifted() (row r where lam[row_next[r]] > 0) in the order of the dual
 * factor the last QP of the mode left (wset[0..chol_n)), which reaches it by updates: its
 * rows that leave the guess or change state are deleted from the last down (remove_row()),
 * the guess's other rows appended in row order (append_row()), when that costs less than
 * a new factor and the budget pays it. A shifted working set keeps most of its rows (a run
 * of bounds loses a row at one end and gains one at the other), so this costs a few
 * updates where a new factor costs its cube. When neither that nor a new factor's dual
 * solve fits, it does what the budget pays and leaves the rest to the next QP, which goes
 * on from there: lam becomes the guess (shifted one stage) and the result OUT_OF_WORK (a
 * TIME_LIMIT) -- so a sample that cannot afford its factor still builds it, and no run of
 * samples stops at the same point each. In a part that the budget cuts, a row whose pivot
 * depends on the rows before it leaves the guess (its multiplier 0), as a new factor drops
 * it (independent_rows()): kept, its breakdown would drop the factor at every sample of
 * the run, and each would stop where the one before stopped (a whole carry hands the
 * breakdown to the polish's new factor). Returns the guess's size (wset and chol its own),
 * -1 (nothing done: the guess is empty, beyond the working set, input bounds only -- the
 * primal form's -- or a new factor fits) or OUT_OF_WORK. Flags in in_set (3: left as
 * dependent), cleared after.
 */
static int carry_factor(rollmpc_work *ws, const rollmpc_mode_data *md,
    rollmpc_real *lam)
{
    int g, i, r, nw = 0, box = 1, size, whole, kept = (ws->chol_holds == ROLLMPC_CHOL_DUAL) ? ws->chol_n : 0;
    uint32_t cost = 0u;
    int16_t *guess = ws->tmp; /* the guess's rows in order, while the working set holds them */
    for (r = 0; r < md->m; ++r) { /* 1: a row of the guess */
        const int in = lam[md->row_next[r]] > R_(0.0);
        ws->in_set[r] = (uint8_t)in;
        if (in) {
            if (nw < md->n) {
                guess[nw] = (int16_t)r;
            }
            ++nw;
            box = box && md->row_q[r] < md->n;
        }
    }
    if (nw > md->n) {
        clear_flags(ws, md, guess, -1);
        return -1;
    }
    size = kept;
    for (i = kept - 1; i >= 0; --i) { /* 2: a factor row the guess keeps in its state */
        r = ws->wset[i];
        if (ws->in_set[r]) {
            ws->in_set[r] = 2;
        } else {
            cost += delete_work(i, size);
            --size;
        }
    }
    for (i = size; i < nw; ++i) {
        cost += append_work(md, i);
    }
    whole = nw > 0 && !box && cost < factor_work(md, nw) && afford(ws, md, cost);
    if (nw == 0 || box || (!whole && afford(ws, md, dual_solve_work(ws, md, nw, 0)))) {
        clear_flags(ws, md, guess, nw);
        return -1;
    }
    if (ws->chol_holds != ROLLMPC_CHOL_DUAL) { /* the factor of the empty set, to append to */
        ws->chol_holds = ROLLMPC_CHOL_DUAL;
        ws->chol_n = 0;
        kept = 0;
    }
    size = kept;
    for (i = kept - 1; i >= 0; --i) {
        if (ws->in_set[ws->wset[i]] != 2) {
            if (!whole && !afford(ws, md, delete_work(i, size))) {
                break; /* (rows outside the guess stay flagged: the pass over lam clears them) */
            }
            remove_row(ws, i, &size);
        }
    }
    for (i = 0; i < size; ++i) {
        ws->in_set[ws->wset[i]] = 2; /* in the factor */
    }
    for (g = 0; g < nw && (whole || size < nw); ++g) {
        r = guess[g];
        if (ws->in_set[r] != 2) {
            if (!whole && !afford(ws, md, append_work(md, size))) {
                break;
            }
            append_row(ws, md, r, size, 0);
            if (!whole && ws->chol_holds != ROLLMPC_CHOL_DUAL) { /* dependent: wset[0..size)'s factor stands */
                ws->chol_holds = ROLLMPC_CHOL_DUAL;
                forget_row(ws, r);
                ws->in_set[r] = 3;
            } else {
                ++size;
                ws->in_set[r] = 2;
            }
        }
    }
    if (whole) {
        clear_flags(ws, md, guess, nw); /* every flag is on a row of the guess */
        return size;
    }
    for (r = 0; r < md->m; ++r) { /* the guess, which the next QP goes on from (row_next[r] >= r) */
        const rollmpc_real l = lam[md->row_next[r]];
        lam[r] = (l > R_(0.0) && ws->in_set[r] != 3u) ? l : R_(0.0);
        ws->in_set[r] = 0;
    }
    return OUT_OF_WORK;
}

/*
 * Working set from the previous active set (optimal, or where a TIME_LIMIT stopped)
 * shifted one stage along the horizon (row r joins when its next-stage row was active):
 * the receding-horizon guess; -1 if more than the working set holds (keep_first: its first).
 * Without keep_first, in the order of the dual factor the last QP left, if carry_factor()
 * brings that factor to it, or OUT_OF_WORK when only part of it fits (lam: the guess).
 */
static int seed_shifted(rollmpc_work *ws, const rollmpc_mode_data *md,
    rollmpc_real *lam, int keep_first)
{
    int r, nw = 0;
    ws->work += (uint32_t)md->m;
    if (!keep_first) {
        nw = carry_factor(ws, md, lam);
        if (nw != -1) {
            return nw;
        }
        nw = 0;
    }
    new_working_set(ws);
    for (r = 0; r < md->m; ++r) {
        if (lam[md->row_next[r]] > R_(0.0)) {
            if (nw == md->n) {
                return keep_first ? nw : -1;
            }
            ws->wset[nw++] = (int16_t)r;
        }
    }
    return nw;
}

/* Working set from the rows violated by the unconstrained solution (K < 0); -1 if > n. */
static int seed_from_violated(rollmpc_work *ws, const rollmpc_mode_data *md)
{
    int r, nw = 0;
    new_working_set(ws);
    ws->work += (uint32_t)md->m;
    for (r = 0; r < md->m; ++r) {
        if (violated_at_th0(ws, md, r)) {
            if (nw == md->n) {
                return -1;
            }
            ws->wset[nw++] = (int16_t)r;
        }
    }
    return nw;
}

/*
 * The rows th0 violates, seeded again as the dual active set's start after their polish
 * failed when no warm start was left (the shifted set empty): resume_working_set() makes
 * them dual feasible, keeping their independent rows, where a cold start would add each
 * of them again one by one. They are also what a TIME_LIMIT before the dual active set
 * has a point keeps (keep_progress(): stop_rows, none with a multiplier yet). Returns
 * their count, or -1 (the budget, none, or more than wcap): the dual active set then
 * starts cold, as before.
 */
static int violated_resume(rollmpc_work *ws, const rollmpc_mode_data *md)
{
    int nw;
    if (!afford(ws, md, (uint32_t)md->m)) {
        return -1;
    }
    nw = seed_from_violated(ws, md);
    if (nw <= 0) {
        return -1;
    }
    ws->stop_rows = nw;
    ws->stop_known = 0;
    return nw;
}


/*
 * Has a guess's first point reversed the sign of its multipliers? Its middle, first and
 * last rows all have negative ones: after a reference step every multiplier of the shifted
 * guess can be negative (the saturation reversed, or, under a heavy terminal weight, ending
 * earlier than the guess's), and given_up() would give it up once free_multipliers() paid
 * for all of them. Three rows cost a few hundredths of that on a large guess; any other
 * guess goes on to free_multipliers(). The middle first: a shifted guess changes at its
 * ends, so its middle row is the likeliest to show, at one row's cost, that it holds.
 * Charged by the row, and skipped unless the budget can pay all three beside what
 * primal_solve() granted polish(): free_multipliers() and primal_reserve().
 */
static int guess_reversed(rollmpc_work *ws, const rollmpc_mode_data *md, int nw)
{
    int s;
    if (nw < 8 || !afford(ws, md, guess_sample_work(md, 3)
            + multipliers_work(md, nw) + primal_reserve(md))) {
        return 0;
    }
    for (s = 0; s < 3; ++s) {
        const int r = ws->wset[(s == 0) ? nw / 2 : ((s == 1) ? 0 : nw - 1)];
        ws->work += guess_sample_work(md, 1);
        if (!(signed_multiplier(ws, md, r, s_row_dot(md->S_p, md->n, md->row_q[r], ws->dv))
              < R_(0.0))) {
            return 0;
        }
    }
    return 1;
}

/*
 * A reversed guess (guess_reversed()) trimmed to the rows it likely holds, or -1 to give
 * it up. Under a heavy terminal weight every multiplier of a guess whose saturated run
 * lasts a few stages too long is negative, though most of the guess holds (the paper
 * config's steps 941 and 3070: 89 and 100 rows, 83 and 93 of them optimal). The rows it
 * should not hold are the run's edge, where the multipliers carried from the previous
 * sample (lam of the next-stage row, which seed_shifted() read) fall towards zero. The
 * trim keeps the rows carrying at least half of the largest, and is taken when it keeps
 * 3/4 of the guess or more (an edge, not a reversal: the whole saturation gone) and its
 * first factor, of the bound or the free inputs, is of lower order than that of the
 * violated rows seed_from_violated() would start from. Rows trimmed wrongly join back as
 * violated rows; a trimmed guess that fails is given up like any other. Updates wset and
 * in_set; charged trim_work().
 */
static int trim_guess(rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *lam, int nw)
{
    rollmpc_real edge = R_(0.0);
    int i, kept = 0, violated = 0;
    if (!afford(ws, md, trim_work(md, nw))) {
        return -1;
    }
    ws->work += 2u * (uint32_t)nw; /* the guess's scans; the rows' below, if it gets there */
    for (i = 0; i < nw; ++i) {
        const rollmpc_real c = lam[md->row_next[ws->wset[i]]];
        edge = (c > edge) ? c : edge;
    }
    edge *= R_(0.5);
    for (i = 0; i < nw; ++i) {
        kept += (lam[md->row_next[ws->wset[i]]] >= edge);
    }
    if (4 * kept < 3 * nw) {
        return -1;
    }
    ws->work += (uint32_t)md->m;
    for (i = 0; i < md->m; ++i) {
        violated += violated_at_th0(ws, md, i);
    }
    if (factor_order(kept, md->n) >= factor_order(violated, md->n)) {
        return -1;
    }
    for (i = 0, kept = 0; i < nw; ++i) {
        const int r = ws->wset[i];
        if (lam[md->row_next[r]] >= edge) {
            ws->wset[kept++] = (int16_t)r;
        } else {
            ws->in_set[r] = 0;
        }
    }
    return kept;
}

/* The working-set rows whose multiplier z is not negative. */
static int kept_rows(const rollmpc_work *ws, int nw)
{
    int i, keep = 0;
    for (i = 0; i < nw; ++i) {
        keep += (ws->z[i] >= R_(0.0));
    }
    return keep;
}

/* Is a working set of nw rows, keep of them with z >= 0, to be given up? Emptied, or a
 * guess that would lose more than half of its rows. */
static int given_up(int keep, int nw, int guess)
{
    return keep == 0 || (guess && 2 * keep < nw);
}

/*
 * Drop the working-set rows with negative multipliers (with a dual factor to update,
 * remove_row() from the last position down; else in one pass). Returns 0 if none was
 * dropped, 1 if some were (solve again), -1 if the working set is to be given up:
 * emptied, or a guess (see polish()) that would lose more than half of its rows;
 * OUT_OF_WORK if the budget cannot afford the deletions.
 */
static int drop_negative(rollmpc_work *ws, const rollmpc_mode_data *md, int *nw, int guess)
{
    int i;
    const int keep = kept_rows(ws, *nw);
    if (keep == *nw) {
        return 0;
    }
    if (given_up(keep, *nw, guess)) {
        return -1;
    }
    if (ws->chol_holds == ROLLMPC_CHOL_DUAL
        && !afford(ws, md, ((uint32_t)*nw - (uint32_t)keep) * delete_work(0, *nw))) {
        return OUT_OF_WORK;
    }
    if (ws->chol_holds != ROLLMPC_CHOL_DUAL) { /* no factor to update: one pass */
        int kept = 0;
        for (i = 0; i < *nw; ++i) {
            if (ws->z[i] >= R_(0.0)) {
                ws->wset[kept] = ws->wset[i];
                ws->z[kept++] = ws->z[i];
            } else {
                forget_row(ws, ws->wset[i]);
            }
        }
        *nw = kept;
        return 1;
    }
    for (i = *nw - 1; i >= 0; --i) {
        if (!(ws->z[i] >= R_(0.0))) {
            remove_row(ws, i, nw);
        }
    }
    return 1;
}

/*
 * drop_negative() for polish(), which also keeps ws->guess_left (wset is in joining order,
 * and the drops keep it). Returns 2 instead of 1 when a row that joined in this polish is
 * among those dropped.
 */
static int drop_negative_tracked(rollmpc_work *ws, const rollmpc_mode_data *md, int *nw,
    int guess)
{
    int i, code, leaving = 0, joined = 0;
    for (i = 0; i < *nw; ++i) {
        if (!(ws->z[i] >= R_(0.0))) {
            leaving += (i < ws->guess_left);
            joined |= (i >= ws->guess_left);
        }
    }
    code = drop_negative(ws, md, nw, guess);
    if (code == 1) {
        ws->guess_left -= leaving;
        code += joined;
    }
    return code;
}

/* lam = the working set's multipliers, 0 elsewhere: the next sample's warm start. */
static void keep_working_set(const rollmpc_work *ws, const rollmpc_mode_data *md,
    rollmpc_real *lam, int nw)
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
static int converged(rollmpc_work *ws, const rollmpc_mode_data *md, rollmpc_real *lam,
    int nw, int *active)
{
    ws->work += (uint32_t)md->m;
    keep_working_set(ws, md, lam, nw);
    *active = nw;
    return 0;
}

#define GUESS_CAPPED (-4) /* polish(): a guess that resume_working_set() would repeat */
#define GUESS_HANDED_OVER (-5) /* polish(): a guess' set goes on, dual feasible or cycling (stopped()) */
#define SET_HANDED_BACK (-6) /* polish(): the dual active set's set goes back to it, a row outside violated */

/*
 * Where polish() stopped when the budget ran out (code OUT_OF_WORK), or at a dual-feasible
 * working set it hands to the dual active set (GUESS_HANDED_OVER, SET_HANDED_BACK): its
 * working set wset[0..nw), the first `known` of them with their multipliers in z. Returns
 * code.
 */
static int stopped(rollmpc_work *ws, int nw, int known, int code)
{
    if (code == OUT_OF_WORK || code == GUESS_HANDED_OVER || code == SET_HANDED_BACK) {
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
static void keep_progress(rollmpc_work *ws, const rollmpc_mode_data *md,
    rollmpc_real *lam)
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
 * optimal and lam set to the exact multipliers, -1 (lam untouched), GUESS_CAPPED (the
 * same, for a guess whose every round was a dual solve that switched soft states or
 * dropped rows: resume_working_set() would repeat them exactly), GUESS_HANDED_OVER (a
 * guess' dual-feasible working set whose violated rows overflow it, or one of which is
 * dependent, or a guess' working set after it dropped a row it had added: the dual active
 * set goes on from that set and its factor, which the appends and drops kept),
 * SET_HANDED_BACK (with hand_back = 1, dual_active_set()'s final set: the same hand-over
 * when its violated rows overflow it or one is dependent, or when its refined point holds
 * it but violates a row outside, which the dual active set makes room for or proves
 * infeasible) or OUT_OF_WORK when the budget cannot afford the next step (where:
 * stopped()).
 */
static int polish(rollmpc_work *ws, const rollmpc_mode_data *md, rollmpc_real *lam,
    int nw, int guess, int hand_back, int *iterations, int *active)
{
    int i, it, code, box, known = 0; /* known: the first wset rows whose z is their multiplier */
    int repeatable = guess; /* every round so far a dual solve that switched or dropped */
    if (nw <= 0 || nw > md->n) {
        return -1;
    }
    if (!afford(ws, md, (uint32_t)md->m)) {
        return stopped(ws, nw, 0, OUT_OF_WORK);
    }
    ws->work += (uint32_t)md->m;
    ws->guess_left = nw;
    for (i = 0; i < md->m; ++i) {
        ws->in_set[i] = 0; /* in_set flags the working set from here on */
    }
    for (i = 0; i < nw; ++i) {
        ws->in_set[ws->wset[i]] = 1;
    }
    box = box_only(ws, md, nw); /* kept through the rounds, which add and drop rows */
    for (it = 0; it < ROLLMPC_SOLVER_POLISH_MAX; ++it) {
        int nadd, dual; /* dual: a guess' wset[0..dual) dual feasible, factored, or -1 */
        ++*iterations;
        if (box) { /* a subset of input bounds stays one: drop_negative() keeps it */
            /* primal: bound rows first; the free form's multipliers only at a feasible point */
            repeatable = 0;
            code = primal_solve(ws, md, nw, primal_reserve(md));
            if (code == OUT_OF_WORK) {
                return stopped(ws, nw, known, OUT_OF_WORK);
            }
            if (code < 0) {
                return -1;
            }
            known = (code == 1) ? nw : 0;
            nadd = violated_outside(ws, md, ws->th, ws->in_set, ws->tmp, md->n - nw);
            if (code == 0 && guess && it == 0 && guess_reversed(ws, md, nw)) {
                nw = trim_guess(ws, md, lam, nw); /* before free_multipliers() below */
                if (nw < 0) {
                    return -1;
                }
                ws->guess_left = nw;
                continue; /* its first point is the next round's, no longer the guess's */
            }
            if (nadd > 0) {
                if (guess && it == 0) {
                    /* a guess whose first point has most multipliers negative (a reference
                     * step reversed the saturation) is given up before it grows */
                    if (code == 0) {
                        free_multipliers(ws, md, nw);
                    }
                    if (given_up(kept_rows(ws, nw), nw, 1)) {
                        return -1;
                    }
                }
                if (code == 1) {
                    /* the bound form's multipliers come with its point: the bounds they
                     * release leave in the round the violated rows join (a primal-dual
                     * active set), not only once the point is feasible (one pass; with
                     * every multiplier negative, given_up() keeps the set) */
                    (void)drop_negative_tracked(ws, md, &nw, 0);
                    known = nw;
                }
            }
            if (nadd == 0) {
                if (code == 0) {
                    free_multipliers(ws, md, nw);
                }
                known = nw;
                code = drop_negative_tracked(ws, md, &nw, guess);
                if (code != 0) {
                    if (code < 0) {
                        return stopped(ws, nw, known, code);
                    }
                    known = nw;
                    continue;
                }
                return converged(ws, md, lam, nw, active);
            }
        } else {
            code = dual_solve(ws, md, nw);
            if (code != 0) {
                return stopped(ws, nw, known, code);
            }
            known = nw;
            code = drop_negative_tracked(ws, md, &nw, guess);
            if (code != 0) {
                if (code < 0) {
                    return stopped(ws, nw, known, code);
                }
                known = nw;
                if (code == 2 && guess && ROLLMPC_SOLVER_ACTIVE_SET
                    && ws->chol_holds == ROLLMPC_CHOL_DUAL) {
                    /* a row the guess added leaves again: rounds that add and drop cycle
                     * (on pmsm_speed to the rounds cap), the dual active set ends them */
                    return stopped(ws, nw, known, GUESS_HANDED_OVER);
                }
                box = box_only(ws, md, nw); /* the last rows of other kinds may have left */
                continue;
            }
            repeatable = 0; /* dual feasible: the resume would stop here */
            if (!afford(ws, md, correct_work(md, nw) + 2u * scan_work(md) + (uint32_t)md->m)) {
                return stopped(ws, nw, known, OUT_OF_WORK);
            }
            correct(ws, md, ws->wset, nw, ws->z, CORRECT_BY_LIST);
            nadd = violated_outside(ws, md, ws->th, ws->in_set, ws->tmp, md->n - nw);
            if (nadd == 0) {
                /* a (near-)singular H_WW, e.g. parallel rows of an infeasible QP, can give
                 * multipliers whose point misses its own working set: not optimal */
                code = working_set_holds(ws, md, nw, 1, 0) ? 0 : refine_dual(ws, md, nw);
                if (code == 1) { /* a row outside: the dual active set makes room for it */
                    code = -1;
                    if (hand_back != 0) { /* dual_active_set()'s set */
                        code = SET_HANDED_BACK;
                    }
                }
                return (code == 0) ? converged(ws, md, lam, nw, active) : stopped(ws, nw, known, code);
            }
        }
        dual = ((guess || hand_back) && ROLLMPC_SOLVER_ACTIVE_SET
                && ws->chol_holds == ROLLMPC_CHOL_DUAL) ? nw : -1;
        if (nadd > md->n - nw) {
            return (dual >= 0) ? stopped(ws, dual, dual, guess ? GUESS_HANDED_OVER : SET_HANDED_BACK) : -1;
        }
        if (ws->chol_holds == ROLLMPC_CHOL_DUAL
            && !afford(ws, md, (uint32_t)nadd * append_work(md, nw + nadd))) {
            return stopped(ws, nw, known, OUT_OF_WORK);
        }
        for (i = 0; i < nadd; ++i) {
            box = box && md->row_q[ws->tmp[i]] < md->n;
            append_row(ws, md, ws->tmp[i], nw++, 0);
        }
        if (dual >= 0 && ws->chol_holds != ROLLMPC_CHOL_DUAL) {
            ws->chol_holds = ROLLMPC_CHOL_DUAL; /* rows 0..dual-1 of it stand */
            ws->chol_n = dual;
            return stopped(ws, dual, dual, guess ? GUESS_HANDED_OVER : SET_HANDED_BACK);
        }
    }
    return repeatable ? GUESS_CAPPED : -1;
}

/*
 * The warm start of dual_active_set(): the working set where the shifted guess' polish
 * stopped (wset[0..from), its factor as ws->chol_holds says), or with from < 0 the
 * previous working set shifted one stage (seed_shifted(): optimal, or where a TIME_LIMIT
 * stopped; its first rows that the working set holds), made dual feasible by solving on
 * it (if its factor breaks down, its dependent rows leave: independent_rows()), switching
 * the soft states whose multipliers cross l1 and dropping the rows with negative
 * multipliers until none is;
 * ws->th is then its point. Returns its size (0: no seed, or it broke down or emptied:
 * start cold) or OUT_OF_WORK (where: stopped()).
 */
static int resume_working_set(rollmpc_work *ws, const rollmpc_mode_data *md,
    rollmpc_real *lam, int from, int *steps)
{
    int i, pass, code, nw = (from >= 0) ? from : seed_shifted(ws, md, lam, 1);
    for (i = 0; i < nw; ++i) {
        ws->in_set[ws->wset[i]] = 1;
    }
    for (pass = 0; nw > 0 && pass < ROLLMPC_SOLVER_POLISH_MAX; ++pass) {
        int known;
        ++*steps;
        code = dual_solve(ws, md, nw);
        if (code == -1) { /* dependent rows: keep the independent ones, in order */
            if (!afford(ws, md, independent_work(md, nw))) {
                break; /* start cold, with the work that is left */
            }
            nw = independent_rows(ws, md, nw);
            continue;
        }
        known = (code == 0) ? nw : 0;
        code = (code == 0) ? drop_negative(ws, md, &nw, 0) : code;
        if (code == OUT_OF_WORK) {
            return stopped(ws, nw, known, OUT_OF_WORK);
        }
        if (code == 0) {
            if (!afford(ws, md, correct_work(md, nw))) {
                return stopped(ws, nw, nw, OUT_OF_WORK);
            }
            correct(ws, md, ws->wset, nw, ws->z, CORRECT_BY_LIST);
            return nw;
        }
        if (code < 0) {
            break;
        }
    }
    for (i = 0; i < nw; ++i) { /* start cold */
        ws->in_set[ws->wset[i]] = 0;
    }
    ws->chol_holds = ROLLMPC_CHOL_DUAL; /* the factor of the empty working set */
    ws->chol_n = 0;
    return 0;
}

/*
 * Is the final working set (no row violated outside it) optimal at ws->th, its outputs just
 * predicted? exact: ws->th is its exact dual solve (the resume), so its rows need only
 * hold; else the steps accumulated its multipliers, so its rows must also be tight within
 * the tolerance and none negative. Dual form only (a box-only set: the primal form's).
 */
static int final_set_holds(rollmpc_work *ws, const rollmpc_mode_data *md, int nw,
    int exact)
{
    return nw <= md->n && !box_only(ws, md, nw) && afford(ws, md, final_check_work(md))
        && working_set_holds(ws, md, nw, 1, !exact);
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
static int most_violated(rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *th)
{
    const int outputs = outputs_to_check(ws, md, th);
    rollmpc_real worst[ADD_BATCH];
    int r, j, count = 0;
    ws->work += 2u * (uint32_t)md->m;
    for (r = 0; r < md->m; ++r) {
        if (!ws->in_set[r] && (outputs || md->row_q[r] < md->n)) {
            const rollmpc_real viol = row_excess(ws, md, th, r);
            const rollmpc_real scale = tol_scale(ws, r);
            if (viol > ROLLMPC_SOLVER_FEAS_TOL * scale) {
                const rollmpc_real rel = viol / scale;
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
 * With `recheck` (p was chosen at an earlier point), p is skipped unless its violation
 * -K_p - H_pW z is still beyond the tolerance. Returns 0 when p joined, 2 when skipped, 1
 * for infeasible, -1 on the step cap or a breakdown, or OUT_OF_WORK before a step the
 * budget cannot afford (z has moved, p not joined).
 */
static int add_to_set(rollmpc_work *ws, const rollmpc_mode_data *md, int p, int recheck,
    int *nw, int *steps)
{
    const rollmpc_real hpp = hq(md, md->row_q[p], md->row_q[p]);
    rollmpc_real lp = R_(0.0);
    rollmpc_real *hcol = ws->ycol; /* the primal factor's Y is not in use (chol_holds) */
    int i, from = 0; /* rhs[0..from) holds y = L^-1 H_Wp of the step before */
    if (!afford(ws, md, ((uint32_t)*nw + 1u) * hq_work(md))) {
        return OUT_OF_WORK;
    }
    ws->work += ((uint32_t)*nw + 1u) * hq_work(md);
    /* H_Wp, read once for every step of this add */
    h_column(md, ws->wset, *nw, p, -1, ws->dv, hcol);
    if (recheck) { /* chosen at an earlier point: still violated at this one? */
        rollmpc_real viol = -ws->K[p];
        for (i = 0; i < *nw; ++i) {
            viol -= hcol[i] * ws->z[i];
        }
        if (!(viol > ROLLMPC_SOLVER_FEAS_TOL * tol_scale(ws, p))) {
            return 2;
        }
    }
    for (;;) {
        rollmpc_real zeta, viol = -ws->K[p] - hpp * lp, tblock = R_(0.0), t;
        int k = -1, dependent;
        if (++*steps > ROLLMPC_SOLVER_ACTIVE_SET_MAX) {
            return -1;
        }
        if (!afford(ws, md, add_step_work(*nw))) {
            return OUT_OF_WORK;
        }
        ws->work += tri_work(*nw) + 4u * (uint32_t)*nw;
        for (i = 0; i < *nw; ++i) { /* y = L^-1 H_Wp (rhs), d = L'^-1 y (dv) */
            viol -= hcol[i] * ws->z[i];
        }
        for (i = from; i < *nw; ++i) {
            ws->rhs[i] = hcol[i];
        }
        zeta = factor_pivot(ws, from, *nw, hpp);
        for (i = 0; i < *nw; ++i) {
            ws->dv[i] = ws->rhs[i];
        }
        rollmpc_chol_ltsolve(ws->chol, *nw, ws->dv);
        for (i = 0; i < *nw; ++i) { /* first row whose multiplier reaches 0 */
            if (ws->dv[i] > R_(0.0)) {
                const rollmpc_real ratio = ws->z[i] / ws->dv[i];
                if (k < 0 || ratio < tblock) {
                    k = i;
                    tblock = ratio;
                }
            }
        }
        dependent = *nw == md->n || !pivot_independent(zeta, hpp);
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
            ++*nw;
            return 0;
        }
        remove_row(ws, k, nw); /* its deletion works on rows k.. of L and of rhs only */
        from = k;
        for (i = k; i < *nw; ++i) {
            hcol[i] = hcol[i + 1];
        }
    }
}

#define COLD_START (-2) /* dual_active_set()'s from: no warm start (the guess' repeat) */

/*
 * The dual active set's steps from ws->th: the most violated rows join wset[0..*nw), a
 * batch per scan (add_to_set()), and th is corrected at the grown set, until no row is
 * violated. Returns 0, 1 (a dependent row no other can make room for: infeasible), -1
 * (step cap, breakdown) or OUT_OF_WORK; *moved = 1 once th is corrected.
 */
static int add_violated_rows(rollmpc_work *ws, const rollmpc_mode_data *md, int *nw,
    int *steps, int *moved)
{
    int code = 0;
    for (;;) {
        int p, c;
        if (!afford(ws, md, scan_work(md) + (uint32_t)md->m)) {
            return OUT_OF_WORK;
        }
        p = most_violated(ws, md, ws->th);
        if (p == 0) {
            return 0;
        }
        for (c = 0; c < p && code == 0; ++c) { /* 2: no longer violated, skipped */
            code = add_to_set(ws, md, ws->tmp[c], c > 0, nw, steps);
            code = (code == 2) ? 0 : code;
        }
        if (code != 0) {
            return code;
        }
        if (!afford(ws, md, correct_work(md, *nw))) {
            return OUT_OF_WORK;
        }
        correct(ws, md, ws->wset, *nw, ws->z, CORRECT_BY_LIST);
        *moved = 1;
    }
}

/*
 * Dual active-set solve (Goldfarb-Idnani) from the warm start (resume_working_set(), from
 * where the shifted guess stopped if from >= 0; none if from is COLD_START) or the
 * unconstrained optimum: add the most violated rows until none is, keeping the multipliers
 * >= 0 and the working set linearly independent, so it finishes where the polish fails
 * (dependent active sets, working sets the shifted guess and the violated rows do not
 * reach). Unless final_set_holds() accepts it as it stands, its working set then goes to
 * polish() for the exact solve and KKT check -- also
 * after a claim of infeasibility, because far from the origin (multipliers ~1e9 in float)
 * th = th0 - E^-1 M' z loses the digits the primal form keeps; with it goes the factor of
 * H_WW, which the polish keeps, and lam takes its multipliers (the next sample's warm
 * start if the budget runs out). Once, the polish may hand the set back (SET_HANDED_BACK:
 * its exact point violates a row outside the set, often one dependent on it, that the
 * dual active set's own point did not); the steps go on from the polish's point,
 * multipliers and factor. Returns 0 (optimal, as polish()), 1 (infeasible: ws->th
 * is then th0), -1 (step cap, breakdown, or the polish rejects the set), OUT_OF_WORK
 * (ws->th the last point reached, lam its working set) or OUT_OF_WORK_AT_TH0 (the same,
 * before it corrected th0: the caller falls back, fallback_point()).
 */
static int dual_active_set(rollmpc_work *ws, const rollmpc_mode_data *md,
    rollmpc_real *lam, int from, int *iterations, int *active)
{
    int i, pass, nw = 0, steps = 0, code = 0, moved = 0; /* moved: ws->th is a corrected point */
    int resumed = 0; /* ws->th: the exact dual solve of the resumed set, as polish() would */
    if (!afford(ws, md, (ws->out_slacks_ok ? 0u : (uint32_t)md->m + predict_work(md))
                        + 2u * (uint32_t)md->m)) {
        if (from >= 0) {
            keep_progress(ws, md, lam); /* where the shifted guess stopped */
        }
        return OUT_OF_WORK_AT_TH0; /* ws->th: a polish's point, or th0 */
    }
    ws->th_solved = 0;
    for (i = 0; i < md->n; ++i) {
        ws->th[i] = ws->th0[i]; /* the point until the dual active set has one */
    }
    output_slacks(ws, md);
    ws->work += (uint32_t)md->m;
    for (i = 0; i < md->m; ++i) {
        ws->in_set[i] = 0;
    }
    if (from < 0) {
        ws->chol_holds = ROLLMPC_CHOL_DUAL; /* the factor of the empty working set */
        ws->chol_n = 0;
    }
    if (from >= 0 || (from != COLD_START && ROLLMPC_SOLVER_WARM_START)) {
        nw = resume_working_set(ws, md, lam, from, &steps);
        if (nw == OUT_OF_WORK) { /* lam: the warm start as far as it got */
            keep_progress(ws, md, lam);
            *iterations += steps;
            return OUT_OF_WORK_AT_TH0;
        }
        moved = (nw > 0); /* corrected at its resumed working set */
        resumed = moved; /* ws->th: its exact dual solve, what polish() would compute again */
    }
    for (pass = 0; pass < 2; ++pass) { /* pass 1: the set the polish handed back */
        int grown = 0;
        code = add_violated_rows(ws, md, &nw, &steps, &grown);
        moved = moved || grown;
        resumed = resumed && !grown;
        if (nw == 0 && code != OUT_OF_WORK) { /* code 0: violations of th0 within the tolerance only */
            *iterations += steps;
            return (code == 0) ? converged(ws, md, lam, 0, active) : code;
        }
        /* the next sample's warm start until polish() replaces it (paid by finish()'s reserve) */
        keep_working_set(ws, md, lam, nw);
        if (code == 0 && moved && final_set_holds(ws, md, nw, resumed)) {
            *iterations += steps;
            return converged(ws, md, lam, nw, active);
        }
        if (code == OUT_OF_WORK) {
            break;
        }
        i = polish(ws, md, lam, nw, 0, pass == 0 && code == 0, iterations, active);
        if (i != SET_HANDED_BACK) {
            break;
        }
        nw = ws->stop_rows; /* dual feasible at ws->th, with its factor */
        resumed = 0;
        for (i = 0; i < md->m; ++i) {
            ws->in_set[i] = 0;
        }
        for (i = 0; i < nw; ++i) {
            ws->in_set[ws->wset[i]] = 1;
        }
    }
    *iterations += steps;
    if (code == OUT_OF_WORK) {
        *active = nw;
        return moved ? OUT_OF_WORK : OUT_OF_WORK_AT_TH0; /* no polish ran */
    }
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
static int finish(rollmpc_work *ws, const rollmpc_mode_data *md, rollmpc_real *lam,
    int status, rollmpc_real *U)
{
    const rollmpc_real *src = ws->th;
    int i;
    ws->work += finish_work(md);
    if (!rollmpc_all_finite(ws->th, md->n)) {
        status = ROLLMPC_NUMERICAL;
        src = ws->th0;
        if (!rollmpc_all_finite(ws->th0, md->n)) {
            for (i = 0; i < md->n; ++i) {
                ws->th[i] = R_(0.0); /* neither is finite: clamp 0 */
            }
            src = ws->th;
        }
    }
    for (i = 0; i < md->n; ++i) {
        const rollmpc_real lo = md->u_min[i % md->nu], hi = md->u_max[i % md->nu];
        const rollmpc_real v = src[i];
        U[i] = (v < lo) ? lo : ((v > hi) ? hi : v);
    }
    if (status != ROLLMPC_OPTIMAL && status != ROLLMPC_TIME_LIMIT) {
        for (i = 0; i < md->m; ++i) {
            lam[i] = R_(0.0); /* no sticky warm start after a failed sample */
        }
    }
    return status;
}

/*
 * The point of a TIME_LIMIT with nothing better than th0: the mode's last plan shifted
 * one stage along the horizon (receding horizon; with move blocking a block of one stage
 * takes the next block's value, a longer block keeps its own), while that plan is younger
 * than the horizon (plan_age: samples since it was optimal); else th0. A plan met every
 * row a sample ago, th0 only the dynamics: under a long run of TIME_LIMIT samples th0
 * drives the outputs through their hard bounds (rollmpc_README.md, "Work budget").
 */
static void fallback_point(rollmpc_work *ws, const rollmpc_mode_data *md,
    const rollmpc_real *plan, int plan_age)
{
    const int nu = md->nu, stages = md->nyq / md->ny;
    int i;
    if (plan_age >= stages - 1) {
        for (i = 0; i < md->n; ++i) {
            ws->th[i] = ws->th0[i];
        }
        return;
    }
    ws->from_plan = 1;
    for (i = 0; i < stages; ++i) { /* stage i opens block b: its value one stage later */
        if (i == 0 || md->stage_block[i] != md->stage_block[i - 1]) {
            const int b = md->stage_block[i];
            const int src = (i + 1 < stages) ? md->stage_block[i + 1] : b;
            int a;
            for (a = 0; a < nu; ++a) {
                ws->th[b * nu + a] = plan[src * nu + a];
            }
        }
    }
}

/*
 * The budget ran out before the dual active set had a point: the command is
 * fallback_point() clamped and, if a polish stopped (polished = 1), lam its working set
 * (keep_progress()). In a mode whose rows are all input bounds, a point this solve's
 * primal polish reached (ws->th_solved) is kept instead: clamped, it meets every row, and
 * it answers this sample's state and reference, where the plan answers the last
 * optimal sample's (after a reference step, the old level).
 */
static int time_limit_at_th0(rollmpc_work *ws, const rollmpc_mode_data *md,
    rollmpc_real *lam, const rollmpc_real *plan, int plan_age, int polished,
    rollmpc_real *U)
{
    if (!((md->m_box == md->m) && ws->th_solved)) {
        fallback_point(ws, md, plan, plan_age);
    }
    if (polished) {
        keep_progress(ws, md, lam);
    }
    return finish(ws, md, lam, ROLLMPC_TIME_LIMIT, U);
}

/**
 * @brief Solve one mode's QP (internal; see rollmpc_solve_qp()).
 * @param ws Work arrays.
 * @param lam Warm-start multipliers of the mode [m], updated.
 * @param plan The mode's last plan [n], for a TIME_LIMIT before the dual active set (read
 *             before U is written: it may be U).
 * @param plan_age Samples since that plan was optimal (ROLLMPC_HORIZON: none).
 * @param md Mode data.
 * @param x State estimate [nx].
 * @param r Reference [N ny].
 * @param U Out: input sequence [n].
 * @param iterations Out: dual sweeps.
 * @param polish_iterations Out: polish corrections.
 * @param active Out: rows in the final active set.
 * @return A rollmpc_status code.
 */
int rollmpc_qp_solve(rollmpc_work *ws, rollmpc_real *lam, const rollmpc_real *plan,
    int plan_age, const rollmpc_mode_data *md, const rollmpc_real *x,
    const rollmpc_real *r, rollmpc_real *U, int *iterations, int *polish_iterations,
    int *active)
{
    int i, count, total = 0, status = ROLLMPC_MAX_ITER, resume = -1;
    *iterations = 0;
    *polish_iterations = 0;
    *active = 0;
    ws->work = 0u;
    ws->work_limit = ROLLMPC_SOLVER_WORK_BUDGET;
    ws->from_plan = 0;
    ws->th_solved = 0;
    unconstrained(ws, md, x, r);
    for (i = 0; i < md->n; ++i) {
        ws->th[i] = ws->th0[i];
    }
    if (slacks(ws, md) == 0) {
        for (i = 0; i < md->m; ++i) {
            lam[i] = R_(0.0);
        }
        return finish(ws, md, lam, ROLLMPC_OPTIMAL, U);
    }
    /* Polish first: from the previous active set (warm start), then from the rows the
     * unconstrained solution violates; what follows runs only if both fail. The shifted
     * guess, in the dual form, may spend a third of what the budget has left: the dual
     * active set then continues from where it stopped, as it does where the polish of the
     * violated rows runs out of work (typically on the block of rows it would append
     * next: parked there, a sample would stop on a fraction of its budget, and the next
     * one the same way) -- except in a mode of input bounds only after a primal solve,
     * whose point meets every row once clamped (time_limit_at_th0()). With a warm start,
     * the violated rows are polished only in the primal form: in the dual form the resumed
     * dual active set costs less than a factor of H_WW over every violated row (which
     * breaks down on dependent rows). */
    count = 0; /* rows of the warm start */
    if (ROLLMPC_SOLVER_WARM_START) {
        if (!afford(ws, md, (uint32_t)md->m)) {
            return time_limit_at_th0(ws, md, lam, plan, plan_age, 0, U);
        }
        count = seed_shifted(ws, md, lam, 0);
        if (count == OUT_OF_WORK) { /* part of its factor built (carry_factor()); lam: the guess */
            return time_limit_at_th0(ws, md, lam, plan, plan_age, 0, U);
        }
        if (ROLLMPC_SOLVER_ACTIVE_SET && !box_only(ws, md, count)) {
            ws->work_limit = ws->work + (ROLLMPC_SOLVER_WORK_BUDGET - ws->work) / 3u;
        }
        i = polish(ws, md, lam, count, 1, 0, polish_iterations, active);
        ws->work_limit = ROLLMPC_SOLVER_WORK_BUDGET;
        if (i == 0) {
            return finish(ws, md, lam, ROLLMPC_OPTIMAL, U);
        }
        if (i == OUT_OF_WORK || i == GUESS_HANDED_OVER) {
            if (!ROLLMPC_SOLVER_ACTIVE_SET) {
                return time_limit_at_th0(ws, md, lam, plan, plan_age, 1, U);
            }
            resume = ws->stop_rows; /* the dual active set takes over from there */
        }
        if (i == GUESS_CAPPED) {
            resume = COLD_START; /* resuming the same guess would repeat it round for round */
        }
    }
    if (resume < 0) {
        if (!afford(ws, md, (uint32_t)md->m)) {
            return time_limit_at_th0(ws, md, lam, plan, plan_age, 0, U);
        }
        i = seed_from_violated(ws, md);
        if (count <= 0 || !ROLLMPC_SOLVER_ACTIVE_SET || box_only(ws, md, i)) {
            i = polish(ws, md, lam, i, 0, 0, polish_iterations, active);
            if (i == 0) {
                return finish(ws, md, lam, ROLLMPC_OPTIMAL, U);
            }
            if (i == OUT_OF_WORK) { /* the dual active set goes on, a row at a time, unless */
                if (!ROLLMPC_SOLVER_ACTIVE_SET || ((md->m_box == md->m) && ws->th_solved)) {
                    return time_limit_at_th0(ws, md, lam, plan, plan_age, 1, U); /* a point */
                }
                resume = ws->stop_rows;
            }
            if (i == -1 && count == 0 && ROLLMPC_SOLVER_ACTIVE_SET) {
                resume = violated_resume(ws, md); /* not cold: from the rows th0 violates */
            }
        }
    }
    /* Before any sweep: the dual active-set solve, which also proves infeasibility. */
    i = dual_active_set(ws, md, lam, resume, polish_iterations, active);
    if (i >= 0) {
        return finish(ws, md, lam, (i == 0) ? ROLLMPC_OPTIMAL : ROLLMPC_INFEASIBLE, U);
    }
    if (i == OUT_OF_WORK) {
        return finish(ws, md, lam, ROLLMPC_TIME_LIMIT, U); /* at its last point */
    }
    if (i == OUT_OF_WORK_AT_TH0) { /* no point of its own: lam as it left it */
        return time_limit_at_th0(ws, md, lam, plan, plan_age, 0, U);
    }
    if (!afford(ws, md, 3u * (uint32_t)md->m + (uint32_t)md->n
                        + (ws->out_slacks_ok ? 0u : predict_work(md)))) {
        return time_limit_at_th0(ws, md, lam, plan, plan_age, 0, U);
    }
    output_slacks(ws, md);
    for (i = 0; i < md->n; ++i) {
        ws->th[i] = ws->th0[i];
    }
    for (i = 0; i < md->m; ++i) {
        ws->in_set[i] = (uint8_t)(ROLLMPC_SOLVER_REDUCED ? (ws->K[i] < ROLLMPC_SOLVER_SIGMA) : 1);
        if (!ROLLMPC_SOLVER_WARM_START || !ws->in_set[i]) {
            lam[i] = R_(0.0);
        }
    }
    count = build_set(ws, md);
    for (;;) {
        int t, converged = 0, diverged = 0, nviol, added = 0, out = 0;
        const int chunk = ROLLMPC_SOLVER_POLISH ? ROLLMPC_SOLVER_POLISH_EVERY : ROLLMPC_SOLVER_MAX_ITER;
        /* after the chunk: the corrected point, then the polish (which checks for itself)
         * or the row checks */
        const uint32_t after = correct_work(md, count) + (uint32_t)count;
        for (t = 0; t < chunk && total < ROLLMPC_SOLVER_MAX_ITER; ++t) {
            rollmpc_real e2;
            out = !afford(ws, md, sweep_work(md, count) + after);
            if (out) {
                break;
            }
            e2 = sweep(ws, md, lam, count, &diverged);
            ++total;
            if (diverged) {
                break;
            }
            if (e2 < ROLLMPC_SOLVER_DELTA) {
                converged = 1;
                break;
            }
        }
        if (out) {
            status = ROLLMPC_TIME_LIMIT; /* ws->th: the last corrected point */
            break;
        }
        if (diverged) {
            status = ROLLMPC_INFEASIBLE;
            break;
        }
        correct(ws, md, ws->lists.set, count, lam, CORRECT_BY_ROW);
        i = polish(ws, md, lam, seed_from_multipliers(ws, md, lam, ws->lists.set, count), 0, 0,
                   polish_iterations, active);
        if (i == 0) {
            status = ROLLMPC_OPTIMAL;
            break;
        }
        if (i == OUT_OF_WORK
            || !afford(ws, md, correct_work(md, count) + 2u * scan_work(md) + 2u * (uint32_t)md->m)) {
            fallback_point(ws, md, plan, plan_age); /* the polish overwrote the sweeps' point */
            status = ROLLMPC_TIME_LIMIT;
            break;
        }
        for (i = 0; i < md->m; ++i) { /* the polish flagged its working set in in_set */
            ws->in_set[i] = 0;
        }
        for (i = 0; i < count; ++i) {
            ws->in_set[ws->lists.set[i]] = 1;
        }
        correct(ws, md, ws->lists.set, count, lam, CORRECT_BY_ROW);
        nviol = violated_outside(ws, md, ws->th, 0, ws->tmp, 0);
        if (ROLLMPC_SOLVER_REDUCED && nviol != 0) {
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
            status = ROLLMPC_OPTIMAL;
            break;
        }
        if (total >= ROLLMPC_SOLVER_MAX_ITER) {
            status = ROLLMPC_MAX_ITER;
            break;
        }
        if (converged && added == 0) {
            status = ROLLMPC_INACCURATE;
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
