/**
 * @file rollmpc_internal.h
 * @brief Internal declarations shared by the generated sources (not part of the API).
 */
#ifndef ROLLMPC_INTERNAL_H
#define ROLLMPC_INTERNAL_H

#include <math.h>
#include "rollmpc.h"
#if ROLLMPC_GENERATION != 0x812c05ccab70e27
#error "rollmpc_internal.h and rollmpc_config.h are of different generations (an interrupted regeneration?): regenerate the whole directory"
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
    const rollmpc_real *A;              /**< [nx][nx] discrete state matrix. */
    const rollmpc_real *B;              /**< [nx][nu] discrete input matrix. */
    const rollmpc_real *C;              /**< [ny][nx] output matrix. */
    const rollmpc_real *L;              /**< [nx][ny] observer gain. */
    const rollmpc_real *innovation_limit;/**< [ny] observer innovation y - C xhat clipped to +-this (the largest finite number: clip off). */
    const rollmpc_real *Kx;             /**< [n][nx] unconstrained state gain. */
    const rollmpc_real *EinvGt;         /**< [n][nyq] E^-1 Gamma'. */
    const rollmpc_real *Sinv_p;         /**< [n(n+1)/2] packed S^-1. */
    const rollmpc_real *Ew;             /**< [nt][n] E^-1 = S^-1 - Ew' Ew (Woodbury). */
    const rollmpc_real *Uv;             /**< [nt][n] V S^-1. */
    const rollmpc_real *T;              /**< [nt][nt] (2P)^-1 + V S^-1 V'. */
    const rollmpc_real *S_p;            /**< [n(n+1)/2] packed stage Hessian S (E = S + V'(2P)V). */
    const rollmpc_real *V;              /**< [nt][n] terminal rows of Gamma (nt = 0: none). */
    const rollmpc_real *P2inv;          /**< [nt][nt] (2P)^-1. */
    const rollmpc_real *GEinvGt_p;      /**< [nyq(nyq+1)/2] packed Gamma E^-1 Gamma' (null: no output rows). */
    const rollmpc_real *Omega2;         /**< [N][ny][ny] 2Q per stage, 2P at the last. */
    const rollmpc_real *Phi;            /**< [nyq][nx] free response of the predicted outputs. */
    const rollmpc_real *markov_by_output;/**< [ny][N*nu] Markov parameters C A^i B by output, the longest lag first: row a holds (C A^(N-1-j) B)[a, :] from j nu, so output a of stage s is its last (s+1) nu entries times th's first ones. */
    const int16_t *pred_out;            /**< [ny] the predicted outputs, ascending, then the others. */
    const int16_t *row_q;               /**< [m] quantity of each row (U index, n + Y index, or n + nyq + Δu index). */
    const int8_t *row_sign;             /**< [m] -1 lower / +1 upper bound row. */
    const rollmpc_real *row_c;          /**< [m] constant right-hand side c. */
    const int16_t *scan_rows;           /**< [m] the rows by kind: the m_box rows that are not output rows, ascending, then the output rows, ascending (violated_kind()). */
    const int16_t *row_next;            /**< [m] same constraint one stage later (shifted warm start). */
    const rollmpc_real *colsum;         /**< [ny][n] sum of the E^-1 Gamma' columns of stages 0..N-2. */
    const rollmpc_real *out_bound;      /**< [nyq] |(Gamma th)_k| <= out_bound[k] max|th|. */
    const rollmpc_real *u_min;          /**< [nu] input lower bounds. */
    const rollmpc_real *u_max;          /**< [nu] input upper bounds. */
} rollmpc_mode_data;

extern const rollmpc_mode_data rollmpc_modes[ROLLMPC_N_MODES];

/*
 * 1 if v[0..n) are all finite. v - v is +0 for a finite v and NaN for an infinite or NaN
 * one; a sum of zeros stays 0 and a NaN stays NaN. No compare per element: each costs the
 * M4F a transfer of the FPU flags.
 */
static inline int rollmpc_all_finite(const rollmpc_real *v, int n)
{
    rollmpc_real z0 = ROLLMPC_R(0.0), z1 = ROLLMPC_R(0.0);
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
#define ROLLMPC_TRI(i, j) ((i) * ((i) + 1) / 2 + (j))

/*
 * What the work array chol holds (ws->chol_holds): nothing valid, or L = chol(H_WW) of the
 * working set wset[0..nw) in its order (kept by updates, solver/polish_dual.c.j2), or the
 * primal polish's factor of S_FF or (S^-1)_BB (solver/polish_primal.c.j2). Whoever changes
 * chol or the working set keeps the flag true, so no form reads a stale factor.
 */
#define ROLLMPC_CHOL_NONE 0
#define ROLLMPC_CHOL_DUAL 1
#define ROLLMPC_CHOL_PRIMAL 2

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
 * may choose with -DROLLMPC_WIDE_KERNELS=0 or 1: the host tests run the target's
 * kernels that way.
 */
#ifndef ROLLMPC_WIDE_KERNELS
#define ROLLMPC_WIDE_KERNELS 0
#endif

/* Linear algebra on packed symmetric matrices (rollmpc_linalg.c). */
int rollmpc_cholesky(rollmpc_real *a, int n);
int rollmpc_cholesky_from(rollmpc_real *a, int from, int n);
void rollmpc_chol_lsolve(const rollmpc_real *l, int n, rollmpc_real *b);
void rollmpc_chol_lsolve_from(const rollmpc_real *l, int from, int n, rollmpc_real *b);
void rollmpc_chol_ltsolve(const rollmpc_real *l, int n, rollmpc_real *b);
void rollmpc_chol_solve(const rollmpc_real *l, int n, rollmpc_real *b);

/* QP solver (rollmpc_solver.c). */
int rollmpc_qp_solve(rollmpc_work *ws, rollmpc_real *lam, const rollmpc_real *plan,
    int plan_age, const rollmpc_mode_data *md, const rollmpc_real *x,
    const rollmpc_real *r, rollmpc_real *U, int *iterations, int *polish_iterations,
    int *active);

#endif /* ROLLMPC_INTERNAL_H */
