"""The primal polish's products over the packed S or S^-1 restricted to the bound inputs
sum every row in increasing column order, however they walk the support:

* sparse_rows_dot() (the free form's -S_FB d_B): run by run along the rows, or a column or
  two at a time down the rows (what primal_solve() chooses when the runs of bound inputs
  are short: scattered saturations, as a multi-motor design's are);
* gather_bound() and gather_product() (the bound form's S^-1_FB beta): the bound inputs
  gathered ascending, four free rows per pass of gather_dot4(), the last repeated past
  the end.

Each must give the reference's dense sequential sum to the bit (reference/dot.py), on any
support.
"""
from __future__ import annotations

import subprocess

import cffi
import numpy as np
import pytest

from rollmpc_codegen.codegen.render import render_sources
from rollmpc_codegen.reference.dot import s_row_dot
from conftest import ROOT, require_tool


@pytest.fixture(scope="module", params=["double", "float"])
def sparse_rows_dot(request, tmp_path_factory):
    """(free_form, bound_form, dtype): the generated solver's static products, compiled
    into a harness that includes P_solver.c: sparse_rows_dot(), and gather_bound() with
    gather_product()."""
    from rollmpc_codegen.pipeline import load_model

    cc = require_tool("gcc", "apt-get install gcc")
    _, ctx = load_model(ROOT / "examples" / "quad_attitude.yaml", request.param)
    p, real = ctx["prefix"], ctx["real"]
    out = tmp_path_factory.mktemp(f"dot_{request.param}")
    for name, text in render_sources(ctx).items():
        (out / name).write_text(text)
    (out / "harness.c").write_text(
        f'#include "{p}_solver.c"\n'
        f"void harness_sparse_rows_dot(const {real} *mp, const int16_t *rows, int nrows, "
        f"const {real} *x, const int16_t *list, int count, int by_columns, {real} *out)\n"
        f"{{\n    sparse_rows_dot(mp, rows, nrows, x, list, count, by_columns, out);\n}}\n"
        f"int harness_gather_bound(const uint8_t *role, int n, const {real} *x, "
        f"int16_t *list, {real} *xs)\n"
        f"{{\n    return gather_bound(role, n, x, list, xs);\n}}\n"
        f"void harness_gather_product(const {real} *mp, const int16_t *list, "
        f"const {real} *xs, int k, const int16_t *rows, int nrows, {real} *out)\n"
        f"{{\n    gather_product(mp, list, xs, k, rows, nrows, out);\n}}\n")
    sources = [out / "harness.c"] + [out / f"{p}_{m}.c" for m in ("data", "linalg",
                                                                  "controller")]
    lib_path = out / "libdot.so"
    subprocess.run([cc, "-O2", "-std=c99", "-fPIC", "-shared", "-ffp-contract=off",
                    f"-I{out}", *map(str, sources), "-lm", "-o", str(lib_path)], check=True)
    ffi = cffi.FFI()
    ffi.cdef(f"void harness_sparse_rows_dot(const {real} *mp, const int16_t *rows, "
             f"int nrows, const {real} *x, const int16_t *list, int count, int by_columns, "
             f"{real} *out);"
             f"int harness_gather_bound(const uint8_t *role, int n, const {real} *x, "
             f"int16_t *list, {real} *xs);"
             f"void harness_gather_product(const {real} *mp, const int16_t *list, "
             f"const {real} *xs, int k, const int16_t *rows, int nrows, {real} *out);")
    lib = ffi.dlopen(str(lib_path))
    dt = np.float64 if real == "double" else np.float32
    buf = lambda a, t: ffi.cast(t, ffi.from_buffer(a))  # noqa: E731

    def free_form(mp, rows, x, support_list, by_columns):
        rows16 = np.ascontiguousarray(rows, np.int16)
        list16 = np.ascontiguousarray(support_list, np.int16)
        res = np.full(rows16.size, np.nan, dt)
        lib.harness_sparse_rows_dot(buf(mp, f"{real} *"), buf(rows16, "int16_t *"),
                                    rows16.size, buf(x, f"{real} *"),
                                    buf(list16, "int16_t *"), list16.size, by_columns,
                                    buf(res, f"{real} *"))
        return res

    def bound_form(mp, bound, x):
        """What primal_solve_bound() does: gather the bound inputs (ROLE_BOUND = 1), then
        the product over them for every free row, by input."""
        n = bound.size
        role = np.where(bound, 1, 0).astype(np.uint8)
        blist, xs = np.zeros(n, np.int16), np.zeros(n, dt)
        k = lib.harness_gather_bound(buf(role, "uint8_t *"), n, buf(x, f"{real} *"),
                                     buf(blist, "int16_t *"), buf(xs, f"{real} *"))
        assert list(blist[:k]) == list(np.flatnonzero(bound))
        free = np.ascontiguousarray(np.flatnonzero(~bound), np.int16)
        out = np.full(n, np.nan, dt)
        lib.harness_gather_product(buf(mp, f"{real} *"), buf(blist, "int16_t *"),
                                   buf(xs, f"{real} *"), k, buf(free, "int16_t *"), free.size,
                                   buf(out, f"{real} *"))
        assert np.all(np.isnan(out[bound]))  # only the free rows are written
        return out[free]

    return free_form, bound_form, dt


def _supports(n, rng):
    """Bound-input patterns: every 4th input (one motor of four), pairs, long runs,
    random and a single input."""
    yield np.arange(n) % 4 == 1
    yield np.isin(np.arange(n) % 8, (2, 3))
    yield (np.arange(n) // 10) % 2 == 0
    yield rng.random(n) < 0.3
    yield np.arange(n) == n // 2


def _matrix_and_x(dt, rng, n=60):
    G = rng.standard_normal((n, n))
    M = (G @ G.T / n + np.eye(n)).astype(dt)
    mp = np.concatenate([M[i, :i + 1] for i in range(n)])
    return M, mp, rng.standard_normal(n).astype(dt)


@pytest.mark.parametrize("by_columns", [1, 0], ids=["by_columns", "by_rows"])
def test_free_form_product_is_the_dense_sequential_sum(sparse_rows_dot, by_columns):
    free_form, _, dt = sparse_rows_dot
    rng = np.random.default_rng(7)
    M, mp, x_full = _matrix_and_x(dt, rng)
    for bound in _supports(M.shape[0], rng):
        x = np.where(bound, x_full, dt(0.0)).astype(dt)
        rows = rng.permutation(np.flatnonzero(~bound))  # the free rows in a factor order
        got = free_form(mp, rows, x, np.flatnonzero(bound), by_columns)
        want = s_row_dot(M, rows, x)
        assert got.tobytes() == want.tobytes(), f"bound inputs {np.flatnonzero(bound)}"


@pytest.mark.parametrize("n", [60, 61, 62, 63])  # free rows a multiple of 4, or 1-3 over
def test_bound_form_product_is_the_dense_sequential_sum(sparse_rows_dot, n):
    _, bound_form, dt = sparse_rows_dot
    rng = np.random.default_rng(n)
    M, mp, x_full = _matrix_and_x(dt, rng, n)
    for bound in _supports(n, rng):
        x = np.where(bound, x_full, dt(0.0)).astype(dt)
        got = bound_form(mp, bound, x)
        want = s_row_dot(M, np.flatnonzero(~bound), x)
        assert got.tobytes() == want.tobytes(), f"bound inputs {np.flatnonzero(bound)}"
