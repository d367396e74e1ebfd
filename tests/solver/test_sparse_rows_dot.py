"""sparse_rows_dot(), the primal polish's product over the packed S or S^-1 restricted to the
bound (or free) inputs, sums every row in increasing column order whichever way it walks
the support: run by run along the rows, or a column or two at a time down the rows (what
primal_solve() chooses when the runs of bound inputs are short: scattered saturations, as
a multi-motor design's are). Both walks must give the reference's dense sequential sum to
the bit (reference/dot.py), on any support.
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
    """(call, dtype): the generated solver's static sparse_rows_dot(), compiled into a
    harness that includes P_solver.c."""
    from rollmpc_codegen.pipeline import load_model

    cc = require_tool("gcc", "apt-get install gcc")
    _, ctx = load_model(ROOT / "examples" / "quad_attitude.yaml", request.param)
    p, real = ctx["prefix"], ctx["real"]
    out = tmp_path_factory.mktemp(f"dot_{request.param}")
    for name, text in render_sources(ctx).items():
        (out / name).write_text(text)
    (out / "harness.c").write_text(
        f'#include "{p}_solver.c"\n'
        f"void harness_sparse_rows_dot(const {real} *mp, int n, const int16_t *rows, "
        f"int nrows, const {real} *x, const int16_t *list, int count, int complement, "
        f"int by_columns, {real} *out)\n{{\n    sparse_rows_dot(mp, n, rows, nrows, x, list, "
        f"count, complement, by_columns, out);\n}}\n")
    sources = [out / "harness.c"] + [out / f"{p}_{m}.c" for m in ("data", "linalg",
                                                                  "controller")]
    lib_path = out / "libdot.so"
    subprocess.run([cc, "-O2", "-std=c99", "-fPIC", "-shared", "-ffp-contract=off",
                    f"-I{out}", *map(str, sources), "-lm", "-o", str(lib_path)], check=True)
    ffi = cffi.FFI()
    ffi.cdef(f"void harness_sparse_rows_dot(const {real} *mp, int n, const int16_t *rows, "
             f"int nrows, const {real} *x, const int16_t *list, int count, int complement, "
             f"int by_columns, {real} *out);")
    lib = ffi.dlopen(str(lib_path))
    dt = np.float64 if real == "double" else np.float32

    def call(mp, n, rows, x, support_list, complement, by_columns):
        rows16 = np.ascontiguousarray(rows, np.int16)
        list16 = np.ascontiguousarray(support_list, np.int16)
        res = np.full(rows16.size, np.nan, dt)
        buf = lambda a, t: ffi.cast(t, ffi.from_buffer(a))  # noqa: E731
        lib.harness_sparse_rows_dot(buf(mp, f"{real} *"), n, buf(rows16, "int16_t *"),
                                    rows16.size, buf(x, f"{real} *"),
                                    buf(list16, "int16_t *"), list16.size, complement,
                                    by_columns, buf(res, f"{real} *"))
        return res

    return call, dt


def _supports(n, rng):
    """Bound-input patterns: every 4th input (one motor of four), pairs, long runs,
    random and a single input."""
    yield np.arange(n) % 4 == 1
    yield np.isin(np.arange(n) % 8, (2, 3))
    yield (np.arange(n) // 10) % 2 == 0
    yield rng.random(n) < 0.3
    yield np.arange(n) == n // 2


@pytest.mark.parametrize("by_columns", [1, 0], ids=["by_columns", "by_rows"])
@pytest.mark.parametrize("complement", [1, 0], ids=["bound_form", "free_form"])
def test_sparse_rows_dot_is_the_dense_sequential_sum(sparse_rows_dot, complement, by_columns):
    call, dt = sparse_rows_dot
    rng = np.random.default_rng(7)
    n = 60
    G = rng.standard_normal((n, n))
    M = (G @ G.T / n + np.eye(n)).astype(dt)
    mp = np.concatenate([M[i, :i + 1] for i in range(n)])
    x_full = rng.standard_normal(n).astype(dt)
    for bound in _supports(n, rng):
        x = np.where(bound, x_full, dt(0.0)).astype(dt)
        if complement:  # the bound form: the free rows, support = the complement of F
            rows = np.flatnonzero(~bound)
            got = call(mp, n, rows, x, rows, 1, by_columns)
        else:  # the free form: the free rows in a factor order, support = B itself
            rows = rng.permutation(np.flatnonzero(~bound))
            got = call(mp, n, rows, x, np.flatnonzero(bound), 0, by_columns)
        want = s_row_dot(M, rows, x)
        assert got.tobytes() == want.tobytes(), f"bound inputs {np.flatnonzero(bound)}"
