"""The signal row kind (general constraints: features/signals.py, templates/solver/signals.c.j2,
reference/signals.py) on the three designs of tests/data/constraints/:

* quad_rates: a quadrotor with body-rate bounds on states no output measures and a
  total-thrust mixed row;
* motor_current: a DC motor whose measured output is the speed, its current bounded;
* servo_terminal: a position servo with an LQR-invariant terminal set.

Each is checked C against reference bit for bit (double and float, the signal rows
active), against an independent QP (tests/independent_constraints.py) to 1e-9 in
double, and in closed loop with its bounds held on the simulated plant; the terminal set
is checked invariant under its law.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import Built
from rollmpc_codegen.qp.rows import SIGNAL
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.status import OPTIMAL

DATA = Path(__file__).resolve().parents[1] / "data" / "constraints"
# per design: the steps of a reference that presses its constraints at once, and samples
STEPS = {"quad_rates": ([[0, 0, 0, 0], [25, -25, 0, 0], [-25, 25, 0, 0]], 40),
         "motor_current": ([[0], [300], [-300]], 60),
         "servo_terminal": ([[0], [0.6], [-0.3]], 60)}


def pressing_reference(design: str) -> np.ndarray:
    levels, hold = STEPS[design]
    return np.repeat(np.array(levels, float), hold, axis=0)


@pytest.fixture(scope="module")
def builds(build_root):
    cache = {}

    def get(design: str, precision: str) -> Built:
        if (design, precision) not in cache:
            cache[design, precision] = Built(DATA / f"{design}.yaml", precision, build_root)
        return cache[design, precision]
    return get


class LockstepWithStates:
    """C and reference on the same inputs; the differences, the solver's inputs (x, r) and
    how many signal rows the reference's solutions make active."""

    def __init__(self, built: Built):
        self.c, self.ref = built.fresh_c(), built.reference()
        self.signal = built.model.modes[0].data.row_kinds == SIGNAL.code
        self.mismatches, self.qps, self.active_signal_rows = [], [], 0

    def step(self, y, s, r):
        st_c, u_c = self.c.step(y, s, r)
        x = self.ref.xhat[self.ref.mode].copy()
        st_r, u_r = self.ref.step(y, s, r)
        info = self.c.info()
        if (st_c, u_c.tobytes(), info["work"]) != (st_r, u_r.tobytes(), self.ref.last["work"]):
            self.mismatches.append((len(self.qps), st_c, st_r))
        active = int(np.count_nonzero((self.ref.solvers[0].lam > 0) & self.signal))
        self.active_signal_rows += active
        self.qps.append((x, np.array(r, float), active))
        return st_c, u_c


def lockstep(built: Built, design: str) -> LockstepWithStates:
    run = LockstepWithStates(built)
    ref = pressing_reference(design)
    run_closed_loop(built.model.config, run, reference=ref, steps=len(ref))
    return run


@pytest.mark.parametrize("precision", ["double", "float"])
@pytest.mark.parametrize("design", sorted(STEPS))
def test_c_and_reference_agree_bit_for_bit_with_signal_rows_active(builds, design, precision):
    run = lockstep(builds(design, precision), design)
    assert run.mismatches == []
    assert run.active_signal_rows > 0  # the closed loop leans on the signal rows


def _independent(built: Built, design: str):
    from independent_constraints import IndependentQPWithSignals
    from independent_qp import ModeSpec

    doc = yaml.safe_load((DATA / f"{design}.yaml").read_text())
    N = int(doc["horizon"])
    terminal = None
    qp = built.model.modes[0].qp
    if qp.signals is not None and any(s.source == "terminal" and doc["modes"][0]["constraints"]
                                      ["terminal"] == "lqr_invariant" for s in qp.signals.signals):
        facets = [s for s in qp.signals.signals if s.source == "terminal"]
        terminal = (np.array([s.Cz for s in facets]), np.array([s.Rz for s in facets]),
                    np.array([s.hi for s in facets]))
    return IndependentQPWithSignals(ModeSpec.from_yaml(doc, 0), built.ctx["modes"][0], N,
                                    doc["modes"][0], terminal)


