"""The Python API (rollmpc_codegen.api): the same C as the YAML, python-control plants, the
same ConfigError messages, the YAML round trip, the host build; and the config hash of the
effective configuration."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import control as ct
import numpy as np
import pytest
import yaml

import rollmpc_codegen as rm
from conftest import ROOT, UAV, config_error, edited_config
from rollmpc_codegen.config import ConfigError, load, parse

G_INNER = ct.tf([-74.15, 8892], [1, 59.11, 1599, 7936])
G_OUTER = ct.tf([4.746, -392.5, 2.443e4, 2.064e5], [1, 80.26, 3026, 2.829e4, 1.21e5])


def uav_args(inner: dict | None = None, outer: dict | None = None, **top) -> dict:
    """The rm.Design arguments of examples/uav_roll.yaml (python-control plants), with
    extra keywords for each Mode and top-level changes (a dict is merged into the default)."""
    common = dict(integrator=True, Q=10, R=10, u_bounds=(-15, 15), y_bounds=(-270, 270))
    inner_poles = [0.80, 0.8333333333333334, 0.8666666666666667, 0.90]
    outer_poles = [0.80, 0.825, 0.85, 0.875, 0.90]
    args = dict(
        sample_time=0.01, horizon=100, outputs=["roll"], actuators=["inner", "outer"],
        modes=[rm.Mode("inner", G_INNER, actuators=["inner"], **{
                   **common, "P": 1e6, "observer": {"poles": inner_poles}, **(inner or {})}),
               rm.Mode("outer", G_OUTER, actuators=["outer"], **{
                   **common, "P": 1e9, "observer": {"poles": outer_poles}, **(outer or {})})],
        prefix="rollmpc", precision="double",
        units={"outputs": "deg", "actuators": "deg", "schedule": "deg/s"},
        scheduler={"signal": "roll_rate", "lower": -16, "upper": 16, "epsilon": 0.5,
                   "inside": "inner", "outside": "outer"},
        solver={"method": "hildreth_plus_prime", "omega": 1.2, "sigma": 0.2, "delta": 1e-13,
                "max_iterations": 1000, "warm_start": True, "polish": True,
                "work_budget": 100000},
        simulation={"schedule_source": "output_rate"},
        target={"cpu_mhz": 168, "flash_kib": 256, "ram_kib": 32})
    for key, value in top.items():
        args[key] = {**args[key], **value} if isinstance(args.get(key), dict) else value
    return args


def uav_design() -> rm.Design:
    return rm.Design(**uav_args())


def chain_design() -> rm.Design:
    """examples/chain_of_masses.yaml from its physics, as a continuous control.StateSpace."""
    n = 6
    coupling = -2 * np.eye(n) + np.eye(n, k=1) + np.eye(n, k=-1)  # springs, k = 1 N/m
    A = np.block([[np.zeros((n, n)), np.eye(n)], [coupling, 0.1 * coupling]])  # d = 0.1
    B = np.zeros((2 * n, 4))
    B[[n, n + 2, n + 3, n + 5], range(4)] = 1.0  # forces on masses 1, 3, 4, 6
    C = np.hstack([np.eye(n), np.zeros((n, n))])
    return rm.Design(
        sample_time=0.5, horizon=10, outputs=[f"p{i}" for i in range(1, 7)],
        actuators=["f1", "f3", "f4", "f6"], prefix="chain", precision="double",
        modes=[rm.Mode("chain", ct.ss(A, B, C, 0), weights={"Q": 10, "R": 1, "P": 10},
                       bounds={"u_min": -0.5, "u_max": 0.5, "y_min": -0.6, "y_max": 0.6})],
        simulation={"reference": {"segment": 20.0, "levels": [
            0.0, 0.5, -0.5, [0.4, 0.2, 0.0, 0.0, -0.2, -0.4], 0.0]}})


def quadruple_tank_design() -> rm.Design:
    """examples/quadruple_tank.yaml: a 2x2 control.TransferFunction, a Kalman observer."""
    G = ct.tf([[[2.6], [1.5]], [[1.4], [2.8]]],
              [[[62, 1], [1426, 85, 1]], [[2700, 120, 1], [90, 1]]])
    return rm.Design(
        sample_time=5.0, horizon=20, outputs=["h1", "h2"], actuators=["v1", "v2"],
        prefix="qtank", precision="double",
        modes=[rm.Mode("tanks", G, Q=1, R=0.01, P=10, u_bounds=(-3, 3),
                       y_bounds=([-10, -10], [7, 7]),
                       observer={"kind": "kalman", "Qn": 0.01, "Rn": 0.01,
                                 "disturbance": "input", "Qd": 0.001})],
        simulation={"reference": {"segment": 400.0, "levels": [
            0.0, [3.0, 2.0], [2.0, -2.0], [-4.0, 1.0], 0.0]}})


def python(code: str, cwd: Path) -> subprocess.CompletedProcess:
    """``code`` in a fresh interpreter that imports this source tree."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def files_of(directory: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())}


