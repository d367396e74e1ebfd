"""What `rollmpc generate` checks, on a design of our own (tests/data/newuser/ship_heading.yaml, a
ship's heading autopilot, not among examples/): what `rollmpc generate` says when the
model has a part no input moves or no output sees, when the design is too large for its
target, and when an output bound cannot be met from rest."""
from __future__ import annotations

import copy
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import ROOT
from rollmpc_codegen import pipeline
from rollmpc_codegen.cli import main as cli
from rollmpc_codegen.config import ConfigError, load, parse
from rollmpc_codegen.config.schema import DEFAULT_FLASH_LIMIT_KIB, DEFAULT_RAM_LIMIT_KIB
from rollmpc_codegen.model.observer import kalman_gain
from rollmpc_codegen.model.plant import DiscretePlant
from rollmpc_codegen.pipeline import load_model
from rollmpc_codegen.qp.feasibility import rest_warnings
from rollmpc_codegen.qp.footprint import check_fits, predict
from rollmpc_codegen.qp.nominal_loop import closed_loop_radius, unstable_law_warnings
from rollmpc_codegen.qp.sanity import design_warnings
from rollmpc_codegen.parts import PARTS

SHIP = ROOT / "tests" / "data" / "newuser" / "ship_heading.yaml"
BASE = yaml.safe_load(SHIP.read_text())
EXAMPLES = sorted((ROOT / "examples").glob("*.yaml"))
ERROR = "rollmpc: error: "


def ship(**changes) -> dict:
    """The ship design with ``changes``: top-level keys, or ``plant``/``bounds``/
    ``weights`` of its one mode (merged)."""
    d = copy.deepcopy(BASE)
    mode = d["modes"][0]
    for key, value in changes.items():
        if key in ("plant", "bounds", "weights"):
            mode[key] = {**mode[key], **value} if key != "plant" else value
        elif value is None:
            d.pop(key)
        else:
            d[key] = value
    return d


def state_space(A, B, C) -> dict:
    return {"state_space": {"A": A, "B": B, "C": C}}


def run(tmp_path: Path, capsys, data: dict, *flags: str) -> tuple[int, str, str, Path]:
    """`rollmpc generate` in process: exit code, stdout, stderr and the output directory."""
    config = tmp_path / "design.yaml"
    config.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / "out"
    rc = cli.main(["generate", str(config), "-o", str(out), *flags])
    captured = capsys.readouterr()
    return rc, captured.out, captured.err, out


def refused(tmp_path: Path, capsys, data: dict, *flags: str) -> str:
    """The one error line of a refused design, after exit 2, an empty stdout and nothing
    written."""
    rc, out, err, directory = run(tmp_path, capsys, data, *flags)
    assert rc == 2 and out == "" and not directory.exists(), (rc, out, err)
    assert err.startswith(ERROR) and err.count("\n") == 1, err
    return err[len(ERROR):-1]


