"""The portable autopilot glue core (firmware_stub/integration/common/rollglue.c) against
the simulated UAV, with the saturated LQR as the autopilot's own controller: bumpless
engage at 20 deg bank, hand-over on stale, frozen and NaN inputs, failure counting and
lock-out, channel/sign mapping, parameter ranges; and P_observe bit for bit."""
from __future__ import annotations

import math
import re
import subprocess

import numpy as np
import pytest
import yaml

from conftest import ROOT, UAV, require_tool, variant_config
from rollmpc_codegen.parts import CORES
from rollmpc_codegen.status import NONFINITE_INPUT
from glue_harness import (ENGAGED, FROZEN, GLUE, LOCKED_OUT, LOCKOUT, NO_PARAMS, NONFINITE, SOLVER,
                          STALE_CMD, STALE_RATE, STALE_ROLL, WARMING, Faults, Glue,
                          build_glue, closed_loop)

F32 = ROOT / "generated" / "uav_roll_f32"
SETTLED = 1500  # samples for the LQR to settle the plant on the command before an engage


@pytest.fixture(scope="module")
def uav_f32():
    from rollmpc_codegen.pipeline import load_model
    return load_model(UAV, "float")


@pytest.fixture(scope="module")
def glue_lib(tmp_path_factory):
    return build_glue(F32, tmp_path_factory.mktemp("glue"))


@pytest.fixture
def glue(glue_lib):
    g = Glue(glue_lib, 2)
    assert g.set_params() == 0
    return g


def first(flags, start=0):
    """Index of the first true entry at or after start."""
    return start + int(np.argmax(np.asarray(flags[start:])))


def test_observe_is_bit_exact_against_the_reference(uav):
    """P_observe (scheduler + observers on an applied command) op for op as the NumPy
    mirror, including a NaN sample (open loop) and a NaN command (nothing changes)."""
    c, ref = uav.fresh_c(), uav.reference()
    rng = np.random.default_rng(7)
    r = np.full(uav.ctx["horizon"], 5.0)
    for k in range(60):
        y, s, u = rng.normal(0, 5, 1), rng.normal(0, 30, 1), rng.uniform(-15, 15, 2)
        if k == 20:
            y = np.array([np.nan])
        if k == 30:
            u = np.array([np.nan, 0.0])
        assert c.observe(y, s, u) == ref.observe(y, s, u), k
        if k % 10 == 9:  # a solve from the tracked state: the same command, bit for bit
            status, u_c = c.step(y, s, r)
            ref_status, u_ref = ref.step(y, s, r)
            assert status == ref_status and u_c.tobytes() == u_ref.astype(c.dtype).tobytes(), k
    assert c.info()["mode_switches"] == ref.mode_switches > 0


def test_a_held_command_is_the_active_modes_after_observe_switches(uav):
    """P_observe() switches to the outer pair; the next sample's measurement is NaN, so
    P_step holds its last command, which drove the inner pair at its limit: the held
    command is the outer mode's (the inner pair 0, the outer within its bounds), as the
    README promises of every command, C and reference bit for bit (a firmware engineer's
    test found the inner pair held at 15 deg by a mode that does not drive it)."""
    c, ref = uav.fresh_c(), uav.reference()
    r = np.full(uav.ctx["horizon"], -40.0)
    for k in range(5):  # a -40 deg demand from rest: the inner pair saturates
        _, u = c.step([-0.1 * k], [0.0], r)
        ref.step([-0.1 * k], [0.0], r)
    assert u[0] != 0 and u[1] == 0
    assert c.observe([-0.5], [40.0], u) == ref.observe([-0.5], [40.0], u)
    assert ref.mode == 1  # a 40 deg/s roll rate: the outer pair's band
    status, held = c.step([np.nan], [40.0], r)
    ref_status, ref_held = ref.step([np.nan], [40.0], r)
    lo, hi = (np.asarray(uav.ctx["modes"][1][k], float) for k in ("u_min", "u_max"))
    assert status == ref_status == NONFINITE_INPUT
    assert held[0] == 0 and lo[0] <= held[1] <= hi[0]
    assert held.tobytes() == ref_held.astype(c.dtype).tobytes()


