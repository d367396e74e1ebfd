"""Offline maths: eqs. (1)-(6) of the paper, the observer, and the structured storage."""
from __future__ import annotations

import control
import numpy as np
import pytest

from conftest import UAV
from rollmpc_codegen.pipeline import load_model
from rollmpc_codegen.qp.storage import unpack_lower


@pytest.fixture(scope="module")
def model():
    return load_model(UAV, "double")[0]


def test_discrete_model_matches_python_control_c2d(model):
    """ZOH of G_j(s)/s: same transfer function as control.c2d of the config's tf."""
    tfs = [([-74.15, 8892], [1, 59.11, 1599, 7936]),
           ([4.746, -392.5, 2.443e4, 2.064e5], [1, 80.26, 3026, 2.829e4, 1.21e5])]
    for mm, (num, den) in zip(model.modes, tfs):
        G = control.tf(num, den) * control.tf([1], [1, 0])
        ref = control.c2d(G, 0.01, "zoh")
        p = mm.plant
        # compare impulse (Markov) responses over 200 samples
        h_ref = control.impulse_response(ref, T=np.arange(200) * 0.01).outputs.ravel()
        x = p.B[:, 0].copy()
        h = [0.0]
        for _ in range(199):
            h.append((p.C @ x).item())
            x = p.A @ x
        # python-control scales a discrete impulse by 1/dt
        assert np.allclose(np.array(h) / 0.01, h_ref, rtol=1e-9, atol=1e-12)


def test_prediction_matrices_match_simulation(model):
    rng = np.random.default_rng(3)
    for mm in model.modes:
        p, qp = mm.plant, mm.qp
        x0 = rng.normal(size=p.nx)
        U = rng.normal(size=qp.n)
        x, Y = x0.copy(), []
        for k in range(qp.N):
            x = p.A @ x + p.B @ U[k * p.nu:(k + 1) * p.nu]
            Y.append(p.C @ x)
        assert np.allclose(qp.Phi @ x0 + qp.Gamma @ U, np.concatenate(Y), rtol=1e-10)


def _simulated_cost(plant, weights, x0: np.ndarray, U: np.ndarray, r: np.ndarray) -> float:
    """J of eq. (5) by simulating the plant from x0: sum_i (y_i - r_i)' W_i (y_i - r_i) +
    sum_k u_k' R u_k, W_i = Q, and the terminal weight P on y_N (README)."""
    nu, ny = plant.nu, plant.ny
    N = r.size // ny
    x, J = x0.copy(), 0.0
    for k in range(N):
        u = U[k * nu:(k + 1) * nu]
        J += u @ weights.R @ u
        x = plant.A @ x + plant.B @ u
        e = plant.C @ x - r[k * ny:(k + 1) * ny]
        J += e @ (weights.P if k == N - 1 else weights.Q) @ e
    return J


def _curvature_and_slope(plant, weights, x, r, V) -> tuple[float, float]:
    """(V'EV, f'V) of J(U) = 1/2 U'EU + f'U + c along V, from the simulated cost alone:
    J(V) + J(-V) - 2 J(0) and (J(V) - J(-V)) / 2; and the scale of those J values."""
    Jp, Jm, J0 = (_simulated_cost(plant, weights, x, U, r) for U in (V, -V, 0 * V))
    return Jp + Jm - 2 * J0, (Jp - Jm) / 2, abs(Jp) + abs(Jm) + abs(J0)


def test_hessians_and_terminal_split(model):
    rng = np.random.default_rng(5)
    for mm, weights in zip(model.modes, model.config.modes):
        qp = mm.qp
        # E and the gradient are those of the cost of eq. (5), evaluated by simulation
        x, r = rng.normal(size=qp.nx) * 10, rng.uniform(-40, 40, size=qp.N * qp.ny)
        for V in rng.normal(size=(4, qp.n)):
            curvature, slope, scale = _curvature_and_slope(mm.plant, weights, x, r, V)
            assert abs(curvature - V @ qp.E @ V) <= 1e-10 * scale
            assert abs(slope - qp.gradient(x, r) @ V) <= 1e-10 * scale
        assert np.linalg.eigvalsh(qp.E).min() > 0
        S, V, P2inv = qp.terminal_split()
        assert np.allclose(S + V.T @ np.linalg.inv(P2inv) @ V, qp.E, rtol=1e-12, atol=1e-9)
        assert np.linalg.cond(S) < 1e4  # the split removes the 1e9 terminal weight
        I = np.eye(qp.n)
        assert np.abs(qp.Einv @ qp.E - I).max() < 1e-9


def test_constraints_eq6_hold_exactly_for_the_prediction(model):
    """L U <= c + W x is the same as the box and output bounds on the prediction."""
    rng = np.random.default_rng(4)
    for mm in model.modes:
        qp = mm.qp
        assert qp.m == 4 * qp.N  # y_0 rows dropped: u_0..u_{N-1}, y_1..y_N, both sides
        x, U = rng.normal(size=qp.nx), rng.uniform(-20, 20, size=qp.n)
        lhs = qp.L @ U - qp.W @ x
        Y = qp.Phi @ x + qp.Gamma @ U
        expect = np.where(qp.row_kind == 0, qp.row_sign * U[qp.row_index],
                          qp.row_sign * Y[np.minimum(qp.row_index, len(Y) - 1)])
        assert np.allclose(lhs, expect)


def test_structured_dual_hessian_equals_dense(model):
    """H = L E^-1 L' is what the C reads through hq() from the packed blocks."""
    from rollmpc_codegen.qp.work import ADD_BATCH, UNBOUNDED_WORK
    from rollmpc_codegen.reference.solver import SolverRef

    for mm in model.modes:
        H = mm.qp.dual_hessian()
        ref = SolverRef(mm.data, {"reduced": True, "warm_start": True, "polish": True,
                                  "omega": 1.2, "sigma": 0.2, "delta": 1e-13,
                                  "feasibility_tol": 1e-9, "max_iterations": 10,
                                  "polish_every": 10, "polish_max": 8,
                                  "work_budget": UNBOUNDED_WORK, "hq_work_factor": 1,
                                  "add_batch": ADD_BATCH})
        assert np.allclose(ref.H, H, rtol=1e-9, atol=1e-12 * np.abs(H).max())
        Lo, D, Up = mm.qp.ldu()
        assert np.allclose(Lo + D + Up, H) and np.allclose(Lo, Up.T)
        Einv = unpack_lower(mm.data.Sinv_p, mm.qp.n) - mm.data.Ew.T @ mm.data.Ew
        assert np.allclose(Einv, mm.qp.Einv, rtol=1e-9, atol=1e-12)


def test_observer_poles_are_placed(model):
    for mm in model.modes:
        p = mm.plant
        eig = np.sort_complex(np.linalg.eigvals(p.A - mm.observer_gain @ p.C))
        want = np.sort_complex(np.array(mm.observer_poles))
        assert np.allclose(eig, want, atol=1e-8)
        assert np.abs(eig).max() < 1


def test_conditioning_of_the_paper_modes(model):
    """cond(E): ~8.9e2 (inner) and ~2.5e6 (outer), as measured on the paper's data."""
    conds = [np.linalg.cond(mm.qp.E) for mm in model.modes]
    assert 8e2 < conds[0] < 1e3
    assert 2e6 < conds[1] < 3e6
