"""The default of ``observer.innovation_limit`` where the config gives an output no range
(no finite bound, a zero reference): ten spans of what the inputs make it reach
(model/reach.py).  fw_lateral without its explicit limit used to be refused
("has no default for output 'sideslip'"); only an output no input moves is now."""
from __future__ import annotations

import copy

import numpy as np
import pytest
import yaml

from conftest import ROOT, UAV, config_error
from rollmpc_codegen.config import load, parse
from rollmpc_codegen.config.schema import INNOVATION_LIMIT_SPANS
from rollmpc_codegen.model.reach import output_reach
from rollmpc_codegen.pipeline import build_model

FW = ROOT / "examples" / "fw_lateral.yaml"
EXAMPLES = sorted((ROOT / "examples").glob("*.yaml"))


def without_limit(path) -> dict:
    data = yaml.safe_load(path.read_text())
    for mode in data["modes"]:
        mode.get("observer", {}).pop("innovation_limit", None)
        if mode.get("observer") == {}:
            del mode["observer"]
    return data


def test_a_lateral_design_with_an_unbounded_zero_sideslip_generates():
    model = build_model(parse(without_limit(FW)))
    cfg, mm = model.config, model.modes[0]
    limit = mm.data.innovation_limit
    assert limit[0] == 700.0  # the bank: ten spans of its +-35 deg bound, as before
    low, high = output_reach(mm.plant, cfg.modes[0].u_min, cfg.modes[0].u_max, cfg.horizon)
    assert limit[1] == pytest.approx(INNOVATION_LIMIT_SPANS * (high[1] - low[1]))
    assert np.isfinite(limit[1]) and limit[1] > 180.0  # the example's own choice clips less


def test_the_reach_is_the_hull_of_rest_the_horizon_and_the_steady_state():
    """A first-order lag y' = -y + 2u, u in [-1, 3]: it reaches [-2, 6] at steady state."""
    data = {"sample_time": 0.1, "horizon": 5, "outputs": ["y"], "actuators": ["u"],
            "modes": [{"name": "m", "plant": {"transfer_function": {"num": [2], "den": [1, 1]}},
                       "weights": {"Q": 1, "R": 1}, "bounds": {"u_min": -1, "u_max": 3}}],
            "simulation": {"reference": {"levels": [0], "segment": 1}}}
    model = build_model(parse(data))
    low, high = output_reach(model.modes[0].plant, np.array([-1.0]), np.array([3.0]), 5)
    assert (low[0], high[0]) == pytest.approx((-2.0, 6.0))
    within = output_reach(model.modes[0].plant, np.array([-1.0]), np.array([3.0]), 5, False)
    assert within[1][0] == pytest.approx(6.0 * (1 - np.exp(-0.5)))  # 5 steps of 0.1 s
    assert model.modes[0].data.innovation_limit[0] == pytest.approx(80.0)


def test_an_output_no_input_moves_still_asks_for_the_key():
    data = {"sample_time": 0.1, "horizon": 5, "outputs": ["y", "idle"], "actuators": ["u"],
            "modes": [{"name": "m", "plant": {"state_space": {
                "A": [[-1.0, 0.0], [0.0, -2.0]], "B": [[1.0], [1.0]],
                "C": [[1.0, 1.0], [0.0, 0.0]]}},  # 'idle' reads nothing: always 0
                "weights": {"Q": 1, "R": 1}, "bounds": {"u_min": -1, "u_max": 1}}],
            "simulation": {"reference": {"levels": [[1, 0]], "segment": 1}}}
    exc = config_error(data, lambda d: build_model(parse(d)))
    assert exc.key == "modes[0].observer.innovation_limit"
    assert exc.problem == (
        "has no default for output 'idle': no finite bound, a scenario reference of 0 and "
        "no input that moves it within the horizon give it no range; give one (.inf: "
        "never clip)")


def test_the_uav_without_roll_bounds_and_a_zero_reference_takes_the_reach():
    data = yaml.safe_load(UAV.read_text())
    for mode in data["modes"]:
        del mode["bounds"]["y_min"], mode["bounds"]["y_max"]
    data["simulation"] = {"reference": {"levels": [0], "segment": 10}}
    model = build_model(parse(data))
    assert all(np.isfinite(mm.data.innovation_limit).all() for mm in model.modes)


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_no_example_takes_the_new_path(path):
    """Their limits come from the config as before, so their generated trees are
    unchanged (tests/codegen/test_generated_snapshot.py)."""
    for mode in load(path).modes:
        assert not np.isnan(mode.innovation_limit).any()


def test_the_config_hash_marks_a_limit_left_to_the_model():
    """The mark is part of the effective config (an explicit limit differs from it)."""
    data = without_limit(FW)
    given = copy.deepcopy(data)
    given["modes"][0]["observer"] = {"innovation_limit": [700, 180]}
    assert parse(data).config_hash != parse(given).config_hash
