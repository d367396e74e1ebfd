"""The simulated plant (sim/scenario.py): modes with their own actuators are channels that
add up; modes sharing an actuator are operating points of one plant, of which simulate
flies the one the scheduler picks at rest (found on a new user's two-airspeed pitch loop
and on examples/c172_roll.yaml, whose three aileron models were summed: 3x the gain, a
settled error of 10 deg)."""
from __future__ import annotations

import numpy as np

from conftest import ROOT, UAV
from rollmpc_codegen.config import load
from rollmpc_codegen.host.build import build_host_controller
from rollmpc_codegen.model.plant import discretise
from rollmpc_codegen.pipeline import load_model
from rollmpc_codegen.sim.scenario import SimulatedPlant, plant_modes
from rollmpc_codegen.sim.simulate import run_closed_loop

C172 = ROOT / "examples" / "c172_roll.yaml"
DRIVES = ROOT / "examples" / "three_drives.yaml"


def test_which_modes_make_the_plant():
    assert plant_modes(load(UAV)) == [0, 1]  # two aileron pairs: both act
    assert plant_modes(load(DRIVES)) == [0, 1, 2]  # three drives of one axis
    cfg = load(C172)  # one aileron at 70, 90, 110 kts: the band of a signal of 0
    assert [m.name for m in cfg.modes] == ["kts70", "kts90", "kts110"]
    assert plant_modes(cfg) == [0]


def test_shared_actuator_plant_is_one_model():
    """A unit aileron step moves the simulated roll exactly as kts70's model alone does."""
    cfg = load(C172)
    plant = SimulatedPlant(cfg)
    d = discretise(cfg.modes[0], cfg.sample_time, "modes[0]")
    x = np.zeros(d.A.shape[0])
    for _ in range(50):
        plant.advance(np.array([1.0]))
        x = d.A @ x + d.B[:, 0]
    assert np.allclose(plant.outputs(), d.C @ x, rtol=1e-12, atol=0)


def test_c172_tracks_its_first_step():
    """The nominal loop settles on -15 deg (it was 9.9 deg off on the summed plant)."""
    model, ctx = load_model(C172)
    log = run_closed_loop(model.config, build_host_controller(ctx, None), steps=1900)
    assert log.r[-1, 0] != 0 and abs(log.y[-1, 0] - log.r[-1, 0]) < 0.05
