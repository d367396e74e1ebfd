"""Bad configurations fail cleanly: one stderr line naming the key, exit 2, nothing written.

Every malformed config is the paper's example (examples/uav_roll.yaml) with one small
mutation.  The product spec asks, for ``rollmpc generate CONFIG -o OUT``:

* exactly one line on stderr, ``rollmpc: error: <key path>: <problem>``;
* exit code 2 and no Python traceback;
* no output directory (not even a half-written one), no stray temporary directory,
  and an existing OUT from an earlier good run left byte-for-byte unchanged.
"""
from __future__ import annotations

import copy
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from rollmpc_codegen.cli import main as cli
from rollmpc_codegen.config import ConfigError, load, parse

ROOT = Path(__file__).resolve().parents[2]
UAV = ROOT / "examples" / "uav_roll.yaml"
BASE = yaml.safe_load(UAV.read_text())


# --------------------------------------------------------------------------- mutations
def _keys(path: str) -> list:
    """``modes[1].weights.P`` -> ``["modes", 1, "weights", "P"]``."""
    out: list = []
    for part in path.split("."):
        name, rest = re.fullmatch(r"([^\[]+)((?:\[\d+\])*)", part).groups()
        out.append(name)
        out += [int(i) for i in re.findall(r"\[(\d+)\]", rest)]
    return out


def _parent(d, path: str):
    keys = _keys(path)
    for k in keys[:-1]:
        d = d[k]
    return d, keys[-1]


def set_(path: str, value):
    def mutate(d):
        parent, last = _parent(d, path)
        parent[last] = value
    return mutate


def drop(path: str):
    def mutate(d):
        parent, last = _parent(d, path)
        del parent[last]
    return mutate


def both(*mutations):
    def mutate(d):
        for m in mutations:
            m(d)
    return mutate


def text(content: str | bytes):
    """Replace the whole file (for cases YAML itself cannot express as a dict)."""
    return lambda d: content


def state_space(A, B, C):
    """Mode 0 becomes an integrating state-space plant (default observer poles)."""
    return both(set_("modes[0].plant", {"state_space": {"A": A, "B": B, "C": C},
                                        "integrator": True}),
                drop("modes[0].observer"))


def three_modes(d):
    third = copy.deepcopy(d["modes"][1])
    third["name"] = "third"
    d["modes"].append(third)


def single_mode_with_scheduler(d):
    d["modes"].pop()


TF0 = "modes[0].plant.transfer_function"
SS_OK = dict(A=[[0, 1], [-2, -3]], B=[[0], [1]], C=[[1, 0]])

