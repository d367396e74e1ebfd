/**
 * @file zrate_linalg.c
 * @brief Packed Cholesky factorisation and solves for the polish step.
 *
 * Operation order is fixed (sequential sums, no fused multiply-add) so the NumPy
 * reference reproduces every result bit for bit. Each sum runs from its first term to
 * its last, one product at a time; the loops below only compute two or four such sums
 * side by side, so that each element read from memory serves two products (a Cortex-M4F
 * spends more cycles loading operands than multiplying them). The packed factor is the
 * lower triangle by rows, element (i, j) at ZRATE_TRI(i, j), so row i + 1 starts
 * i + 1 elements after row i.
 */
#include <math.h>
#include "zrate_internal.h"

/*
 * Entries (i, j), (i, j + 1), (i + 1, j), (i + 1, j + 1) of L, from rows i, i + 1 of A
 * (r0, r1 = r0 + i + 1) and rows j, j + 1 of L (q0, q1 = q0 + j + 1): each
 * s = a - sum_k r[k] q[k] in k order, divided by its pivot.
 */
static void cholesky_block(zrate_real *r0, zrate_real *r1, const zrate_real *q0,
    int j)
{
    const zrate_real *q1 = q0 + j + 1;
    zrate_real s00 = r0[j], s01 = r0[j + 1], s10 = r1[j], s11 = r1[j + 1];
    const zrate_real *x0 = r0, *x1 = r1, *y0 = q0, *y1 = q1, *end = q0 + j;
    if (j & 1) {
        const zrate_real a0 = *x0++, a1 = *x1++, b0 = *y0++, b1 = *y1++;
        s00 -= a0 * b0;
        s01 -= a0 * b1;
        s10 -= a1 * b0;
        s11 -= a1 * b1;
    }
    while (y0 != end) { /* two k per trip */
        zrate_real a0 = x0[0], a1 = x1[0], b0 = y0[0], b1 = y1[0];
        s00 -= a0 * b0;
        s01 -= a0 * b1;
        s10 -= a1 * b0;
        s11 -= a1 * b1;
        a0 = x0[1];
        a1 = x1[1];
        b0 = y0[1];
        b1 = y1[1];
        s00 -= a0 * b0;
        s01 -= a0 * b1;
        s10 -= a1 * b0;
        s11 -= a1 * b1;
        x0 += 2;
        x1 += 2;
        y0 += 2;
        y1 += 2;
    }
    r0[j] = s00 / q0[j];
    r1[j] = s10 / q0[j];
    s01 -= r0[j] * q1[j];
    s11 -= r1[j] * q1[j];
    r0[j + 1] = s01 / q1[j + 1];
    r1[j + 1] = s11 / q1[j + 1];
}

/* As cholesky_block() for one row of L (q0, column j) against rows r0, r1. */
static void cholesky_column(zrate_real *r0, zrate_real *r1, const zrate_real *q0,
    int j)
{
    zrate_real s0 = r0[j], s1 = r1[j];
    const zrate_real *x0 = r0, *x1 = r1, *y0 = q0, *end = q0 + j;
    while (y0 != end) {
        const zrate_real b0 = *y0++;
        s0 -= *x0++ * b0;
        s1 -= *x1++ * b0;
    }
    r0[j] = s0 / q0[j];
    r1[j] = s1 / q0[j];
}

/*
 * One row i of L alone (r = row i, the rows above already factored), against two rows
 * j, j + 1 of L at a time; -1 on a bad pivot.
 */
static int cholesky_row(zrate_real *a, zrate_real *r, int i)
{
    int j = 0;
    zrate_real s;
    const zrate_real *x, *end;
    for (; j + 1 < i; j += 2) {
        const zrate_real *q0 = &a[ZRATE_TRI(j, 0)], *q1 = q0 + j + 1, *y0 = q0, *y1 = q1;
        zrate_real s0 = r[j], s1 = r[j + 1];
        x = r;
        end = r + j;
        while (x != end) {
            s0 -= *x * *y0++;
            s1 -= *x * *y1++;
            ++x;
        }
        r[j] = s0 / q0[j];
        s1 -= r[j] * q1[j];
        r[j + 1] = s1 / q1[j + 1];
    }
    if (j < i) {
        const zrate_real *q = &a[ZRATE_TRI(j, 0)], *y = q;
        s = r[j];
        for (x = r, end = r + j; x != end;) {
            s -= *x++ * *y++;
        }
        r[j] = s / q[j];
    }
    s = r[i];
    for (x = r, end = r + i; x != end; ++x) {
        s -= *x * *x;
    }
    if (!(s > ZRATE_R(0.0))) {
        return -1;
    }
    r[i] = ZRATE_SQRT(s);
    return 0;
}

/**
 * @brief Cholesky factorisation A = L L' of a packed lower triangle, from row @p from on.
 *
 * Rows 0..from-1 must already hold L (the row-oriented algorithm computes row i from the
 * rows above it), so a working set that lost a row refactors only the rows below it, and
 * one that gained rows at the end computes only those (bordering). Rows are computed two
 * at a time, against two rows of L at a time; every entry is the sequential sum of the
 * plain algorithm, L_ij = (A_ij - sum_{k<j} L_ik L_jk) / L_jj, so the result does not
 * depend on @p from (a division, not a multiplication by 1 / L_jj: the dual active set's
 * infeasibility proofs on nearly dependent rows are sensitive to that rounding).
 * Cost: sum_{i=from}^{n-1} i (i + 1) / 2 = (n^3 - n - from^3 + from) / 6 multiply-adds,
 * (n - from)(n + from - 1) / 2 divisions and n - from square roots.
 * @param a Packed lower triangle: L in rows < from, A in rows >= from on entry; L on return.
 * @param from First row to factor (0 for the whole matrix).
 * @param n Order of A.
 * @return 0 on success, -1 if a pivot is not positive (A not numerically definite).
 */
