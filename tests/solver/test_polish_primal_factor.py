"""The primal polish keeps its factor between corrections, bit for bit.

The C factors again only the rows of the primal factor from the first one that changed
(templates/solver/polish_primal.c.j2). That is sound only because the row-oriented
Cholesky and the forward solve compute row i from the rows above it alone, however the
loops pair rows and columns: ``P_cholesky_from(a, p, n)`` and ``P_chol_lsolve_from`` on
kept rows must give the full factorisation and solve to the bit, for every p, and agree
with the reference, which never keeps a factor. The reference's row order (head, then
tail) is what makes an update cheap; its bookkeeping is pinned on the paper's S.
"""
from __future__ import annotations

import subprocess

import cffi
import numpy as np
import pytest

from rollmpc_codegen.codegen.render import render_sources
from rollmpc_codegen.reference import linalg as reference
from rollmpc_codegen.reference.primal_rows import BOUND, FREE
from conftest import require_tool

PREFIX = "rollmpc"


@pytest.fixture(scope="module", params=["double", "float"])
def linalg(request, tmp_path_factory):
    """(cholesky_from, chol_lsolve_from, dtype): the generated P_linalg.c of the paper
    config alone, compiled and loaded, each taking numpy arrays."""
    from conftest import UAV
    from rollmpc_codegen.pipeline import load_model

    cc = require_tool("gcc", "apt-get install gcc")
    _, ctx = load_model(UAV, request.param)
    out = tmp_path_factory.mktemp(f"linalg_{request.param}")
    for name, text in render_sources(ctx).items():
        (out / name).write_text(text)
    lib_path = out / "liblinalg.so"
    subprocess.run([cc, "-O2", "-std=c99", "-fPIC", "-shared", "-ffp-contract=off",
                    f"-I{out}", str(out / f"{PREFIX}_linalg.c"), "-lm", "-o", str(lib_path)],
                   check=True)
    real = ctx["real"]
    ffi = cffi.FFI()
    ffi.cdef(f"int {PREFIX}_cholesky_from({real} *a, int from, int n);"
             f"void {PREFIX}_chol_lsolve_from(const {real} *l, int from, int n, {real} *b);")
    lib = ffi.dlopen(str(lib_path))
    ptr = lambda a: ffi.cast(f"{real} *", ffi.from_buffer(a))  # noqa: E731
    return (lambda a, p, n: getattr(lib, f"{PREFIX}_cholesky_from")(ptr(a), p, n),
            lambda l, p, n, b: getattr(lib, f"{PREFIX}_chol_lsolve_from")(ptr(l), p, n, ptr(b)),
            np.float64 if real == "double" else np.float32)


def _packed_spd(n, dt, seed):
    rng = np.random.default_rng(seed)
    G = rng.standard_normal((n, n))
    A = (G @ G.T + n * np.eye(n)).astype(dt)
    return np.concatenate([A[i, :i + 1] for i in range(n)])


