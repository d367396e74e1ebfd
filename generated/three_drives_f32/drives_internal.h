/**
 * @file drives_internal.h
 * @brief Internal declarations shared by the generated sources (not part of the API).
 */
#ifndef DRIVES_INTERNAL_H
#define DRIVES_INTERNAL_H

#include "drives.h"

/** Static data of one mode (all arrays row-major; "_p" = packed lower triangle). */
typedef struct {
    int nx, nu, ny, n, m, nyq, nt;
    const int16_t *actuator;        /**< [nu] physical actuator of each mode input. */
    const drives_real *A, *B, *C, *L; /**< Discrete model and observer gain. */
    const drives_real *Kx;      /**< [n][nx] unconstrained state gain. */
    const drives_real *EinvGt;  /**< [n][nyq] E^-1 Gamma'. */
    const drives_real *Sinv_p;  /**< S^-1, packed. */
    const drives_real *Ew;      /**< [nt][n]: E^-1 = S^-1 - Ew' Ew (Woodbury). */
    const drives_real *Uv;      /**< [nt][n] V S^-1. */
    const drives_real *T;       /**< [nt][nt] (2P)^-1 + V S^-1 V'. */
    const drives_real *S_p;     /**< Stage Hessian S (E = S + V'(2P)V), packed. */
    const drives_real *V;       /**< [nt][n] terminal rows of Gamma (nt = 0: none). */
    const drives_real *P2inv;   /**< [nt][nt] (2P)^-1. */
    const drives_real *GEinvGt_p; /**< Gamma E^-1 Gamma', packed (output rows only). */
    const drives_real *Omega2;  /**< [N][ny][ny] 2Q per stage, 2P last. */
    const drives_real *Phi;     /**< [nyq][nx]. */
    const drives_real *markov;  /**< [N][ny][nu] C A^i B. */
    const int16_t *row_q;             /**< [m] quantity of each row (U index, or n + Y index). */
    const int8_t *row_sign;           /**< [m] -1 lower / +1 upper bound row. */
    const drives_real *row_c;   /**< [m] constant right-hand side c. */
    const int16_t *row_next;          /**< [m] same constraint one stage later (shifted warm start). */
    const drives_real *colsum;  /**< [ny][n] sum of the E^-1 Gamma' columns of stages 0..N-2. */
    const drives_real *out_bound; /**< [nyq] |(Gamma th)_k| <= out_bound[k] max|th|. */
    const drives_real *u_min, *u_max; /**< [nu] input bounds. */
} drives_mode_data;

extern const drives_mode_data drives_modes[DRIVES_N_MODES];

/** Packed lower-triangle index of (i, j), j <= i. */
#define DRIVES_TRI(i, j) ((i) * ((i) + 1) / 2 + (j))

/* Linear algebra on packed symmetric matrices (drives_linalg.c). */
int drives_cholesky(drives_real *a, int n);
int drives_cholesky_from(drives_real *a, int from, int n);
void drives_chol_lsolve(const drives_real *l, int n, drives_real *b);
void drives_chol_ltsolve(const drives_real *l, int n, drives_real *b);
void drives_chol_solve(const drives_real *l, int n, drives_real *b);

/* QP solver (drives_solver.c). */
int drives_qp_solve(drives_work *ws, drives_real *lam, const drives_mode_data *md,
    const drives_real *x, const drives_real *r, drives_real *U, int *iterations,
    int *polish_iterations, int *active);

#endif /* DRIVES_INTERNAL_H */