# (mutation, key the error must name, fragment of the problem)
CASES = [
    # ---- missing required keys
    pytest.param(drop("sample_time"), "sample_time", "missing", id="missing-sample_time"),
    pytest.param(drop("horizon"), "horizon", "missing", id="missing-horizon"),
    pytest.param(drop("modes"), "modes", "missing", id="missing-modes"),
    pytest.param(drop("outputs"), "outputs", "missing", id="missing-outputs"),
    pytest.param(drop("actuators"), "actuators", "missing", id="missing-actuators"),
    pytest.param(drop("modes[0].plant"), "modes[0].plant", "missing", id="missing-mode-plant"),
    pytest.param(drop("modes[1].weights"), "modes[1].weights", "missing",
                 id="missing-mode-weights"),
    pytest.param(drop("modes[0].bounds"), "modes[0].bounds", "missing", id="missing-mode-bounds"),
    pytest.param(drop("modes[0].weights.R"), "modes[0].weights.R", "missing", id="missing-R"),
    pytest.param(drop("modes[1].bounds.u_max"), "modes[1].bounds.u_max", "missing",
                 id="missing-u_max"),
    pytest.param(drop(f"{TF0}.den"), f"{TF0}.den", "missing", id="missing-tf-den"),
    pytest.param(drop("modes[1].name"), "modes[1].name", "missing", id="missing-mode-name"),
    pytest.param(drop("scheduler"), "scheduler", "missing", id="missing-scheduler-two-modes"),
    pytest.param(set_("modes[0].plant", {"integrator": True}), "modes[0].plant",
                 "exactly one", id="plant-without-model"),
    # ---- unknown keys, at every level
    pytest.param(set_("horizn", 100), "horizn", "unknown key", id="unknown-top"),
    pytest.param(set_("modes[1].weight", {}), "modes[1].weight", "unknown key",
                 id="unknown-mode"),
    pytest.param(set_("modes[0].plant.integrate", True), "modes[0].plant.integrate",
                 "unknown key", id="unknown-plant"),
    pytest.param(set_(f"{TF0}.gain", 2), f"{TF0}.gain", "unknown key", id="unknown-tf"),
    pytest.param(set_("modes[0].weights.S", 1), "modes[0].weights.S", "unknown key",
                 id="unknown-weights"),
    pytest.param(set_("modes[0].bounds.dy_max", 1), "modes[0].bounds.dy_max", "unknown key",
                 id="unknown-bounds"),
    pytest.param(set_("solver.tolerance", 1e-9), "solver.tolerance", "unknown key",
                 id="unknown-solver"),
    pytest.param(set_("scheduler.hysteresis", 0.5), "scheduler.hysteresis", "unknown key",
                 id="unknown-scheduler"),
    pytest.param(set_("modes[1].observer.gain", 1), "modes[1].observer.gain", "unknown key",
                 id="unknown-observer"),
    pytest.param(set_("simulation.steps", 10), "simulation.steps", "unknown key",
                 id="unknown-simulation"),
    pytest.param(lambda d: d.update({1: "x", "zz": 2}), "1", "unknown key",
                 id="unknown-top-keys-of-mixed-types"),
    pytest.param(lambda d: d.update({"foo\nbar": 1}), "foo bar", "unknown key",
                 id="unknown-key-with-newline"),
    # ---- wrong types
    pytest.param(set_("horizon", "100"), "horizon", "integer", id="horizon-string"),
    pytest.param(set_("horizon", 100.5), "horizon", "integer", id="horizon-float"),
    pytest.param(set_("horizon", True), "horizon", "integer", id="horizon-bool"),
    pytest.param(set_("sample_time", [0.01]), "sample_time", "number", id="sample_time-list"),
    pytest.param(set_("sample_time", "10ms"), "sample_time", "number", id="sample_time-unit"),
    pytest.param(set_("modes[0].weights.Q", True), "modes[0].weights.Q", "number",
                 id="Q-bool"),
    pytest.param(set_("modes[0].plant.integrator", "yes"), "modes[0].plant.integrator",
                 "true or false", id="integrator-string"),
    pytest.param(set_("outputs", "roll"), "outputs", "list", id="outputs-string"),
    pytest.param(set_("modes[1]", "outer"), "modes[1]", "mapping", id="mode-not-mapping"),
    pytest.param(set_("modes[0].weights", 10), "modes[0].weights", "mapping",
                 id="weights-not-mapping"),
    pytest.param(set_("solver", ["hildreth"]), "solver", "mapping", id="solver-not-mapping"),
    pytest.param(set_("modes", {"inner": {}}), "modes", "list", id="modes-not-list"),
    # ---- out-of-range scalars
    pytest.param(set_("horizon", 0), "horizon", ">= 1", id="horizon-zero"),
    pytest.param(set_("horizon", -5), "horizon", ">= 1", id="horizon-negative"),
    pytest.param(set_("horizon", 100000), "horizon", "QP rows", id="horizon-too-long"),
    pytest.param(set_("sample_time", 0), "sample_time", "> 0", id="sample_time-zero"),
    pytest.param(set_("sample_time", -0.01), "sample_time", "> 0", id="sample_time-negative"),
    pytest.param(set_("sample_time", float("nan")), "sample_time", "finite",
                 id="sample_time-nan"),
    pytest.param(set_("scheduler.lower", float("nan")), "scheduler.lower", "finite",
                 id="scheduler-lower-nan"),
    pytest.param(set_("modes[0].weights.Q", 10**400), "modes[0].weights.Q", "too large",
                 id="Q-400-digit-integer"),
    # ---- shapes
    pytest.param(set_("modes[0].bounds.u_min", [-15, -15]), "modes[0].bounds.u_min",
                 "1 entries", id="u_min-wrong-length"),
    pytest.param(set_("modes[0].weights.Q", [[10, 0], [0, 10]]), "modes[0].weights.Q",
                 "1x1", id="Q-wrong-size"),
    pytest.param(state_space(SS_OK["A"], [[0], [1], [0]], SS_OK["C"]),
                 "modes[0].plant.state_space.B", "2 rows", id="ss-B-wrong-rows"),
    pytest.param(state_space([[0, 1]], SS_OK["B"], SS_OK["C"]),
                 "modes[0].plant.state_space.A", "square", id="ss-A-not-square"),
    pytest.param(state_space(SS_OK["A"], SS_OK["B"], [[1, 0], [0, 1]]),
                 "modes[0].plant.state_space.C", "1 rows", id="ss-C-two-outputs"),
    pytest.param(state_space(SS_OK["A"], [[0, 1], [1, 0]], SS_OK["C"]),
                 "modes[0].plant.state_space.B", "1 columns", id="ss-B-two-inputs"),
    # ---- transfer functions
    pytest.param(set_(f"{TF0}.num", [1, 2, 3, 4, 5]), f"{TF0}.num", "improper",
                 id="tf-improper"),
    pytest.param(both(set_(f"{TF0}.num", [1, 2, 3, 4]), set_("modes[0].plant.integrator", False)),
                 f"{TF0}.num", "strictly proper", id="tf-biproper-no-integrator"),
    pytest.param(set_(f"{TF0}.den", [0, 0, 0, 0]), f"{TF0}.den", "all zeros",
                 id="tf-den-all-zero"),
    pytest.param(set_(f"{TF0}.num", []), f"{TF0}.num", "empty", id="tf-num-empty"),
    pytest.param(set_("modes[0].plant.state_space", SS_OK), "modes[0].plant", "exactly one",
                 id="plant-tf-and-ss"),
    pytest.param(set_("outputs", ["roll", "pitch"]), "modes[0].plant.transfer_function",
                 "SISO", id="tf-with-two-outputs"),
    # ---- system properties (found while building the model)
    pytest.param(state_space([[-1, 0], [0, -2]], [[1], [0]], [[1, 1]]), "modes[0].plant",
                 "not controllable", id="uncontrollable-decoupled-state"),
    pytest.param(state_space([[-1, 0], [0, -2]], [[1], [1]], [[1, 0]]), "modes[0].plant",
                 "not observable", id="unobservable-hidden-state"),
    pytest.param(both(set_(f"{TF0}.num", [1, 1]), set_(f"{TF0}.den", [1, 3, 2]),
                      drop("modes[0].observer")),
                 "modes[0].plant", "not observable", id="tf-pole-zero-cancellation"),
    pytest.param(set_("modes[0].plant.integrator", False), "modes[0].plant.integrator",
                 "output_rate", id="output_rate-needs-integrator"),
    # ---- weights
    pytest.param(set_("modes[0].weights.R", 0), "modes[0].weights.R", "positive definite",
                 id="R-zero"),
    pytest.param(set_("modes[1].weights.R", -1), "modes[1].weights.R", "positive definite",
                 id="R-negative"),
    pytest.param(set_("modes[1].weights.Q", -10), "modes[1].weights.Q", "semidefinite",
                 id="Q-negative"),
    pytest.param(set_("modes[1].weights.P", float("inf")), "modes[1].weights.P", "finite",
                 id="P-inf"),
    pytest.param(set_("modes[0].weights.Q", float("nan")), "modes[0].weights.Q", "finite",
                 id="Q-nan"),
    pytest.param(set_("modes[0].weights.R", 1e-300), "modes[0].weights", "Hessian",
                 id="hessian-not-positive-definite"),
    # ---- bounds
    pytest.param(both(set_("modes[0].bounds.u_min", 15), set_("modes[0].bounds.u_max", -15)),
                 "modes[0].bounds.u_min", "< u_max", id="u_min-above-u_max"),
    pytest.param(both(set_("modes[1].bounds.y_min", 270), set_("modes[1].bounds.y_max", -270)),
                 "modes[1].bounds.y_min", "< y_max", id="y_min-above-y_max"),
    pytest.param(set_("modes[0].bounds.u_min", 1), "modes[0].bounds.u_min", "contain 0",
                 id="u-bounds-above-0"),
    pytest.param(both(set_("modes[1].bounds.u_min", -15), set_("modes[1].bounds.u_max", -1)),
                 "modes[1].bounds.u_max", "contain 0", id="u-bounds-below-0"),
    pytest.param(set_("modes[0].bounds.u_min", float("-inf")), "modes[0].bounds.u_min",
                 "finite", id="u_min-inf"),
    pytest.param(both(set_("precision", "float"), set_("modes[0].bounds.y_max", 1e39)),
                 "modes[0].bounds.y_max", "float precision", id="y_max-beyond-float"),
    # ---- scheduler
    pytest.param(both(set_("scheduler.lower", 16), set_("scheduler.upper", -16)),
                 "scheduler.lower", "< upper", id="scheduler-lower-above-upper"),
    pytest.param(set_("scheduler.epsilon", 16), "scheduler.epsilon", "no inside band",
                 id="scheduler-epsilon-empty-band"),
    pytest.param(set_("scheduler.epsilon", -0.5), "scheduler.epsilon", ">= 0",
                 id="scheduler-epsilon-negative"),
    pytest.param(set_("scheduler.inside", "middle"), "scheduler.inside", "unknown mode",
                 id="scheduler-unknown-mode"),
    pytest.param(set_("scheduler.outside", "inner"), "scheduler.outside", "differ",
                 id="scheduler-same-mode-twice"),
    pytest.param(set_("scheduler.signal", "roll rate */"), "scheduler.signal", "identifier",
                 id="scheduler-signal-not-identifier"),
    pytest.param(single_mode_with_scheduler, "scheduler", "single-mode",
                 id="scheduler-with-single-mode"),
    pytest.param(three_modes, "scheduler", "serves no band", id="three-modes-shorthand"),
    pytest.param(set_("simulation.schedule_source", "roll"), "simulation.schedule_source",
                 "one of", id="unknown-schedule-source"),
    # ---- solver
    pytest.param(set_("solver.method", "hildreth_prime"), "solver.method", "one of",
                 id="solver-unknown-method"),
    pytest.param(set_("solver.omega", 2.0), "solver.omega", "0 < omega < 2", id="omega-2"),
    pytest.param(set_("solver.omega", 0), "solver.omega", "0 < omega < 2", id="omega-0"),
    pytest.param(set_("solver.max_iterations", 0), "solver.max_iterations", ">= 1",
                 id="max_iterations-zero"),
    pytest.param(set_("solver.max_iterations", 10**12), "solver.max_iterations", "<=",
                 id="max_iterations-beyond-c-int"),
    pytest.param(set_("solver.delta", 0), "solver.delta", "> 0", id="delta-zero"),
    # ---- observer
    pytest.param(set_("modes[0].observer.poles", [0.8, 0.83, 0.86, 1.05]),
                 "modes[0].observer.poles[3]", "unit circle", id="observer-pole-outside"),
    pytest.param(set_("modes[0].observer.poles", [0.8, 0.83, 0.86, -1.0]),
                 "modes[0].observer.poles[3]", "unit circle", id="observer-pole-on-circle"),
    pytest.param(set_("modes[0].observer.poles", [0.8, 0.85, 0.9]),
                 "modes[0].observer.poles", "needs 4 poles", id="observer-pole-count"),
    pytest.param(set_("modes[0].observer.poles", [[0.8, 0.1], 0.83, 0.86, 0.9]),
                 "modes[0].observer.poles", "conjugate", id="observer-pole-no-conjugate"),
    pytest.param(set_("modes[0].observer.poles", 0.8), "modes[0].observer.poles", "list",
                 id="observer-poles-not-list"),
    pytest.param(set_("modes[0].observer.poles", [0.8, 0.8, 0.8, 0.8]),
                 "modes[0].observer.poles", "repeated more often than the mode has outputs", id="observer-poles-repeated"),
    # a flat list is a diagonal: its length is the output count (was "must be a matrix")
    pytest.param(set_("modes[0].weights.Q", [1.0, 2.0]), "modes[0].weights.Q",
                 "must have 1 entries, got 2", id="Q-diagonal-length"),
    # 1e-7 apart: placed 0.06 off (was silently accepted)
    pytest.param(set_("modes[0].observer.poles", [0.8, 0.8000001, 0.8000002, 0.8000003]),
                 "modes[0].observer.poles", "missed a pole", id="observer-poles-clustered"),
    pytest.param(set_("modes[0].observer.innovation_limit", 0),
                 "modes[0].observer.innovation_limit", "must be > 0", id="innovation-limit-zero"),
    pytest.param(set_("modes[1].observer.innovation_limit", -5.0),
                 "modes[1].observer.innovation_limit", "must be > 0",
                 id="innovation-limit-negative"),
    pytest.param(set_("modes[0].observer.innovation_limit", -math.inf),
                 "modes[0].observer.innovation_limit", "must be > 0",
                 id="innovation-limit-minus-inf"),
    pytest.param(set_("modes[0].observer.innovation_limit", [1, 2]),
                 "modes[0].observer.innovation_limit", "must have 1 entries",
                 id="innovation-limit-length"),
    pytest.param(set_("modes[0].observer.innovation_limit", "big"),
                 "modes[0].observer.innovation_limit", "must be a number",
                 id="innovation-limit-string"),
    # an output with no bound and a zero reference takes its default from the model now
    # (tests/config/test_innovation_default.py has the case nothing bounds)
    # ---- names
    pytest.param(set_("modes[0].actuators", ["middle"]), "modes[0].actuators[0]",
                 "unknown actuator", id="mode-unknown-actuator"),
    pytest.param(set_("modes[1].name", "inner"), "modes[1].name", "duplicate",
                 id="duplicate-mode-names"),
    pytest.param(set_("modes[0].name", "inner pair"), "modes[0].name", "identifier",
                 id="mode-name-not-identifier"),
    pytest.param(set_("actuators", ["inner", "inner"]), "actuators", "unique",
                 id="duplicate-actuators"),
    pytest.param(set_("prefix", "roll-mpc"), "prefix", "C identifier", id="prefix-dash"),
    pytest.param(set_("prefix", "2roll"), "prefix", "C identifier", id="prefix-digit-first"),
    pytest.param(set_("precision", "quad"), "precision", "one of", id="precision-unknown"),
    # ---- the file itself
    pytest.param(text("- prefix: rollmpc\n- horizon: 100\n"), "<top>", "mapping",
                 id="top-level-list"),
    pytest.param(text("rollmpc\n"), "<top>", "mapping", id="top-level-scalar"),
    pytest.param(text(""), "<top>", "empty", id="empty-file"),
    pytest.param(text("# nothing but a comment\n"), "<top>", "empty", id="comment-only-file"),
    pytest.param(text("horizon: 100\nmodes: [1, 2\n"), "<yaml line 3>", "not valid YAML",
                 id="yaml-unclosed-bracket"),
    pytest.param(text("solver:\n\tmethod: hildreth\n"), "<yaml line 2>", "not valid YAML",
                 id="yaml-tab-indent"),
    pytest.param(text("prefix: roll\x01mpc\n"), "<yaml character 13>", "not valid YAML",
                 id="yaml-control-character"),
    pytest.param(text("a: 1\n---\nb: 2\n"), "<yaml line 2>", "not valid YAML",
                 id="yaml-two-documents"),
    pytest.param(text(b"prefix: caf\xe9\n"), "{config}", "not UTF-8", id="not-utf8"),
]


