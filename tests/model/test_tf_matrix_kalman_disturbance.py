"""Transfer-function matrix plants, the steady-state Kalman observer and
offset-free tracking (disturbance models), end to end.

examples/quadruple_tank.yaml has all three (a 2x2 TF matrix, realised with 4 states;
Kalman; input-disturbance model: 6 states).  Variants written to tmp_path switch one
feature at a time.  Checked: the realisation's frequency response equals the matrix and
its order is the McMillan degree; the Kalman gain is the predictor-form DARE gain;
P_step bit for bit against the NumPy reference over the disturbed closed loop (both
precisions); the double QP solutions within 1e-8 of DAQP and of the extended-precision
solution; the steady offset of a constant input disturbance (and of a plant-gain
mismatch) is present without a disturbance model and gone with one (tank and the
two-mode UAV); one-line errors naming the key; the UAV's matrices unchanged.
"""
from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest
import scipy.linalg
import yaml

from conftest import (ROOT, UAV, Built, config_error, edited_config,
                      sampled_qps_against_independent_solvers, simulate_and_bench)
from lockstep import Lockstep
from rollmpc_codegen.host.build import build_host_controller
from rollmpc_codegen.cli.main import main
from rollmpc_codegen.config import load, parse
from rollmpc_codegen.pipeline import build_model
from rollmpc_codegen.pipeline import generate, load_model
from rollmpc_codegen.model.observer import process_noise
from rollmpc_codegen.model.plant import continuous_realisation
from rollmpc_codegen.sim.scenario import SimulatedPlant, scenario_reference
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.status import OPTIMAL
from rollmpc_codegen.model.tf_realisation import (column_realisation, frequency_response,
                                            matrix_response)

TANK = ROOT / "examples" / "quadruple_tank.yaml"
DIST = 0.3  # V on both pumps, the constant input disturbance of the closed-loop runs
SEGMENT, N_TANK = 80, 20  # samples per reference level, horizon
# the last sample of each level before the preview sees the next step (steady state)
STEADY = [SEGMENT * (i + 1) - N_TANK - 1 for i in range(4)]
KALMAN = {"kind": "kalman", "Qn": 0.01, "Rn": 0.01}


def _tank_observer(**observer):
    def edit(data):
        data["modes"][0]["observer"] = observer
    return edit


def _steady_error(log) -> np.ndarray:
    return np.abs(log.y[STEADY] - log.r[STEADY])


# --------------------------------------------------------------------------- TF matrix
def test_tf_matrix_realisation_is_minimal_and_exact():
    cfg = load(TANK)
    plant = cfg.modes[0].plant
    assert plant.kind == "transfer_function" and plant.tf_matrix is not None
    cont = continuous_realisation(plant, "modes[0]")
    # 6 states column by column (poles 1/62 and 1/90 twice), 4 minimal: the McMillan degree
    assert column_realisation(plant.tf_matrix)[0].shape == (6, 6)
    assert cont.A.shape == (4, 4)
    assert np.allclose(np.sort(np.linalg.eigvals(cont.A).real),
                       -1.0 / np.array([23.0, 30.0, 62.0, 90.0]), rtol=1e-10, atol=0)
    D = np.zeros((2, 2))
    for w in np.logspace(-4, 1, 25):
        G = matrix_response(plant.tf_matrix, 1j * w)
        H = frequency_response(cont.A, cont.B, cont.C, D, 1j * w)
        assert np.abs(H - G).max() <= 1e-12 * np.abs(G).max(), w


def test_tf_matrix_with_integrator_and_feedthrough():
    """integrator: true appends 1/s per output; a biproper element's D feeds the rate
    output; a zero element and a pole-zero cancellation leave no state behind."""
    data = yaml.safe_load(TANK.read_text())
    tf = data["modes"][0]["plant"]["transfer_function"]
    tf["num"] = [[[1, 2], [3]], [0, [1, 0, 4]]]  # (s+2)/((s+1)(s+2)) cancels; 0; biproper
    tf["den"] = [[[1, 3, 2], [1, 5]], [[1], [1, 1, 1]]]
    data["modes"][0]["plant"]["integrator"] = True
    data["modes"][0]["observer"] = KALMAN
    cfg = parse(data)
    plant = cfg.modes[0].plant
    cont = continuous_realisation(plant, "modes[0]")
    assert cont.A.shape == (6, 6)  # McMillan degree 4 (poles -1, -5, s^2+s+1) + 2 integrators
    for w in (0.05, 0.7, 3.0, 20.0):
        s = 1j * w
        G = matrix_response(plant.tf_matrix, s)
        H = frequency_response(cont.A, cont.B, cont.C, np.zeros((2, 2)), s)
        assert np.abs(H - G / s).max() <= 1e-11 * np.abs(G / s).max()
        Hr = frequency_response(cont.A, cont.B, cont.Cr, cont.Dr, s)  # the rate: G itself
        assert np.abs(Hr - G).max() <= 1e-11 * np.abs(G).max()
    model = build_model(cfg)  # observer (Kalman on the integrating plant) and QP build
    assert model.modes[0].plant.nx == 6


