"""The generated C flies the JSBSim c172p (docs/flight.md): `rollmpc identify`
writes examples/c172_roll.yaml, `rollmpc fly` closes the loop in turbulence against the
PX4-style PID, and `rollmpc report --flight` replays a flight on the emulated M4F.

The quick suite flies 10 s in moderate turbulence (float, the M4F's precision) from
99 kts with the airspeed commanded to 110, so the airspeed scheduler switches modes in
flight; the full matrix of docs/flight.md runs in `make check-long`.
"""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import yaml

from conftest import ROOT, cli, require_tool

from rollmpc_codegen.extras import installed

C172 = ROOT / "examples" / "c172_roll.yaml"
FLIGHT_HINT = "jsbsim is missing; install with: pip install 'rollmpc-codegen[flight]'"
needs_jsbsim = pytest.mark.skipif(not installed("jsbsim"), reason=FLIGHT_HINT)
ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"
# roll 0, +20, -20 deg (3.5 s each at least: the settled window needs > 3.3 horizons)
REFERENCE = "t,roll,airspeed\n0,0,110\n3.5,20,110\n7,-20,110\n"
TRACKING_BOUND_DEG = 1.0  # settled |roll - r| per segment, moderate turbulence
SETTLING_BOUND_S = 0.5  # 10 % settling after each step


@pytest.fixture(scope="module")
def flight(tmp_path_factory, build_root):
    """`rollmpc fly` for 10 s with every output; (exit status, stdout, summary, paths)."""
    if not installed("jsbsim"):
        pytest.skip(FLIGHT_HINT)
    out = tmp_path_factory.mktemp("fly")
    (out / "ref.csv").write_text(REFERENCE)
    paths = {name: out / f"flight.{ext}" for name, ext in
             (("csv", "csv"), ("json", "json"), ("plot", "png"))}
    rc, stdout, stderr = cli(["fly", str(C172), "--airspeed", "99", "--turbulence", "moderate",
                              "--seed", "1", "--duration", "10", "--reference",
                              str(out / "ref.csv"), "--precision", "float", "--baseline", "pid",
                              "-q", "--build-dir", str(build_root),
                              *(a for name, p in paths.items() for a in (f"--{name}", str(p)))])
    assert rc == 0, stderr
    return stdout, json.loads(paths["json"].read_text()), paths


def test_flight_commands_are_finite_and_within_the_travel(flight):
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.target.flight_replay import read_flight_inputs

    _, summary, paths = flight
    _, ctx = load_model(C172, "float")
    u = read_flight_inputs(paths["csv"], ctx).u[:, 0]
    lo, hi = summary["aileron_travel_deg"]
    assert u.size == 1000 and np.all(np.isfinite(u)) and np.all((lo <= u) & (u <= hi))
    for run in (summary, summary["baseline"]):
        assert run["constraint_violations"]["total"] == 0
        assert run["stalled_samples"] == 0
    assert summary["status_counts"] == {"optimal": 1000}
    assert summary["switches"] >= 1  # 102 kts crossed: kts90 -> kts110 in flight
    assert summary["aircraft"] == "c172p" and summary["stall_alpha_deg"] == 16.0  # the config's
    assert summary["engines"] == {"count": 1, "min_running": 1, "first_loss_s": None}
    assert summary["warnings"] == []  # 99 and 110 kts: inside the identified 70-110 kts


def test_fly_flies_the_mpc_without_preview_and_the_tuned_pid_beside_it(flight):
    """The preview's worth and the feedback's: the MPC without the preview, on the same
    flight, beside the PID whose gains the model gives (the c172p's grid optimum)."""
    stdout, summary, _ = flight
    blind, pid = summary["no_preview"], summary["baseline"]
    assert summary["rms_roll_error_deg"] < blind["rms_roll_error_deg"]
    assert max(s["settled_error"] for s in blind["segments"]) < TRACKING_BOUND_DEG
    assert pid["gains"]["rule"] == "model" and pid["gains"]["rate_p"] == pytest.approx(0.3, 0.02)
    for name in ("MPC without preview:", "PID:", "PID gains (model)", "delay margin"):
        assert name in stdout


