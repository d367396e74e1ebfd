/**
 * @file zones_linalg.c
 * @brief Packed Cholesky factorisation and solves for the polish step.
 *
 * Operation order is fixed (sequential sums, no fused multiply-add) so the NumPy
 * reference reproduces every result bit for bit. Each sum runs from its first term to
 * its last, one product at a time; the loops below only compute two or four such sums
 * side by side, so that each element read from memory serves two products (a Cortex-M4F
 * spends more cycles loading operands than multiplying them). The packed factor is the
 * lower triangle by rows, element (i, j) at ZONES_TRI(i, j), so row i + 1 starts
 * i + 1 elements after row i.
 */
#include <math.h>
#include "zones_internal.h"

/*
 * Entries (i, j), (i, j + 1), (i + 1, j), (i + 1, j + 1) of L, from rows i, i + 1 of A
 * (r0, r1 = r0 + i + 1) and rows j, j + 1 of L (q0, q1 = q0 + j + 1): each
 * s = a - sum_k r[k] q[k] in k order, divided by its pivot.
 */
static void cholesky_block(zones_real *r0, zones_real *r1, const zones_real *q0,
    int j)
{
    const zones_real *q1 = q0 + j + 1;
    zones_real s00 = r0[j], s01 = r0[j + 1], s10 = r1[j], s11 = r1[j + 1];
    const zones_real *x0 = r0, *x1 = r1, *y0 = q0, *y1 = q1, *end = q0 + j;
    if (j & 1) {
        const zones_real a0 = *x0++, a1 = *x1++, b0 = *y0++, b1 = *y1++;
        s00 -= a0 * b0;
        s01 -= a0 * b1;
        s10 -= a1 * b0;
        s11 -= a1 * b1;
    }
    while (y0 != end) { /* two k per trip */
        zones_real a0 = x0[0], a1 = x1[0], b0 = y0[0], b1 = y1[0];
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
static void cholesky_column(zones_real *r0, zones_real *r1, const zones_real *q0,
    int j)
{
    zones_real s0 = r0[j], s1 = r1[j];
    const zones_real *x0 = r0, *x1 = r1, *y0 = q0, *end = q0 + j;
    while (y0 != end) {
        const zones_real b0 = *y0++;
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
static int cholesky_row(zones_real *a, zones_real *r, int i)
{
    int j = 0;
    zones_real s;
    const zones_real *x, *end;
    for (; j + 1 < i; j += 2) {
        const zones_real *q0 = &a[ZONES_TRI(j, 0)], *q1 = q0 + j + 1, *y0 = q0, *y1 = q1;
        zones_real s0 = r[j], s1 = r[j + 1];
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
        const zones_real *q = &a[ZONES_TRI(j, 0)], *y = q;
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
    if (!(s > ZONES_R(0.0))) {
        return -1;
    }
    r[i] = ZONES_SQRT(s);
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
int zones_cholesky_from(zones_real *a, int from, int n)
{
    int i = from, j;
    for (; i + 1 < n; i += 2) {
        zones_real *r0 = &a[ZONES_TRI(i, 0)], *r1 = r0 + i + 1;
        zones_real s00, s10, s11;
        const zones_real *x0 = r0, *x1 = r1, *end = r0 + i;
        for (j = 0; j + 1 < i; j += 2) {
            cholesky_block(r0, r1, &a[ZONES_TRI(j, 0)], j);
        }
        if (j < i) {
            cholesky_column(r0, r1, &a[ZONES_TRI(j, 0)], j);
        }
        /* the 2 x 2 diagonal block: (i, i), (i + 1, i), (i + 1, i + 1) */
        s00 = r0[i];
        s10 = r1[i];
        s11 = r1[i + 1];
        while (x0 != end) {
            const zones_real a0 = *x0++, a1 = *x1++;
            s00 -= a0 * a0;
            s10 -= a1 * a0;
            s11 -= a1 * a1;
        }
        if (!(s00 > ZONES_R(0.0))) {
            return -1;
        }
        r0[i] = ZONES_SQRT(s00);
        r1[i] = s10 / r0[i];
        s11 -= r1[i] * r1[i];
        if (!(s11 > ZONES_R(0.0))) {
            return -1;
        }
        r1[i + 1] = ZONES_SQRT(s11);
    }
    if (i < n) {
        return cholesky_row(a, &a[ZONES_TRI(i, 0)], i);
    }
    return 0;
}

/**
 * @brief In-place Cholesky factorisation A = L L' of a packed lower triangle.
 * @param a Packed lower triangle of A on entry, of L on return.
 * @param n Order of A.
 * @return 0 on success, -1 if a pivot is not positive (A not numerically definite).
 */
int zones_cholesky(zones_real *a, int n)
{
    return zones_cholesky_from(a, 0, n);
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
void zones_chol_lsolve_from(const zones_real *l, int from, int n, zones_real *b)
{
    int i = from;
    for (; i + 1 < n; i += 2) {
        const zones_real *r0 = &l[ZONES_TRI(i, 0)], *r1 = r0 + i + 1, *y = b;
        const zones_real *end = b + i;
        zones_real s0 = b[i], s1 = b[i + 1];
        while (y != end) {
            const zones_real v = *y++;
            s0 -= *r0++ * v;
            s1 -= *r1++ * v;
        }
        b[i] = s0 / *r0;
        s1 -= r1[0] * b[i];
        b[i + 1] = s1 / r1[1];
    }
    if (i < n) {
        const zones_real *r0 = &l[ZONES_TRI(i, 0)], *y = b, *end = b + i;
        zones_real s0 = b[i];
        while (y != end) {
            s0 -= *r0++ * *y++;
        }
        b[i] = s0 / *r0;
    }
}

/**
 * @brief Solve L y = b in place (forward substitution), L from zones_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b Right-hand side on entry, y on return.
 */
void zones_chol_lsolve(const zones_real *l, int n, zones_real *b)
{
    zones_chol_lsolve_from(l, 0, n, b);
}

/**
 * @brief Solve L' x = y in place (back substitution), L from zones_cholesky().
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
void zones_chol_ltsolve(const zones_real *l, int n, zones_real *b)
{
    int i, k;
    for (i = n - 1; i >= 0; --i) {
        const zones_real *lk = &l[ZONES_TRI(i + 1, i)]; /* L_(i+1),i */
        zones_real s = b[i];
        for (k = i + 1; k + 3 < n; k += 4) {
            const zones_real *l1 = lk + k + 1, *l2 = l1 + k + 2, *l3 = l2 + k + 3;
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
        b[i] = s / l[ZONES_TRI(i, i)];
    }
}

/**
 * @brief Solve L L' x = b in place, L from zones_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b Right-hand side on entry, solution on return.
 */
void zones_chol_solve(const zones_real *l, int n, zones_real *b)
{
    zones_chol_lsolve(l, n, b);
    zones_chol_ltsolve(l, n, b);
}
