/**
 * @file drives_linalg.c
 * @brief Packed Cholesky factorisation and solves for the polish step.
 *
 * Operation order is fixed (sequential sums, no fused multiply-add) so the NumPy
 * reference reproduces every result bit for bit. Each sum runs from its first term to
 * its last, one product at a time; the loops below only compute two or four such sums
 * side by side, so that each element read from memory serves two products (a Cortex-M4F
 * spends more cycles loading operands than multiplying them). The packed factor is the
 * lower triangle by rows, element (i, j) at DRIVES_TRI(i, j), so row i + 1 starts
 * i + 1 elements after row i.
 */
#include <math.h>
#include "drives_internal.h"
#if DRIVES_GENERATION != 0x0dee47a3fbc1639
#error "drives_linalg.c and drives_config.h are of different generations (an interrupted regeneration?): regenerate the whole directory"
#endif

/*
 * Entries (i, j), (i, j + 1), (i + 1, j), (i + 1, j + 1) of L, from rows i, i + 1 of A
 * (r0, r1 = r0 + i + 1) and rows j, j + 1 of L (q0, q1 = q0 + j + 1): each
 * s = a - sum_k r[k] q[k] in k order, divided by its pivot.
 */
static void cholesky_block(drives_real *r0, drives_real *r1, const drives_real *q0,
    int j)
{
    const drives_real *q1 = q0 + j + 1;
    drives_real s00 = r0[j], s01 = r0[j + 1], s10 = r1[j], s11 = r1[j + 1];
    const drives_real *x0 = r0, *x1 = r1, *v0 = q0, *v1 = q1, *end = q0 + j;
    if (j & 1) {
        const drives_real a0 = *x0++, a1 = *x1++, b0 = *v0++, b1 = *v1++;
        s00 -= a0 * b0;
        s01 -= a0 * b1;
        s10 -= a1 * b0;
        s11 -= a1 * b1;
    }
    while (v0 != end) { /* two k per trip */
        drives_real a0 = x0[0], a1 = x1[0], b0 = v0[0], b1 = v1[0];
        s00 -= a0 * b0;
        s01 -= a0 * b1;
        s10 -= a1 * b0;
        s11 -= a1 * b1;
        a0 = x0[1];
        a1 = x1[1];
        b0 = v0[1];
        b1 = v1[1];
        s00 -= a0 * b0;
        s01 -= a0 * b1;
        s10 -= a1 * b0;
        s11 -= a1 * b1;
        x0 += 2;
        x1 += 2;
        v0 += 2;
        v1 += 2;
    }
    r0[j] = s00 / q0[j];
    r1[j] = s10 / q0[j];
    s01 -= r0[j] * q1[j];
    s11 -= r1[j] * q1[j];
    r0[j + 1] = s01 / q1[j + 1];
    r1[j + 1] = s11 / q1[j + 1];
}

/*
 * Columns j .. j + 3 of row r of L from their sums s0 .. s3 over k < j, against rows
 * q0 .. q3 = q2 + j + 3 of L: the terms k = j .. j + 2 in k order, each column divided by
 * its pivot before the next one uses it.
 */
static inline void finish_four(drives_real *r, drives_real s0, drives_real s1, drives_real s2,
    drives_real s3, const drives_real *q0, int j)
{
    const drives_real *q1 = q0 + j + 1, *q2 = q1 + j + 2, *q3 = q2 + j + 3;
    drives_real t1 = s1, t2 = s2, t3 = s3;
    r[j] = s0 / q0[j];
    t1 -= r[j] * q1[j];
    r[j + 1] = t1 / q1[j + 1];
    t2 -= r[j] * q2[j];
    t2 -= r[j + 1] * q2[j + 1];
    r[j + 2] = t2 / q2[j + 2];
    t3 -= r[j] * q3[j];
    t3 -= r[j + 1] * q3[j + 1];
    t3 -= r[j + 2] * q3[j + 2];
    r[j + 3] = t3 / q3[j + 3];
}