int zrate_cholesky_from(zrate_real *a, int from, int n)
{
    int i = from, j;
    for (; i + 1 < n; i += 2) {
        zrate_real *r0 = &a[ZRATE_TRI(i, 0)], *r1 = r0 + i + 1;
        zrate_real s00, s10, s11;
        const zrate_real *x0 = r0, *x1 = r1, *end = r0 + i;
        for (j = 0; j + 1 < i; j += 2) {
            cholesky_block(r0, r1, &a[ZRATE_TRI(j, 0)], j);
        }
        if (j < i) {
            cholesky_column(r0, r1, &a[ZRATE_TRI(j, 0)], j);
        }
        /* the 2 x 2 diagonal block: (i, i), (i + 1, i), (i + 1, i + 1) */
        s00 = r0[i];
        s10 = r1[i];
        s11 = r1[i + 1];
        while (x0 != end) {
            const zrate_real a0 = *x0++, a1 = *x1++;
            s00 -= a0 * a0;
            s10 -= a1 * a0;
            s11 -= a1 * a1;
        }
        if (!(s00 > ZRATE_R(0.0))) {
            return -1;
        }
        r0[i] = ZRATE_SQRT(s00);
        r1[i] = s10 / r0[i];
        s11 -= r1[i] * r1[i];
        if (!(s11 > ZRATE_R(0.0))) {
            return -1;
        }
        r1[i + 1] = ZRATE_SQRT(s11);
    }
    if (i < n) {
        return cholesky_row(a, &a[ZRATE_TRI(i, 0)], i);
    }
    return 0;
}

/**
 * @brief In-place Cholesky factorisation A = L L' of a packed lower triangle.
 * @param a Packed lower triangle of A on entry, of L on return.
 * @param n Order of A.
 * @return 0 on success, -1 if a pivot is not positive (A not numerically definite).
 */
int zrate_cholesky(zrate_real *a, int n)
{
    return zrate_cholesky_from(a, 0, n);
}

/**
 * @brief Solve L y = b in place (forward substitution) from row @p from on.
 *
 * b[0..from) must already hold y (they do not depend on the rows below), so a factor
 * that kept its first rows keeps that part of its solves. Two rows at a time; each y_i
 * is the sequential sum b_i - sum_{k<i} L_ik y_k divided by L_ii.
 * Cost: (n^2 - n - from^2 + from) / 2 multiply-adds and n - from divisions.
 * @param l Packed lower Cholesky factor.
 * @param from First row to solve.
 * @param n Order.
 * @param b Right-hand side on entry (y in rows < from), y on return.
 */
void zrate_chol_lsolve_from(const zrate_real *l, int from, int n, zrate_real *b)
{
    int i = from;
    for (; i + 1 < n; i += 2) {
        const zrate_real *r0 = &l[ZRATE_TRI(i, 0)], *r1 = r0 + i + 1, *y = b;
        const zrate_real *end = b + i;
        zrate_real s0 = b[i], s1 = b[i + 1];
        while (y != end) {
            const zrate_real v = *y++;
            s0 -= *r0++ * v;
            s1 -= *r1++ * v;
        }
        b[i] = s0 / *r0;
        s1 -= r1[0] * b[i];
        b[i + 1] = s1 / r1[1];
    }
    if (i < n) {
        const zrate_real *r0 = &l[ZRATE_TRI(i, 0)], *y = b, *end = b + i;
        zrate_real s0 = b[i];
        while (y != end) {
            s0 -= *r0++ * *y++;
        }
        b[i] = s0 / *r0;
    }
}

/**
 * @brief Solve L y = b in place (forward substitution), L from zrate_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b Right-hand side on entry, y on return.
 */
void zrate_chol_lsolve(const zrate_real *l, int n, zrate_real *b)
{
    zrate_chol_lsolve_from(l, 0, n, b);
}

/**
 * @brief Solve L' x = y in place (back substitution), L from zrate_cholesky().
 *
 * x_i = (y_i - sum_{k>i} L_ki x_k) / L_ii, the sum in increasing k down column i of the
 * packed rows (row k starts k + 1 after row k - 1), four terms per loop trip. (The order
 * matters beyond rounding: the dual active set's infeasibility proofs on nearly dependent
 * rows follow it.)
 * Cost: (n^2 - n) / 2 multiply-adds and n divisions.
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b y on entry, x on return.
 */
void zrate_chol_ltsolve(const zrate_real *l, int n, zrate_real *b)
{
    int i, k;
    for (i = n - 1; i >= 0; --i) {
        const zrate_real *lk = &l[ZRATE_TRI(i + 1, i)]; /* L_(i+1),i */
        zrate_real s = b[i];
        for (k = i + 1; k + 3 < n; k += 4) {
            const zrate_real *l1 = lk + k + 1, *l2 = l1 + k + 2, *l3 = l2 + k + 3;
            s -= *lk * b[k];
            s -= *l1 * b[k + 1];
            s -= *l2 * b[k + 2];
            s -= *l3 * b[k + 3];
            lk = l3 + k + 4;
        }
        for (; k < n; ++k) {
            s -= *lk * b[k];
            lk += k + 1;
        }
        b[i] = s / l[ZRATE_TRI(i, i)];
    }
}

/**
 * @brief Solve L L' x = b in place, L from zrate_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b Right-hand side on entry, solution on return.
 */
void zrate_chol_solve(const zrate_real *l, int n, zrate_real *b)
{
    zrate_chol_lsolve(l, n, b);
    zrate_chol_ltsolve(l, n, b);
}
