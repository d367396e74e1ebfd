/**
 * @file zrate_internal.h
 * @brief Internal declarations shared by the generated sources (not part of the API).
 */
#ifndef ZRATE_INTERNAL_H
#define ZRATE_INTERNAL_H

#include "zrate.h"

/** Static data of one mode (all arrays row-major; "_p" = packed lower triangle). */
typedef struct {
    int nx, nu, ny, n, m, nyq, nt;
    const int16_t *actuator;        /**< [nu] physical actuator of each mode input. */
    const zrate_real *A, *B, *C, *L; /**< Discrete model and observer gain. */
    const zrate_real *Kx;      /**< [n][nx] unconstrained state gain. */
    const zrate_real *EinvGt;  /**< [n][nyq] E^-1 Gamma'. */
    const zrate_real *Sinv_p;  /**< S^-1, packed. */
    const zrate_real *Ew;      /**< [nt][n]: E^-1 = S^-1 - Ew' Ew (Woodbury). */
    const zrate_real *Uv;      /**< [nt][n] V S^-1. */
    const zrate_real *T;       /**< [nt][nt] (2P)^-1 + V S^-1 V'. */
    const zrate_real *S_p;     /**< Stage Hessian S (E = S + V'(2P)V), packed. */
    const zrate_real *V;       /**< [nt][n] terminal rows of Gamma (nt = 0: none). */
    const zrate_real *P2inv;   /**< [nt][nt] (2P)^-1. */
    const zrate_real *GEinvGt_p; /**< Gamma E^-1 Gamma', packed (output rows only). */
    const zrate_real *Omega2;  /**< [N][ny][ny] 2Q per stage, 2P last. */
    const zrate_real *Phi;     /**< [nyq][nx]. */
    const zrate_real *markov;  /**< [N][ny][nu] C A^i B. */
    const int16_t *row_q;             /**< [m] quantity of each row (U index, or n + Y index). */
    const int8_t *row_sign;           /**< [m] -1 lower / +1 upper bound row. */
    const zrate_real *row_c;   /**< [m] constant right-hand side c. */
    const int16_t *row_next;          /**< [m] same constraint one stage later (shifted warm start). */
    const zrate_real *colsum;  /**< [ny][n] sum of the E^-1 Gamma' columns of stages 0..N-2. */
    const zrate_real *out_bound; /**< [nyq] |(Gamma th)_k| <= out_bound[k] max|th|. */
    const zrate_real *u_min, *u_max; /**< [nu] input bounds. */
} zrate_mode_data;

extern const zrate_mode_data zrate_modes[ZRATE_N_MODES];

/** Packed lower-triangle index of (i, j), j <= i. */
#define ZRATE_TRI(i, j) ((i) * ((i) + 1) / 2 + (j))

/* Linear algebra on packed symmetric matrices (zrate_linalg.c). */
int zrate_cholesky(zrate_real *a, int n);
int zrate_cholesky_from(zrate_real *a, int from, int n);
void zrate_chol_lsolve(const zrate_real *l, int n, zrate_real *b);
void zrate_chol_ltsolve(const zrate_real *l, int n, zrate_real *b);
void zrate_chol_solve(const zrate_real *l, int n, zrate_real *b);

/* QP solver (zrate_solver.c). */
int zrate_qp_solve(zrate_work *ws, zrate_real *lam, const zrate_mode_data *md,
    const zrate_real *x, const zrate_real *r, zrate_real *U, int *iterations,
    int *polish_iterations, int *active);

#endif /* ZRATE_INTERNAL_H */