@pytest.mark.parametrize("n", [1, 2, 7, 12, 33])
def test_factor_and_forward_solve_from_any_row_are_the_full_ones(linalg, n):
    cholesky_from, lsolve_from, dt = linalg
    A = _packed_spd(n, dt, n)
    full = A.copy()
    assert cholesky_from(full, 0, n) == 0
    ref = A.copy()
    assert reference.cholesky_from(ref, n)
    assert full.tobytes() == ref.tobytes()
    b = np.random.default_rng(n + 1).standard_normal(n).astype(dt)
    y_full = b.copy()
    lsolve_from(full, 0, n, y_full)
    y_ref = b.copy()
    reference.chol_lsolve_from(ref, n, y_ref)
    assert y_full.tobytes() == y_ref.tobytes()
    for p in range(n + 1):
        kept = A.copy()
        kept[:p * (p + 1) // 2] = full[:p * (p + 1) // 2]  # rows < p already factored
        assert cholesky_from(kept, p, n) == 0
        assert kept.tobytes() == full.tobytes(), f"from row {p}"
        y = b.copy()
        y[:p] = y_full[:p]
        lsolve_from(full, p, n, y)
        assert y.tobytes() == y_full.tobytes(), f"solve from row {p}"


def test_bad_pivot_is_reported_in_any_row_pairing(linalg):
    cholesky_from, _, dt = linalg
    for n in (5, 6):
        for bad in range(n):  # definite up to row `bad` only
            A = _packed_spd(n, dt, 3)
            A[bad * (bad + 1) // 2 + bad] = -1
            assert cholesky_from(A.copy(), 0, n) == -1
            assert not reference.cholesky_from(A.copy(), n)


def test_reference_rows_keep_the_head_and_append_the_tail(uav_double):
    """Free form on the paper's outer mode: an input that becomes bound leaves the factor
    where the working set changes (the end of the descending head), one freed joins the
    tail; the form stays while an update costs fewer multiply-adds than a new factor."""
    from rollmpc_codegen.reference.solver import SolverRef

    md = uav_double.model.modes[1].data
    ref = SolverRef(md, uav_double.ctx["solver"])
    n = md.n
    lower = {int(q): r for r, q in enumerate(md.row_q) if q < n and md.row_sign[r] < 0}
    th0 = np.zeros(n)

    def solve(bound_inputs):
        W = np.array(sorted(lower[q] for q in bound_inputs), np.int64)
        ref.work = 0  # each call within the budget, as a QP's first solve
        ok, th, _ = ref.primal_solve(th0, W, 0)
        assert ok and np.all(np.isfinite(th))
        return ref.factor_rows

    rows = solve(range(60))  # 60 bound: a new free-form factor, inputs 99..60
    assert rows.form == FREE and rows.head == list(range(99, 59, -1)) and rows.tail == []
    rows = solve(range(61))  # input 60 bound: the last head row leaves
    assert rows.form == FREE and rows.head == list(range(99, 60, -1)) and rows.tail == []
    rows = solve([q for q in range(61) if q != 3])  # input 3 freed: the tail
    assert rows.head == list(range(99, 60, -1)) and rows.tail == [3]
    # 48 bound: updating the free form (order 52, rows 39.. new: 19,877 multiply-adds,
    # primal_cost() 6 x that) beats a new bound-form factor (order 48: 25,480)
    rows = solve(range(48))
    assert rows.form == FREE and rows.head == list(range(99, 60, -1))
    assert rows.tail == list(range(60, 47, -1))
    ref.unconstrained(np.zeros(md.nx), np.zeros(md.N * md.ny))  # the mode's next QP keeps it
    assert ref.factor_rows is rows
    ref.forget_factor()  # another mode's QP came between: no factor
    assert ref.factor_rows is None
    rows = solve(range(48))  # a new factor takes the smaller order: 48 bound rows
    assert rows.form == BOUND and rows.head == list(range(48)) and rows.tail == []


def test_tail_keeps_joining_order_and_its_generations(uav_double):
    """An input that joins the free form's tail goes after the tail rows already there,
    even where it sorts before them: only its own row is factored. Each update that
    appends starts a generation; when ROLE_GEN_MAX generations are used up the next
    solve takes a new factor (the C keeps the generation in 5 bits of input_role)."""
    from rollmpc_codegen.reference.primal_rows import GEN_MAX
    from rollmpc_codegen.reference.solver import SolverRef

    md = uav_double.model.modes[1].data
    ref = SolverRef(md, uav_double.ctx["solver"])
    n = md.n
    lower = {int(q): r for r, q in enumerate(md.row_q) if q < n and md.row_sign[r] < 0}
    th0 = np.zeros(n)

    def solve(free):
        bound = [q for q in range(81) if q not in free]
        W = np.array(sorted(lower[q] for q in bound), np.int64)
        ref.work = 0
        order, rows, start, _ = ref.primal_order(np.isin(np.arange(n), bound),
                                              BOUND if len(bound) < n - len(bound) else FREE)
        ok, _, _ = ref.primal_solve(th0, W, 0)
        assert ok and ref.factor_rows == rows
        return rows, start

    solve(set())  # head 99..81
    rows, start = solve({3})
    assert (rows.tail, rows.gens, start) == ([3], [1], 19)
    rows, start = solve({3, 10})  # 10 sorts before 3 in the free form, yet goes after it
    assert (rows.tail, rows.gens, start) == ([3, 10], [1, 2], 20)
    rows, start = solve({3, 10, 7, 20})  # one generation, in the head's order
    assert (rows.tail, rows.gens, start) == ([3, 10, 20, 7], [1, 2, 3, 3], 21)
    rows, start = solve({3, 20, 7})  # 10 leaves: the rows from its position on
    assert (rows.tail, rows.gens, start) == ([3, 20, 7], [1, 3, 3], 20)
    free = {3, 20, 7}
    for q in range(21, 21 + GEN_MAX - 3):  # up to the last generation, one input each
        free.add(q)
        rows, start = solve(free)
    assert rows.gens[-1] == GEN_MAX and start == 19 + len(rows.tail) - 1
    free.add(79)
    rows, start = solve(free)  # no generation left: a new factor, every row in the head
    nb = 81 - len(free)
    assert rows.tail == [] and start == 0 and len(rows.head) == min(nb, n - nb)


def test_a_row_that_leaves_mid_factor_is_deleted_by_an_update(uav_double):
    """Free form on the paper's outer mode: input 80 becoming bound leaves the descending
    head at position 19 of 40. Deleting its row by a rank-one update of the 20 rows below
    (Y carried) costs less than factoring them again, so the solve keeps them: the charge
    is the deletion's plus a solve with no row factored, and the updated L and Y are those
    of the new order (L L' = S_FF, L Y = V_F'), to rounding."""
    from rollmpc_codegen.qp.work import UNIT_CALL_WORK, primal_delete_work, primal_work
    from rollmpc_codegen.reference.linalg import _tri_offsets
    from rollmpc_codegen.reference.solver import SolverRef

    md = uav_double.model.modes[1].data
    ref = SolverRef(md, uav_double.ctx["solver"])
    n = md.n
    lower = {int(q): r for r, q in enumerate(md.row_q) if q < n and md.row_sign[r] < 0}

    def solve(bound_inputs):
        W = np.array(sorted(lower[q] for q in bound_inputs), np.int64)
        ref.work = 0
        ok, th, _ = ref.primal_solve(np.zeros(n), W, 0)
        assert ok and np.all(np.isfinite(th))
        return W

    solve(range(60))
    assert ref.factor_rows.head == list(range(99, 59, -1))
    W = solve([*range(60), 80])
    order = [q for q in range(99, 59, -1) if q != 80]
    assert ref.factor_rows.head == order and list(ref._idx) == order
    runs = 2  # bound runs: 0..59 and 80
    assert ref.work == UNIT_CALL_WORK + primal_delete_work(19, 40, md.nt) + primal_work(
        md, 39, 39, False, runs) < primal_work(md, 39, 19, False, runs)
    k, tri = 39, _tri_offsets(39)
    L = np.zeros((k, k))
    for i in range(k):
        L[i, :i + 1] = ref._chol[tri[i]:tri[i] + i + 1]
    idx = np.array(order)
    S_FF = ref.S[np.ix_(idx, idx)]
    assert np.allclose(L @ L.T, S_FF, rtol=1e-12, atol=1e-12 * np.abs(S_FF).max())
    assert np.allclose(L @ ref._Y.T, md.V[:, idx].T, rtol=1e-10,
                       atol=1e-12 * np.abs(md.V).max())
