/**
 * @file c172p_roll_linalg.c
 * @brief Packed Cholesky factorisation and solves for the polish step.
 *
 * Operation order is fixed (sequential sums, no fused multiply-add) so the NumPy
 * reference reproduces every result bit for bit.
 */
#include <math.h>
#include "c172p_roll_internal.h"

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
int c172p_roll_cholesky_from(c172p_roll_real *a, int from, int n)
{
    int i, j, k;
    for (i = from; i < n; ++i) {
        c172p_roll_real *ri = &a[C172P_ROLL_TRI(i, 0)];
        for (j = 0; j <= i; ++j) {
            const c172p_roll_real *rj = &a[C172P_ROLL_TRI(j, 0)];
            c172p_roll_real s = ri[j];
            for (k = 0; k < j; ++k) {
                s -= ri[k] * rj[k];
            }
            if (i == j) {
                if (!(s > C172P_ROLL_R(0.0))) {
                    return -1;
                }
                ri[i] = C172P_ROLL_SQRT(s);
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
int c172p_roll_cholesky(c172p_roll_real *a, int n)
{
    return c172p_roll_cholesky_from(a, 0, n);
}

/**
 * @brief Solve L y = b in place (forward substitution), L from c172p_roll_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b Right-hand side on entry, y on return.
 */
void c172p_roll_chol_lsolve(const c172p_roll_real *l, int n, c172p_roll_real *b)
{
    int i, k;
    for (i = 0; i < n; ++i) {
        const c172p_roll_real *li = &l[C172P_ROLL_TRI(i, 0)];
        c172p_roll_real s = b[i];
        for (k = 0; k < i; ++k) {
            s -= li[k] * b[k];
        }
        b[i] = s / li[i];
    }
}

/**
 * @brief Solve L' x = y in place (back substitution), L from c172p_roll_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b y on entry, x on return.
 */
void c172p_roll_chol_ltsolve(const c172p_roll_real *l, int n, c172p_roll_real *b)
{
    int i, k, off;
    for (i = n - 1; i >= 0; --i) {
        c172p_roll_real s = b[i];
        off = C172P_ROLL_TRI(i + 1, i); /* column i below the diagonal: stride k + 1 */
        for (k = i + 1; k < n; ++k) {
            s -= l[off] * b[k];
            off += k + 1;
        }
        b[i] = s / l[C172P_ROLL_TRI(i, i)];
    }
}

/**
 * @brief Solve L L' x = b in place, L from c172p_roll_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b Right-hand side on entry, solution on return.
 */
void c172p_roll_chol_solve(const c172p_roll_real *l, int n, c172p_roll_real *b)
{
    c172p_roll_chol_lsolve(l, n, b);
    c172p_roll_chol_ltsolve(l, n, b);
}
