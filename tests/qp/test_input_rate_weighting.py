"""Δu weighting, ``modes[].weights.R_delta``.

examples/thermal_zones.yaml (2x2 TF matrix, Kalman, input-disturbance model, R = 0, a
full R_delta: 4 + 2 + 2 = 8 prediction states) and a variant of examples/three_drives.yaml
(3 modes, switching) with R_delta on every mode.  Checked: the condensed QP equals the
cost summed stage by stage (with the previous input and the input target); E's terminal
split; the observer's u_prev rows are deadbeat and the gain of the other states is the
one without Δu; P_step bit for bit against the NumPy reference over the disturbed closed
loop (both precisions) with every observer's u_prev estimate equal, exactly, to the
command its mode's actuators got (0 while inactive); the double QP solutions within 1e-8
of DAQP and of the extended-precision solution; smoother inputs (total variation) with
R_delta; no nominal offset with R = 0; config errors; `rollmpc simulate` and `bench`.
"""
from __future__ import annotations


import numpy as np
import pytest

from conftest import (ROOT, Built, config_error, edited_config,
                      sampled_qps_against_independent_solvers, simulate_and_bench)
from lockstep import Lockstep
from rollmpc_codegen.host.build import build_host_controller
from rollmpc_codegen.pipeline import load_model
from rollmpc_codegen.sim.scenario import scenario_reference
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.status import OPTIMAL

ZONES = ROOT / "examples" / "thermal_zones.yaml"
DRIVES = ROOT / "examples" / "three_drives.yaml"
DIST = 0.3  # kW on both heaters, the constant input disturbance of the closed loop
STEADY = [80 * (i + 1) - 21 for i in range(5)]  # settled, before the preview sees a step


def _weights(**w):
    def edit(data):
        for m in data["modes"]:
            m["weights"].update(w)
            for k, v in w.items():
                if v is None:
                    del m["weights"][k]
    return edit


def _total_variation(log) -> float:
    return float(np.abs(np.diff(log.u, axis=0)).sum())


# --------------------------------------------------------------------------- model
def test_condensed_qp_is_the_stagewise_cost():
    """1/2 U'EU + f'U + const equals the cost summed stage by stage, with
    (u_k - u_{k-1})' R_delta (u_k - u_{k-1}), u_{-1} = u_prev, and R on u - u_s(d)."""
    model, _ = load_model(ZONES)
    mode, mm = model.config.modes[0], model.modes[0]
    p, qp = mm.plant, mm.qp
    assert (p.nx, p.nd, p.n_prev, p.nu) == (8, 2, 2, 2)
    N, nu, ny = qp.N, qp.nu, qp.ny
    # velocity form: u_prev+ = u, and the outputs do not see u_prev
    assert np.array_equal(p.A[-2:], np.zeros((2, 8))) and np.array_equal(p.A[:, -2:], 0 * p.A[:, -2:])
    assert np.array_equal(p.B[-2:], np.eye(2)) and not np.any(p.C[:, -2:])
    assert not np.any(qp.Phi[:, -2:]) and not np.any(qp.W[:, -2:])
    rng = np.random.default_rng(3)
    x0, R = rng.normal(size=8), rng.normal(size=N * ny)

    def cost(U):
        x, u_prev, J = x0.copy(), x0[-2:], 0.0
        u_s = p.input_target @ x0  # the disturbance-cancelling input (d is constant)
        for k in range(N):
            u = U[k * nu:(k + 1) * nu]
            du = u - u_prev
            J += du @ mode.R_delta @ du + (u - u_s) @ mode.R @ (u - u_s)
            x = p.A @ x + p.B @ u
            e = p.C @ x - R[k * ny:(k + 1) * ny]
            J += e @ (mode.P if k == N - 1 else mode.Q) @ e
            u_prev = u
        return J

    f = qp.gradient(x0, R)
    for _ in range(3):
        U = rng.normal(size=N * nu)
        assert np.isclose(cost(U) - cost(np.zeros_like(U)), 0.5 * U @ qp.E @ U + f @ U,
                          rtol=1e-10, atol=1e-9)
    S, V, P2inv = qp.terminal_split()  # the primal polish's split keeps the Δu term
    assert np.allclose(S + V.T @ np.linalg.inv(P2inv) @ V, qp.E, rtol=1e-12, atol=1e-9)
    # the unconstrained minimiser is th0 = Kx x + Kr R
    assert np.allclose(qp.theta0(x0, R), np.linalg.solve(qp.E, -f), rtol=1e-9, atol=1e-10)