#if DRIVES_WIDE_KERNELS
/*
 * As cholesky_block() for four rows of L (q0 .. q3, columns j .. j + 3, j a multiple of
 * 4) against four rows r0 .. r3 of A (each r_(a+1) = r_a + i + a + 1): each element read
 * serves four products, so a Cortex-M4F loads 8 operands per 16 multiply-adds instead of
 * 4 per 4. The sums over k < j run side by side; finish_four() completes each row.
 */
static void cholesky_block44(drives_real *r0, drives_real *r1, drives_real *r2,
    drives_real *r3, const drives_real *q0, int j)
{
    const drives_real *q1 = q0 + j + 1, *q2 = q1 + j + 2, *q3 = q2 + j + 3;
    drives_real s00 = r0[j], s01 = r0[j + 1], s02 = r0[j + 2], s03 = r0[j + 3];
    drives_real s10 = r1[j], s11 = r1[j + 1], s12 = r1[j + 2], s13 = r1[j + 3];
    drives_real s20 = r2[j], s21 = r2[j + 1], s22 = r2[j + 2], s23 = r2[j + 3];
    drives_real s30 = r3[j], s31 = r3[j + 1], s32 = r3[j + 2], s33 = r3[j + 3];
    const drives_real *x0 = r0, *x1 = r1, *x2 = r2, *x3 = r3;
    const drives_real *v0 = q0, *v1 = q1, *v2 = q2, *v3 = q3, *end = q0 + j;
    while (v0 != end) { /* one k per trip */
        const drives_real a0 = *x0++, a1 = *x1++, a2 = *x2++, a3 = *x3++;
        const drives_real b0 = *v0++, b1 = *v1++, b2 = *v2++, b3 = *v3++;
        s00 -= a0 * b0;
        s01 -= a0 * b1;
        s02 -= a0 * b2;
        s03 -= a0 * b3;
        s10 -= a1 * b0;
        s11 -= a1 * b1;
        s12 -= a1 * b2;
        s13 -= a1 * b3;
        s20 -= a2 * b0;
        s21 -= a2 * b1;
        s22 -= a2 * b2;
        s23 -= a2 * b3;
        s30 -= a3 * b0;
        s31 -= a3 * b1;
        s32 -= a3 * b2;
        s33 -= a3 * b3;
    }
    finish_four(r0, s00, s01, s02, s03, q0, j);
    finish_four(r1, s10, s11, s12, s13, q0, j);
    finish_four(r2, s20, s21, s22, s23, q0, j);
    finish_four(r3, s30, s31, s32, s33, q0, j);
}
#endif

/*
 * As cholesky_block44() for two rows r0, r1 of A (j even): 6 operands per 8
 * multiply-adds.
 */
static void cholesky_block4(drives_real *r0, drives_real *r1, const drives_real *q0,
    int j)
{
    const drives_real *q1 = q0 + j + 1, *q2 = q1 + j + 2, *q3 = q2 + j + 3;
    drives_real s00 = r0[j], s01 = r0[j + 1], s02 = r0[j + 2], s03 = r0[j + 3];
    drives_real s10 = r1[j], s11 = r1[j + 1], s12 = r1[j + 2], s13 = r1[j + 3];
    const drives_real *x0 = r0, *x1 = r1, *v0 = q0, *v1 = q1, *v2 = q2, *v3 = q3;
    const drives_real *end = q0 + j;
    while (v0 != end) { /* two k per trip */
        drives_real a0 = x0[0], a1 = x1[0], b0 = v0[0], b1 = v1[0], b2 = v2[0], b3 = v3[0];
        s00 -= a0 * b0;
        s01 -= a0 * b1;
        s02 -= a0 * b2;
        s03 -= a0 * b3;
        s10 -= a1 * b0;
        s11 -= a1 * b1;
        s12 -= a1 * b2;
        s13 -= a1 * b3;
        a0 = x0[1];
        a1 = x1[1];
        b0 = v0[1];
        b1 = v1[1];
        b2 = v2[1];
        b3 = v3[1];
        s00 -= a0 * b0;
        s01 -= a0 * b1;
        s02 -= a0 * b2;
        s03 -= a0 * b3;
        s10 -= a1 * b0;
        s11 -= a1 * b1;
        s12 -= a1 * b2;
        s13 -= a1 * b3;
        x0 += 2;
        x1 += 2;
        v0 += 2;
        v1 += 2;
        v2 += 2;
        v3 += 2;
    }
    finish_four(r0, s00, s01, s02, s03, q0, j);
    finish_four(r1, s10, s11, s12, s13, q0, j);
}