def _write(tmp_path: Path, mutate) -> Path:
    d = copy.deepcopy(BASE)
    content = mutate(d)
    path = tmp_path / "config.yaml"
    if content is None:
        path.write_text(yaml.safe_dump(d, sort_keys=False))
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return path


def _assert_clean_failure(rc: int, err: str, key: str, problem: str) -> None:
    assert rc == 2, err
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].strip() and err == lines[0] + "\n", repr(err)
    assert lines[0].startswith(f"rollmpc: error: {key}: "), lines[0]
    assert problem in lines[0], lines[0]


def _assert_nothing_written(out: Path) -> None:
    assert not out.exists()
    stray = [p.name for p in out.parent.iterdir() if p.name.startswith(".")]
    assert stray == [], stray


@pytest.fixture
def no_debug(monkeypatch):
    monkeypatch.delenv("ROLLMPC_DEBUG", raising=False)  # it turns errors into tracebacks


# A numerical RuntimeWarning would be a second stderr line outside pytest; make it fail.
@pytest.mark.filterwarnings("error::RuntimeWarning")
@pytest.mark.parametrize("mutate, key, problem", CASES)
def test_bad_config_fails_cleanly(tmp_path, capsys, no_debug, mutate, key, problem):
    config = _write(tmp_path, mutate)
    (tmp_path / "gen").mkdir()
    out = tmp_path / "gen" / "out"
    rc = cli.main(["generate", str(config), "-o", str(out)])
    captured = capsys.readouterr()
    _assert_clean_failure(rc, captured.err, key.format(config=config), problem)
    assert captured.out == ""
    _assert_nothing_written(out)