# --------------------------------------------------------------------------- item 2: PBH
A_SHIP = BASE["modes"][0]["plant"]["state_space"]["A"]
B_SHIP = BASE["modes"][0]["plant"]["state_space"]["B"]
PBH = [
    pytest.param(  # the yaw rate measured instead of the heading: the heading is hidden
        {"plant": state_space(A_SHIP, B_SHIP, [[0.0, 1.0, 0.0]])},
        "modes[0].plant: the discrete model of mode 'cruise' is not observable: x[2] (pole "
        "s = 0: an integrator) does not reach any output; drop it or measure it (C)",
        id="unobservable-heading"),
    pytest.param(  # the rudder moves the sway only, and nothing couples it to the yaw
        {"plant": state_space([[-0.45, -0.25, 0.0], [0.0, -0.7, 0.0], [0.0, 1.0, 0.0]],
                              [[0.08], [0.0], [0.0]], [[0.0, 0.0, 1.0]])},
        "modes[0].plant: the discrete model of mode 'cruise' is not controllable: the "
        "combination x[1] + 0.7 x[2] (pole s = 0: an integrator) is not moved by any of the "
        "mode's actuators (rudder); drop it or actuate it (B); 1 more eigenvalue fails the "
        "same way", id="uncontrollable-yaw"),
    pytest.param(  # a sensor mixing the states so that one mode cancels: a direction
        {"plant": state_space([[-0.45, 0.2, 0.0], [0.0, -0.6, 0.0], [0.0, 0.0, -0.7]],
                              [[0.08], [0.04], [0.35]], [[0.75, 1.0, 1.0]])},
        "modes[0].plant: the discrete model of mode 'cruise' is not observable: the "
        "direction x[0] - 0.75 x[1] (pole s = -0.6) does not reach any output; drop it or "
        "measure it (C)", id="unobservable-direction"),
    pytest.param(  # a transfer function whose zero cancels a pole: no states to name
        {"plant": {"transfer_function": {"num": [0.35, 0.35], "den": [1, 3, 2]},
                   "integrator": True}},
        "modes[0].plant: the discrete model of mode 'cruise' is not observable: the pole "
        "s = -1 cancels a zero of the transfer function: remove the common factor from num "
        "and den", id="tf-cancellation"),
    pytest.param(  # a zero at s = 0 cancels the integrator
        {"plant": {"transfer_function": {"num": [0.35, 0.0], "den": [1, 1.15, 0.255]},
                   "integrator": True}},
        "modes[0].plant: the discrete model of mode 'cruise' is not controllable: the pole "
        "s = 0 (an integrator) cancels a zero of G(s) at s = 0: remove the factor s from "
        "num, or set integrator: false", id="tf-zero-at-integrator"),
    pytest.param(  # a lightly damped roll oscillation the compass cannot see
        {"plant": {"transfer_function": {"num": [0.35, 0.07, 1.4],
                                         "den": [1, 0.9, 4.14, 2.8]},
                   "integrator": True}},
        "modes[0].plant: the discrete model of mode 'cruise' is not observable: the pole "
        "s = -0.1 ± 1.997j cancels a zero of the transfer function: remove the common "
        "factor from num and den", id="tf-oscillation"),
]


@pytest.mark.parametrize("changes, message", PBH)
def test_a_model_defect_names_the_mode_the_eigenvalue_and_the_direction(tmp_path, capsys,
                                                                       changes, message):
    assert refused(tmp_path, capsys, ship(**changes)) == message


def test_an_undetectable_kalman_model_names_its_direction():
    """Kalman needs (A, C) detectable: here the heading of a state-space ship model."""
    cfg = parse(ship(plant=state_space(A_SHIP, B_SHIP, [[0.0, 0.0, 1.0]])))
    A = np.array(A_SHIP)
    plant = DiscretePlant(A=np.eye(3) + 0.1 * A, B=0.1 * np.array(B_SHIP),
                          C=np.array([[0.0, 1.0, 0.0]]), Cr=None, Dr=None)
    with pytest.raises(ConfigError) as exc:
        kalman_gain(plant, cfg.modes[0], "modes[0]")
    assert str(exc.value) == ("modes[0].observer: (A, C) is not detectable: no Kalman filter "
                              "converges: x[2] (eigenvalue z = 1: an integrator) does not "
                              "reach any output")


# --------------------------------------------------------------------------- item 3: sizes
PREDICTION = ("rollmpc: predicted on a Cortex-M4F (FPv4-SP) at 72 MHz (float build): flash "
              "67.5 of 128 KiB, RAM 10.1 of 32 KiB, a step without active bounds about 15,000 "
              "of the 7,200,000 cycles of a sample and 1,150 of the solver's 179,865 work "
              "units (an estimate; active bounds cost more)")
