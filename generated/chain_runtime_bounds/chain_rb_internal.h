/**
 * @file chain_rb_internal.h
 * @brief Internal declarations shared by the generated sources (not part of the API).
 */
#ifndef CHAIN_RB_INTERNAL_H
#define CHAIN_RB_INTERNAL_H

#include <math.h>
#include "chain_rb.h"
#if CHAIN_RB_GENERATION != 0x0d1e96d0ea317cb
#error "chain_rb_internal.h and chain_rb_config.h are of different generations (an interrupted regeneration?): regenerate the whole directory"
#endif

/**
 * Static data of one mode (all arrays row-major; "_p" = packed lower triangle), each
 * member declared once by the generator.
 */
typedef struct {
    int nx;                             /**< States (with disturbance and u_prev states). */
    int nu;                             /**< Inputs of the mode. */
    int ny;                             /**< Outputs of the mode. */
    int n;                              /**< Decision variables (N nu, or blocks * nu). */
    int m;                              /**< Constraint rows. */
    int nyq;                            /**< Predicted outputs N ny. */
    int nt;                             /**< Terminal rows of the E split (0: P stays in S). */
    int m_box;                          /**< Rows that are not output rows (input and Δu bounds): the first m_box of scan_rows. */
    int ny_pred;                        /**< Outputs predict_outputs() computes: the first ny_pred of pred_out (those with constraint rows, or all of them). */
    const int16_t *actuator_index;      /**< [nu] physical actuator of each mode input. */
    const chain_rb_real *A;             /**< [nx][nx] discrete state matrix. */
    const chain_rb_real *B;             /**< [nx][nu] discrete input matrix. */
    const chain_rb_real *C;             /**< [ny][nx] output matrix. */
    const chain_rb_real *L;             /**< [nx][ny] observer gain. */
    const chain_rb_real *innovation_limit;/**< [ny] observer innovation y - C xhat clipped to +-this (the largest finite number: clip off). */
    const chain_rb_real *Kx;            /**< [n][nx] unconstrained state gain. */
    const chain_rb_real *EinvGt;        /**< [n][nyq] E^-1 Gamma'. */
    const chain_rb_real *Sinv_p;        /**< [n(n+1)/2] packed S^-1. */
    const chain_rb_real *Ew;            /**< [nt][n] E^-1 = S^-1 - Ew' Ew (Woodbury). */
    const chain_rb_real *Uv;            /**< [nt][n] V S^-1. */
    const chain_rb_real *T;             /**< [nt][nt] (2P)^-1 + V S^-1 V'. */
    const chain_rb_real *S_p;           /**< [n(n+1)/2] packed stage Hessian S (E = S + V'(2P)V). */
    const chain_rb_real *V;             /**< [nt][n] terminal rows of Gamma (nt = 0: none). */
    const chain_rb_real *P2inv;         /**< [nt][nt] (2P)^-1. */
    const chain_rb_real *GEinvGt_p;     /**< [nyq(nyq+1)/2] packed Gamma E^-1 Gamma' (null: no output rows). */
    const chain_rb_real *Omega2;        /**< [N][ny][ny] 2Q per stage, 2P at the last. */
    const chain_rb_real *Phi;           /**< [nyq][nx] free response of the predicted outputs. */
    const chain_rb_real *markov_by_output;/**< [ny][N*nu] Markov parameters C A^i B by output, the longest lag first: row a holds (C A^(N-1-j) B)[a, :] from j nu, so output a of stage s is its last (s+1) nu entries times th's first ones. */
    const int16_t *pred_out;            /**< [ny] the predicted outputs, ascending, then the others. */
    const int16_t *row_q;               /**< [m] quantity of each row (U index, n + Y index, or n + nyq + Δu index). */
    const int8_t *row_sign;             /**< [m] -1 lower / +1 upper bound row. */
    const chain_rb_real *row_c;         /**< [m] constant right-hand side c. */
    const int16_t *scan_rows;           /**< [m] the rows by kind: the m_box rows that are not output rows, ascending, then the output rows, ascending (violated_kind()). */
    const int16_t *row_next;            /**< [m] same constraint one stage later (shifted warm start). */
    const chain_rb_real *colsum;        /**< [ny][n] sum of the E^-1 Gamma' columns of stages 0..N-2. */
    const chain_rb_real *out_bound;     /**< [nyq] |(Gamma th)_k| <= out_bound[k] max|th|. */
    const chain_rb_real *u_min;         /**< [nu] input lower bounds. */
    const chain_rb_real *u_max;         /**< [nu] input upper bounds. */
} chain_rb_mode_data;