# An unknown key is reported before anything else in its section, with the closest known
# key (else the section's keys, when few): (mutation, the exact message).  Each mutation
# also holds the problem the misspelling caused before (in the comment), read later.
UNKNOWN_FIRST = [
    pytest.param(both(drop("horizon"), set_("horizn", 100)),  # horizon: missing required key
                 "horizn: unknown key (did you mean horizon?)", id="top"),
    pytest.param(set_("modes[0].weights", {"Q": 10, "R": 0, "P": 1e6, "R_detla": 1}),
                 # modes[0].weights.R: must be positive definite
                 "modes[0].weights.R_detla: unknown key (did you mean R_delta?)", id="weights"),
    pytest.param(set_("modes[1].bounds", {"u_min": -15, "u_mx": 15}),
                 # modes[1].bounds.u_max: missing required key
                 "modes[1].bounds.u_mx: unknown key (did you mean u_max?)", id="bounds"),
    pytest.param(both(set_("solver.omega", 3.0), set_("solver.max_iter", 50)),
                 # solver.omega: SOR needs 0 < omega < 2, got 3.0
                 "solver.max_iter: unknown key (did you mean max_iterations?)", id="solver"),
    pytest.param(both(set_("scheduler.upper", -20), set_("scheduler.epsilion", 1)),
                 # scheduler.lower: must be < upper (-16.0 >= -20.0)
                 "scheduler.epsilion: unknown key (did you mean epsilon?)", id="scheduler"),
    pytest.param(set_("modes[0].weights.S", 1),  # no close match: the four keys
                 "modes[0].weights.S: unknown key; valid keys are Q, R, P, R_delta",
                 id="weights-no-match"),
    pytest.param(set_("solver.tolerance", 1e-9),  # no close match among 14 keys: none listed
                 "solver.tolerance: unknown key", id="solver-no-match"),
]


