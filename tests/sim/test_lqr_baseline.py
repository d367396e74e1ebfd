"""`rollmpc simulate --baseline lqr` (sim/lqr_baseline.py) on designs with an offset-free
disturbance model: the disturbance states are not controllable, and dlqr on the whole
state failed ("Failed to find a finite solution", exit 1; found on a new user's
Wood-Berry column and on examples/quadruple_tank.yaml)."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT
from rollmpc_codegen.pipeline import load_model
from rollmpc_codegen.sim.lqr_baseline import LqrController
from rollmpc_codegen.sim.simulate import run_closed_loop


@pytest.mark.parametrize("example", ["quadruple_tank", "thermal_zones_rate"])
def test_baseline_runs_and_is_offset_free(example):
    """Under a constant input disturbance the LQR settles on the reference: its steady
    state cancels the observer's disturbance estimate."""
    model, ctx = load_model(ROOT / "examples" / f"{example}.yaml")
    assert model.modes[0].plant.nd > 0  # the case that failed
    lqr = LqrController(model, ctx)
    log = run_closed_loop(model.config, lqr, disturbance=0.05, steps=None)
    end = slice(len(log.t) - 20, None)  # the last level, long settled
    assert np.all(np.isfinite(log.u))
    assert np.abs(log.y[end] - log.r[end]).max() < 1e-3
