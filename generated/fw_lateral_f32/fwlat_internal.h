/**
 * @file fwlat_internal.h
 * @brief Internal declarations shared by the generated sources (not part of the API).
 */
#ifndef FWLAT_INTERNAL_H
#define FWLAT_INTERNAL_H

#include <math.h>
#include "fwlat.h"
#if FWLAT_GENERATION != 0xd594b3415a246c7
#error "fwlat_internal.h and fwlat_config.h are of different generations (an interrupted regeneration?): regenerate the whole directory"
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
    int w_cap;                          /**< Working-set capacity: n + soft (output, stage) pairs. */
    const int16_t *actuator_index;      /**< [nu] physical actuator of each mode input. */
    const fwlat_real *A;                /**< [nx][nx] discrete state matrix. */
    const fwlat_real *B;                /**< [nx][nu] discrete input matrix. */
    const fwlat_real *C;                /**< [ny][nx] output matrix. */
    const fwlat_real *L;                /**< [nx][ny] observer gain. */
    const fwlat_real *innovation_limit; /**< [ny] observer innovation y - C xhat clipped to +-this (the largest finite number: clip off). */
    const fwlat_real *Kx;               /**< [n][nx] unconstrained state gain. */
    const fwlat_real *EinvGt;           /**< [n][nyq] E^-1 Gamma'. */
    const fwlat_real *Sinv_p;           /**< [n(n+1)/2] packed S^-1. */
    const fwlat_real *Ew;               /**< [nt][n] E^-1 = S^-1 - Ew' Ew (Woodbury). */
    const fwlat_real *Uv;               /**< [nt][n] V S^-1. */
    const fwlat_real *T;                /**< [nt][nt] (2P)^-1 + V S^-1 V'. */
    const fwlat_real *S_p;              /**< [n(n+1)/2] packed stage Hessian S (E = S + V'(2P)V). */
    const fwlat_real *V;                /**< [nt][n] terminal rows of Gamma (nt = 0: none). */
    const fwlat_real *P2inv;            /**< [nt][nt] (2P)^-1. */
    const fwlat_real *GEinvGt_p;        /**< [nyq(nyq+1)/2] packed Gamma E^-1 Gamma' (null: no output rows). */
    const fwlat_real *Omega2;           /**< [N][ny][ny] 2Q per stage, 2P at the last. */
    const fwlat_real *Phi;              /**< [nyq][nx] free response of the predicted outputs. */
    const fwlat_real *markov_by_output; /**< [ny][N*nu] Markov parameters C A^i B by output, the longest lag first: row a holds (C A^(N-1-j) B)[a, :] from j nu, so output a of stage s is its last (s+1) nu entries times th's first ones. */
    const int16_t *pred_out;            /**< [ny] the predicted outputs, ascending, then the others. */
    const int16_t *row_q;               /**< [m] quantity of each row (U index, n + Y index, or n + nyq + Δu index). */
    const int8_t *row_sign;             /**< [m] -1 lower / +1 upper bound row. */
    const fwlat_real *row_c;            /**< [m] constant right-hand side c. */
    const int16_t *scan_rows;           /**< [m] the rows by kind: the m_box rows that are not output rows, ascending, then the output rows, ascending (violated_kind()). */
    const int16_t *row_next;            /**< [m] same constraint one stage later (shifted warm start). */
    const fwlat_real *colsum;           /**< [ny][n] sum of the E^-1 Gamma' columns of stages 0..N-2. */
    const fwlat_real *out_bound;        /**< [nyq] |(Gamma th)_k| <= out_bound[k] max|th|. */
    const fwlat_real *u_min;            /**< [nu] input lower bounds. */
    const fwlat_real *u_max;            /**< [nu] input upper bounds. */
    const fwlat_real *soft_l1;          /**< [2*ny] soft bound penalty l1 (index 2 j + side, side 1 = y_max). */
    const fwlat_real *soft_w;           /**< [2*ny] 1/(2 l2) of a soft bound, 0 for a hard one. */
} fwlat_mode_data;

extern const fwlat_mode_data fwlat_modes[FWLAT_N_MODES];

/*
 * 1 if v[0..n) are all finite. v - v is +0 for a finite v and NaN for an infinite or NaN
 * one; a sum of zeros stays 0 and a NaN stays NaN. No compare per element: each costs the
 * M4F a transfer of the FPU flags.
 */
static inline int fwlat_all_finite(const fwlat_real *v, int n)
{
    fwlat_real z0 = FWLAT_R(0.0), z1 = FWLAT_R(0.0);
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
#define FWLAT_TRI(i, j) ((i) * ((i) + 1) / 2 + (j))

/*
 * What the work array chol holds (ws->chol_holds): nothing valid, or L = chol(H_WW) of the
 * working set wset[0..nw) in its order (kept by updates, solver/polish_dual.c.j2), or the
 * primal polish's factor of S_FF or (S^-1)_BB (solver/polish_primal.c.j2). Whoever changes
 * chol or the working set keeps the flag true, so no form reads a stale factor.
 */
#define FWLAT_CHOL_NONE 0
#define FWLAT_CHOL_DUAL 1
#define FWLAT_CHOL_PRIMAL 2

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
 * may choose with -DFWLAT_WIDE_KERNELS=0 or 1: the host tests run the target's
 * kernels that way.
 */
#ifndef FWLAT_WIDE_KERNELS
#if defined(__ARM_FP) && (__ARM_FP & 4) && !defined(__aarch64__)
#define FWLAT_WIDE_KERNELS 1
#else
#define FWLAT_WIDE_KERNELS 0
#endif
#endif

/* Linear algebra on packed symmetric matrices (fwlat_linalg.c). */
int fwlat_cholesky(fwlat_real *a, int n);
int fwlat_cholesky_from(fwlat_real *a, int from, int n);
void fwlat_chol_lsolve(const fwlat_real *l, int n, fwlat_real *b);
void fwlat_chol_lsolve_from(const fwlat_real *l, int from, int n, fwlat_real *b);
void fwlat_chol_ltsolve(const fwlat_real *l, int n, fwlat_real *b);
void fwlat_chol_solve(const fwlat_real *l, int n, fwlat_real *b);

/* QP solver (fwlat_solver.c). */
int fwlat_qp_solve(fwlat_work *ws, fwlat_real *lam, const fwlat_real *plan,
    int plan_age, const fwlat_mode_data *md, const fwlat_real *x,
    const fwlat_real *r, fwlat_real *U, int *iterations, int *polish_iterations,
    int *active);

#endif /* FWLAT_INTERNAL_H */