def test_no_parameters_no_output(glue_lib):
    g = Glue(glue_lib, 2)
    valid, out = g.step(10_000, True, 0.0, 0.0, 0.0, 10_000, 10_000, 10_000, {0: 0.0, 1: 0.0})
    assert valid == 0 and g.telemetry().reasons == NO_PARAMS and out.channel_mask == 0


def test_engage_at_20_deg_bank_is_bumpless(glue, uav_f32, build_root):
    """The autopilot holds 20 deg; the MPC takes over with warm observers: no transient.
    The old glue re-initialised the controller at engage (cold observers): 1.3 deg."""
    from rollmpc_codegen.host.build import build_host_controller
    from rollmpc_codegen.sim.lqr_baseline import LqrController
    from rollmpc_codegen.sim.scenario import SimulatedPlant

    model, ctx = uav_f32
    log = closed_loop(glue, model, ctx, SETTLED + 300, lambda k: k >= SETTLED,
                      lambda k: 20.0).arrays()
    assert first(log["valid"]) == SETTLED and log["valid"][SETTLED:].all()
    assert np.abs(log["y"][SETTLED - 1] - 20.0) < 1e-4
    warm = np.abs(log["y"][SETTLED:] - 20.0).max()
    assert warm < 1e-3, warm
    assert np.abs(log["u"][SETTLED] - log["u"][SETTLED - 1]).max() < 0.01
    assert glue.telemetry().engagements == 1 and glue.telemetry().state == ENGAGED

    cold = build_host_controller(ctx, build_root)  # the old behaviour, for contrast
    plant, autopilot = SimulatedPlant(model.config), LqrController(model, ctx)
    ys = []
    for k in range(SETTLED + 300):
        y, rate = plant.outputs()[:1], plant.schedule_signal()[:1]
        _, u = autopilot.step(y, rate, np.full(ctx["horizon"], 20.0))
        if k == SETTLED:
            cold.init()
        if k >= SETTLED:
            _, u = cold.step(y, rate, np.full(ctx["horizon"], 20.0))
        ys.append(y[0])
        plant.advance(u)
    assert np.abs(np.array(ys[SETTLED:]) - 20.0).max() > 1.0 > 1000 * warm


@pytest.mark.parametrize("slew, max_rate", [(5.0, 6.5), (0.0, None)])
def test_engage_reference_ramps_from_the_measured_roll(glue, uav_f32, slew, max_rate):
    """Engaged at 20 deg with the command at 0: the reference starts at the measured roll
    and ramps at ref_slew_dps (a step when 0, which rolls faster than the ramp allows)."""
    model, ctx = uav_f32
    assert glue.set_params(ref_slew_dps=slew) == 0
    log = closed_loop(glue, model, ctx, SETTLED + 700, lambda k: k >= SETTLED,
                      lambda k: 20.0 if k < SETTLED else 0.0,
                      params={"ref_slew_dps": slew}).arrays()
    peak = np.abs(log["rate"][SETTLED:]).max()
    if max_rate is None:
        assert peak > 10.0, peak
    else:
        assert peak < max_rate, peak
    assert abs(log["y"][-1]) < 0.5 and log["valid"][SETTLED:].all()


@pytest.mark.parametrize("topic, bit", [("roll", STALE_ROLL), ("rate", STALE_RATE),
                                        ("cmd", STALE_CMD)])
def test_stale_input_hands_over_within_the_timeout(glue, uav_f32, topic, bit):
    """A topic stops (last value, old timestamp) while the command steps 20 -> -20: the
    MPC hands over once the age passes 25 ms, the autopilot flies the step, the MPC
    re-engages after the topic returns and the failure count resets."""
    model, ctx = uav_f32
    k0, k1 = SETTLED + 100, SETTLED + 400
    log = closed_loop(glue, model, ctx, SETTLED + 900, lambda k: k >= SETTLED,
                      lambda k: 20.0 if k < k0 + 50 else -20.0,
                      Faults(stale={k: {topic} for k in range(k0, k1)})).arrays()
    assert log["valid"][k0:k0 + 2].all() and not log["valid"][k0 + 2:k1].any()
    assert all(r & bit for r in log["reasons"][k0 + 2:k1])
    assert log["y"].max() < 20.5 and log["y"][k1] < -10.0  # the autopilot flew the step
    assert abs(log["y"][-1] + 20.0) < 0.05
    assert log["valid"][-100:].all()
    tm = glue.telemetry()
    assert tm.failures == 1 and tm.engagements == 2 and tm.consecutive_failures == 0


