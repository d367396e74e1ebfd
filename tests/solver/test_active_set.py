"""The dual active-set (Goldfarb-Idnani) solve of the default solver, on its own.

With ``polish_first: false`` every constrained QP starts in ``dual_active_set()`` (the
default runs it only when the warm-started polish fails), so these QPs exercise it
directly: the UAV's two modes (N = 20) from random states, feasible and infeasible.
Checked: C == NumPy reference bit for bit (status, U, counters); OPTIMAL exactly when the
extended-precision reference finds the QP feasible, INFEASIBLE otherwise; the error
against that reference within the bound for the mode's cond(E) (reliability/test_random_qps.py); no sweep ever runs.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import Built, short_uav_config
from rollmpc_codegen.qp.exact import qp_data, relative_error, solve_exact
from rollmpc_codegen.verify.qp_campaign import error_bound
from rollmpc_codegen.reference.solver import SolverRef
from rollmpc_codegen.status import INFEASIBLE, OPTIMAL

N = 20
QPS = 48


@pytest.fixture(scope="module", params=["double", "float"])
def gi_only(request, tmp_path_factory, build_root):
    tmp = tmp_path_factory.mktemp("gi")
    cfg = short_uav_config(tmp, N, "gi_only", polish_first=False)
    return Built(cfg, request.param, build_root)


def _draws(model, count):
    """Random states and held references; the large states make many QPs infeasible."""
    rng = np.random.default_rng(7)
    for k in range(count):
        mode = k % 2
        nx = model.modes[mode].data.nx
        scale = 3.0 if k % 4 < 2 else 30.0
        x = (rng.normal(size=nx) * rng.uniform(0, scale)).astype(model.dtype)
        r = np.full(N, rng.uniform(-80, 80)).astype(model.dtype)
        yield mode, x, r


def test_dual_active_set_matches_reference_and_exact_solution(gi_only):
    model, ctx = gi_only.model, gi_only.ctx
    statuses = {OPTIMAL: 0, INFEASIBLE: 0}
    for mode, x, r in _draws(model, QPS):
        md, qp = model.modes[mode].data, model.modes[mode].qp
        c = gi_only.fresh_c()  # cold, like the reference below
        st, U, sweeps = c.solve_qp(mode, x, r)
        st_r, U_r, sweeps_r, steps_r, _ = SolverRef(md, ctx["solver"]).solve_mode(x, r)
        assert (st, sweeps) == (st_r, sweeps_r) and U.tobytes() == U_r.tobytes()
        assert c.info()["polish_iterations"] == steps_r
        assert sweeps == 0  # the sweeps are only the last resort
        sol = solve_exact(qp_data(qp, x.astype(float), r.astype(float)))
        assert st == (OPTIMAL if sol.status == "optimal" else INFEASIBLE), (mode, sol.status)
        assert np.all(np.isfinite(U)) and np.all(U >= md.u_min[0]) and np.all(U <= md.u_max[0])
        if st == OPTIMAL:
            err = relative_error(U, sol.U)
            cond = float(np.linalg.cond(qp.E))
            assert err <= error_bound(cond, ctx["precision"]), (mode, cond, err)
        statuses[st] += 1
    assert min(statuses.values()) >= QPS // 8, statuses  # both outcomes exercised


@pytest.fixture(scope="module", params=[{}, {"polish": False}], ids=["polish_first", "sweeps"])
def warm_reader(request, tmp_path_factory, build_root):
    """Builds that read the multipliers a solve leaves behind (``gi_only`` never does: its
    dual active set starts from th0): the default's shifted warm start of the polish, and
    the sweeps' warm start without the polish."""
    tmp = tmp_path_factory.mktemp("warm")
    return Built(short_uav_config(tmp, N, "warm_reader", **request.param), "double", build_root)


def test_infeasible_sample_leaves_no_warm_start(warm_reader):
    """A failed solve clears the multipliers: an optimal QP with active rows (its multipliers
    become the warm start), an infeasible QP of the same mode, then the first QP again
    solves as from cold (status, U bit for bit, sweeps, polish corrections, active rows)."""
    model = warm_reader.model
    draws = list(_draws(model, QPS))
    exact = [solve_exact(qp_data(model.modes[m].qp, x.astype(float), r.astype(float))).status
             for m, x, r in draws]
    c, cold = warm_reader.fresh_c(), warm_reader.fresh_c()
    pairs = 0
    for mode, x, r in (d for d, e in zip(draws, exact) if e == "optimal"):
        c.init()
        if c.solve_qp(mode, x, r)[0] != OPTIMAL or c.info()["active"] == 0:
            continue
        for m2, x2, r2 in (d for d, e in zip(draws, exact) if e == "infeasible"):
            if m2 == mode:
                st, _, _ = c.solve_qp(m2, x2, r2)
                if st != OPTIMAL:  # INFEASIBLE, or MAX_ITER for the sweeps
                    break
        else:
            pytest.fail("no infeasible draw")
        st_warm, U_warm, _ = c.solve_qp(mode, x, r)
        warm_info = c.info()
        cold.init()
        st_cold, U_cold, _ = cold.solve_qp(mode, x, r)
        assert st_warm == st_cold == OPTIMAL and U_warm.tobytes() == U_cold.tobytes()
        keys = ("iterations", "polish_iterations", "active")
        assert [warm_info[k] for k in keys] == [cold.info()[k] for k in keys]
        pairs += 1
    assert pairs >= 6, pairs