/* As cholesky_block() for one row of L (q0, column j) against rows r0, r1. */
static void cholesky_column(drives_real *r0, drives_real *r1, const drives_real *q0,
    int j)
{
    drives_real s0 = r0[j], s1 = r1[j];
    const drives_real *x0 = r0, *x1 = r1, *v0 = q0, *end = q0 + j;
    while (v0 != end) {
        const drives_real b0 = *v0++;
        s0 -= *x0++ * b0;
        s1 -= *x1++ * b0;
    }
    r0[j] = s0 / q0[j];
    r1[j] = s1 / q0[j];
}

/*
 * Columns first .. end - 1 of rows r0, r1 of L (first even, end <= the first row's index), four
 * columns at a time, then two, then one.
 */
static void pair_columns(drives_real *a, drives_real *r0, drives_real *r1, int first,
    int end)
{
    int j = first;
    for (; j + 3 < end; j += 4) {
        cholesky_block4(r0, r1, &a[DRIVES_TRI(j, 0)], j);
    }
    if (j + 1 < end) {
        cholesky_block(r0, r1, &a[DRIVES_TRI(j, 0)], j);
        j += 2;
    }
    if (j < end) {
        cholesky_column(r0, r1, &a[DRIVES_TRI(j, 0)], j);
    }
}

/*
 * The 2 x 2 diagonal block (i, i), (i + 1, i), (i + 1, i + 1) of rows r0, r1, whose
 * columns < i are L's; -1 on a bad pivot.
 */
static inline int pair_diagonal(drives_real *r0, drives_real *r1, int i)
{
    drives_real s00 = r0[i], s10 = r1[i], s11 = r1[i + 1];
    const drives_real *x0 = r0, *x1 = r1, *end = r0 + i;
    while (x0 != end) {
        const drives_real a0 = *x0++, a1 = *x1++;
        s00 -= a0 * a0;
        s10 -= a1 * a0;
        s11 -= a1 * a1;
    }
    if (!(s00 > DRIVES_R(0.0))) {
        return -1;
    }
    r0[i] = DRIVES_SQRT(s00);
    r1[i] = s10 / r0[i];
    s11 -= r1[i] * r1[i];
    if (!(s11 > DRIVES_R(0.0))) {
        return -1;
    }
    r1[i + 1] = DRIVES_SQRT(s11);
    return 0;
}

/*
 * One row i of L alone (r = row i, the rows above already factored), against two rows
 * j, j + 1 of L at a time; -1 on a bad pivot.
 */