def test_frozen_attitude_hands_over(glue, uav_f32):
    """The estimator re-publishes one attitude at fresh timestamps: after frozen_samples
    bit-identical samples the MPC hands over."""
    model, ctx = uav_f32
    k0 = SETTLED + 100
    log = closed_loop(glue, model, ctx, SETTLED + 400, lambda k: k >= SETTLED,
                      lambda k: 20.0 if k < k0 else 10.0,
                      Faults(frozen=range(k0, SETTLED + 300))).arrays()
    n = 25  # DEFAULTS["frozen_samples"]
    assert log["valid"][:k0 + n - 1][SETTLED:].all() and not log["valid"][k0 + n - 1]
    assert log["reasons"][k0 + n - 1] & FROZEN
    assert 10.0 < log["y"][SETTLED + 299] < 12.0  # the autopilot flies the new command
    assert glue.telemetry().failures == 1


def test_nan_burst_hands_over_and_reengages_after_warmup(glue, uav_f32):
    model, ctx = uav_f32
    k0, burst, warmup = SETTLED + 50, 5, 20
    log = closed_loop(glue, model, ctx, SETTLED + 200, lambda k: k >= SETTLED,
                      lambda k: 20.0, Faults(nan=range(k0, k0 + burst))).arrays()
    back = first(log["valid"], k0)
    assert not log["valid"][k0:k0 + burst].any() and back == k0 + burst + warmup - 1
    assert all(r & NONFINITE for r in log["reasons"][k0:k0 + burst])
    assert all(r & WARMING for r in log["reasons"][k0 + burst:back])
    valid_values = np.array(log["values"])[log["valid"].astype(bool)][:, :2]
    assert np.isfinite(valid_values).all() and np.abs(log["y"][SETTLED:] - 20.0).max() < 0.05
    assert glue.telemetry().failures == 1


@pytest.fixture(scope="module")
def failing_glue_lib(tmp_path_factory):
    """A controller that cannot solve a constrained QP: one sweep, no polish."""
    from rollmpc_codegen.pipeline import generate

    tmp = tmp_path_factory.mktemp("glue_fail")
    tree = tmp / "gen"
    generate(variant_config(tmp, "one_sweep", max_iterations=1, polish=False), tree, "float")
    return build_glue(tree, tmp)


def test_repeated_solver_failures_lock_out_until_re_requested(failing_glue_lib, uav_f32):
    model, ctx = uav_f32
    g = Glue(failing_glue_lib, 2)
    assert g.set_params(warmup_samples=1, max_failures=3) == 0
    off = SETTLED + 60
    log = closed_loop(g, model, ctx, SETTLED + 120, lambda k: SETTLED <= k != off,
                      lambda k: 20.0 if k < SETTLED else 80.0,
                      params={"warmup_samples": 1}).arrays()
    assert not log["valid"][SETTLED:].any()
    # one tracked sample re-warms (warmup 1): three attempts in a row fail, then lock-out
    assert all(r & SOLVER and not r & LOCKED_OUT for r in log["reasons"][SETTLED:SETTLED + 3])
    assert all(r & LOCKED_OUT for r in log["reasons"][SETTLED + 3:off])
    assert all(r & SOLVER for r in log["reasons"][off + 1:off + 4])  # withdrawn once: new count
    assert all(r & LOCKED_OUT for r in log["reasons"][off + 4:])
    tm = g.telemetry()
    assert tm.failures == 6 and tm.consecutive_failures == 3 and tm.state == LOCKOUT
    assert tm.engagements == 6 and tm.status != 0


BAD_PARAMS = [
    ({"timeout_us": 4999}, 1), ({"timeout_us": 100_001}, 1), ({"frozen_samples": 1}, 2),
    ({"frozen_samples": 1001}, 2), ({"warmup_samples": 0}, 3), ({"max_failures": 0}, 4),
    ({"max_failures": 1001}, 4), ({"ref_slew_dps": -1.0}, 5), ({"ref_slew_dps": math.nan}, 5),
    ({"channel": ((0, -1), (8, -1))}, 6), ({"channel": ((-1, 2), (1, -1))}, 6),
    ({"channel": ((2, -1), (2, -1))}, 7), ({"channel": ((0, 1), (4, 1))}, 7),
    ({"sign": ((1, 1), (0, 1))}, 8), ({"channel": ((0, 2), (1, -1)), "sign": ((1, 0), (1, 1))}, 8), ({"throw_deg": (15.0, 0.5)}, 9), ({"throw_deg": (math.inf, 15.0)}, 9),
    ({"throw_deg": (math.nan, 15.0)}, 9), ({"n_channels": 0}, 10), ({"n_channels": 33}, 10),
]


