"""fallback_point() (templates/solver/qp_solve.c.j2, reference/solver.py): a TIME_LIMIT
sample with no point of its own commands the last OPTIMAL plan shifted one stage per
sample since, its last stage held. On the nominal model (no noise, no mismatch: the state
goes where the plan predicted) that plan meets every hard row of each later sample's QP on
the stages it still plans, stage s being the optimal plan's stage s + age: it stays
feasible sample after sample for its life. The held tail is not planned and is not
feasible in general, which is why the plan is given up after N - 1 samples (docs/solver.md,
"Work budget"; issue 44, item 2).

tests/data/heavy/pmsm_speed.yaml without a budget plans its q current at the 10 A bound
over many stages after a speed step; from an OPTIMAL sample there, the solver is forced to
fall back (a budget of 0 on the samples after it). The rows are checked as the condensed
QP states them (L U <= c + W x + Wr R), not as the solver stores them."""
from __future__ import annotations

import numpy as np

from conftest import ROOT, edited_config
from rollmpc_codegen.pipeline import load_model
from rollmpc_codegen.qp.rows import OUTPUT, SIGNAL
from rollmpc_codegen.reference.controller import ControllerRef
from rollmpc_codegen.reference.solver import SolverRef
from rollmpc_codegen.sim.scenario import scenario_reference
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.status import OPTIMAL, TIME_LIMIT

PMSM = ROOT / "tests" / "data" / "heavy" / "pmsm_speed.yaml"
TIGHT = 1e-3  # a row within this of its bound is tight


def _row_stages(qp) -> np.ndarray:
    """The stage of each row's quantity: an input's, an output's, a signal's Markov stage."""
    stage = np.where(qp.row_kind == OUTPUT.code, qp.row_index // qp.ny, qp.row_index // qp.nu)
    if qp.signals is not None:
        sig = qp.row_kind == SIGNAL.code
        idx = np.clip(qp.row_index, 0, qp.signals.nzq - 1)
        stage = np.where(sig, qp.signals.stage[idx], stage)
    return stage


def _excess(qp, x, r, U):
    rhs = qp.c + qp.W @ x + (0 if qp.Wr is None else qp.Wr @ r.reshape(-1))
    return (qp.L @ U - rhs) / np.maximum(1.0, np.abs(rhs))


def _forced_fallbacks(tmp_path, monkeypatch):
    """The nominal loop without a budget, forced to fall back on the N samples after
    the first OPTIMAL one whose plan holds tight q-current rows: per sample (x, R, status,
    from_plan, the plan's age before it, U), the model's QP and config."""
    path = edited_config(tmp_path, PMSM, "pmsm_unbudgeted",
                         lambda d: d["solver"].update(work_budget=1_000_000_000))
    model, ctx = load_model(path, "float")
    cfg, qp, budget = model.config, model.modes[0].qp, ctx["solver"]["work_budget"]
    signal_rows = qp.row_kind == SIGNAL.code
    solve, samples, forced = SolverRef.qp_solve, [], []

    def recording(self, x, r):
        k = len(samples)
        self.budget = 0 if forced and forced[0] < k <= forced[0] + cfg.horizon else budget
        age = self.last_plan.age  # samples since the plan was optimal, before this one
        out = solve(self, x, r)
        x, r, U = np.array(x, float), np.array(r, float), np.array(out[1], float)
        samples.append((x, r, out[0], self.from_plan, age, U))
        if not forced and out[0] == OPTIMAL and k > 100:  # past the start's transient
            if np.count_nonzero(signal_rows & (_excess(qp, x, r, U) > -TIGHT)) >= 5:
                forced.append(k)
        return out

    monkeypatch.setattr(SolverRef, "qp_solve", recording)
    ref = ControllerRef(ctx, [m.data for m in model.modes])
    run_closed_loop(cfg, ref, steps=len(scenario_reference(cfg)))
    assert forced, "no OPTIMAL plan with tight q-current rows"
    return qp, cfg, forced[0], samples


def test_the_shifted_plan_keeps_every_hard_row_it_still_plans(tmp_path, monkeypatch):
    qp, cfg, k0, samples = _forced_fallbacks(tmp_path, monkeypatch)
    horizon, tol = cfg.horizon, cfg.feasibility_tol  # relative to max(1, |rhs|)
    nu, stage = qp.nu, _row_stages(qp)
    optimal_plan = samples[k0][5]
    tight_checked = 0
    for age in range(1, horizon):
        x, r, status, from_plan, age_before, U = samples[k0 + age]
        assert (status, from_plan, age_before) == (TIME_LIMIT, True, age - 1)
        held = np.tile(optimal_plan[-nu:], age)  # the receding horizon, stated independently
        assert np.array_equal(U, np.concatenate((optimal_plan[age * nu:], held)).astype(U.dtype))
        excess = _excess(qp, x, r, U)
        planned = stage <= horizon - 1 - age
        assert excess[planned].max() <= tol, (age, excess[planned].max())
        tight_checked += np.count_nonzero(planned & (qp.row_kind == SIGNAL.code)
                                          & (excess > -TIGHT))
    assert tight_checked >= 20  # q-current rows at their bound are among those held
    # past its life (N - 1 samples) the plan is given up: the sample commands th0 instead
    assert samples[k0 + horizon][2:5] == (TIME_LIMIT, False, horizon - 1)
