"""A TIME_LIMIT with nothing better than th0 falls back to the mode's last plan, shifted one
stage (docs/solver.md, "Work budget"): bit for bit in the host C and the reference, for at
most horizon - 1 samples in a row, never across modes; and in a closed loop whose
manoeuvres outrun the budget the hard output bounds then hold, where th0 broke them."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import Built, short_uav_config

QUAD = Path(__file__).resolve().parents[2] / "examples" / "quad_attitude.yaml"
HORIZON = 20


def tight_uav(tmp: Path, build_root: Path, name: str, **top) -> Built:
    """The UAV at N = 20 (with the top-level keys ``top``) given the smallest budget the
    generator accepts (the unconstrained step and finish()) and no warm start: any QP with
    an active bound stops at TIME_LIMIT before the dual active set has a point. (With a
    warm start the working set kept from each TIME_LIMIT grows, and a later sample's dual
    active set returns its own point.)"""
    import yaml

    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.qp.work import base_work

    path = short_uav_config(tmp, HORIZON, name, warm_start=False)
    data = {**yaml.safe_load(path.read_text()), **top}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    model, _ = load_model(path, "double")
    data["solver"]["work_budget"] = max(base_work(m.data, m.data.has_output_rows)
                                        for m in model.modes)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return Built(path, "double", build_root)


@pytest.fixture(scope="module")
def tight(tmp_path_factory, build_root):
    return tight_uav(tmp_path_factory.mktemp("tight"), build_root, "uav_tight")


def shifted(U, nu=1):
    """The plan one stage later, its last stage held."""
    return np.concatenate((U[nu:], U[-nu:]))


def test_time_limit_shifts_the_last_plan_for_horizon_minus_one_samples(tight):
    from rollmpc_codegen.status import OPTIMAL, TIME_LIMIT

    c, ref = tight.fresh_c(), tight.reference()
    nx = tight.model.modes[0].data.nx

    def both(mode, x, r):
        st_c, U_c, _ = c.solve_qp(mode, x, r)
        st_r, U_r, *_ = ref.solvers[mode].solve_mode(x, r)
        assert int(st_c) == int(st_r) and U_c.tobytes() == U_r.tobytes()
        return int(st_c), U_c

    x = np.zeros(nx)
    status, plan = both(0, x, np.full(HORIZON, 0.2))  # a small step: no bound active
    assert status == OPTIMAL and np.abs(plan).max() > 0
    saturating = np.full(HORIZON, 80.0)
    fallbacks = 0
    for _ in range(HORIZON + 2):
        status, U = both(0, x, saturating)
        assert status == TIME_LIMIT
        if not np.array_equal(U, shifted(plan)):
            break
        fallbacks, plan = fallbacks + 1, U
    assert fallbacks == HORIZON - 1  # then the plan has run out: th0, clamped
    assert np.abs(U).max() == 15.0  # th0 of an 80 deg step saturates the aileron

    # a plan of mode 0 is never another mode's: mode 1 falls back to its own th0
    status, plan = both(0, x, np.full(HORIZON, 0.2))
    assert status == OPTIMAL
    nx1 = tight.model.modes[1].data.nx
    status, U = both(1, np.zeros(nx1), saturating)
    fresh = tight.fresh_c()
    assert status == TIME_LIMIT and U.tobytes() == fresh.solve_qp(1, np.zeros(nx1), saturating)[1].tobytes()


BLOCKS = [1, 1, 2, 4, 12]  # N = 20: blocks of one stage, and longer ones


@pytest.fixture(scope="module")
def tight_blocked(tmp_path_factory, build_root):
    """A block of one stage takes the next block's value, a longer block keeps its own."""
    return tight_uav(tmp_path_factory.mktemp("tight_blocked"), build_root,
                     "uav_blocked_tight", move_blocking=BLOCKS)