@pytest.mark.parametrize("change, code", BAD_PARAMS)
def test_out_of_range_parameters_are_refused_and_change_nothing(glue, change, code):
    assert glue.set_params(channel=((3, -1), (5, -1))) == 0
    assert glue.set_params(**change) == code
    valid, out = glue.step(10_000, True, 0.0, 0.0, 0.0, 10_000, 10_000, 10_000,
                           {3: 0.0, 5: 0.0})
    assert out.channel_mask == (1 << 3) | (1 << 5)  # the accepted mapping still holds


def test_channel_sign_and_throw_mapping(glue_lib, uav_f32):
    """The inner pair on channels 3 (reversed) and 6, the outer on 5 alone, unequal
    throws: the plant sees the same deflections as with the identity mapping, the second
    servo mirrors the first; a throw below the deflection saturates at 1."""
    model, ctx = uav_f32
    runs = {}
    for name, params in {"identity": {}, "mapped": {"channel": ((3, 6), (5, -1)),
                                                    "sign": ((-1, 1), (1, 1)),
                                                    "throw_deg": (20.0, 16.0)}}.items():
        g = Glue(glue_lib, 2)
        assert g.set_params(**params) == 0
        runs[name] = closed_loop(g, model, ctx, 400, lambda k: True, lambda k: -30.0,
                                 params=params).arrays()
        assert g.telemetry().engagements == 1
    mapped = runs["mapped"]
    values = np.array(mapped["values"])
    k = first(mapped["valid"])
    assert np.float32(values[k, 3]) == -np.float32(np.float32(mapped["u"][k, 0]) / np.float32(20.0))
    assert np.array_equal(values[mapped["valid"].astype(bool)][:, 6],
                          -values[mapped["valid"].astype(bool)][:, 3])
    assert np.isnan(values[:, [0, 1, 2, 4, 7]]).all()
    assert np.abs(runs["identity"]["y"] - mapped["y"]).max() < 1e-3
    g = Glue(glue_lib, 2)
    assert g.set_params(throw_deg=(5.0, 5.0)) == 0
    log = closed_loop(g, model, ctx, 100, lambda k: True, lambda k: -30.0,
                      params={"throw_deg": (5.0, 5.0)}).arrays()
    assert np.nanmax(np.abs(np.array(log["values"]))) == 1.0


def header_ranges() -> dict[str, float]:
    text = (GLUE / "rollglue.h").read_text()
    return {m[1]: float(m[2].rstrip("uf")) for m in
            re.finditer(r"#define ROLLGLUE_(\w+?)\s+([-\d.]+[uf]?)", text)}


def test_autopilot_parameter_ranges_match_the_core():
    """PX4's module.yaml repeats the core's enforced ranges."""
    h = header_ranges()
    px4 = yaml.safe_load((ROOT / "firmware_stub/integration/px4/rollmpc/module.yaml").read_text())
    defs = {k: v for group in px4["parameters"] for k, v in group["definitions"].items()}
    assert all(len(name) <= 16 for name in defs)
    expect = {"RMPC_TIMEOUT": (h["TIMEOUT_MIN_US"] / 1000, h["TIMEOUT_MAX_US"] / 1000),
              "RMPC_FROZEN": (0, h["FROZEN_MAX"]), "RMPC_WARMUP": (h["WARMUP_MIN"], h["WARMUP_MAX"]),
              "RMPC_MAX_FAIL": (h["MAX_FAIL_MIN"], h["MAX_FAIL_MAX"]),
              "RMPC_SLEW": (0, h["SLEW_MAX_DPS"]),
              "RMPC_THROW_IN": (h["THROW_MIN_DEG"], h["THROW_MAX_DEG"]),
              "RMPC_THROW_OUT": (h["THROW_MIN_DEG"], h["THROW_MAX_DEG"])}
    for name, (lo, hi) in expect.items():
        assert (defs[name]["min"], defs[name]["max"]) == (lo, hi), name