static int cholesky_row(drives_real *a, drives_real *r, int i)
{
    int j = 0;
    drives_real s;
    const drives_real *x, *end;
    for (; j + 1 < i; j += 2) {
        const drives_real *q0 = &a[DRIVES_TRI(j, 0)], *q1 = q0 + j + 1, *v0 = q0, *v1 = q1;
        drives_real s0 = r[j], s1 = r[j + 1];
        x = r;
        end = r + j;
        while (x != end) {
            s0 -= *x * *v0++;
            s1 -= *x * *v1++;
            ++x;
        }
        r[j] = s0 / q0[j];
        s1 -= r[j] * q1[j];
        r[j + 1] = s1 / q1[j + 1];
    }
    if (j < i) {
        const drives_real *q = &a[DRIVES_TRI(j, 0)], *y = q;
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
    if (!(s > DRIVES_R(0.0))) {
        return -1;
    }
    r[i] = DRIVES_SQRT(s);
    return 0;
}

/**
 * @brief Cholesky factorisation A = L L' of a packed lower triangle, from row @p from on.
 *
 * Rows 0..from-1 must already hold L (the row-oriented algorithm computes row i from the
 * rows above it), so a working set that lost a row refactors only the rows below it, and
 * one that gained rows at the end computes only those (bordering). Rows are computed four
 * at a time against four rows of L at a time (then in pairs); every entry is the
 * sequential sum of the plain algorithm, L_ij = (A_ij - sum_{k<j} L_ik L_jk) / L_jj, so
 * the result does not depend on @p from or on the blocking (a division, not a
 * multiplication by 1 / L_jj: the dual active set's infeasibility proofs on nearly
 * dependent rows are sensitive to that rounding).
 * Cost: sum_{i=from}^{n-1} i (i + 1) / 2 = (n^3 - n - from^3 + from) / 6 multiply-adds,
 * (n - from)(n + from - 1) / 2 divisions and n - from square roots.
 * @param a Packed lower triangle: L in rows < from, A in rows >= from on entry; L on return.
 * @param from First row to factor (0 for the whole matrix).
 * @param n Order of A.
 * @return 0 on success, -1 if a pivot is not positive (A not numerically definite).
 */
int drives_cholesky_from(drives_real *a, int from, int n)
{
    int i = from;
#if DRIVES_WIDE_KERNELS
    for (; i + 3 < n; i += 4) {
        int j;
        drives_real *r0 = &a[DRIVES_TRI(i, 0)], *r1 = r0 + i + 1;
        drives_real *r2 = r1 + i + 2, *r3 = r2 + i + 3;
        for (j = 0; j + 3 < i; j += 4) {
            cholesky_block44(r0, r1, r2, r3, &a[DRIVES_TRI(j, 0)], j);
        }
        if (j < i) { /* the last one to three columns */
            pair_columns(a, r0, r1, j, i);
            pair_columns(a, r2, r3, j, i);
        }
        if (pair_diagonal(r0, r1, i) != 0) {
            return -1;
        }
        cholesky_block(r2, r3, r0, i); /* columns i, i + 1 of rows i + 2, i + 3 */
        if (pair_diagonal(r2, r3, i + 2) != 0) {
            return -1;
        }
    }
#endif
    for (; i + 1 < n; i += 2) {
        drives_real *r0 = &a[DRIVES_TRI(i, 0)], *r1 = r0 + i + 1;
        if (i > 0) {
            pair_columns(a, r0, r1, 0, i);
        }
        if (pair_diagonal(r0, r1, i) != 0) {
            return -1;
        }
    }
    if (i < n) {
        return cholesky_row(a, &a[DRIVES_TRI(i, 0)], i);
    }
    return 0;
}

/**
 * @brief In-place Cholesky factorisation A = L L' of a packed lower triangle.
 * @param a Packed lower triangle of A on entry, of L on return.
 * @param n Order of A.
 * @return 0 on success, -1 if a pivot is not positive (A not numerically definite).
 */
int drives_cholesky(drives_real *a, int n)
{
    return drives_cholesky_from(a, 0, n);
}

/**
 * @brief Solve L y = b in place (forward substitution) from row @p from on.
 *
 * b[0..from) must already hold y (they do not depend on the rows below), so a factor
 * that kept its first rows keeps that part of its solves. Four rows at a time, then two;
 * each y_i is the sequential sum b_i - (sum over k < i of L_ik y_k) divided by L_ii.
 * Cost: (n^2 - n - from^2 + from) / 2 multiply-adds and n - from divisions.
 * @param l Packed lower Cholesky factor.
 * @param from First row to solve.
 * @param n Order.
 * @param b Right-hand side on entry (y in rows < from), y on return.
 */
void drives_chol_lsolve_from(const drives_real *l, int from, int n, drives_real *b)
{
    int i = from;
    for (; i + 3 < n; i += 4) { /* rows i .. i + 3: each y_k read serves four sums */
        const drives_real *r0 = &l[DRIVES_TRI(i, 0)], *r1 = r0 + i + 1;
        const drives_real *r2 = r1 + i + 2, *r3 = r2 + i + 3, *y = b, *end = b + i;
        drives_real s0 = b[i], s1 = b[i + 1], s2 = b[i + 2], s3 = b[i + 3];
        while (y != end) {
            const drives_real v = *y++;
            s0 -= *r0++ * v;
            s1 -= *r1++ * v;
            s2 -= *r2++ * v;
            s3 -= *r3++ * v;
        }
        b[i] = s0 / r0[0];
        s1 -= r1[0] * b[i];
        s2 -= r2[0] * b[i];
        s3 -= r3[0] * b[i];
        b[i + 1] = s1 / r1[1];
        s2 -= r2[1] * b[i + 1];
        s3 -= r3[1] * b[i + 1];
        b[i + 2] = s2 / r2[2];
        s3 -= r3[2] * b[i + 2];
        b[i + 3] = s3 / r3[3];
    }
    for (; i + 1 < n; i += 2) {
        const drives_real *r0 = &l[DRIVES_TRI(i, 0)], *r1 = r0 + i + 1, *y = b;
        const drives_real *end = b + i;
        drives_real s0 = b[i], s1 = b[i + 1];
        while (y != end) {
            const drives_real v = *y++;
            s0 -= *r0++ * v;
            s1 -= *r1++ * v;
        }
        b[i] = s0 / *r0;
        s1 -= r1[0] * b[i];
        b[i + 1] = s1 / r1[1];
    }
    if (i < n) {
        const drives_real *r0 = &l[DRIVES_TRI(i, 0)], *y = b, *end = b + i;
        drives_real s0 = b[i];
        while (y != end) {
            s0 -= *r0++ * *y++;
        }
        b[i] = s0 / *r0;
    }
}

/**
 * @brief Solve L y = b in place (forward substitution), L from drives_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b Right-hand side on entry, y on return.
 */
void drives_chol_lsolve(const drives_real *l, int n, drives_real *b)
{
    drives_chol_lsolve_from(l, 0, n, b);
}

/**
 * @brief Solve L' x = y in place (back substitution), L from drives_cholesky().
 *
 * x_i = (y_i - sum_{k>i} L_ki x_k) / L_ii, the sum in decreasing k: the terms of the rows
 * solved first come first, so four rows i - 3..i accumulate together from the same x_k
 * (their L_ki are adjacent in packed row k) while x_i is not yet known, and each row's
 * chain waits only for its last terms. Every x_i is the same sequential sum however many
 * rows share a trip.
 * Cost: (n^2 - n) / 2 multiply-adds and n divisions.
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b y on entry, x on return.
 */
void drives_chol_ltsolve(const drives_real *l, int n, drives_real *b)
{
    int i = n - 1, k;
    for (; i >= 3; i -= 4) {
        drives_real s0 = b[i - 3], s1 = b[i - 2], s2 = b[i - 1], s3 = b[i];
        const drives_real *r3 = &l[DRIVES_TRI(i, 0)], *r2 = r3 - i;
        const drives_real *r1 = r2 - (i - 1);
        const drives_real *lk = &l[DRIVES_TRI(n - 1, i - 3)];
        for (k = n - 1; k > i; lk -= k, --k) { /* L_k,(i-3..i): adjacent in packed row k */
            const drives_real v = b[k];
            s0 -= lk[0] * v;
            s1 -= lk[1] * v;
            s2 -= lk[2] * v;
            s3 -= lk[3] * v;
        }
        b[i] = s3 / r3[i];
        s0 -= r3[i - 3] * b[i];
        s1 -= r3[i - 2] * b[i];
        s2 -= r3[i - 1] * b[i];
        b[i - 1] = s2 / r2[i - 1];
        s0 -= r2[i - 3] * b[i - 1];
        s1 -= r2[i - 2] * b[i - 1];
        b[i - 2] = s1 / r1[i - 2];
        s0 -= r1[i - 3] * b[i - 2];
        b[i - 3] = s0 / l[DRIVES_TRI(i - 3, i - 3)];
    }
    for (; i >= 0; --i) {
        const drives_real *lk = &l[DRIVES_TRI(n - 1, i)];
        drives_real s = b[i];
        for (k = n - 1; k > i; lk -= k, --k) {
            s -= *lk * b[k];
        }
        b[i] = s / l[DRIVES_TRI(i, i)];
    }
}

/**
 * @brief Solve L L' x = b in place, L from drives_cholesky().
 * @param l Packed lower Cholesky factor.
 * @param n Order.
 * @param b Right-hand side on entry, solution on return.
 */
void drives_chol_solve(const drives_real *l, int n, drives_real *b)
{
    drives_chol_lsolve(l, n, b);
    drives_chol_ltsolve(l, n, b);
}
