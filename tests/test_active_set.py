"""The dual active-set (Goldfarb-Idnani) solve of the default solver, on its own.

With ``polish_first: false`` every constrained QP starts in ``dual_active_set()`` (the
default runs it only when the warm-started polish fails), so these QPs exercise it
directly: the UAV's two modes (N = 20) from random states, feasible and infeasible.
Checked: C == NumPy reference bit for bit (status, U, counters); OPTIMAL exactly when the
extended-precision reference finds the QP feasible, INFEASIBLE otherwise; the error
against that reference within the issue-4 bound of the mode's cond(E); no sweep ever runs.
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
        st_r, U_r, sweeps_r, steps_r, _ = SolverRef(md, ctx["solver"]).solve(x, r)
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


def test_infeasible_sample_leaves_no_warm_start(gi_only):
    """INFEASIBLE clears the multipliers: the next feasible QP solves as from cold."""
    model = gi_only.model
    draws = list(_draws(model, QPS))
    c = gi_only.fresh_c()
    for mode, x, r in draws:
        st, _, _ = c.solve_qp(mode, x, r)
        if st == INFEASIBLE:
            break
    else:
        pytest.fail("no infeasible draw")
    feasible = next((m, x2, r2) for m, x2, r2 in draws if m == mode and
                    solve_exact(qp_data(model.modes[m].qp, x2.astype(float),
                                        r2.astype(float))).status == "optimal")
    st_warm, U_warm, _ = c.solve_qp(*feasible)
    st_cold, U_cold, _ = gi_only.fresh_c().solve_qp(*feasible)
    assert st_warm == st_cold == OPTIMAL and U_warm.tobytes() == U_cold.tobytes()