@pytest.mark.parametrize("script", ["precheck_px4.py"])
def test_check_script_skips_without_a_tree(script, monkeypatch):
    """The real-tree checks run only when a tree is given (CI has none): a hint, exit 0."""
    monkeypatch.delenv("PX4_TREE", raising=False)
    proc = subprocess.run(["python3", str(ROOT / "firmware_stub/integration/check" / script)],
                          capture_output=True, text=True)
    assert proc.returncode == 0 and "skipped" in proc.stdout and "--px4" in proc.stdout


@pytest.mark.parametrize("core", sorted(CORES))
def test_glue_builds_for_each_core_with_the_dwt_timestamp(tmp_path, core):
    """The glue and the controller compile with -Werror for every declared core (PX4's
    fmu-v2/v3, fmu-v5/v6 and ArduPilot's F4/F7/H7 flags, parts.py), and the solve is
    timed by the DWT cycle counter (0xE0001004, read through its 0xE0001000 base)."""
    require_tool("arm-none-eabi-gcc", "apt-get install -y gcc-arm-none-eabi")
    from glue_harness import WARNINGS
    flags = [*CORES[core].cflags, "-O2",
             *WARNINGS, "-Wframe-larger-than=1300", f"-I{F32}", f"-I{GLUE}",
             "-include", str(GLUE / "rollglue_cycles.h"), "-DROLLMPC_TIMESTAMP()=ROLLGLUE_CYCLES()"]
    for src in (GLUE / "rollglue.c", F32 / "rollmpc_controller.c"):
        obj = tmp_path / (src.stem + ".o")
        proc = subprocess.run(["arm-none-eabi-gcc", *flags, "-c", str(src), "-o", str(obj)],
                              capture_output=True, text=True)
        assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    dump = subprocess.run(["arm-none-eabi-objdump", "-d", str(tmp_path / "rollmpc_controller.o")],
                          capture_output=True, text=True).stdout
    assert ".word\t0xe0001000" in dump


@pytest.mark.parametrize("tree, defines, error", [
    # three_drives is scheduled on a speed; the glue feeds the roll rate or the airspeed
    ("three_drives_f32", ["-DROLLGLUE_PREFIX=drives", "-DROLLGLUE_PREFIX_UPPER=DRIVES",
                          '-DROLLGLUE_HEADER="drives.h"'], "scheduled on another signal"),
    # the UAV runs at 10 ms: a 50 Hz task would run its model at the wrong sample time
    ("uav_roll_f32", ["-DROLLGLUE_SAMPLE_HZ=50u"], "not 1 / the controller's sample time"),
], ids=["speed schedule", "50 Hz for a 10 ms controller"])
def test_the_glue_refuses_a_controller_it_would_feed_wrongly(tree, defines, error, tmp_path):
    """A design scheduled on a signal the glue does not feed (once c172_roll's airspeed,
    now fed) compiled silently against the glue, and a 20 ms design against its fixed
    100 Hz: both now stop at compile time, naming why."""
    from glue_harness import GLUE, WARNINGS

    gen = ROOT / "generated" / tree
    cmd = ["gcc", "-c", *WARNINGS, *defines, f"-I{gen}", f"-I{GLUE}", "-o",
           str(tmp_path / "g.o"), str(GLUE / "rollglue.c")]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode != 0 and error in proc.stderr, proc.stderr


def test_the_glue_rate_defaults_to_the_controller_sample_time(tmp_path):
    """Without ROLLGLUE_SAMPLE_HZ the glue runs at 1 / the controller's sample time."""
    from glue_harness import GLUE, WARNINGS

    gen = ROOT / "generated" / "uav_roll_f32"
    probe = tmp_path / "rate.c"
    probe.write_text('#include "rollglue.h"\nunsigned rate(void) { return ROLLGLUE_SAMPLE_HZ; }\n'
                     "#if ROLLGLUE_SAMPLE_HZ != 100u\n#error wrong rate\n#endif\n")
    proc = subprocess.run(["gcc", "-c", *WARNINGS, f"-I{gen}", f"-I{GLUE}", "-o",
                           str(tmp_path / "r.o"), str(probe)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
