"""The float check of ``rollmpc generate --precision float`` (host/float_check.py): the
figure on designs of our own, not the committed examples; the warning where float does
not serve the design; the floor build equal to float_floor's stored-data floor; and a
check that cannot make generation fail."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from rollmpc_codegen.cli.main import main
from rollmpc_codegen.host.build import build_host_controller
from rollmpc_codegen.host.float_check import (FLOAT_ERROR_LIMIT, FloatCheck, check_float,
                                              double_twin, floor_context)
from rollmpc_codegen.pipeline import load_model, load_model_from_config
from rollmpc_codegen.qp.work import UNBOUNDED_WORK
from rollmpc_codegen.status import OPTIMAL
from rollmpc_codegen.verify.float_floor import stored_data_floor

# two inputs on two coupled integrating outputs, R = 0 with Δu weighting only, a hard
# roll bound below a level of the scenario: float accepts plans whose later moves are
# 1e-2 off double's (the kind of design a new user wrote)
TWIN = """\
prefix: twin
sample_time: 0.02
horizon: 40
outputs: [roll, yaw]
actuators: [a, b]
modes:
  - name: only
    actuators: [a, b]
    plant:
      state_space: {A: [[-2, 0.5], [0.3, -1]], B: [[4, 3], [1, -1]], C: [[1, 0], [0, 1]]}
      integrator: true
    weights: {Q: [1, 4], R: 0, R_delta: [0.5, 0.5], P: [1, 4]}
    bounds: {u_min: [-25, -30], u_max: [25, 30], y_min: [-35, -.inf], y_max: [35, .inf]}
simulation:
  reference: {segment: 4.0, levels: [0, [30, 0], [-30, 0], [45, 0], 0]}
"""
# the UAV's inner loop alone, also R = 0 with Δu weighting only: float serves it
ROLL = """\
prefix: rollrd
sample_time: 0.01
horizon: 60
outputs: [roll]
actuators: [ail]
modes:
  - name: only
    actuators: [ail]
    plant:
      transfer_function: {num: [-74.15, 8892], den: [1, 59.11, 1599, 7936]}
      integrator: true
    weights: {Q: 10, R: 0, R_delta: 1, P: 1000}
    bounds: {u_min: -15, u_max: 15, y_min: -45, y_max: 45}
simulation:
  reference: {segment: 3.0, levels: [0, 30, -30, 60, 0]}