@pytest.mark.parametrize("mutate, message", UNKNOWN_FIRST)
def test_unknown_key_is_reported_first(tmp_path, capsys, no_debug, mutate, message):
    config = _write(tmp_path, mutate)
    (tmp_path / "gen").mkdir()
    out = tmp_path / "gen" / "out"
    rc = cli.main(["generate", str(config), "-o", str(out)])
    captured = capsys.readouterr()
    key = message.split(":")[0]
    _assert_clean_failure(rc, captured.err, key, "unknown key")
    assert captured.err == f"rollmpc: error: {message}\n"
    _assert_nothing_written(out)


def test_case_ids_and_count():
    ids = [p.id for p in CASES]
    assert len(ids) == len(set(ids))
    assert len(ids) >= 35


def test_missing_config_file(tmp_path, capsys, no_debug):
    config = tmp_path / "nope.yaml"
    out = tmp_path / "out"
    rc = cli.main(["generate", str(config), "-o", str(out)])
    _assert_clean_failure(rc, capsys.readouterr().err, str(config), "cannot read")
    _assert_nothing_written(out)


def test_subprocess_has_no_traceback(tmp_path):
    """End to end through the interpreter: a model-building failure (not only parsing)."""
    config = _write(tmp_path, state_space([[-1, 0], [0, -2]], [[1], [0]], [[1, 1]]))
    (tmp_path / "gen").mkdir()
    out = tmp_path / "gen" / "out"
    env = {k: v for k, v in os.environ.items() if k != "ROLLMPC_DEBUG"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    proc = subprocess.run(
        [sys.executable, "-m", "rollmpc_codegen.cli.main", "generate", str(config), "-o", str(out)],
        capture_output=True, text=True, cwd=tmp_path, env=env, timeout=120)
    _assert_clean_failure(proc.returncode, proc.stderr, "modes[0].plant", "not controllable")
    assert "Traceback" not in proc.stdout
    _assert_nothing_written(out)


def _snapshot(directory: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())}