@pytest.mark.parametrize("design", sorted(STEPS))
def test_plans_match_an_independent_qp(builds, build_root, tmp_path, design):
    """Each QP solved cold by P_solve_qp, without a work budget (what is checked is the
    solution, not its time), against DAQP on the independent formulation."""
    pytest.importorskip("daqp", reason="install with: pip install 'rollmpc-codegen[peers]'")
    from conftest import edited_config

    run = lockstep(builds(design, "double"), design)
    unbudgeted = edited_config(tmp_path, DATA / f"{design}.yaml", design,
                               lambda d: d.setdefault("solver", {}).update(work_budget=10**9))
    built = Built(unbudgeted, "double", build_root)
    ind = _independent(built, design)
    busy = [q for q in run.qps if q[2] > 0]
    assert busy, "no QP with an active signal row"
    c = built.fresh_c()
    worst = 0.0
    for x, r, _ in busy[::max(1, len(busy) // 8)][:8]:
        status, U, _ = c.solve_qp(0, x, r)
        flag, U_ind = ind.solve(x, r)
        assert status == OPTIMAL and flag == 1
        worst = max(worst, float(np.abs(U - U_ind).max() / max(1.0, np.abs(U_ind).max())))
    assert worst <= 1e-9


def plant_signals(built: Built, log) -> list[tuple]:
    """(values over the run, lo, hi, soft) of each configured signal on the simulated
    plant's states (the config's model, from rest, under the logged commands)."""
    from rollmpc_codegen.model.plant import discretise

    cfg = built.model.config
    mode = cfg.modes[0]
    disc = discretise(mode, cfg.sample_time, "modes[0]")
    x = np.zeros(disc.nx)
    states, inputs = [], []
    for u in log.u:
        states.append(x.copy())
        inputs.append(u)
        x = disc.A @ x + disc.B @ u
    states.append(x)
    out = []
    for s in mode.signals:
        c = np.r_[s.C, np.zeros(disc.nx - s.C.size)]
        d = np.r_[s.D, np.zeros(disc.nu - s.D.size)]
        z = np.array([c @ xk + d @ uk for xk, uk in zip(states, inputs)])
        out.append((z, s.lo, s.hi, bool(np.any(s.soft_l2 > 0))))
    return out


@pytest.mark.parametrize("design", sorted(STEPS))
def test_closed_loop_holds_the_signal_bounds(builds, design):
    built = builds(design, "double")
    ref = pressing_reference(design)
    log = run_closed_loop(built.model.config, built.fresh_c(), reference=ref, steps=len(ref))
    assert np.mean(log.status == OPTIMAL) >= 0.95
    hard = [(z, lo, hi) for z, lo, hi, soft in plant_signals(built, log) if not soft]
    assert hard  # each design has a hard signal bound
    for z, lo, hi in hard:
        scale = max([1.0] + [abs(b) for b in (lo, hi) if np.isfinite(b)])
        assert z.min() >= lo - 1e-6 * scale and z.max() <= hi + 1e-6 * scale
    # the loop's own reading of the hard signals (sim/signal_bounds.py, what simulate
    # counts) is this independent one, sample for sample
    ours = {s.name: log.z[:, i] for i, s in enumerate(log.signals)}
    mine = {s.name: z for s, (z, _, _, soft) in
            zip(built.model.config.modes[0].signals, plant_signals(built, log)) if not soft}
    assert ours.keys() == mine.keys()
    for name, z in mine.items():
        np.testing.assert_allclose(ours[name], z, rtol=1e-12, atol=1e-12)


def test_terminal_set_is_invariant_under_its_law(builds):
    """Points of the LQR-invariant set stay in it, within every hard bound, under the
    terminal law (model/terminal_law.py) with the reference held."""
    from rollmpc_codegen.model.terminal_law import tracking_law

    built = builds("servo_terminal", "double")
    mode, plant = built.model.config.modes[0], built.model.modes[0].plant
    facets = [s for s in built.model.modes[0].qp.signals.signals if s.source == "terminal"]
    Hx, Hr, h = (np.array([s.Cz for s in facets]), np.array([s.Rz for s in facets]),
                 np.array([s.hi for s in facets]))
    law = tracking_law(plant.A, plant.B, plant.C, mode.Q, mode.R, plant.disturbance_states)
    Kx, Kr = law.affine(plant.nx, plant.ny)
    rng = np.random.default_rng(7)
    inside = 0
    for _ in range(4000):
        x, r = rng.uniform(-3, 3, plant.nx) * [1, 0.3], rng.uniform(-2.9, 2.9, 1)
        if not np.all(Hx @ x + Hr @ r <= h):
            continue
        inside += 1
        for _ in range(60):
            u = Kx @ x + Kr @ r
            assert np.all(np.abs(u) <= 1 + 1e-9) and abs(x[1]) <= 0.8 + 1e-9
            assert abs(plant.C @ x)[0] <= 3 + 1e-9
            x = plant.A @ x + plant.B @ u
            assert np.all(Hx @ x + Hr @ r <= h + 1e-9)
    assert inside >= 50  # enough of the samples fell in the set to mean something


def test_existing_kinds_have_no_signal_block(builds):
    """A design without constraints has no signal data: its C is the one before the kind."""
    from rollmpc_codegen.pipeline import load_model

    model, ctx = load_model(Path(__file__).resolve().parents[2] / "examples" / "chain_soft.yaml")
    assert model.modes[0].qp.signals is None and "has_signal_rows" not in ctx


def test_no_solve_passes_its_budget_on_a_loop_of_signal_rows(build_root, tmp_path):
    """A heavy design whose certificate reads signal bounds (tests/data/heavy/pmsm_speed
    with an LQR-invariant terminal set, 0.85 of Ts): on an envelope flight with noise and
    mismatch every solve stays within the work budget. scan_work() without the
    certificate's nzq let 7 of these samples pass it (by up to 52 units)."""
    from conftest import edited_config
    from rollmpc_codegen.sim.flight_plan import FlightPlan

    def edit(d):
        d["solver"]["budget_share"] = 0.85
        d["modes"][0]["constraints"]["terminal"] = "lqr_invariant"
    cfg_path = edited_config(tmp_path, DATA.parent / "heavy" / "pmsm_speed.yaml", "pmsm_tl", edit)
    built = Built(cfg_path, "float", build_root)
    cfg, c = built.model.config, built.fresh_c()
    plan = FlightPlan(flights=1, seed=107, noise_std=0.5, mismatch=0.2)
    works = []
    log = run_closed_loop(cfg, c, **plan.loop_options(plan.plan(cfg, None)[0]),
                          info=lambda: works.append(c.info()["work"]) or c.info())
    budget = built.ctx["solver"]["work_budget"]
    assert max(works) <= budget
    # the budget binds: measured 16 samples within 100 units of it and 141 TIME_LIMIT
    assert np.count_nonzero(np.array(works) >= budget - 100) >= 10
    assert np.all(np.isfinite(log.u))