"""
CHAIN_SOFT = Path(__file__).resolve().parents[2] / "examples" / "chain_soft.yaml"
FIGURE = re.compile(r"float plans within (\S+) of double \(first moves (\S+)\), stored-data "
                    r"floor (\S+),.* (\d+) of 48 not OPTIMAL in float")


def _generate(tmp_path, capsys, text: str, *extra: str):
    cfg = tmp_path / "design.yaml"
    cfg.write_text(text)
    out = tmp_path / "out"
    code = main(["generate", str(cfg), "--precision", "float", "-o", str(out), *extra])
    return code, out, capsys.readouterr()


def test_float_check_warns_on_a_design_float_does_not_serve(tmp_path, capsys):
    # the TWIN design warned (0.033) until the dual active set kept its factor by updates
    # (1.7e-5 since); chain_soft's soft rows still leave float 4.5e-3 off double
    code, out, cap = _generate(tmp_path, capsys, CHAIN_SOFT.read_text())
    assert code == 0 and (out / "chain_soft_data.c").is_file()  # warned, not refused
    line = next(ln for ln in cap.out.splitlines() if "float check" in ln)
    assert "(40 scenario + 8 perturbed QPs, " in line
    error, first, floor, not_optimal = FIGURE.search(line).groups()
    assert float(error) > 2 * FLOAT_ERROR_LIMIT  # measured 4.5e-3
    assert float(floor) < FLOAT_ERROR_LIMIT  # the data are fine: float arithmetic is not
    assert float(first) <= float(error)
    warning = cap.err.strip()
    assert warning.startswith("rollmpc: warning: float is not accurate enough for this "
                              "design: a plan is ")
    assert "mostly float arithmetic" in warning and warning.count("\n") == 0
    assert "use --precision double (docs/reliability.md, \"Float\"), at a cost on the target: " \
        "the Cortex-M4F computes in single precision only, so double is soft-float, 7-22 " \
        "times the float build's cycles" in warning


@pytest.mark.slow
def test_float_check_is_quiet_where_float_serves(tmp_path, capsys):
    code, _, cap = _generate(tmp_path, capsys, ROLL)
    assert code == 0 and cap.err == ""
    error, first, floor, not_optimal = FIGURE.search(cap.out).groups()
    assert float(error) < 1e-4 and float(floor) < 1e-4 and not_optimal == "0"


def test_no_float_check_and_double_print_no_check(tmp_path, capsys):
    code, _, cap = _generate(tmp_path, capsys, ROLL, "--no-float-check")
    assert code == 0 and "float check" not in cap.out + cap.err
    cfg = tmp_path / "design.yaml"
    assert main(["generate", str(cfg), "-o", str(tmp_path / "d")]) == 0
    assert "float check" not in capsys.readouterr().out


def test_a_failing_check_only_warns(tmp_path, capsys, monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("gcc: not found\nmore")

    monkeypatch.setattr("rollmpc_codegen.host.float_check.check_float", broken)
    code, out, cap = _generate(tmp_path, capsys, ROLL)
    assert code == 0 and (out / "rollrd_solver.c").is_file()
    assert cap.err == "rollmpc: warning: float check not run (RuntimeError: gcc: not found)\n"


@pytest.mark.slow
def test_floor_build_is_the_stored_data_floor(tmp_path):
    """The floor build (double C on the float-stored numbers) solves as
    float_floor.stored_data_floor's reference does, bit for bit, on a constrained QP."""
    cfg = tmp_path / "twin.yaml"
    # a cold solve from far outside the bound needs more than the default work budget
    cfg.write_text(TWIN.replace("    weights:", "    observer: {innovation_limit: [.inf, .inf]}\n    weights:")
                   + f"solver: {{work_budget: {UNBOUNDED_WORK}}}\n")
    model, _ = load_model(cfg, "float")
    double_model, double_ctx = load_model_from_config(double_twin(model.config))
    floor_c = build_host_controller(floor_context(double_model, model))
    double_c = build_host_controller(double_ctx)
    x = np.array([30.0, -5.0, 2.0, 1.0, 0.5, -0.5])  # far beyond the 35 deg roll bound
    r = np.tile([45.0, 0.0], 40)
    status, U_floor, _ = floor_c.solve_qp(0, x, r)
    d_status, U_double, _ = double_c.solve_qp(0, x, r)
    assert status == d_status == OPTIMAL and floor_c.info()["active"] > 0
    ref_status, floor = stored_data_floor(model.modes[0].data, double_ctx["solver"], x, r,
                                          U_double)
    assert ref_status == OPTIMAL
    assert floor == float(np.abs(U_floor - U_double).max() / max(1.0, np.abs(U_double).max()))
    assert 0 < floor < FLOAT_ERROR_LIMIT


def test_check_float_library_call(tmp_path):
    """The library function returns the figures the CLI prints; it is deterministic."""
    cfg = tmp_path / "roll.yaml"
    cfg.write_text(ROLL)
    model, ctx = load_model(cfg, "float")
    a = check_float(model, ctx, scenario_qps=10, perturbed_qps=2)
    b = check_float(model, ctx, scenario_qps=10, perturbed_qps=2)
    assert (a.qps, a.perturbed) == (10, 2)
    assert sum(a.float_statuses.values()) == 12 and not a.unsafe and a.warning() is None
    assert (a.error, a.first_move_error, a.floor) == (b.error, b.first_move_error, b.floor)


@pytest.mark.slow
def test_a_scenario_without_moves_checks_nothing_and_does_not_warn(tmp_path, capsys):
    code, _, cap = _generate(tmp_path, capsys, ROLL.replace("[0, 30, -30, 60, 0]", "[0]"))
    assert code == 0 and cap.err == ""
    assert "rollmpc: float check: nothing to check (the scenario's states and references " \
           "are all zero)\n" in cap.out


def _check(lost: dict) -> FloatCheck:
    return FloatCheck(qps=40, perturbed=8, error=2e-6, first_move_error=2e-6, floor=1e-6,
                      float_statuses={"optimal": 48 - sum(lost.values()), **lost}, lost=lost,
                      seconds=1.0, worst="sample 3, mode m")


def test_a_qp_float_stops_at_the_budget_is_not_laid_to_float():
    """A small inverter loop's check said "2 QPs that double solves are not OPTIMAL in float
    (29 TIME_LIMIT)" and sent it to double, 7-22 times slower on the M4F, for budget stops
    (its 29 counted every float QP, not the 2)."""
    assert not _check({"time_limit": 2}).unsafe and _check({"time_limit": 2}).warning() is None
    mixed = _check({"time_limit": 2, "max_iter": 1})
    assert mixed.unsafe and "1 QPs that double solves are not OPTIMAL in float (1 MAX_ITER)" \
        in mixed.warning()
