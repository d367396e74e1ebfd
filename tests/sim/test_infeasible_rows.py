"""simulate's INFEASIBLE warning names the constraints the QPs could not meet (sim/
infeasible_rows.py, qp/infeasibility.py): a terminal set a too-large reference step
cannot reach, and an output bound no input can hold."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from rollmpc_codegen.qp.infeasibility import violated_keys
from rollmpc_codegen.sim.scenario_run import run_scenario

SERVO = Path(__file__).resolve().parents[1] / "data" / "constraints" / "servo_terminal.yaml"


def test_the_warning_names_the_terminal_set_a_step_cannot_reach(tmp_path):
    doc = yaml.safe_load(SERVO.read_text())
    doc["simulation"]["reference"] = {"levels": [0, 2], "segment": 0.5}  # 2 m at 0.8 m/s: no
    path = tmp_path / "servo_far.yaml"
    path.write_text(yaml.safe_dump(doc))
    run = run_scenario(path, steps=30)
    (warning,) = [w for w in run.warnings if w.code == "infeasible_samples"]
    assert warning.key == "modes[0].constraints.terminal"
    assert "modes[0].constraints.terminal (" in warning.message


def test_a_feasible_qp_has_no_violated_keys_and_an_unreachable_bound_has_its_own():
    from rollmpc_codegen.pipeline import load_model

    model, _ = load_model(SERVO)
    qp = model.modes[0].qp
    x, r = np.zeros(qp.nx), np.zeros(qp.N * qp.ny)
    assert violated_keys(qp, 0, x, r) == []
    # far past the position bound, faster than the velocity bound: the plan cannot help it
    assert "modes[0].bounds.y_max" in violated_keys(qp, 0, np.array([3.5, 0.79]), r)
