"""A working set "full" by count but not by rank must not prove a feasible QP infeasible.

The reliability campaign's delay plants (rollmpc_codegen.verify.random_configs, kind
"delay") have output rows identical to input rows. On config 28's QP 93 (warm after QP 92)
the dual active set resumed the previous working set shifted one stage, 16 rows for
n = 16, whose H_WW has rank 8: the bare Cholesky took pivots of a few roundoffs as
positive, the set passed for a vertex (nw = wcap), and the next violated row "proved"
the QP infeasible (`make check-long` failed from 0b634f7 on). factor_working_set() now
applies the dependence tolerance to its pivots, as a joining row's pivot always had it,
so the resume keeps the independent rows (independent_rows()) and the solve is OPTIMAL.
The QPs' inputs are the campaign's, to the bit."""
from __future__ import annotations

import numpy as np

from conftest import Built
from rollmpc_codegen.status import OPTIMAL
from rollmpc_codegen.verify.random_configs import random_config

# x and r of the campaign's QPs 92 (cold) and 93 (warm) of config 28, double, as hex
QP92_X = [
        "-0x1.f147dfd1cd218p-6", "-0x1.1b6cb0fe5e283p-3", "-0x1.e72d8cd81b274p-6"
]
QP92_R = [
        "-0x1.5894634667208p+0", "-0x1.15f07d6c139c0p-5", "-0x1.15f07d6c139c0p-5",
        "-0x1.15f07d6c139c0p-5", "-0x1.15f07d6c139c0p-5", "-0x1.15f07d6c139c0p-5",
        "-0x1.15f07d6c139c0p-5", "-0x1.15f07d6c139c0p-5", "-0x1.1465b64d50174p-2",
        "-0x1.1465b64d50174p-2", "-0x1.1465b64d50174p-2", "-0x1.1465b64d50174p-2",
        "-0x1.1465b64d50174p-2", "-0x1.1465b64d50174p-2", "-0x1.1465b64d50174p-2",
        "-0x1.1465b64d50174p-2"
]
QP93_X = [
        "-0x1.c94819e27d336p-6", "-0x1.21a9fee967a87p-3", "-0x1.a3eb91f00395fp-6"
]
QP93_R = [
        "-0x1.15f07d6c139c0p-5", "-0x1.15f07d6c139c0p-5", "-0x1.15f07d6c139c0p-5",
        "-0x1.15f07d6c139c0p-5", "-0x1.15f07d6c139c0p-5", "-0x1.15f07d6c139c0p-5",
        "-0x1.15f07d6c139c0p-5", "-0x1.1465b64d50174p-2", "-0x1.1465b64d50174p-2",
        "-0x1.1465b64d50174p-2", "-0x1.1465b64d50174p-2", "-0x1.1465b64d50174p-2",
        "-0x1.1465b64d50174p-2", "-0x1.1465b64d50174p-2", "-0x1.1465b64d50174p-2",
        "-0x1.1465b64d50174p-2"
]


# the previous working set shifted one stage, as the dual active set resumes it on QP 93:
# 16 rows (wcap = n) whose H_WW has rank 8
SHIFTED_SET = np.array([18, 22, 26, 30, 32, 34, 36, 38, 40, 42, 44, 46, 48, 52, 56, 60])


def _vec(hexes):
    return np.array([float.fromhex(h) for h in hexes])


def _rq28(tmp_path, build_root) -> Built:
    """The campaign's config 28 (a delay plant), double."""
    rc = random_config(28, prefix="rq28", kind="delay", cond_decade=0)
    path = tmp_path / "rq28.yaml"
    path.write_text(rc.yaml())
    return Built(path, "double", build_root)


def test_a_dependent_shifted_set_is_not_a_vertex(tmp_path, build_root):
    built = _rq28(tmp_path, build_root)
    c, solver = built.fresh_c(), built.reference().solvers[0]
    for x, r in ((QP92_X, QP92_R), (QP93_X, QP93_R)):
        x, r = _vec(x), _vec(r)
        status_c, U_c, _ = c.solve_qp(0, x, r)
        status_r, U_r, *_ = solver.qp_solve(x, r)
        assert int(status_c) == int(status_r) == OPTIMAL, (status_c, status_r)
        assert U_c.tobytes() == U_r.astype(U_c.dtype).tobytes()
    # the shifted set the warm start resumes: its factor now breaks down on the repeats
    W = SHIFTED_SET
    assert np.linalg.matrix_rank(solver.H[np.ix_(W, W)]) < W.size
    assert not solver.factor_working_set(W)


def test_the_rows_before_the_breakdown_stand(tmp_path, build_root):
    """After the breakdown at row j, independent_rows() keeps rows 0..j-1 of the failed
    factor as they are: the same bits as appending every row again from an empty factor."""
    solver = _rq28(tmp_path, build_root).reference().solvers[0]
    W = SHIFTED_SET
    assert not solver.factor_working_set(W)
    j = solver.chol_rows
    assert 0 < j < W.size
    head = solver.chol[:j * (j + 1) // 2].copy()
    solver.work = 0
    kept = solver.independent_rows(W)
    reused_work, reused = solver.work, solver.chol[:kept.size * (kept.size + 1) // 2].copy()
    assert solver.chol[:head.size].tobytes() == head.tobytes()
    solver.chol_rows, solver.work = 0, 0
    again = solver.independent_rows(W)  # from an empty factor
    assert np.array_equal(again, kept)
    assert solver.chol[:reused.size].tobytes() == reused.tobytes()
    assert reused_work < solver.work  # the rows that stand are not charged again