@pytest.mark.parametrize("edit, key, text", [
    (lambda tf: tf.update(num=[[[2.6], [1.5]]], den=[62, 1]),
     "modes[0].plant.transfer_function.num",
     "2x2"),
    (lambda tf: tf.update(den=[[[62, 1], [1426, 85, 1]]]),
     "modes[0].plant.transfer_function.den", "shape of num"),
    (lambda tf: tf["num"][1].__setitem__(0, [1, 2, 3, 4]),
     "modes[0].plant.transfer_function.num[1][0]", "improper"),
    (lambda tf: tf["num"][0].__setitem__(1, [1, 0, 0]),
     "modes[0].plant.transfer_function.num[0][1]", "feedthrough"),
    (lambda tf: tf["num"][1].append([1.0]), "modes[0].plant.transfer_function.num[1]",
     "has 3 elements where modes[0].plant.transfer_function.num[0] has 2"),
])
def test_tf_matrix_errors_name_the_key(tmp_path, edit, key, text):
    path = edited_config(tmp_path, TANK, "bad",
                    lambda d: edit(d["modes"][0]["plant"]["transfer_function"]))
    err = config_error(path)
    assert err.key == key and text in err.problem


# --------------------------------------------------------------------------- Kalman
def test_kalman_gain_is_the_predictor_form_dare_gain():
    model, ctx = load_model(TANK)
    mm, mode = model.modes[0], model.config.modes[0]
    A, C = mm.plant.A, mm.plant.C
    assert (mm.plant.nx, mm.plant.nd) == (6, 2)
    Qx = process_noise(mm.plant, mode)
    P = scipy.linalg.solve_discrete_are(A.T, C.T, Qx, mode.observer_Rn)
    L = A @ P @ C.T @ np.linalg.inv(C @ P @ C.T + mode.observer_Rn)
    assert np.allclose(mm.observer_gain, L, rtol=1e-9, atol=1e-12)
    poles = np.linalg.eigvals(A - L @ C)
    assert np.abs(poles).max() < 1.0
    assert np.allclose(np.sort_complex(poles), np.sort_complex(
        [complex(*p) for p in ctx["modes"][0]["observer_poles"]]), atol=1e-9)


@pytest.mark.parametrize("observer, key, text", [
    ({"kind": "kalman", "Qn": 1, "Rn": [[1, 0], [0, 0]]}, "observer.Rn", "positive definite"),
    ({"kind": "kalman", "Qn": [[1, 2], [2, 1]], "Rn": 1}, "observer.Qn", "semidefinite"),
    ({"kind": "kalman", "Qn": [1, 1, 1], "Rn": 1}, "observer.Qn", "must have 2 entries"),
    ({"kind": "kalman", "Qn": 1}, "observer.Rn", "missing"),
    ({"kind": "kalman", "Qn": 1, "Rn": 1, "poles": [0.5]}, "observer.poles", "kind: poles"),
    ({"kind": "kalman", "Qn": 1, "Rn": 1, "Qd": 1}, "observer.Qd", "disturbance"),
    ({"kind": "kalman", "Qn": 1, "Rn": 1, "disturbance": "input"}, "observer.Qd", "missing"),
    ({"Qn": 1}, "observer.Qn", "kind: kalman"),
    ({"kind": "luenberger"}, "observer.kind", "one of"),
    ({"disturbance": "state"}, "observer.disturbance", "one of"),
    ({"disturbance": "input", "poles": [0.8, 0.81, 0.82, 0.83]}, "observer.poles",
     "6 states: 4 of the plant + 2 disturbance states"),
])
def test_observer_errors_name_the_key(tmp_path, observer, key, text):
    path = edited_config(tmp_path, TANK, "bad", _tank_observer(**observer))
    err = config_error(path, load_model)
    assert err.key == f"modes[0].{key}" and text in err.problem


