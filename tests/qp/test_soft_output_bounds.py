"""Soft output bounds, ``modes[].bounds.soft`` (soft_constraints.py).

examples/chain_soft.yaml: the chain of masses with |p_i| <= 0.4 m soft on both sides
(l1 = l2 = 1000). Checked: the per-row penalties and the C's per-bound data; P_step bit
for bit against the NumPy reference (info.slack_max/slack_rows included) over a closed
loop pushed by an input disturbance the model does not know, in both precisions, every
QP optimal and slacks in use; the double QPs with a positive slack within 1e-8 of the
explicit-slack QP solved by DAQP and by the extended-precision KKT solver, with the
reported slack equal to the largest slack of that solution; the same QPs through the
dual active set alone and through the sweeps alone, C == reference; exactness of the L1
penalty (where the hard bounds can hold, the soft plan is the hard plan); always
feasible (where the hard QP is INFEASIBLE, the soft one is OPTIMAL); config errors.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT, Built, config_error, edit_bounds, edited_config
from lockstep import Lockstep
from rollmpc_codegen.qp.exact import qp_data, solve_exact
from rollmpc_codegen.pipeline import load_model
from rollmpc_codegen.codegen.render import render_sources
from rollmpc_codegen.sim.scenario import preview, scenario_reference
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.features.soft_constraints import explicit_qp, multiplier_slack
from rollmpc_codegen.reference.solver import SolverRef
from rollmpc_codegen.status import INFEASIBLE, OPTIMAL

SOFT = ROOT / "examples" / "chain_soft.yaml"
CHAIN = ROOT / "examples" / "chain_of_masses.yaml"
PUSH = 0.05  # N on every force input: pushes masses past 0.4 m, the QPs stay feasible
HARD_PUSH = 0.3  # makes the hard bounds infeasible on most samples
BOUND, U_MAX = 0.4, 0.5


def _hard(data):
    for m in data["modes"]:
        m["bounds"].pop("soft")


def _solver(**s):
    return lambda data: data.setdefault("solver", {}).update(s)


# --------------------------------------------------------------------------- model
def test_penalties_of_the_rows_and_the_stored_data():
    model, ctx = load_model(SOFT)
    qp, d = model.modes[0].qp, model.modes[0].data
    out = qp.row_kind == 1
    assert np.all(qp.soft_l1[out] == 1000.0) and np.all(qp.soft_l2[out] == 1000.0)
    assert not np.any(qp.soft_l1[~out]) and not np.any(qp.soft_l2[~out])
    assert np.all(d.soft_w == 1.0 / 2000.0) and np.all(d.soft_l1 == 1000.0)
    # 6 outputs x 10 stages of (output, stage) pairs on top of n = 40
    assert d.w_cap == qp.n + qp.N * qp.ny == 100 and ctx["sizes"]["w_max"] == 100
    assert ctx["has_soft_rows"] and d.has_soft_rows
    # the explicit form: one slack per soft row, U first, l1 in the gradient
    ex = explicit_qp(qp)
    assert ex.n == qp.n + 120 and ex.m == qp.m + 120
    f = ex.gradient(np.zeros(qp.nx), np.zeros(qp.N * qp.ny))
    assert np.all(f[qp.n:] == 1000.0) and np.all(np.diag(ex.E)[qp.n:] == 2000.0)


def test_default_builds_carry_no_soft_code():
    _, ctx = load_model(CHAIN)
    assert not ctx["has_soft_rows"]
    src = render_sources(ctx)
    text = "".join(src.values())
    assert "slack_on" not in text and "slack_max" not in text and "W_MAX" not in text


def test_slack_formula():
    lam = np.array([0.0, 500.0, 1500.0, 3000.0])
    l1 = np.full(4, 1000.0)
    w = np.array([5e-4, 5e-4, 5e-4, 0.0])  # 1 / (2 l2), l2 = 1000; the last row hard
    assert np.array_equal(multiplier_slack(lam, l1, w), [0.0, 0.0, 0.25, 0.0])


# --------------------------------------------------------------------------- closed loop
@pytest.fixture(scope="module", params=["double", "float"])
def soft_run(request, build_root):
    built = Built(SOFT, request.param, build_root)
    lock = Lockstep(built)
    infos = []

    class Recorded:
        def step(self, y, s, r):
            st, u = lock.step(y, s, r)
            infos.append((lock.c.info(), dict(lock.ref.last)))
            return st, u

        info = staticmethod(lock.info)

    log = run_closed_loop(built.model.config, Recorded(), disturbance=PUSH, info=lock.info)
    return built, lock, log, infos


def test_step_bit_exact_with_slacks_in_use(soft_run):
    built, lock, log, infos = soft_run
    assert lock.mismatches == [], f"{len(lock.mismatches)} mismatching steps, first: " \
                                  f"{lock.mismatches[0]}"
    assert np.all(log.status == OPTIMAL)
    assert np.all(np.abs(log.u) <= U_MAX) and np.any(np.abs(log.u) == U_MAX)
    c_slack = np.array([c["slack_max"] for c, _ in infos])
    r_slack = np.array([r["slack_max"] for _, r in infos])
    assert np.array_equal(c_slack.astype(built.model.dtype), r_slack.astype(built.model.dtype))
    assert [c["slack_rows"] for c, _ in infos] == [r["slack_rows"] for _, r in infos]
    assert np.count_nonzero(c_slack > 0) >= 20 and c_slack.max() > 0.1
    assert np.abs(log.y).max() > BOUND + 0.1  # the unknown push does exceed the bound


def _slack_states(built, lock, infos, count=8):
    """Lockstep states whose plan has a positive slack, with their preview."""
    ny, N = built.ctx["n_outputs"], built.ctx["horizon"]
    reference = scenario_reference(built.model.config)
    ks = [k for k, (c, _) in enumerate(infos) if c["slack_max"] > 0]
    picks = np.linspace(0, len(ks) - 1, count).astype(int)
    return [(lock.states[ks[i]][1], preview(reference, lock.states[ks[i]][2], N, ny))
            for i in picks]


def test_double_matches_the_explicit_slack_qp(soft_run):
    built, lock, _, infos = soft_run
    if built.ctx["precision"] != "double":
        pytest.skip("the 1e-8 agreement is a double-precision check")
    daqp = pytest.importorskip("daqp", reason="install with: pip install 'rollmpc-codegen[peers]'")
    qp = built.model.modes[0].qp
    c = built.fresh_c()
    worst_daqp = worst_exact = worst_slack = 0.0
    for x, r in _slack_states(built, lock, infos):
        st, U, _ = c.solve_qp(0, x, r)
        assert st == OPTIMAL
        data = qp_data(qp, x, r)
        m = data.b.size
        sol, _, flag, _ = daqp.solve(data.E, data.f.astype(float), data.L, data.b.astype(float),
                                     np.full(m, -1e30), np.zeros(m, dtype=np.intc))
        exact = solve_exact(data)
        assert flag == 1 and exact.status == "optimal"
        worst_daqp = max(worst_daqp, float(np.abs(U - sol[:qp.n]).max()))
        worst_exact = max(worst_exact, float(np.abs(U - exact.U).max()))
        s_exact = sol[qp.n:].max()  # the explicit slacks (DAQP's, to its precision)
        assert s_exact > 1e-6
        worst_slack = max(worst_slack, abs(c.info()["slack_max"] - s_exact))
    assert worst_daqp <= 1e-8 and worst_exact <= 1e-8, (worst_daqp, worst_exact)
    assert worst_slack <= 1e-8, worst_slack


@pytest.mark.parametrize("solver", [
    {"polish_first": False},  # the dual active set (then the polish) alone
    {"polish": False, "max_iterations": 50000, "delta": 1e-24},  # the sweeps alone
], ids=["active_set", "sweeps"])
def test_other_solver_paths_on_slack_qps(soft_run, solver, tmp_path):
    built, lock, _, infos = soft_run
    prec = built.ctx["precision"]
    if "polish" in solver and prec == "float":
        pytest.skip("float sweeps stall at the float step size long before a 1e-24 delta")
    other = Built(edited_config(tmp_path, SOFT, "path", _solver(**solver)), prec, built.build_root)
    c = other.fresh_c()
    ref = SolverRef(other.model.modes[0].data, other.ctx["solver"])
    base = built.fresh_c()
    worst = 0.0
    for x, r in _slack_states(built, lock, infos, count=5):
        st_c, U_c, its = c.solve_qp(0, x, r)
        st_r, U_r, its_r, _, _ = ref.solve_mode(x, r)
        assert st_c == st_r and U_c.tobytes() == U_r.tobytes() and its == its_r
        assert st_c == OPTIMAL
        if "polish" not in solver:
            assert its == 0  # no sweep: the dual active set finished
        st_b, U_b, _ = base.solve_qp(0, x, r)
        worst = max(worst, float(np.abs(U_c - U_b).max()))
    tol = ({"double": 1e-8, "float": 2e-3}[prec] if "polish" not in solver
           else 1e-5)  # the sweeps stop at the delta test: less exact than a polish
    assert worst <= tol, worst


# --------------------------------------------------------------------------- exact, feasible
def test_l1_penalty_is_exact_where_the_hard_bounds_hold(build_root, tmp_path):
    """Undisturbed: the hard 0.4 m bounds can hold on every sample, so the soft plan is
    the hard plan (l1 = 1000 is above every multiplier they need) and no slack is used."""
    soft = Built(SOFT, "double", build_root)
    hard = Built(edited_config(tmp_path, SOFT, "hard", _hard), "double", build_root)
    cs, ch = soft.fresh_c(), hard.fresh_c()
    worst, slack = 0.0, 0.0

    class Both:
        def step(self, y, s, r):
            st, u = cs.step(y, s, r)
            st_h, u_h = ch.step(y, s, r)
            assert st == st_h == OPTIMAL
            nonlocal worst, slack
            worst = max(worst, float(np.abs(u - u_h).max()))
            slack = max(slack, cs.info()["slack_max"])
            return st, u

        info = staticmethod(cs.info)

    log = run_closed_loop(soft.model.config, Both(), info=cs.info)
    assert np.abs(log.y).max() > BOUND - 1e-3  # the 0.5 m level drives masses to the bound
    assert slack == 0.0 and worst <= 1e-9, (slack, worst)


@pytest.mark.parametrize("precision", ["double", "float"])
def test_always_feasible_where_the_hard_qp_is_not(build_root, tmp_path, precision):
    """The push of 0.3 N drives the chain metres past the bound: the hard QP is
    INFEASIBLE on most samples; the soft one stays feasible (OPTIMAL in double). In float,
    slacks of metres (multipliers ~5e3) defeat the 1e-4 feasibility check of the dual
    polish on most samples (docs/features.md): MAX_ITER, still a finite command."""
    soft = Built(SOFT, precision, build_root)
    hard = Built(edited_config(tmp_path, SOFT, "hard", _hard), precision, build_root)
    logs = {}
    for name, built in (("soft", soft), ("hard", hard)):
        c = built.fresh_c()
        logs[name] = run_closed_loop(built.model.config, c, disturbance=HARD_PUSH, info=c.info)
    assert np.count_nonzero(logs["hard"].status == INFEASIBLE) > 100
    assert not np.any(logs["soft"].status == INFEASIBLE)
    if precision == "double":
        assert np.all(logs["soft"].status == OPTIMAL)
    for log in logs.values():
        assert np.all(np.isfinite(log.u)) and np.all(np.abs(log.u) <= U_MAX)


# --------------------------------------------------------------------------- config
@pytest.mark.parametrize("soft, key, text", [
    ({"y_max": {"l1": 10, "l2": 0}}, "modes[0].bounds.soft.y_max.l2", "must be > 0 where l1"),
    ({"y_max": {"l1": -1, "l2": 1}}, "modes[0].bounds.soft.y_max.l1", "must be >= 0"),
    ({"y_max": {"l1": 1, "l2": [1, 1]}}, "modes[0].bounds.soft.y_max.l2", "must have 6"),
    ({"y_max": {"l1": 1}}, "modes[0].bounds.soft.y_max.l2", "missing"),
    ({"y_max": {"l1": 1, "l2": 1, "l3": 1}}, "modes[0].bounds.soft.y_max.l3", "unknown"),
    ({"u_max": {"l1": 1, "l2": 1}}, "modes[0].bounds.soft.u_max", "unknown"),
    ({"y_max": {"l1": 0, "l2": 0}}, "modes[0].bounds.soft", "softens no bound"),
])
def test_config_errors_name_the_key(tmp_path, soft, key, text):
    err = config_error(edited_config(tmp_path, SOFT, "bad", edit_bounds(soft=soft)))
    assert err.key == key and text in str(err)


def test_soft_bound_needs_a_finite_bound(tmp_path):
    err = config_error(edited_config(tmp_path, SOFT, "inf", edit_bounds(y_max=[0.4] * 5 + ["inf"])))
    assert err.key == "modes[0].bounds.soft.y_max" and "no finite y_max" in str(err)


def test_per_output_choice_keeps_the_others_hard(tmp_path):
    l2 = [1000, 0, 0, 0, 0, 0]
    model, _ = load_model(edited_config(tmp_path, SOFT, "one", edit_bounds(
        soft={"y_max": {"l1": [1000, 0, 0, 0, 0, 0], "l2": l2}})))
    qp = model.modes[0].qp
    soft = np.flatnonzero(qp.soft_l2 > 0)
    assert soft.size == qp.N and np.all(qp.row_sign[soft] > 0)
    assert np.all(qp.row_index[soft] % qp.ny == 0)


def test_simulate_reports_the_slack(tmp_path):
    from conftest import cli

    code, out, err = cli(["simulate", str(SOFT), "--disturbance", str(PUSH),
                          "--json", str(tmp_path / "s.json")])
    assert code == 0, err
    line = next(l for l in out.splitlines() if "soft output bounds" in l)
    assert "in 61 samples" in line and "max slack 0.208" in line
    import json
    sb = json.loads((tmp_path / "s.json").read_text())["soft_bounds"]
    assert sb["samples_with_slack"] == 61 and abs(sb["max_slack"] - 0.2078) < 1e-3