@pytest.mark.parametrize("observer", [None, {"poles": [0.3, 0.4, 0.5, 0.6, 0.7, 0.8]}])
def test_observer_previous_input_rows_are_deadbeat(tmp_path, observer):
    """L is the gain without Δu on [x; d], zero on u_prev; eig(A - LC) adds nu zeros."""
    def edit(data):
        if observer is not None:
            data["modes"][0]["observer"] = {**observer, "disturbance": "input"}
    with_du, _ = load_model(edited_config(tmp_path, ZONES, "du", edit))
    without, _ = load_model(edited_config(tmp_path, ZONES, "plain", lambda d: (
        edit(d), _weights(R=0.01, R_delta=None)(d))))
    a, b = with_du.modes[0], without.modes[0]
    assert a.observer_gain.shape == (8, 2) and b.observer_gain.shape == (6, 2)
    assert np.array_equal(a.observer_gain[:6], b.observer_gain)
    assert not np.any(a.observer_gain[6:])
    eig = np.linalg.eigvals(a.plant.A - a.observer_gain @ a.plant.C)
    assert np.sum(np.abs(eig) < 1e-12) == 2
    assert a.observer_poles[-2:] == (0j, 0j)


# --------------------------------------------------------------------------- closed loop
def checked_closed_loop(built, disturbance: float):
    """Lockstep C/reference closed loop of a one-mode config with previous-input states;
    returns (lock, log, per sample: the reference's u_prev estimate == the applied command)."""
    lock = Lockstep(built)
    prev_ok = []
    nu = built.ctx["modes"][0]["nu"]

    class Checked:
        def step(self, y, s, r):
            st, u = lock.step(y, s, r)
            prev_ok.append(np.array_equal(lock.ref.xhat[0][-nu:], u))
            return st, u

        info = staticmethod(lock.info)

    log = run_closed_loop(built.model.config, Checked(), disturbance=disturbance, info=lock.info)
    return lock, log, prev_ok


@pytest.fixture(scope="module", params=["double", "float"])
def zones_run(request, build_root):
    built = Built(ZONES, request.param, build_root)
    return (built, *checked_closed_loop(built, DIST))


def test_step_bit_exact_over_disturbed_closed_loop(zones_run):
    built, lock, log, prev_ok = zones_run
    assert len(log.t) == 400 and built.ctx["modes"][0]["nx"] == 8
    assert lock.mismatches == [], f"{len(lock.mismatches)} mismatching steps, first: " \
                                  f"{lock.mismatches[0]}"
    assert all(prev_ok)
    assert np.all(log.status == OPTIMAL)
    assert np.any(np.abs(log.u) == 2.0) and np.all(np.abs(log.u) <= 2.0)  # saturates
    tol = 1e-3 if built.ctx["precision"] == "float" else 1e-6
    # offset-free despite the disturbance and with no absolute input weight
    assert np.abs(log.y[STEADY[1:]] - log.r[STEADY[1:]]).max() < 1e-3 + tol


def test_double_matches_independent_solvers(zones_run):
    built, lock, _, _ = zones_run
    if built.ctx["precision"] != "double":
        pytest.skip("the independent check is a double-precision property")
    # qp_data's gradient carries the Δu term (CondensedQP.gradient)
    saturated, worst_daqp, worst_exact = sampled_qps_against_independent_solvers(
        built, lock.states, scenario_reference(built.model.config), bound=2.0, perturb=3.0,
        seed=11)
    assert saturated >= 4
    assert worst_daqp <= 1e-8 and worst_exact <= 1e-8, (worst_daqp, worst_exact)


def _log(tmp_path, build_root, base, name, edit, disturbance=0.0, steps=None):
    model, ctx = load_model(edited_config(tmp_path, base, name, edit))
    c = build_host_controller(ctx, build_root)
    return run_closed_loop(model.config, c, disturbance=disturbance, info=c.info, steps=steps)


