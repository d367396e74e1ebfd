/**
 * @file rollmpc_linalg.c
 * @brief Packed Cholesky factorisation and solves for the polish step.
 *
 * Operation order is fixed (sequential sums, no fused multiply-add) so the NumPy
 * reference reproduces every result bit for bit.
 */
#include <math.h>
#include "rollmpc_internal.h"

/**
 * @brief In-place Cholesky factorisation A = L L' of a packed lower triangle.
 * @param a Packed lower triangle of A on entry, of L on return.
 * @param n Order of A.
 * @return 0 on success, -1 if a pivot is not positive (A not numerically definite).
 */
int rollmpc_cholesky(rollmpc_real *a, int n)
{
    int i, j, k;
    for (i = 0; i < n; ++i) {
        for (j = 0; j <= i; ++j) {
            rollmpc_real s = a[ROLLMPC_TRI(i, j)];
            for (k = 0; k < j; ++k) {
                s -= a[ROLLMPC_TRI(i, k)] * a[ROLLMPC_TRI(j, k)];
            }
            if (i == j) {
                if (!(s > ROLLMPC_R(0.0))) {
                    return -1;
                }
                a[ROLLMPC_TRI(i, i)] = ROLLMPC_SQRT(s);
            } else {
                a[ROLLMPC_TRI(i, j)] = s / a[ROLLMPC_TRI(j, j)];
            }
        }
    }
    return 0;
}

/**
 * @brief Solve L L' x = b in place, L from rollmpc_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b Right-hand side on entry, solution on return.
 */
void rollmpc_chol_solve(const rollmpc_real *l, int n, rollmpc_real *b)
{
    int i, k;
    for (i = 0; i < n; ++i) {
        rollmpc_real s = b[i];
        for (k = 0; k < i; ++k) {
            s -= l[ROLLMPC_TRI(i, k)] * b[k];
        }
        b[i] = s / l[ROLLMPC_TRI(i, i)];
    }
    for (i = n - 1; i >= 0; --i) {
        rollmpc_real s = b[i];
        for (k = i + 1; k < n; ++k) {
            s -= l[ROLLMPC_TRI(k, i)] * b[k];
        }
        b[i] = s / l[ROLLMPC_TRI(i, i)];
    }
}