extern const chain_rb_mode_data chain_rb_modes[CHAIN_RB_N_MODES];

/*
 * 1 if v[0..n) are all finite. v - v is +0 for a finite v and NaN for an infinite or NaN
 * one; a sum of zeros stays 0 and a NaN stays NaN. No compare per element: each costs the
 * M4F a transfer of the FPU flags.
 */
static inline int chain_rb_all_finite(const chain_rb_real *v, int n)
{
    chain_rb_real z0 = CHAIN_RB_R(0.0), z1 = CHAIN_RB_R(0.0);
    int i;
    for (i = 0; i + 1 < n; i += 2) {
        z0 += v[i] - v[i];
        z1 += v[i + 1] - v[i + 1];
    }
    if (i < n) {
        z0 += v[i] - v[i];
    }
    return !isnan(z0 + z1);
}

/** Packed lower-triangle index of (i, j), j <= i. */
#define CHAIN_RB_TRI(i, j) ((i) * ((i) + 1) / 2 + (j))

/*
 * What the work array chol holds (ws->chol_holds): nothing valid, or L = chol(H_WW) of the
 * working set wset[0..nw) in its order (kept by updates, solver/polish_dual.c.j2), or the
 * primal polish's factor of S_FF or (S^-1)_BB (solver/polish_primal.c.j2). Whoever changes
 * chol or the working set keeps the flag true, so no form reads a stale factor.
 */
#define CHAIN_RB_CHOL_NONE 0
#define CHAIN_RB_CHOL_DUAL 1
#define CHAIN_RB_CHOL_PRIMAL 2

/*
 * The widest kernel loops where the FPU has 32 single-precision registers (ARM VFP, the
 * Cortex-M4F) and the tree is in float: cholesky_from()'s 4 x 4 blocks keep 16 sums and 8
 * operands in registers, and the unconstrained step's sums over a run of stages take four
 * terms per trip. On a host (16 SSE registers) the same loops would spill to the stack or
 * widen the frames on the worst path past its 1,024-B budget, and a double tree on a
 * single-precision FPU computes in software, where they only spill (+472 B of stack on
 * the M4F): both take the plain ones. Every sum is the same sequential sum either way, so
 * the commands agree bit for bit; a factor that breaks down is left with other partial
 * rows, so the instance's bytes agree only between builds of the same kernels. A build
 * may choose with -DCHAIN_RB_WIDE_KERNELS=0 or 1: the host tests run the target's
 * kernels that way.
 */
#ifndef CHAIN_RB_WIDE_KERNELS
#define CHAIN_RB_WIDE_KERNELS 0
#endif

/* Linear algebra on packed symmetric matrices (chain_rb_linalg.c). */
int chain_rb_cholesky(chain_rb_real *a, int n);
int chain_rb_cholesky_from(chain_rb_real *a, int from, int n);
void chain_rb_chol_lsolve(const chain_rb_real *l, int n, chain_rb_real *b);
void chain_rb_chol_lsolve_from(const chain_rb_real *l, int from, int n, chain_rb_real *b);
void chain_rb_chol_ltsolve(const chain_rb_real *l, int n, chain_rb_real *b);
void chain_rb_chol_solve(const chain_rb_real *l, int n, chain_rb_real *b);

/* QP solver (chain_rb_solver.c). */
int chain_rb_qp_solve(chain_rb_work *ws, chain_rb_real *lam, const chain_rb_real *plan,
    int plan_age, const chain_rb_mode_data *md, const chain_rb_real *x,
    const chain_rb_real *r, chain_rb_real *U, int *iterations, int *polish_iterations,
    int *active);

#endif /* CHAIN_RB_INTERNAL_H */