def test_smoother_inputs_and_no_nominal_offset(tmp_path, build_root):
    """R_delta lowers the total variation of u; R = 0 (only Δu weighted) removes the
    nominal offset that absolute input weighting leaves."""
    absolute = _log(tmp_path, build_root, ZONES, "absolute", _weights(R=0.01, R_delta=None))
    both = _log(tmp_path, build_root, ZONES, "both", _weights(R=0.01))
    delta = _log(tmp_path, build_root, ZONES, "delta", lambda d: None)
    tv = [_total_variation(x) for x in (absolute, both, delta)]
    assert tv[1] < 0.8 * tv[0] and tv[2] < 0.8 * tv[0], tv  # measured 36.6, 24.9, 25.1
    max_du = [np.abs(np.diff(x.u, axis=0)).max() for x in (absolute, delta)]
    assert max_du[1] < 0.25 * max_du[0], max_du  # measured 2.41, 0.42
    err = [np.abs(x.y[STEADY] - x.r[STEADY]).max() for x in (absolute, both, delta)]
    assert err[0] > 0.01 and err[1] > 0.01 and err[2] < 1e-3, err  # 0.013, 0.013, 6e-5


def test_switching_modes_bit_exact_with_inactive_previous_input(tmp_path, build_root):
    """Three drives (3 modes, 5 bands) with R_delta on every mode: bit for bit over the
    switching scenario; an inactive mode's u_prev estimate is exactly 0, the active one's
    its actuator's command."""
    path = edited_config(tmp_path, DRIVES, "drives_du", _weights(R_delta=1.0))
    built = Built(path, "double", build_root)
    assert [m["nx"] for m in built.ctx["modes"]] == [3, 3, 3]
    lock = Lockstep(built)
    prev_ok = []

    class Checked:
        def step(self, y, s, r):
            st, u = lock.step(y, s, r)
            for j, md in enumerate(built.model.modes):
                prev_ok.append(np.array_equal(lock.ref.xhat[j][-1:], u[md.data.actuator_index]))
            return st, u

        info = staticmethod(lock.info)

    log = run_closed_loop(built.model.config, Checked(), info=lock.info)
    assert lock.mismatches == [], lock.mismatches[0]
    assert all(prev_ok) and np.all(log.status == OPTIMAL)
    assert set(log.mode) == {0, 1, 2} and np.count_nonzero(np.diff(log.mode)) >= 10


# --------------------------------------------------------------------------- config
@pytest.mark.parametrize("weights, key, text", [
    ({"R": 0, "R_delta": None}, "modes[0].weights.R", "positive definite"),
    ({"R": 0, "R_delta": [1, 0]}, "modes[0].weights.R", "positive definite"),
    ({"R_delta": [[1, 0, 0], [0, 1, 0]]}, "modes[0].weights.R_delta", "must be 2x2"),
    ({"R_delta": [[1, 2], [0, 1]]}, "modes[0].weights.R_delta", "symmetric"),
    ({"R_delta": -1}, "modes[0].weights.R_delta", "positive semidefinite"),
    ({"R_delta": "a"}, "modes[0].weights.R_delta", "number"),
])
def test_config_errors_name_the_key(tmp_path, weights, key, text):
    err = config_error(edited_config(tmp_path, ZONES, "bad", _weights(**weights)))
    assert err.key == key and text in str(err)


def test_zero_r_delta_is_no_delta_weighting(tmp_path):
    model, ctx = load_model(edited_config(tmp_path, ZONES, "zero", _weights(R=0.01, R_delta=0)))
    assert model.config.modes[0].R_delta is None and ctx["modes"][0]["nx"] == 6
    assert model.modes[0].plant.n_prev == 0


# --------------------------------------------------------------------------- CLI
def test_simulate_and_bench_cli(tmp_path):
    summary, out, rows = simulate_and_bench(ZONES, tmp_path, "--disturbance", str(DIST))
    assert summary["samples"] == 400 and summary["non_optimal"] == 0
    assert "[K]" in out and "deg" not in out  # the config's units (units:)
    # the peers solve the QP with the Δu gradient (CondensedQP.gradient)
    assert rows["default"]["optimal"] == 40 and rows["default"]["max_abs_err"] <= 1e-8
    assert rows["daqp"]["max_abs_err"] <= 1e-8