def test_two_output_placement_is_exact_and_quiet(tmp_path):
    """With two outputs scipy's robust placement warns that its iteration stopped short
    (this config did); the poles are placed all the same, so generation is silent and the
    observer's poles are the six asked for."""
    import warnings

    from rollmpc_codegen.model.observer import default_poles

    path = edited_config(tmp_path, TANK, "placed", _tank_observer(disturbance="input"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model, _ = load_model(path)
    mode = model.modes[0]
    A, C = mode.plant.A, mode.plant.C
    achieved = np.sort(np.linalg.eigvals(A - mode.observer_gain @ C).real)
    assert np.allclose(achieved, np.sort(np.real(default_poles(6))), atol=1e-12, rtol=0)


@pytest.mark.parametrize("observer, key, text", [
    # the integrator (roll angle = G(s)/s) is a marginal mode no input noise of 0 drives
    ({"kind": "kalman", "Qn": 0, "Rn": 1}, "observer.Qn", "process noise"),
    # an output disturbance looks exactly like the integrator: not observable
    ({"disturbance": "output"}, "observer.disturbance", "integrator"),
])
def test_uav_observer_errors(tmp_path, observer, key, text):
    def edit(data):
        for m in data["modes"]:
            m["observer"] = dict(observer)
    err = config_error(edited_config(tmp_path, UAV, "bad", edit), load_model)
    assert err.key == f"modes[0].{key}" and text in err.problem


def test_cli_error_is_one_line(tmp_path):
    path = edited_config(tmp_path, TANK, "bad", _tank_observer(kind="kalman", Qn=1, Rn=0))
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        rc = main(["generate", str(path), "-o", str(tmp_path / "out")])
    assert rc == 2 and err.getvalue().count("\n") == 1
    assert err.getvalue().startswith("rollmpc: error: modes[0].observer.Rn")
    assert not (tmp_path / "out").exists()


def test_uav_matrices_unchanged_by_the_new_defaults():
    """Change detector (against the committed generated/uav_roll): with no new key in
    examples/uav_roll.yaml, the plant, observer and Kx it was rendered from, bit for bit."""
    committed = json.loads((ROOT / "generated" / "uav_roll" / "rollmpc_context.json").read_text())
    model, ctx = load_model(UAV)
    for mm, new, old in zip(model.modes, ctx["modes"], committed["modes"]):
        assert mm.plant.nd == 0 and mm.qp.Ut is None
        for k in ("A", "B", "C", "L", "Kx", "observer_poles"):
            assert new[k] == old[k], k


# --------------------------------------------------------------------------- closed loop
@pytest.fixture(scope="module", params=["double", "float"])
def tank_run(request, build_root):
    built = Built(TANK, request.param, build_root)
    lock = Lockstep(built)
    log = run_closed_loop(built.model.config, lock, disturbance=DIST, info=lock.info)
    return built, lock, log


def test_step_bit_exact_over_disturbed_closed_loop(tank_run):
    built, lock, log = tank_run
    assert len(log.t) == 400 and built.ctx["modes"][0]["nx"] == 6
    assert lock.mismatches == [], f"{len(lock.mismatches)} mismatching steps, first: " \
                                  f"{lock.mismatches[0]}"
    assert np.all(log.status == OPTIMAL)
    assert np.any(np.abs(log.u) == 3.0) and np.all(np.abs(log.u) <= 3.0)  # saturates
    tol = 1e-3 if built.ctx["precision"] == "float" else 1e-6
    assert _steady_error(log).max() < 0.02 + tol  # offset-free (the R offset: <= 0.018)


def test_double_matches_independent_solvers(tank_run):
    built, lock, log = tank_run
    if built.ctx["precision"] != "double":
        pytest.skip("the independent check is a double-precision property")
    # qp_data's gradient includes the offset-free target term (CondensedQP.gradient)
    saturated, worst_daqp, worst_exact = sampled_qps_against_independent_solvers(
        built, lock.states, scenario_reference(built.model.config), bound=3.0, perturb=4.0,
        seed=7)
    assert saturated >= 4
    assert worst_daqp <= 1e-8 and worst_exact <= 1e-8, (worst_daqp, worst_exact)


def _tank_log(tmp_path, build_root, name, observer, true_plant=None, disturbance=DIST,
              R=None):
    def edit(data):
        _tank_observer(**observer)(data)
        if R is not None:
            data["modes"][0]["weights"]["R"] = R
    model, ctx = load_model(edited_config(tmp_path, TANK, name, edit))
    c = build_host_controller(ctx, build_root)
    cfg = model.config if true_plant is None else load(true_plant)
    return run_closed_loop(cfg, c, disturbance=disturbance, info=c.info)



def test_input_disturbance_offset_removed(tmp_path, build_root):
    nominal = _tank_log(tmp_path, build_root, "none", KALMAN, disturbance=0.0)
    without = _tank_log(tmp_path, build_root, "none", KALMAN)
    with_model = _tank_log(tmp_path, build_root, "input",
                           {**KALMAN, "disturbance": "input", "Qd": 0.001})
    placed = _tank_log(tmp_path, build_root, "placed", {"disturbance": "input"})
    assert _steady_error(without).min() > 0.3  # measured 0.33 .. 0.43 cm
    # the disturbed loop settles where the undisturbed one does (its R offset <= 0.018 cm)
    for log in (with_model, placed):
        # (the first level: still settling from the disturbance switched on at t = 0)
        assert np.abs(log.y[STEADY[1:]] - nominal.y[STEADY[1:]]).max() < 1e-4
        assert np.all(log.status == OPTIMAL)


def test_output_disturbance_removes_a_gain_mismatch(tmp_path, build_root):
    """The true plant's gains are 20 % higher than the model's: an output-disturbance
    model removes the offset (simulated on the unaugmented, mismatched plant).  R is
    small so that the nominal offset of absolute input weighting does not mask it."""
    def stronger(data):
        tf = data["modes"][0]["plant"]["transfer_function"]
        tf["num"] = [[[1.2 * v for v in e] for e in row] for row in tf["num"]]
    true_plant = edited_config(tmp_path, TANK, "true", stronger)
    without = _tank_log(tmp_path, build_root, "none", KALMAN, true_plant, 0.0, R=1e-4)
    with_model = _tank_log(tmp_path, build_root, "output",
                           {**KALMAN, "disturbance": "output", "Qd": 0.001}, true_plant, 0.0,
                           R=1e-4)
    assert _steady_error(without)[1:].min() > 0.04  # measured 0.045 .. 0.40 cm
    assert _steady_error(with_model).max() < 0.005  # measured <= 0.0016 cm (settling)


@pytest.mark.slow  # the input model's offset removal: test_input_disturbance_offset_removed
def test_uav_input_disturbance_offset_removed(tmp_path, build_root):
    """Both UAV modes with an input-disturbance model (5 resp. 6 states), switching."""
    def short(obs):
        def edit(data):
            data["horizon"] = 20
            data["simulation"]["reference"] = {"levels": [0.0, 20.0, 0.0], "segment": 3.0}
            for m in data["modes"]:
                m["observer"] = dict(obs) if obs else m["observer"]
        return edit
    logs = {}
    for name, obs in (("plain", None), ("input", {"disturbance": "input"})):
        model, ctx = load_model(edited_config(tmp_path, UAV, f"uav_{name}", short(obs)))
        c = build_host_controller(ctx, build_root)
        logs[name] = run_closed_loop(model.config, c, disturbance=1.0, info=c.info)
    assert [m["nx"] for m in ctx["modes"]] == [5, 6]
    steady = [270, 570, 870]  # 0.3 s before each next level (N = 20 samples)
    err = {k: np.abs(v.y[steady, 0] - v.r[steady, 0]) for k, v in logs.items()}
    assert err["plain"].min() > 0.5  # measured 0.74 deg
    assert err["input"].max() < 1e-3
    assert set(logs["input"].mode) == {0, 1}  # the outer pair engages on the 20 deg step


# --------------------------------------------------------------------------- CLI
def test_simulate_and_bench_cli_on_tank(tmp_path):
    summary, _, rows = simulate_and_bench(TANK, tmp_path, "--disturbance", str(DIST))
    assert summary["samples"] == 400 and summary["non_optimal"] == 0
    # the peers solve the QP with the offset-free gradient (CondensedQP.gradient)
    assert rows["default"]["optimal"] == 40 and rows["default"]["max_abs_err"] <= 1e-8
    assert rows["daqp"]["max_abs_err"] <= 1e-8


@pytest.mark.parametrize("precision", ["double", "float"])
def test_tank_generates_and_compiles_strict(tmp_path, precision):
    from compile_flags import STRICT, compile_objects

    _, ctx = generate(TANK, tmp_path / "qtank", precision)
    assert [m["nx"] for m in ctx["modes"]] == [6]  # 4 plant + 2 disturbance states
    proc = compile_objects("gcc", tmp_path / "qtank", ["-O2", "-ffp-contract=off", *STRICT],
                           tmp_path / "obj")
    assert proc.returncode == 0 and not proc.stderr.strip(), proc.stderr


def test_simulated_true_plant_is_unaugmented_and_discrete_as_given(tmp_path):
    """SimulatedPlant: the config's plant without disturbance states; a `discrete: true`
    state-space plant is used as given (not sampled a second time)."""
    tank = SimulatedPlant(load(TANK))
    assert tank.channels[0].A.shape == (4, 4)
    chain = ROOT / "examples" / "chain_of_masses.yaml"
    cont = SimulatedPlant(load(chain)).channels[0]

    def as_discrete(data):
        ss = data["modes"][0]["plant"]["state_space"]
        ss.update(A=cont.A.tolist(), B=cont.B.tolist(), discrete=True)
    disc = SimulatedPlant(load(edited_config(tmp_path, chain, "disc", as_discrete))).channels[0]
    assert np.array_equal(disc.A, cont.A) and np.array_equal(disc.B, cont.B)
