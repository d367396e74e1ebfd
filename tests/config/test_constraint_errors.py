"""``modes[].constraints`` (config/constraints.py): a bad entry is one error naming its key;
a terminal set that cannot be computed names ``constraints.terminal``."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from conftest import config_error
from rollmpc_codegen.config.controller import parse

SERVO = Path(__file__).resolve().parents[1] / "data" / "constraints" / "servo_terminal.yaml"
UAV = Path(__file__).resolve().parents[2] / "examples" / "uav_roll.yaml"


def servo(**constraints) -> dict:
    doc = yaml.safe_load(SERVO.read_text())
    doc["modes"][0]["constraints"] = constraints
    return doc


CASES = [
    ("signal C of the wrong width", dict(signals={"v": {"C": [0, 1, 0], "max": 1}}),
     "modes[0].constraints.signals.v.C", "columns"),
    ("a signal without a bound", dict(signals={"v": {"C": [0, 1]}}),
     "modes[0].constraints.signals.v", "min, max"),
    ("min above max", dict(signals={"v": {"C": [0, 1], "min": 2, "max": 1}}),
     "modes[0].constraints.signals.v.min", "<= max"),
    ("a signal of zeros", dict(signals={"v": {"C": [0, 0], "max": 1}}),
     "modes[0].constraints.signals.v", "constrains nothing"),
    ("stages past the horizon", dict(signals={"v": {"C": [0, 1], "max": 1, "stages": [1, 99]}}),
     "modes[0].constraints.signals.v.stages", "1..20"),
    ("a stage 0 without an input term", dict(signals={"v": {"C": [0, 1], "max": 1,
                                                            "stages": [0, 5]}}),
     "modes[0].constraints.signals.v.stages", "time 0"),
    ("an unknown key", dict(signals={"v": {"C": [0, 1], "maxi": 1}}),
     "modes[0].constraints.signals.v.maxi", "did you mean max"),
    ("a mixed row without E or F", dict(mixed={"m": {"g": [1.0]}}),
     "modes[0].constraints.mixed.m", "needs E"),
    ("a mixed F of the wrong shape", dict(mixed={"m": {"F": [[1, 1]], "g": [1.0]}}),
     "modes[0].constraints.mixed.m.F", "1x1"),
    ("an unknown terminal kind", dict(terminal="invariant"),
     "modes[0].constraints.terminal.kind", "lqr_invariant"),
    ("a polytope excluding its steady state", dict(terminal={"kind": "polytope",
                                                            "H": [[1, 0]], "h": [-1]}),
     "modes[0].constraints.terminal.h", ">= 0"),
    ("H on an equality", dict(terminal={"kind": "equality", "H": [[1, 0]]}),
     "modes[0].constraints.terminal.H", "polytope"),
]


@pytest.mark.parametrize("what, constraints, key, words", CASES, ids=[c[0] for c in CASES])
def test_a_bad_constraint_names_its_key(what, constraints, key, words):
    err = config_error(servo(**constraints), parse)
    assert err.key == key and words in err.problem


def test_a_transfer_function_plant_names_no_states():
    """The UAV's plant is a transfer function: its states are the generator's."""
    doc = yaml.safe_load(UAV.read_text())
    doc["modes"][0]["constraints"] = {"signals": {"s": {"C": [1, 0, 0, 0], "max": 1}}}
    err = config_error(doc, parse)
    assert err.key == "modes[0].constraints.signals.s.C" and "state_space" in err.problem


def test_an_input_only_signal_on_a_transfer_function_plant_is_accepted():
    doc = yaml.safe_load(UAV.read_text())
    doc["modes"][0]["constraints"] = {"mixed": {"m": {"F": [[1.0]], "g": [10.0]}}}
    cfg = parse(doc)
    s = cfg.modes[0].signals[0]
    assert (s.name, s.first, s.last, s.hi) == ("m[0]", 0, cfg.horizon - 1, 10.0)


def test_an_lqr_set_the_bounds_leave_empty_names_the_terminal_key(tmp_path):
    """Bounds whose steady states exclude rest (a velocity held above its bound at rest)
    leave no admissible set."""
    from rollmpc_codegen.config import ConfigError
    from rollmpc_codegen.pipeline import load_model

    doc = servo(signals={"v": {"C": [0, 1], "min": 0.1, "max": 0.8}}, terminal="lqr_invariant")
    path = tmp_path / "empty.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError) as exc:
        load_model(path)
    assert exc.value.key == "modes[0].constraints.terminal"
