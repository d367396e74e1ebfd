"""Hard bounds on constrained signals, read on the simulated plant (sim/signal_bounds.py):
counted beyond the tolerance like output bounds, soft and late-stage signals left out,
and on a heavy design (tests/data/heavy/pmsm_speed: the q current is a signal, not an
output) a budget too small for it shows as signal violations and a warning that names
the signal's key, where the unbudgeted loop holds the bound."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import edited_config
from rollmpc_codegen.pipeline import load_config
from rollmpc_codegen.qp.work import UNBOUNDED_WORK
from rollmpc_codegen.sim.scenario_run import run_scenario
from rollmpc_codegen.sim.signal_bounds import PlantSignal, plant_signals, signal_violations

PMSM = Path(__file__).resolve().parents[1] / "data" / "heavy" / "pmsm_speed.yaml"


def _signal(lo, hi, mode=0):
    return PlantSignal("z", mode, 0, np.ones(1), np.zeros(1), np.zeros(1, int), lo, hi)


def test_violations_are_counted_beyond_the_tolerance_in_the_active_mode():
    sig = [_signal(-10.0, 10.0), _signal(-np.inf, 2.0, mode=1)]
    z = np.array([[10.0 + 5e-4, 0.0],   # within 1e-4 * 10: roundoff
                  [10.0 + 2e-3, 0.0],   # past
                  [-12.0, 5.0],         # past (mode 0); the mode-1 signal is not active
                  [0.0, 2.5]])          # mode 1: past its 2
    count, far = signal_violations(sig, z, np.array([0, 0, 0, 1]), 1e-4)
    assert count == 3
    assert far == {"z": pytest.approx(2.0)}  # the larger of 2e-3, 2.0 and 0.5


def test_soft_and_late_signals_are_not_plant_bounds(tmp_path):
    def edit(d):
        signals = d["modes"][0]["constraints"]["signals"]
        signals["iq_end"] = {"C": [0.0, 1.0, 0.0], "min": -1, "max": 1, "stages": [20, 20]}
        signals["id_soft"] = {"C": [1.0, 0.0, 0.0], "min": -9, "max": 9,
                              "soft": {"l1": 0, "l2": 1000}}
    cfg = load_config(edited_config(tmp_path, PMSM, "pmsm", edit))
    assert [s.name for s in plant_signals(cfg, [3])] == ["iq"]
    assert plant_signals(cfg, [2]) == []  # a plant without the signal's states


@pytest.mark.parametrize("budget, violated", [(None, True), (UNBOUNDED_WORK, False)])
def test_a_budget_too_small_shows_as_signal_violations(tmp_path, budget, violated):
    def edit(d):
        if budget is not None:
            d["solver"]["work_budget"] = budget
    path = edited_config(tmp_path, PMSM, "pmsm", edit)
    run = run_scenario(path, precision="float", build_dir=tmp_path / "b")
    cv = run.summary["constraint_violations"]
    assert cv["y"] == 0 and cv["u"] == 0  # the outputs and inputs are kept either way
    if violated:  # measured: 9 samples, iq 16.2 A past 10 A, the longest TIME_LIMIT run 43
        assert cv["z"] > 0 and cv["total"] == cv["z"] and cv["y_max_beyond"]["iq"] > 1.0
        (w,) = [w for w in run.warnings if w.code == "hard_bound_passed"]
        assert w.key == "modes[0].constraints.signals.iq" and "signals passed" in w.message
    else:
        assert cv["z"] == 0 and cv["y_max_beyond"] == {}
        assert run.summary["non_optimal"] == 0