FORCE = "; --force-size generates it anyway"
TOO_LARGE = [
    pytest.param({"horizon": 400},  # a user's horizon: 12 s and 36 MB of files here
                 "horizon: too large for the target: the float build needs about 1,640 KiB "
                 "of flash (1,602 KiB of data + 38 KiB of code; modes[0]: n = 400 "
                 "variables, m = 1600 rows), above target.flash_kib = 128" + FORCE,
                 id="flash"),
    pytest.param({"target": {"cpu_mhz": 72, "flash_kib": 128, "ram_kib": 8}},
                 "horizon: too large for the target: the float build needs about 10 KiB of "
                 "RAM for one controller instance (modes[0]: n = 50 variables, m = 200 "
                 "rows), above target.ram_kib = 8" + FORCE, id="ram"),
    pytest.param({"target": {"cpu_mhz": 0.1}},  # 10,000 cycles in 0.1 s
                 "horizon: too large for the target: the float build would take about "
                 "15,000 cycles (1,150 work units) for a step without active bounds (an "
                 "estimate; modes[0]: n = 50 variables, m = 200 rows), above the 10,000 of "
                 "one sample (sample_time 0.1 s at target.cpu_mhz = 0.1); what fits: horizon "
                 "<= 28; or control_horizon: 15; or target.cpu_mhz >= 0.154; or sample_time "
                 ">= 0.154" + FORCE,
                 id="cycles"),
    pytest.param({"horizon": 600, "target": None},
                 "horizon: too large for the target: the float build needs about 3,613 KiB "
                 "of flash (3,575 KiB of data + 38 KiB of code; modes[0]: n = 600 "
                 "variables, m = 2400 rows), above the default limit of 2048 KiB (set "
                 "target.flash_kib)" + FORCE, id="default-flash"),
    pytest.param({"horizon": 600, "target": {"flash_kib": 8192}},
                 "horizon: too large for the target: the float build needs about 765 KiB of "
                 "RAM for one controller instance (modes[0]: n = 600 variables, m = 2400 "
                 "rows), above the default limit of 512 KiB (set target.ram_kib)" + FORCE,
                 id="default-ram"),
]


def test_generate_prints_the_prediction(tmp_path, capsys):
    rc, out, err, directory = run(tmp_path, capsys, ship(precision="float"))
    assert (rc, err) == (0, "")
    lines = out.splitlines()  # then the float check's line (tests/host/test_float_check.py)
    assert lines[:2] == [PREDICTION, f"rollmpc: wrote {directory}/ (float; cruise: n=50 m=200)"]
    assert len(lines) == 3 and lines[2].startswith("rollmpc: float check (")


def test_a_double_build_is_judged_as_its_float_build_and_shows_its_own_size(tmp_path, capsys):
    rc, out, err, _ = run(tmp_path, capsys, ship())
    assert (rc, err) == (0, "")
    assert out.splitlines()[:2] == [PREDICTION, "rollmpc: this double build: data 57.6 "
                                    "KiB, controller instance 19.2 KiB"]


@pytest.mark.parametrize("changes, message", TOO_LARGE)
def test_a_design_beyond_its_target_is_refused_before_the_maths(tmp_path, capsys, changes,
                                                                message):
    start = time.perf_counter()
    assert refused(tmp_path, capsys, ship(**changes)) == message
    assert time.perf_counter() - start < 0.5  # the maths of N = 600 takes ~30 s


@pytest.mark.parametrize("drop_output_bounds, message", [
    (False, "horizon: too long: modes[0] would have 40000 QP rows; at most 32767 supported"),
    (True, "horizon: too long: condensing modes[0] would need 2,400,000,000 bytes of dense "
           "N x N matrices; at most 536,870,912 supported")])
def test_a_horizon_of_10000_is_refused_in_well_under_a_second(tmp_path, capsys,
                                                             drop_output_bounds, message):
    data = ship(horizon=10_000)
    if drop_output_bounds:
        del data["modes"][0]["bounds"]["y_min"], data["modes"][0]["bounds"]["y_max"]
    start = time.perf_counter()
    assert refused(tmp_path, capsys, data, "--force-size") == message  # a safety limit
    assert time.perf_counter() - start < 0.5


