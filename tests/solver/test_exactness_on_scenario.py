"""Exactness and bounded work of the default solver on the paper's own QPs.

Every QP of the 6000-step scenario is replayed through the compiled C solver (warm starts
carried over in order, as in the closed loop) and compared with an extended-precision KKT
solution on the optimal active set (rollmpc_codegen.qp.exact). The float build is compared
with the double build on the applied first move. No timing is asserted here: speed is
measured by `rollmpc bench` and `rollmpc report`.
"""
from __future__ import annotations

import numpy as np
import pytest

from rollmpc_codegen.host.bench_record import record_qp_sequence
from rollmpc_codegen.qp.exact import qp_data, solve_exact
from rollmpc_codegen.status import OPTIMAL


@pytest.fixture(scope="module")
def double_replay(uav_double):
    seq = record_qp_sequence(uav_double.model, uav_double.fresh_c())
    qps = list(zip(seq.mode, seq.x, seq.r))
    c = uav_double.fresh_c()
    out = []
    for mode, x, r in qps:
        status, U, sweeps = c.solve_qp(mode, x, r)
        out.append((mode, x, r, status, U, sweeps, c.info()["polish_iterations"]))
    return uav_double, out


def test_every_scenario_qp_is_optimal_without_sweeps(double_replay):
    """Measured: the polish from the shifted active set (or the violated rows) solves all
    6000 QPs; no Gauss-Seidel sweep runs, and at most 10 active-set corrections (asserted
    with a margin of 2)."""
    built, out = double_replay
    assert len(out) == 6000
    assert [o[3] for o in out].count(OPTIMAL) == 6000
    assert max(o[5] for o in out) == 0
    polish = np.array([o[6] for o in out])
    assert polish.max() <= 2 * built.ctx["solver"]["polish_max"]
    assert polish.max() <= 12, polish.max()
    assert np.count_nonzero(polish) >= 700  # the constrained QPs really went through it


def _worst_kkt_error(built, qps) -> float:
    worst = 0.0
    for mode, x, r, status, U, *_ in qps:
        exact = solve_exact(qp_data(built.model.modes[mode].qp, x, r))
        assert exact.status == "optimal"
        worst = max(worst, float(np.abs(U - exact.U).max()))
    return worst


def test_double_matches_extended_precision_kkt_to_1e_8(double_replay):
    """Every QP the polish corrected (bounds active) and every eighth of the others; all
    6000 in the slow test below."""
    built, out = double_replay
    picked = [o for k, o in enumerate(out) if o[6] > 0 or k % 8 == 0]
    assert len(picked) >= 1400
    worst = _worst_kkt_error(built, picked)
    assert worst <= 1e-8, worst


@pytest.mark.slow
def test_every_scenario_qp_matches_extended_precision_kkt_to_1e_8(double_replay):
    built, out = double_replay
    assert len(out) == 6000
    worst = _worst_kkt_error(built, out)
    assert worst <= 1e-8, worst


def test_float_first_move_within_1e_5_deg_of_double(double_replay, build_root):
    """Measured 8.4e-6 deg on the 6000 QPs; asserted <= 1e-5 deg (a 20 % margin)."""
    from conftest import UAV, Built

    built, out = double_replay
    f32 = Built(UAV, "float", build_root).fresh_c()
    worst = 0.0
    for mode, x, r, status, U, *_ in out:
        st, Uf, _ = f32.solve_qp(mode, x.astype(np.float32), r.astype(np.float32))
        assert st == OPTIMAL
        nu = built.ctx["modes"][mode]["nu"]
        worst = max(worst, float(np.abs(Uf[:nu].astype(np.float64) - U[:nu]).max()))
    assert worst <= 1e-5, worst