def test_failed_generate_loses_nothing(tmp_path, capsys, no_debug):
    """OUT from an earlier good run survives failures at parse and at model-building time."""
    out = tmp_path / "gen" / "out"
    assert cli.main(["generate", str(UAV), "-o", str(out)]) == 0
    capsys.readouterr()
    before = _snapshot(out)
    assert before  # the good run really wrote something
    failures = [
        (set_("horizon", 0), "horizon"),
        (set_("modes[0].observer.poles", [0.8, 0.85, 0.9]), "modes[0].observer.poles"),
    ]
    for mutate, key in failures:
        config = _write(tmp_path, mutate)
        rc = cli.main(["generate", str(config), "-o", str(out)])
        _assert_clean_failure(rc, capsys.readouterr().err, key, "")
        assert _snapshot(out) == before
        assert [p.name for p in out.parent.iterdir()] == ["out"]


# --------------------------------------------------------------------------- good configs
def _parse(mutate=None):
    d = copy.deepcopy(BASE)
    if mutate is not None:
        mutate(d)
    return parse(d)


def test_example_parses():
    cfg = load(UAV)
    assert cfg.horizon == 100 and cfg.sample_time == 0.01
    assert [m.name for m in cfg.modes] == ["inner", "outer"]
    assert cfg.scheduler is not None and cfg.scheduler.band_modes == (1, 0, 1)  # out, in, out