def test_blocked_plans_shift_block_by_block(tight_blocked):
    from rollmpc_codegen.status import OPTIMAL, TIME_LIMIT

    c, ref = tight_blocked.fresh_c(), tight_blocked.reference()
    x = np.zeros(tight_blocked.model.modes[0].data.nx)
    st, plan, _ = c.solve_qp(0, x, np.full(HORIZON, 0.2))
    assert int(st) == OPTIMAL and plan.size == len(BLOCKS) and len(set(plan)) == len(BLOCKS)
    ref.solvers[0].solve_mode(x, np.full(HORIZON, 0.2))
    st, U, _ = c.solve_qp(0, x, np.full(HORIZON, 80.0))
    st_r, U_r, *_ = ref.solvers[0].solve_mode(x, np.full(HORIZON, 80.0))
    assert int(st) == int(st_r) == TIME_LIMIT and U.tobytes() == U_r.tobytes()
    # blocks 0 and 1 (one stage each) take blocks 1 and 2; 2, 3 and 4 keep their own
    assert np.array_equal(U, plan[[1, 2, 2, 3, 4]])


def test_tilt_limits_hold_through_the_time_limited_manoeuvre(build_root):
    """quad_attitude's nominal closed loop (float, default budget): its hardest samples stop
    at TIME_LIMIT (35 of 1050), and with the shifted plan as their command roll and pitch
    stay within the hard 30 deg (with th0 they reached 53.5 deg)."""
    from rollmpc_codegen.sim.simulate import run_closed_loop
    from rollmpc_codegen.status import TIME_LIMIT

    built = Built(QUAD, "float", build_root)
    log = run_closed_loop(built.model.config, built.fresh_c())
    assert np.count_nonzero(log.status == TIME_LIMIT) >= 20
    assert np.abs(log.y[:, :2]).max() <= 30.0 * (1 + 1e-4)


def test_inputs_only_time_limit_commands_the_polish_point(tmp_path, build_root):
    """In a mode whose rows are all input bounds (the UAV without its roll bounds), a
    TIME_LIMIT after the primal polish has solved a working set commands that point, not
    the plan: clamped it meets every row, and after a step it is this sample's answer. Bit
    for bit in the C and the reference, at a budget the reference finds for the step."""
    import yaml

    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.qp.work import base_work
    from rollmpc_codegen.reference.controller import ControllerRef
    from rollmpc_codegen.status import OPTIMAL, TIME_LIMIT

    path = short_uav_config(tmp_path, HORIZON, "uav_inputs_only", warm_start=False)
    data = yaml.safe_load(path.read_text())
    for mode in data["modes"]:
        mode["bounds"] = {k: v for k, v in mode["bounds"].items() if k.startswith("u_")}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    model, ctx = load_model(path, "double")
    x = np.zeros(model.modes[0].data.nx)
    small, step = np.full(HORIZON, 0.2), np.full(HORIZON, 80.0)

    def solve_at(budget):
        ref = ControllerRef({**ctx, "solver": {**ctx["solver"], "work_budget": budget}},
                            [m.data for m in model.modes])
        solver = ref.solvers[0]
        plan = solver.solve_mode(x, small)
        return plan, solver.solve_mode(x, step), solver

    least = max(base_work(m.data, True) for m in model.modes)  # at least what generate takes
    for budget in range(least, 200000, 100):  # the first that stops after a primal solve
        (st0, plan, *_), (st, U, *_), solver = solve_at(budget)
        if st0 == OPTIMAL and st == TIME_LIMIT and solver.th_solved is not None:
            break
    else:
        pytest.fail("no budget stops the step's QP after a primal solve")
    assert solver.inputs_only() and not np.array_equal(U, shifted(plan))
    assert U[0] == 15.0 and abs(plan[1]) < 5.0  # the step's answer, not the old level's

    data["solver"]["work_budget"] = budget
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    c = Built(path, "double", build_root).fresh_c()
    assert int(c.solve_qp(0, x, small)[0]) == OPTIMAL
    st_c, U_c, _ = c.solve_qp(0, x, step)
    assert int(st_c) == TIME_LIMIT and U_c.tobytes() == U.tobytes()