@pytest.mark.parametrize("design,committed,precision", [
    (uav_design, "uav_roll", None),
    pytest.param(uav_design, "uav_roll_f32", "float", marks=pytest.mark.slow),
    (chain_design, "chain_of_masses", None), (quadruple_tank_design, "quadruple_tank", None)])
def test_api_generates_the_committed_files(tmp_path, design, committed, precision):
    """The API design renders byte for byte the files `make generate` committed from the
    YAML (the config hash included: it is the hash of the effective configuration)."""
    design().generate(tmp_path / "out", precision=precision)
    assert files_of(tmp_path / "out") == files_of(ROOT / "generated" / committed)


def test_readme_command_reproduces_the_committed_tree(tmp_path):
    """Change detector (a snapshot of generated/): without --precision (the precision from
    the file) the README's command gives the committed tree, hash lines included."""
    from rollmpc_codegen.cli.main import main

    assert main(["generate", str(UAV), "-o", str(tmp_path / "uav")]) == 0
    assert files_of(tmp_path / "uav") == files_of(ROOT / "generated" / "uav_roll")


def test_hash_is_the_effective_configuration(tmp_path):
    in_file = edited_config(tmp_path, UAV, "uav_float", lambda d: d.update(precision="float"))
    overridden = load(UAV, "float")
    assert load(in_file).config_hash == overridden.config_hash
    assert load(in_file) == overridden
    assert load(UAV).config_hash != overridden.config_hash  # the precision is hashed
    # comments and spelling (1.0e6 vs 1000000) do not count; a changed number does
    respelled = edited_config(tmp_path, UAV, "uav_respelled", lambda d: None)
    assert respelled.read_text() != UAV.read_text()
    assert load(respelled).config_hash == load(UAV).config_hash
    heavier = edited_config(tmp_path, UAV, "uav_q11",
                            lambda d: d["modes"][0]["weights"].update(Q=11))
    assert load(heavier).config_hash != load(UAV).config_hash


def test_to_yaml_round_trips(tmp_path):
    design = uav_design()
    text = design.to_yaml(tmp_path / "design.yaml")
    assert parse(yaml.safe_load(text)) == design.config
    assert load(tmp_path / "design.yaml").config_hash == design.config.config_hash
    assert design.config == load(UAV)
    rich = rm.Design(  # inf, complex poles, numpy arrays and scalars, nested options
        sample_time=0.1, horizon=12, outputs=["a", "b"], actuators=["u"],
        control_horizon=4, solver={"max_iterations": np.int64(50)},
        modes=[rm.Mode("m", (np.diag([0.5, -0.2]), [[1.0], [0.5]], np.eye(2)),
                       Q=np.array([1.0, 2.0]), R=np.float64(0.1), R_delta=0.5,
                       u_bounds=(-1, 1), y_min=[-np.inf, -2.0], y_max=[np.inf, 2.0],
                       soft={"y_max": {"l1": 0, "l2": [0, 100]}},
                       observer={"poles": [0.5 + 0.1j, 0.5 - 0.1j, 0.6]})])
    text = rich.to_yaml()
    assert ".inf" in text
    assert parse(yaml.safe_load(text)) == rich.config
    assert rich.config.modes[0].observer_poles == (0.5 + 0.1j, 0.5 - 0.1j, 0.6 + 0j)
    assert rich.config.modes[0].blocks == (1, 1, 1, 9)


def markov(ctx_mode: dict, count: int = 30) -> np.ndarray:
    """The first ``count`` Markov parameters C A^k B of a mode's discrete model."""
    A, B, C = (np.array(ctx_mode[k]) for k in "ABC")
    out, AkB = [], B
    for _ in range(count):
        out.append(C @ AkB)
        AkB = A @ AkB
    return np.array(out)


def one_mode(plant, sample_time: float = 0.01, **mode) -> rm.Design:
    return rm.Design(sample_time=sample_time, horizon=20, outputs=["y"], actuators=["u"],
                     modes=[rm.Mode("m", plant, Q=10, R=1, u_bounds=(-15, 15), **mode)])


def test_python_control_plants_give_the_same_discrete_model():
    """A continuous TF, its StateSpace, its ZOH-sampled StateSpace and TF, the YAML-form
    dict and an (A, B, C) tuple are one plant: the same discrete response."""
    S = ct.ss(G_INNER)
    reference = markov(one_mode(G_INNER).build()[1]["modes"][0])
    assert np.abs(reference).max() > 0.01  # a response worth comparing (not all zeros)
    for plant in (S, ct.c2d(S, 0.01), ct.c2d(G_INNER, 0.01), (S.A, S.B, S.C),
                  {"num": [-74.15, 8892], "den": [1, 59.11, 1599, 7936]},
                  {"A": S.A, "B": S.B, "C": S.C}):
        got = markov(one_mode(plant).build()[1]["modes"][0])
        np.testing.assert_allclose(got, reference, rtol=1e-9, atol=1e-12 * np.abs(reference).max())
    discrete = one_mode(ct.c2d(S, 0.01)).config.modes[0].plant
    assert discrete.kind == "state_space" and discrete.discrete
    assert one_mode(ct.tf([1], [1, 1], True)).config.modes[0].plant.discrete  # dt=True