def test_scalar_or_list_broadcasting():
    """A scalar bound broadcasts to every actuator; a scalar weight means scalar * I."""
    cfg = _parse(both(
        set_("modes[0].actuators", ["inner", "outer"]),
        set_("modes[0].plant", {"state_space": {"A": [[0, 1], [-2, -3]], "B": [[0, 0], [1, 2]],
                                                "C": [[1, 0]]}, "integrator": True}),
        drop("modes[0].observer"),
        set_("modes[0].bounds", {"u_min": -15, "u_max": [10, 15], "y_min": -270}),
        set_("modes[0].weights", {"Q": 10, "R": [1, 2]})))
    m = cfg.modes[0]
    np.testing.assert_array_equal(m.u_min, [-15, -15])
    np.testing.assert_array_equal(m.u_max, [10, 15])
    np.testing.assert_array_equal(m.R, np.diag([1.0, 2.0]))  # a flat list is a diagonal
    np.testing.assert_array_equal(m.Q, [[10.0]])
    np.testing.assert_array_equal(m.P, m.Q)  # P defaults to Q
    np.testing.assert_array_equal(m.y_max, [math.inf])


def test_yaml11_exponent_without_sign_is_a_number(tmp_path):
    # PyYAML implements YAML 1.1, where 1.0e6 (no exponent sign) is a string
    assert BASE["modes"][0]["weights"]["P"] == "1.0e6"
    cfg = load(UAV)
    assert cfg.modes[0].P[0, 0] == 1.0e6
    assert cfg.modes[1].P[0, 0] == 1.0e9
    assert cfg.solver.delta == 1e-13
    path = tmp_path / "c.yaml"
    path.write_text(UAV.read_text().replace("sample_time: 0.01", "sample_time: 1e-2"))
    assert load(path).sample_time == 0.01