def test_flight_tracks_within_the_bound_and_beats_the_pid(flight):
    stdout, summary, paths = flight
    steps = summary["segments"][1:]
    assert [s["reference"] for s in summary["segments"]] == [0.0, 20.0, -20.0]
    assert max(s["settled_error"] for s in summary["segments"]) < TRACKING_BOUND_DEG
    assert max(s["settling_time_10pct_s"] for s in steps) < SETTLING_BOUND_S
    pid = summary["baseline"]
    assert summary["rms_roll_error_deg"] < pid["rms_roll_error_deg"]
    assert all(m["settling_time_10pct_s"] < p["settling_time_10pct_s"]
               for m, p in zip(steps, pid["segments"][1:]))
    assert "RMS roll error" in stdout and paths["plot"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    header = paths["csv"].read_text().splitlines()[0].split(",")
    assert header[:10] == ["k", "t", "r", "y", "rho", "mode", "u_aileron", "status",
                           "iterations", "solve_us"] and "true_altitude" in header
    assert header[10] == "work"  # the MPC's work count, after the columns that were there


def test_flight_c_equals_the_numpy_reference_bit_for_bit(flight):
    """Every recorded input of the flight through ControllerRef: the same commands and
    statuses as the C flew, bit for bit."""
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.reference.controller import ControllerRef
    from rollmpc_codegen.sim.scenario import preview
    from rollmpc_codegen.target.flight_replay import read_flight_inputs

    _, _, paths = flight
    model, ctx = load_model(C172, "float")
    inputs = read_flight_inputs(paths["csv"], ctx)
    ref = ControllerRef(ctx, [m.data for m in model.modes])
    modes = set()
    for k in range(len(inputs.y)):
        status, u = ref.step(inputs.y[k], inputs.sched[k],
                             preview(inputs.reference, k, ctx["horizon"]))
        assert status == inputs.status[k]
        assert np.float64(u[0]).tobytes() == inputs.u[k, 0].tobytes(), k
        modes.add(ref.mode)
    assert len(modes) == 2


def test_report_replays_the_flight_on_the_m4f(flight, build_root, tmp_path):
    require_tool("arm-none-eabi-gcc", ARM_HINT)
    for module in ("unicorn", "capstone", "elftools"):
        pytest.importorskip(module, reason="pip install 'rollmpc-codegen[target]'")
    _, _, paths = flight
    out = tmp_path / "report.json"
    rc, stdout, stderr = cli(["report", str(C172), "--precision", "float", "--flight",
                              str(paths["csv"]), "--steps", "400", "--sample-every", "50",
                              "--hardest", "2", "--host-repeats", "1", "--json", str(out),
                              "--quiet", "--build-dir", str(build_root)])
    assert rc == 0, stderr
    rep = json.loads(out.read_text())
    assert rep["bit_exact_vs_host"] is True and rep["steps_emulated"] == 400
    assert rep["flight"] == {"path": str(paths["csv"]), "samples": 400,
                             "commands_match": True, "mismatching_samples": 0,
                             "first_mismatch": None}
    assert rep["worst_step_cycles"] > rep["median_step_cycles"] > 0
    assert "host replay == the flight's commands: yes" in stdout
    # one flight is replayed, not a table of horizons
    rc, _, stderr = cli(["report", str(C172), "--precision", "float", "--flight",
                         str(paths["csv"]), "--horizons", "50", "--quiet"])
    assert rc == 2 and "--flight" in stderr


@needs_jsbsim
def test_identify_reproduces_the_example(tmp_path):
    """The committed example is what `rollmpc identify` writes (its header names the
    command); the matrices to 1e-4 (JSBSim versions may move the sixth digit)."""
    from rollmpc_codegen.flight.identify import EXAMPLE_AIRSPEEDS_KTS

    text = C172.read_text()
    command = text.splitlines()[1].lstrip("# ").split()
    assert command[:2] == ["rollmpc", "identify"]
    assert [float(v) for a, v in zip(command, command[1:]) if a == "--airspeed"] \
        == list(EXAMPLE_AIRSPEEDS_KTS)
    out = tmp_path / "c172.yaml"
    rc, stdout, stderr = cli([*command[1:], "-o", str(out), "--quiet"])
    assert rc == 0, stderr
    assert "wrote" in stdout and "(3 modes)" in stdout
    new, old = yaml.safe_load(out.read_text()), yaml.safe_load(text)
    for a, b in zip(new.pop("modes"), old.pop("modes")):
        pa, pb = a.pop("plant")["state_space"], b.pop("plant")["state_space"]
        assert a == b
        for key in "ABC":
            np.testing.assert_allclose(pa[key], pb[key], rtol=1e-4, atol=1e-4)
    assert new == old
    assert old["scheduler"]["initial"] == "kts90"
    assert [b.get("below") for b in old["scheduler"]["bands"]] == [80.0, 100.0, None]
    # the same file again needs --force
    rc, _, stderr = cli([*command[1:], "-o", str(out), "--quiet"])
    assert rc == 2 and "--force" in stderr


@needs_jsbsim
def test_aileron_travel_and_command_mapping():
    """The c172p's FCS: +1 -> +15 deg, -1 -> -20 deg (times its 0.01745 rad/deg gain)."""
    from rollmpc_codegen.flight.aircraft import DEFAULT_AIRCRAFT, Aircraft

    ac = Aircraft(DEFAULT_AIRCRAFT, 0.005)
    lo, hi = ac.travel_deg
    assert lo == pytest.approx(-20 * 0.01745 * 180 / np.pi) and hi == pytest.approx(
        15 * 0.01745 * 180 / np.pi)
    assert ac.aileron_command(hi) == 1.0 and ac.aileron_command(lo) == -1.0
    assert ac.aileron_command(hi / 2) == 0.5 and ac.aileron_command(lo / 4) == -0.25
    bounds = yaml.safe_load(C172.read_text())["modes"][0]["bounds"]
    assert lo < bounds["u_min"] < 0 < bounds["u_max"] < hi


@needs_jsbsim
@pytest.mark.parametrize("args,word", [
    (["fly", str(ROOT / "examples" / "uav_roll.yaml")], "outputs"),
    (["fly", str(C172), "--aircraft", "no_such_plane"], "aircraft"),
    (["fly", str(C172), "--reference", "sideways"], "--reference"),
    (["fly", str(C172), "--delay", "-1"], "--delay"),
    (["fly", str(C172), "--airspeed", "20"], "airspeed"),
])
def test_fly_bad_input_is_one_line_exit_2(args, word, build_root):
    rc, _, stderr = cli(args + ["--quiet", "--build-dir", str(build_root)])
    assert rc == 2 and stderr.count("\n") == 1 and word in stderr, stderr


@needs_jsbsim
def test_fly_warns_before_a_delay_beyond_the_margin(build_root):
    """5 samples of delay the model does not know: the 110 kts mode's margin is 4, so the
    warning comes before the flight (the example limit-cycles there, docs/flight.md)."""
    rc, stdout, stderr = cli(["fly", str(C172), "--delay", "5", "--duration", "0.5", "-q",
                              "--build-dir", str(build_root)])
    assert rc == 0 and stderr.startswith("rollmpc: warning: --delay 5:"), stderr
    assert "delay margin on its model (4 samples, mode kts110)" in stderr
    assert "kts110 4" in stdout


@needs_jsbsim
def test_fly_refuses_bounds_past_the_aircraft_travel(tmp_path, build_root):
    """u_max past the C172's aileron travel is refused before the flight, naming the key
    (it stopped 40 s into a flight with a traceback-like CommandError, exit 1)."""
    data = yaml.safe_load(C172.read_text())
    data["modes"][1]["bounds"]["u_max"] = 15.0  # the travel ends at 14.997 deg
    path = tmp_path / "wide.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    rc, _, stderr = cli(["fly", str(path), "--quiet", "--build-dir", str(build_root)])
    assert rc == 2 and stderr.count("\n") == 1, stderr
    assert "modes[1].bounds.u_max: 15 deg is past the c172p's aileron travel" in stderr


def test_fly_without_jsbsim_says_how_to_install(monkeypatch):
    from rollmpc_codegen import extras

    monkeypatch.setattr(extras, "installed", lambda module: module != "jsbsim")
    rc, _, stderr = cli(["fly", str(C172), "--quiet"])
    assert rc == 1 and "pip install 'rollmpc-codegen[flight]'" in stderr


def test_reference_default_file_and_duration(tmp_path):
    from rollmpc_codegen.config import ConfigError
    from rollmpc_codegen.flight.scenario import flight_reference

    ref = flight_reference(None, 0.01, 90.0, None)
    assert len(ref) == 6000
    assert list(ref.roll_deg[::1000]) == [0.0, -15.0, 15.0, -30.0, 30.0, 0.0]
    assert list(ref.airspeed_kts[::1000]) == [90.0, 90.0, 75.0, 75.0, 105.0, 105.0]
    assert flight_reference("40", 0.01, 90.0, None).roll_deg.max() == 40.0
    short, long = (flight_reference(None, 0.01, 90.0, d) for d in (15.0, 65.0))
    assert len(short) == 1500 and short.roll_deg[-1] == -15.0
    assert len(long) == 6500 and long.roll_deg[-1] == 0.0
    path = tmp_path / "r.csv"
    path.write_text("t,roll\n0,5\n1.5,-5\n")
    ref = flight_reference(str(path), 0.01, 80.0, None)
    assert len(ref) == 1150 and ref.roll_deg[149] == 5.0 and ref.roll_deg[150] == -5.0
    assert set(ref.airspeed_kts) == {80.0}
    path.write_text("t,roll\n1,5\n")
    with pytest.raises(ConfigError, match="--reference"):
        flight_reference(str(path), 0.01, 80.0, None)


@pytest.mark.slow
def test_matrix_of_conditions():
    """docs/flight.md's table: every turbulence level, 3 seeds, and the latency sweep."""
    from rollmpc_codegen.flight.matrix import run_matrix
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.target.measure import budget_verdict

    if not installed("jsbsim"):
        pytest.skip(FLIGHT_HINT)
    target = installed("unicorn") and shutil.which("arm-none-eabi-gcc") is not None
    matrix = run_matrix(str(C172), target=target)
    cfg = load_model(C172, "float")[0].config
    assert len(matrix["cells"]) == 12
    for cell in matrix["cells"]:
        mpc, pid, blind = cell["mpc"], cell["pid"], cell["mpc_no_preview"]
        # the default work budget: a few TIME_LIMIT samples, nothing else (measured 2-4 a
        # flight), and at least 99 % OPTIMAL
        assert set(mpc["statuses"]) <= {"optimal", "time_limit"}, mpc["statuses"]
        assert mpc["statuses"]["optimal"] >= 0.99 * 6000
        assert mpc["rms"] < 0.6 * pid["rms"] and blind["rms"] <= 1.02 * pid["rms"]
        if cell["turbulence"] != "severe":
            assert mpc["stalled"] == pid["stalled"] == 0
            assert np.mean(blind["settled"]) <= np.mean(pid["settled"])
        if target:
            m4f = cell["m4f"]
            assert m4f["bit_exact_vs_host"] and m4f["commands_match_flight"]
            assert budget_verdict(cfg, m4f["worst_cycles"])["worst_fits"]  # within its Ts
            assert m4f["flash_fits"] is True  # on the config's part (target.part)
    for row in matrix["latency"]:
        assert row["mpc_latency_model"]["rms"] < row["pid"]["rms"]
        assert row["warned"] == (row["latency"] >= 5)  # the margin is 4 samples (kts110)
    # table 3, the goals: five classes, moderate turbulence, every seed
    assert len(matrix["aircraft"]) == 5
    for case in matrix["aircraft"]:
        for f in case["flights"]:
            mpc, blind, pid = f["mpc"], f["no_preview"], f["pid"]
            assert mpc["rms"] < 0.7 * pid["rms"], case["aircraft"]  # the preview: clearly
            assert blind["settled"] <= pid["settled"], case["aircraft"]
            assert blind["rms"] <= 1.03 * pid["rms"], case["aircraft"]  # a tie at worst
            for run in (mpc, blind, pid):
                assert run["violations"] == 0 and run["engines_lost"] == 0
                assert run["altitude_loss"] <= 500.0, case["aircraft"]
        # over the 3 seeds (table 3's mean), without preview at least as good as the PID
        rms = {who: np.mean([f[who]["rms"] for f in case["flights"]])
               for who in ("no_preview", "pid")}
        assert rms["no_preview"] <= rms["pid"], case["aircraft"]