@pytest.mark.slow
def test_force_size_generates_it_and_force_does_not(tmp_path, capsys):
    small = ship(target={"flash_kib": 16}, precision="float")
    message = ("horizon: too large for the target: the float build needs about 67 KiB of "
               "flash (29 KiB of data + 38 KiB of code; modes[0]: n = 50 variables, m = 200 "
               "rows), above target.flash_kib = 16" + FORCE)
    assert refused(tmp_path, capsys, small) == message
    assert refused(tmp_path, capsys, small, "--force") == message  # the directory rule only
    rc, out, err, directory = run(tmp_path, capsys, small, "--force-size")
    assert (rc, err) == (0, "") and (directory / "ship.h").is_file()
    assert out.startswith("rollmpc: predicted on a Cortex-M4F (FPv4-SP) at 168 MHz (float build): "
                          "flash 67.5 of 16 "
                          "KiB, RAM 10.1 of 512 KiB (default limit), ")


def test_a_slow_design_is_announced_before_the_dense_maths(tmp_path, monkeypatch):
    """N = 250: the condensing matrices pass 1 MiB, so the CLI prints before condensing."""
    events = []
    condense = pipeline.condense
    monkeypatch.setattr(pipeline, "condense",
                        lambda *a: events.append("condense") or condense(*a))
    cfg = parse(ship(horizon=250, target=None, precision="float"))
    pipeline.generate_config(cfg, tmp_path / "out",
                             announce=lambda fp: events.append(("announce", fp.slow)))
    assert events == [("announce", True), "condense"]
    assert not predict(parse(ship())).slow


def test_the_python_api_refuses_the_same_way(tmp_path):
    import rollmpc_codegen as rm

    d = ship(target={"flash_kib": 16})
    design = rm.Design(**{k: d.pop(k) for k in ("sample_time", "horizon", "outputs",
                                                  "actuators", "modes")}, **d)
    with pytest.raises(ConfigError) as exc:
        design.generate(tmp_path / "api")
    assert str(exc.value).startswith("horizon: too large for the target: the float build "
                                     "needs about 67 KiB of flash")
    assert not (tmp_path / "api").exists()
    design.generate(tmp_path / "api", force_size=True)
    assert (tmp_path / "api" / "ship.h").is_file()


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_every_example_fits_its_target_in_both_precisions(path):
    for precision in ("double", "float"):
        cfg = load(path, precision)
        check_fits(cfg, predict(cfg))


def test_the_default_limits_are_the_largest_declared_part():
    """Without target.flash_kib / ram_kib, generate refuses what no declared part holds:
    2 MiB of flash and a 512 KiB RAM region (the F765's and the H743's)."""
    assert DEFAULT_FLASH_LIMIT_KIB == max(p.flash.kib for p in PARTS.values()) == 2048
    assert DEFAULT_RAM_LIMIT_KIB == max(p.ram.kib for p in PARTS.values()) == 512


# median steps measured on the emulated M4F, float, at d2fac9d (docs/target.md, "Before
# generation"); chain_of_masses': of its steps whose output rows are certified (its
# median step also predicts them, 58,932, which the estimate does not count); the two
# designs of tests/data/newuser (`rollmpc report --precision float`, docs/checks.md)
MEASURED_MEDIANS = [("uav_roll", 25, 10_678), ("uav_roll", 50, 18_988),
                    ("uav_roll", 100, 35_618), ("uav_roll", 200, 68_784),
                    ("uav_roll_blocked", None, 20_926), ("chain_of_masses", None, 32_898),
                    ("quad_attitude", None, 60_139), ("newuser/buck", None, 4_021),
                    ("newuser/ship_heading", None, 17_467)]


@pytest.mark.parametrize("example, horizon, cycles", MEASURED_MEDIANS)
def test_the_cycle_estimate_is_within_20_percent_of_the_measured_median(example, horizon,
                                                                        cycles):
    where = ROOT / "tests" / "data" if example.startswith("newuser/") else ROOT / "examples"
    data = yaml.safe_load((where / f"{example}.yaml").read_text())
    data["horizon"] = horizon or data["horizon"]
    assert abs(predict(parse(data)).step_cycles / cycles - 1) <= 0.15