def test_output_bounds_may_be_omitted():
    cfg = _parse(both(drop("modes[0].bounds.y_min"), drop("modes[0].bounds.y_max")))
    assert np.all(np.isneginf(cfg.modes[0].y_min)) and np.all(np.isposinf(cfg.modes[0].y_max))
    # unbounded outputs contribute no QP rows: only the 2 N box rows remain
    from rollmpc_codegen.qp.condense import condense
    from rollmpc_codegen.model.plant import discretise

    plant = discretise(cfg.modes[0], cfg.sample_time, "modes[0]")
    assert condense(plant, cfg.modes[0], cfg.horizon, "modes[0]").m == 2 * cfg.horizon


@pytest.mark.parametrize("mutate", [drop("modes[0].observer"), set_("modes[0].observer", None),
                                    set_("modes[0].observer.poles", None)],
                         ids=["absent", "null", "null-poles"])
def test_observer_may_be_omitted(mutate):
    from rollmpc_codegen.model.observer import default_poles, observer_gain
    from rollmpc_codegen.model.plant import discretise

    cfg = _parse(mutate)
    mode = cfg.modes[0]
    assert mode.observer_poles is None
    plant = discretise(mode, cfg.sample_time, "modes[0]")
    L, poles = observer_gain(plant, mode, "modes[0]")
    assert poles == default_poles(plant.nx)
    achieved = np.sort(np.linalg.eigvals(plant.A - L @ plant.C).real)
    np.testing.assert_allclose(achieved, np.sort([p.real for p in poles]), atol=1e-6)


@pytest.mark.parametrize("mutate", [set_("solver.feasibility_tol", None),
                                    set_("scheduler.initial", None)],
                         ids=["feasibility_tol", "scheduler-initial"])
def test_null_optional_key_means_default(mutate):
    cfg = _parse(mutate)
    assert cfg.solver.feasibility_tol is None
    assert cfg.scheduler.initial == 0  # the shorthand's inside mode


def test_config_error_is_one_line():
    assert "\n" not in str(ConfigError("a\nb", "c\r\nd"))


def test_config_error_loads_no_parser():
    """move_blocking.py raises ConfigError and config/mode.py calls move_blocking: importing
    the error alone must not load the parsers (the old config <-> move_blocking cycle),
    and the package must still load completely afterwards."""
    code = ("import json, sys\n"
            "import rollmpc_codegen.features.move_blocking\n"
            "print(json.dumps(sorted(m for m in sys.modules if 'codegen.config' in m)))\n"
            "from rollmpc_codegen.config import load\n"
            f"print(load({str(UAV)!r}).horizon)\n")
    env = dict(os.environ,
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    loaded, horizon = proc.stdout.splitlines()
    assert json.loads(loaded) == ["rollmpc_codegen.config", "rollmpc_codegen.config.errors"]
    assert horizon == "100"