def test_discrete_plant_with_another_sample_time_is_refused():
    with pytest.raises(ConfigError) as exc:
        one_mode(ct.c2d(G_INNER, 0.02))
    assert str(exc.value) == ("modes[0].plant: is discrete with dt = 0.02, but sample_time is "
                              "0.01: resample it (control.sample_system) or give the "
                              "continuous plant")
    with pytest.raises(ConfigError, match=r"^modes\[0\]\.plant: must be a control"):
        one_mode("G(s)")


@pytest.mark.parametrize("api_change,yaml_edit", [
    (dict(inner={"Q": -1}), lambda d: d["modes"][0]["weights"].update(Q=-1)),
    (dict(outer={"u_bounds": (1, 15)}), lambda d: d["modes"][1]["bounds"].update(u_min=1)),
    (dict(horizon=0), lambda d: d.update(horizon=0)),
    (dict(scheduler={"inside": "middle"}), lambda d: d["scheduler"].update(inside="middle")),
    (dict(solver={"omega": 2.5}), lambda d: d["solver"].update(omega=2.5)),
    (dict(inner={"horizon": 3}), lambda d: d["modes"][0].update(horizon=3)),
])
def test_bad_value_gives_the_yaml_message(tmp_path, api_change, yaml_edit):
    with pytest.raises(ConfigError) as exc:
        rm.Design(**uav_args(**api_change))
    expected = config_error(edited_config(tmp_path, UAV, "bad", yaml_edit))
    assert str(exc.value) == str(expected)


def test_bad_bound_pair_names_the_bounds():
    with pytest.raises(ConfigError) as exc:
        rm.Design(**uav_args(inner={"u_bounds": 15}))
    assert str(exc.value) == "modes[0].bounds: u_bounds must be a pair (u_min, u_max), got 15"


def test_compile_and_step_closed_loop(tmp_path):
    """The host C through cffi: optimal, finite, within bounds, and tracking the reference
    on the generator's own discrete model."""
    design = one_mode(G_INNER, integrator=True, P=1e6)
    ctrl = design.compile()
    mode = ctrl.context["modes"][0]
    A, B, C = (np.array(mode[k]) for k in "ABC")
    x, y, saturated = np.zeros(A.shape[0]), np.zeros(1), 0
    for _ in range(300):
        u, status = ctrl.step(y, None, 10.0)
        assert status == 0, ctrl.status_message(status)
        assert np.all(np.isfinite(u)) and np.all(np.abs(u) <= 15.0)
        saturated += bool(np.abs(u[0]) == 15.0)
        x = A @ x + B @ u
        y = C @ x
    assert saturated > 0  # the step of 10 deg saturates the ailerons first
    assert abs(y[0] - 10.0) < 0.05
    assert ctrl.info()["status"] == 0
    with pytest.raises(ValueError, match="r must have 1 or 20 values, got 3"):
        ctrl.step(y, None, [1.0, 2.0, 3.0])


def readme_block(language: str) -> str:
    """The README quick start's first ``language`` block, as written."""
    section = (ROOT / "README.md").read_text().split("## Quick start", 1)[1]
    return section.split(f"```{language}\n", 1)[1].split("```", 1)[0]


def test_readme_quick_start_yaml_and_python_give_the_same_c(tmp_path):
    """The README's quick start, as written, in a fresh interpreter: its YAML through the
    CLI and its Python through the API write the same files, and the compiled controller
    steps with a finite command within its bounds."""
    (tmp_path / "motor.yaml").write_text(readme_block("yaml"))
    cli = python("import sys; from rollmpc_codegen.cli.main import main; sys.exit(main(["
                 "'generate', 'motor.yaml', '-o', 'motor_c', '--precision', 'float', "
                 "'--no-float-check']))", tmp_path)
    assert cli.returncode == 0, cli.stderr
    proc = python(readme_block("python"), tmp_path)
    assert proc.returncode == 0, proc.stderr
    u0, message = proc.stdout.split()[-2:]
    assert message == "optimal" and abs(float(u0.strip("[]"))) <= 12.0
    assert files_of(tmp_path / "motor_py") == files_of(tmp_path / "motor_c")
    assert "motor.h" in files_of(tmp_path / "motor_c")


def test_import_is_cheap(tmp_path):
    """``import rollmpc_codegen`` loads no compiler glue, python-control, NumPy or the
    pipeline: only model.blas_kernels, which must run before NumPy loads."""
    code = ("import sys, rollmpc_codegen; print(sorted(m for m in sys.modules if m.split('.')[0] "
            "in ('cffi', 'control', 'jinja2', 'numpy') or (m.startswith('rollmpc_codegen.') "
            "and m not in ('rollmpc_codegen.model', 'rollmpc_codegen.model.blas_kernels'))))")
    proc = python(code, tmp_path)
    assert proc.returncode == 0 and proc.stdout.strip() == "[]", proc.stdout + proc.stderr