# --------------------------------------------------------------------------- item 4: rest
def warned(tmp_path, capsys, **changes) -> str:
    """stderr of a generation that succeeds (exit 0, files written)."""
    rc, out, err, directory = run(tmp_path, capsys, ship(**changes))
    assert rc == 0 and (directory / "ship.h").is_file() and "rollmpc: wrote" in out
    return err


def test_a_bound_above_rest_that_no_rudder_reaches_in_time_warns(tmp_path, capsys):
    assert warned(tmp_path, capsys, bounds={"y_min": 10, "y_max": 30}) == (
        "rollmpc: warning: modes[0] (cruise): heading >= 10 deg (bounds.y_min) cannot be "
        "met from rest: at prediction step 1 the inputs within their bounds reach heading = "
        "0.05979 deg at most, so the QP near rest is INFEASIBLE; widen the bound or make it "
        "soft (bounds.soft)\n")


def test_a_bound_below_rest_warns_with_the_lowest_reach(tmp_path, capsys):
    assert warned(tmp_path, capsys, bounds={"y_min": -30, "y_max": -10}) == (
        "rollmpc: warning: modes[0] (cruise): heading <= -10 deg (bounds.y_max) cannot be "
        "met from rest: at prediction step 1 the inputs within their bounds reach heading = "
        "-0.05979 deg at least, so the QP near rest is INFEASIBLE; widen the bound or make "
        "it soft (bounds.soft)\n")


@pytest.mark.parametrize("bounds", [
    {"y_min": 0.05, "y_max": 30},  # excludes rest, but the rudder gets there by step 1
    {"y_min": 10, "y_max": 30, "soft": {"y_min": {"l1": 0, "l2": 1e4}}},  # a slack holds it
], ids=["reachable", "soft"])
def test_a_bound_the_inputs_can_meet_or_a_soft_one_does_not_warn(tmp_path, capsys, bounds):
    assert warned(tmp_path, capsys, bounds=bounds) == ""


@pytest.mark.parametrize("y_min, status", [(10, 3), (0.05, 0)])  # INFEASIBLE, OPTIMAL
def test_the_warning_is_what_the_solver_finds_at_rest(y_min, status):
    """The reference solver (the C's mirror) on the QP at rest: INFEASIBLE exactly when
    generate warns."""
    from rollmpc_codegen.codegen.context import build_context
    from rollmpc_codegen.reference.solver import SolverRef

    model = pipeline.build_model(parse(ship(bounds={"y_min": y_min, "y_max": 30})))
    solver = SolverRef(model.modes[0].data, build_context(model)["solver"])
    assert solver.solve_mode(np.zeros(3), np.full(50, 20.0))[0] == status
    assert len(rest_warnings(model)) == (status == 3)


def test_bounds_that_only_conflict_together_are_named_together():
    """Two outputs that are the same state: each bound alone is reachable at step 1,
    both together are not."""
    data = ship(outputs=["heading", "heading_copy"], units=None, simulation=None,
                plant={"state_space": {"A": [[0.5]], "B": [[2.0]], "C": [[1.0], [1.0]],
                                       "discrete": True}},
                bounds={"y_min": [1, -30], "y_max": [30, 0.5]},
                weights={"Q": 1, "R": 0.1, "P": 1})
    model = pipeline.build_model(parse(data))
    assert [w.message for w in rest_warnings(model)] == [
        "modes[0] (cruise): the output bounds cannot all be met from rest: at prediction "
        "step 1 no input within its bounds meets them together, so the QP near rest is "
        "INFEASIBLE; widen them or make them soft (bounds.soft)"]


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_no_example_warns(path):
    """Neither warning of generate: bounds unreachable from rest, nor a controller that
    does not stabilise its model (qp/nominal_loop.py; every example's radius is at most
    0.995, c172_roll's)."""
    model = load_model(path)[0]
    assert rest_warnings(model) == []
    assert unstable_law_warnings(model) == []
    assert design_warnings(model) == []  # nor the sanity checks (docs/checks.md)
    assert max(closed_loop_radius(model, j) for j in range(len(model.modes))) < 0.996
