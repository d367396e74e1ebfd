/**
 * @file quadatt_linalg.c
 * @brief Packed Cholesky factorisation and solves for the polish step.
 *
 * Operation order is fixed (sequential sums, no fused multiply-add) so the NumPy
 * reference reproduces every result bit for bit.
 */
#include <math.h>
#include "quadatt_internal.h"

/**
 * @brief Cholesky factorisation A = L L' of a packed lower triangle, from row @p from on.
 *
 * Rows 0..from-1 must already hold L (the row-oriented algorithm computes row i from the
 * rows above it), so a working set that lost a row refactors only the rows below it.
 * @param a Packed lower triangle: L in rows < from, A in rows >= from on entry; L on return.
 * @param from First row to factor (0 for the whole matrix).
 * @param n Order of A.
 * @return 0 on success, -1 if a pivot is not positive (A not numerically definite).
 */
int quadatt_cholesky_from(quadatt_real *a, int from, int n)
{
    int i, j, k;
    for (i = from; i < n; ++i) {
        quadatt_real *ri = &a[QUADATT_TRI(i, 0)];
        for (j = 0; j <= i; ++j) {
            const quadatt_real *rj = &a[QUADATT_TRI(j, 0)];
            quadatt_real s = ri[j];
            for (k = 0; k < j; ++k) {
                s -= ri[k] * rj[k];
            }
            if (i == j) {
                if (!(s > QUADATT_R(0.0))) {
                    return -1;
                }
                ri[i] = QUADATT_SQRT(s);
            } else {
                ri[j] = s / rj[j];
            }
        }
    }
    return 0;
}

/**
 * @brief In-place Cholesky factorisation A = L L' of a packed lower triangle.
 * @param a Packed lower triangle of A on entry, of L on return.
 * @param n Order of A.
 * @return 0 on success, -1 if a pivot is not positive (A not numerically definite).
 */
int quadatt_cholesky(quadatt_real *a, int n)
{
    return quadatt_cholesky_from(a, 0, n);
}

/**
 * @brief Solve L y = b in place (forward substitution), L from quadatt_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b Right-hand side on entry, y on return.
 */
void quadatt_chol_lsolve(const quadatt_real *l, int n, quadatt_real *b)
{
    int i, k;
    for (i = 0; i < n; ++i) {
        const quadatt_real *li = &l[QUADATT_TRI(i, 0)];
        quadatt_real s = b[i];
        for (k = 0; k < i; ++k) {
            s -= li[k] * b[k];
        }
        b[i] = s / li[i];
    }
}

/**
 * @brief Solve L' x = y in place (back substitution), L from quadatt_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b y on entry, x on return.
 */
void quadatt_chol_ltsolve(const quadatt_real *l, int n, quadatt_real *b)
{
    int i, k, off;
    for (i = n - 1; i >= 0; --i) {
        quadatt_real s = b[i];
        off = QUADATT_TRI(i + 1, i); /* column i below the diagonal: stride k + 1 */
        for (k = i + 1; k < n; ++k) {
            s -= l[off] * b[k];
            off += k + 1;
        }
        b[i] = s / l[QUADATT_TRI(i, i)];
    }
}

/**
 * @brief Solve L L' x = b in place, L from quadatt_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b Right-hand side on entry, solution on return.
 */
void quadatt_chol_solve(const quadatt_real *l, int n, quadatt_real *b)
{
    quadatt_chol_lsolve(l, n, b);
    quadatt_chol_ltsolve(l, n, b);
}
