"""Δu constraints (input-rate limits), ``modes[].bounds.du_min/du_max``.

examples/thermal_zones_rate.yaml (the thermal plate with R = 0.01, no R_delta, and heater
ramp limits |u_k - u_{k-1}| <= 0.3 kW, k = 0..N-1, u_{-1} = the previous command) and a
variant with R_delta and asymmetric, partly absent bounds.  Checked: the Δu rows of the
condensed QP (row kind 2, u_prev in the first stage's right-hand side); P_step bit for bit
against the NumPy reference over the disturbed closed loop in both precisions, every QP
optimal, every applied |Δu| within the bound (+ the feasibility tolerance) while the
bound is active; the double QPs within 1e-8 of DAQP and of exact_qp.solve_exact, with Δu
rows in their active sets; random states (u_prev anywhere, including outside the
input box: infeasible) bit for bit, optimal ones within 1e-8 of DAQP; config errors
naming the key; default builds carry no Δu code.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import (ROOT, Built, config_error, edit_bounds, edited_config,
                      sampled_qps_against_independent_solvers)
from lockstep import Lockstep
from rollmpc_codegen.qp.exact import qp_data, solve_exact
from rollmpc_codegen.pipeline import load_model
from rollmpc_codegen.codegen.render import render_sources
from rollmpc_codegen.sim.scenario import preview, scenario_reference
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.reference.solver import SolverRef
from rollmpc_codegen.status import INFEASIBLE, OPTIMAL
from test_input_rate_weighting import checked_closed_loop

RATE = ROOT / "examples" / "thermal_zones_rate.yaml"
ZONES = ROOT / "examples" / "thermal_zones.yaml"
DU = 0.3  # kW per sample, the example's ramp limit
DIST = 0.3  # kW on both heaters


def _applied_du(log) -> np.ndarray:
    """u_k - u_{k-1} of the applied commands, u_{-1} = 0 (the command after P_init)."""
    return np.diff(np.vstack((np.zeros((1, log.u.shape[1])), log.u)), axis=0)


# --------------------------------------------------------------------------- model
def test_rate_rows_of_the_condensed_qp(tmp_path):
    model, ctx = load_model(RATE)
    mm = model.modes[0]
    qp, d = mm.qp, mm.data
    N, nu, nx, n = qp.N, qp.nu, qp.nx, qp.n
    assert mm.plant.n_prev == nu == 2 and nx == 8  # u_prev states without R_delta
    rate = np.flatnonzero(qp.row_kind == 2)
    assert rate.size == 2 * N * nu and ctx["has_rate_rows"] and d.has_rate_rows
    rng = np.random.default_rng(5)
    U, x = rng.normal(size=n), rng.normal(size=nx)
    du = U - np.concatenate((x[-nu:], U[:-nu]))  # u_k - u_{k-1}, u_{-1} = u_prev
    lhs = qp.L[rate] @ U - qp.W[rate] @ x  # sign * du_i <= c
    assert np.allclose(lhs, qp.row_sign[rate] * du[qp.row_index[rate]], atol=1e-14)
    assert np.array_equal(qp.c[rate], np.full(rate.size, DU))  # +du_max, -du_min
    # stored quantities n + N ny + i; the shifted warm start stays inside the Δu rows
    assert np.array_equal(d.row_q[rate], n + N * qp.ny + qp.row_index[rate])
    assert np.all(d.row_q[d.row_next[rate]] >= n + N * qp.ny)
    # the cost does not see the bounds (R_delta absent): E and Kx as without u_prev
    plain, _ = load_model(edited_config(tmp_path, RATE, "plain", edit_bounds(du_min=None, du_max=None)))
    assert plain.modes[0].plant.n_prev == 0
    assert np.allclose(qp.E, plain.modes[0].qp.E, rtol=1e-13, atol=0)
    assert np.allclose(qp.Kx[:, :-nu], plain.modes[0].qp.Kx, rtol=1e-9, atol=1e-12)
    assert not np.any(qp.Kx[:, -nu:])


def test_default_builds_carry_no_rate_code():
    _, ctx = load_model(ZONES)  # R_delta (u_prev states) but no Δu bounds: no Δu rows
    assert not ctx["has_rate_rows"]
    src = render_sources(ctx)
    solver = next(text for name, text in src.items() if name.endswith("_solver.c"))
    assert "hq_side" not in solver
    _, ctx = load_model(RATE)
    solver = next(text for name, text in render_sources(ctx).items()
                  if name.endswith("_solver.c"))
    assert "hq_side" in solver


# --------------------------------------------------------------------------- closed loop
@pytest.fixture(scope="module", params=["double", "float"])
def rate_run(request, build_root):
    built = Built(RATE, request.param, build_root)
    return (built, *checked_closed_loop(built, DIST))


def test_step_bit_exact_and_rate_limited(rate_run):
    built, lock, log, prev_ok = rate_run
    assert len(log.t) == 400
    assert lock.mismatches == [], f"{len(lock.mismatches)} mismatching steps, first: " \
                                  f"{lock.mismatches[0]}"
    assert all(prev_ok) and np.all(log.status == OPTIMAL)
    du = np.abs(_applied_du(log))
    # the solver's tolerance is relative: feasibility_tol * max(1, |gamma|), |gamma| <= 2.3
    tol = 2.3 * built.ctx["solver"]["feasibility_tol"]
    assert du.max() <= DU + tol, du.max()
    assert np.count_nonzero(du >= DU - 1e-6) >= 40  # the limit is active (measured 85/74)
    assert np.all(np.abs(log.u) <= 2.0)


def test_double_matches_independent_solvers(rate_run):
    built, lock, log, _ = rate_run
    if built.ctx["precision"] != "double":
        pytest.skip("the independent check is a double-precision property")
    _, worst_daqp, worst_exact = sampled_qps_against_independent_solvers(
        built, lock.states, scenario_reference(built.model.config), bound=2.0, perturb=3.0,
        seed=7)
    assert worst_daqp <= 1e-8 and worst_exact <= 1e-8, (worst_daqp, worst_exact)
    # and where the applied move sits on the limit, the exact optimum has Δu rows active
    qp = built.model.modes[0].qp
    rate = qp.row_kind == 2
    at_limit = np.flatnonzero(np.abs(_applied_du(log)).max(axis=1) >= DU - 1e-9)
    ref = scenario_reference(built.model.config)
    for k in at_limit[:: max(1, at_limit.size // 4)][:4]:
        _, x, kk = lock.states[k]
        r = preview(ref, kk, qp.N, qp.ny)
        data = qp_data(qp, x, r)
        exact = solve_exact(data)
        st, U, _ = built.c.solve_qp(0, x, r)
        assert st == OPTIMAL and exact.status == "optimal"
        assert np.abs(U - exact.U).max() <= 1e-8
        slack = (data.b - qp.L @ exact.U.astype(np.longdouble)).astype(float)
        assert np.any(np.abs(slack[rate]) < 1e-9)


def _variant_both(tmp_path):
    def edit(data):
        edit_bounds(du_min=[-0.2, "-inf"], du_max=[0.4, 0.25])(data)
        data["modes"][0]["weights"]["R_delta"] = [[0.05, 0.0], [0.0, 0.05]]
    return edited_config(tmp_path, RATE, "both", edit)


def test_with_r_delta_and_partial_bounds_random_states(tmp_path, build_root):
    """R_delta plus asymmetric, partly absent bounds: random states (u_prev inside and
    outside the input box) bit for bit; optimal ones within 1e-8 of DAQP, the ones with
    u_prev beyond u_max + 0.4 proved infeasible."""
    daqp = pytest.importorskip("daqp", reason="install with: pip install 'rollmpc-codegen[peers]'")
    built = Built(_variant_both(tmp_path), "double", build_root)
    qp = built.model.modes[0].qp
    assert np.count_nonzero(qp.row_kind == 2) == 3 * qp.N  # du_min of heater 2 absent
    solver = SolverRef(built.model.modes[0].data, built.ctx["solver"])
    c = built.fresh_c()
    rng = np.random.default_rng(17)
    states = Lockstep(built)
    log = run_closed_loop(built.model.config, states, steps=160, info=states.info)
    assert states.mismatches == [] and np.all(log.status == OPTIMAL)
    du = _applied_du(log)
    assert du[:, 0].max() <= 0.4 + 1e-8 and du[:, 0].min() >= -0.2 - 1e-8
    assert du[:, 1].max() <= 0.25 + 1e-8
    statuses, worst = [], 0.0
    for i in range(40):
        _, x, _ = states.states[int(rng.integers(len(states.states)))]
        x = x + rng.normal(scale=0.5, size=x.size)
        x[-2:] = rng.uniform(-2.0, 2.0, 2) if i < 34 else (2.5, 0.0)  # last: infeasible
        r = rng.uniform(-6.0, 6.0, qp.N * qp.ny)
        st_c, U_c, _ = c.solve_qp(0, x, r)
        st_r, U_r, _, _, _ = solver.solve_mode(x, r)
        assert st_c == st_r and U_c.tobytes() == U_r.tobytes(), i
        statuses.append(st_c)
        if st_c == OPTIMAL:
            data = qp_data(qp, x, r)
            U_d, _, flag, _ = daqp.solve(qp.E, data.f.astype(float), qp.L,
                                         data.b.astype(float), np.full(qp.m, -1e30),
                                         np.zeros(qp.m, dtype=np.intc))
            assert flag == 1
            worst = max(worst, float(np.abs(U_c - U_d).max()))
    assert statuses[:34].count(OPTIMAL) >= 30 and set(statuses[34:]) == {INFEASIBLE}
    assert worst <= 1e-8, worst


# --------------------------------------------------------------------------- config
@pytest.mark.parametrize("bounds, key, text", [
    ({"du_min": 0.0, "du_max": 0.0}, "modes[0].bounds.du_min", "must be < du_max"),
    ({"du_min": 0.1, "du_max": 0.3}, "modes[0].bounds.du_min", "must be <= 0"),
    ({"du_min": -0.3, "du_max": -0.1}, "modes[0].bounds.du_max", "must be >= 0"),
    ({"du_max": [0.3, 0.3, 0.3]}, "modes[0].bounds.du_max", "must have 2 entries"),
    ({"du_min": "a"}, "modes[0].bounds.du_min", "number"),
])
def test_config_errors_name_the_key(tmp_path, bounds, key, text):
    err = config_error(edited_config(tmp_path, RATE, "bad", edit_bounds(**bounds)))
    assert err.key == key and text in str(err)


def test_runtime_bounds_with_rate_rows_is_rejected(tmp_path):
    err = config_error(edited_config(tmp_path, RATE, "rt", lambda d: d.update(runtime_bounds=True)))
    assert err.key == "runtime_bounds" and "Δu" in str(err)


def test_infinite_rate_bounds_are_absent(tmp_path):
    model, ctx = load_model(edited_config(tmp_path, RATE, "inf", edit_bounds(du_min="-inf",
                                                                   du_max="inf")))
    assert ctx["modes"][0]["nx"] == 6 and not ctx["has_rate_rows"]
    assert not np.any(model.modes[0].qp.row_kind == 2)


def test_move_blocking_with_rate_rows_is_rejected(tmp_path):
    err = config_error(edited_config(tmp_path, RATE, "mb", lambda d: d.update(control_horizon=5)))
    assert err.key == "modes[0].bounds.du_min" and "blocking" in str(err)
