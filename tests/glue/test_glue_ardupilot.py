"""The ArduPilot side of the glue (firmware_stub/integration/ardupilot/): its plain-C units
and timing (rollglue_ap.c) on the host, its parameter ranges against the core's, and,
when an ArduPilot tree is given (ARDUPILOT_TREE, plus ARDUPILOT_MODULES for submodules it
lacks), the patches against the named upstream commit and the real-flag compile check."""
from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
from pathlib import Path

import cffi
import pytest

from conftest import ROOT
from glue_harness import CDEF, MAX_CHANNELS, build_glue
from test_glue_core import F32, header_ranges

AP = ROOT / "firmware_stub" / "integration" / "ardupilot"
CHECK = ROOT / "firmware_stub" / "integration" / "check" / "precheck_ardupilot.py"
PATCHES = {"plane/arduplane.patch": "ArduPlane", "copter/custom_control.patch": "libraries"}
AILERON, ELEVATOR = 4, 19
PARAMS_OK, PARAMS_TIMEOUT, PARAMS_CHANNEL = 0, 1, 6

AP_CDEF = """
typedef struct {{
    int32_t timeout_ms; int32_t frozen_samples; int32_t warmup_samples; int32_t max_failures;
    float slew_dps; float throw_deg[2]; int32_t servo[2][2]; int32_t reversed;
}} rollglue_ap_settings;
typedef struct {{
    int32_t roll_cd; uint64_t roll_us; float gyro_x_rads; float airspeed_mps; uint64_t airspeed_us;
    int32_t roll_cmd_cd; uint64_t cmd_us;
    float applied_scaled[{c}]; int engage;
}} rollglue_ap_sample;
void rollglue_ap_params(const rollglue_ap_settings *s, rollglue_params *p);
int rollglue_ap_foreign_channel(const rollglue_params *p, const uint16_t *functions, uint32_t n);
void rollglue_ap_input(const rollglue_ap_sample *s, rollglue_input *in);
float rollglue_ap_scaled(float norm);
uint16_t rollglue_ap_ticks_per_sample(uint32_t loop_rate_hz);
int rollglue_ap_sample_due(uint32_t tick, uint16_t ticks_per_sample);
"""


@pytest.fixture(scope="module")
def ap(tmp_path_factory):
    lib = build_glue(F32, tmp_path_factory.mktemp("glue_ap"),
                     extra=(AP / "AP_RollMPC" / "rollglue_ap.c",))
    ffi = cffi.FFI()
    ffi.cdef(CDEF.format(n=2, c=MAX_CHANNELS) + AP_CDEF.format(c=MAX_CHANNELS))
    return ffi, ffi.dlopen(str(lib))


def settings(ffi, **changes):
    s = ffi.new("rollglue_ap_settings *")
    values = dict(timeout_ms=25, frozen_samples=25, warmup_samples=50, max_failures=10,
                  slew_dps=30.0, throw_deg=[15.0, 20.0], servo=[[1, 2], [5, 0]], reversed=0)
    for key, value in {**values, **changes}.items():
        setattr(s, key, value)
    return s


@pytest.mark.parametrize("loop_hz, ticks", [(50, 0), (100, 1), (200, 2), (250, 0), (300, 3),
                                            (333, 0), (400, 4), (1000, 10), (0, 0)])
def test_ticks_per_sample_needs_a_multiple_of_100_hz(ap, loop_hz, ticks):
    """SCHED_LOOP_RATE 50 (Plane's default) or 250 would give 50 or 125 Hz: refused (0)."""
    assert ap[1].rollglue_ap_ticks_per_sample(loop_hz) == ticks


@pytest.mark.parametrize("loop_hz", [100, 300, 400])
def test_decimation_gives_100_hz_at_every_accepted_loop_rate(ap, loop_hz):
    lib = ap[1]
    per = lib.rollglue_ap_ticks_per_sample(loop_hz)
    due = [k for k in range(3 * loop_hz) if lib.rollglue_ap_sample_due(k, per)]
    assert len(due) == 300 and set(b - a for a, b in zip(due, due[1:])) == {per}
    assert not any(lib.rollglue_ap_sample_due(k, 0) for k in range(loop_hz))


def test_input_units_centidegrees_rad_s_and_servo_units(ap):
    ffi, lib = ap
    s = ffi.new("rollglue_ap_sample *")
    s.roll_cd, s.roll_us, s.gyro_x_rads = -2050, 123_456, 0.5
    s.roll_cmd_cd, s.cmd_us, s.engage = 3000, 123_000, 1
    s.airspeed_mps, s.airspeed_us = 41.5, 123_400
    scaled = {0: 4500.0, 1: -2250.0, 2: 9000.0, 3: -1e9}
    for c in range(MAX_CHANNELS):
        s.applied_scaled[c] = scaled.get(c, math.nan)
    inp = ffi.new("rollglue_input *")
    lib.rollglue_ap_input(s, inp)
    assert inp.roll_deg == pytest.approx(-20.5, abs=1e-5) and inp.roll_cmd_deg == pytest.approx(30.0)
    assert inp.roll_rate_dps == pytest.approx(0.5 * 180 / math.pi, rel=1e-6)
    assert (inp.roll_us, inp.rate_us, inp.cmd_us, inp.engage) == (123_456, 123_456, 123_000, 1)
    assert (inp.airspeed_mps, inp.airspeed_us) == (41.5, 123_400)  # m/s: the core scales it
    assert list(inp.applied)[:4] == [1.0, -0.5, 1.0, -1.0]  # clamped to the servo's throw
    assert all(math.isnan(v) for v in list(inp.applied)[4:])


@pytest.mark.parametrize("norm, scaled", [(1.0, 4500.0), (-0.25, -1125.0), (1.5, 4500.0),
                                          (-7.0, -4500.0), (math.nan, 0.0), (math.inf, 4500.0)])
def test_output_to_servo_units(ap, norm, scaled):
    assert ap[1].rollglue_ap_scaled(norm) == scaled


def test_parameter_values_map_to_the_glue(ap):
    """SERVOn numbers are 1-based (0 = none), RMPC_REV bits reverse single servos, the
    timeout goes from ms to us; the core accepts the result."""
    ffi, lib = ap
    p = ffi.new("rollglue_params *")
    lib.rollglue_ap_params(settings(ffi, reversed=0b0110), p)
    assert (p.timeout_us, p.frozen_samples, p.warmup_samples, p.max_failures) == (25_000, 25, 50, 10)
    assert [list(r) for r in p.channel] == [[0, 1], [4, -1]]
    assert [list(r) for r in p.sign] == [[1, -1], [-1, 1]]
    assert list(p.throw_deg) == [15.0, 20.0] and p.ref_slew_dps == 30.0
    sizes = ffi.new("uint32_t[5]")
    lib.rollglue_sizes(sizes)
    g = ffi.new("char[]", sizes[0])
    lib.rollglue_init(g)
    assert lib.rollglue_set_params(g, p, 16) == PARAMS_OK


@pytest.mark.parametrize("change, code", [
    ({"timeout_ms": -1}, PARAMS_TIMEOUT), ({"timeout_ms": 70_000}, PARAMS_TIMEOUT),
    ({"servo": [[0, 2], [5, 0]]}, PARAMS_CHANNEL), ({"servo": [[1, 2], [17, 0]]}, PARAMS_CHANNEL),
    ({"servo": [[1, 2], [300, 0]]}, PARAMS_CHANNEL), ({"servo": [[1, -3], [5, 0]]}, PARAMS_CHANNEL),
    ({"frozen_samples": 1 << 20}, 2), ({"max_failures": -5}, 4)])
def test_out_of_range_parameter_values_are_refused_never_wrapped(ap, change, code):
    """A value that does not fit its field becomes one the core refuses (16 servo outputs)."""
    ffi, lib = ap
    p = ffi.new("rollglue_params *")
    lib.rollglue_ap_params(settings(ffi, **change), p)
    sizes = ffi.new("uint32_t[5]")
    lib.rollglue_sizes(sizes)
    g = ffi.new("char[]", sizes[0])
    lib.rollglue_init(g)
    assert lib.rollglue_set_params(g, p, 16) == code


def test_only_aileron_channels_may_be_mapped(ap):
    ffi, lib = ap
    p = ffi.new("rollglue_params *")
    lib.rollglue_ap_params(settings(ffi), p)  # SERVO1, SERVO2, SERVO5
    functions = ffi.new("uint16_t[16]", [AILERON, AILERON, ELEVATOR, 0, AILERON] + [0] * 11)
    assert lib.rollglue_ap_foreign_channel(p, functions, 16) == -1
    functions[4] = ELEVATOR
    assert lib.rollglue_ap_foreign_channel(p, functions, 16) == 4
    assert lib.rollglue_ap_foreign_channel(p, functions, 4) == 4  # beyond the outputs


def test_ardupilot_parameter_ranges_match_the_core():
    """AP_RollMPC.cpp's @Range lines repeat the core's enforced ranges."""
    h = header_ranges()
    text = (AP / "AP_RollMPC" / "AP_RollMPC.cpp").read_text()
    ranges = {m[1]: (float(m[2]), float(m[3])) for m in
              re.finditer(r"@Param: (\w+)\n(?:\s*// @(?!Param)[^\n]*\n)*?\s*// @Range: (\S+) (\S+)", text)}
    expect = {"TIMEOUT": (h["TIMEOUT_MIN_US"] / 1000, h["TIMEOUT_MAX_US"] / 1000),
              "FROZEN": (0, h["FROZEN_MAX"]), "WARMUP": (h["WARMUP_MIN"], h["WARMUP_MAX"]),
              "MAX_FAIL": (h["MAX_FAIL_MIN"], h["MAX_FAIL_MAX"]), "SLEW": (0, h["SLEW_MAX_DPS"]),
              "THROW_IN": (h["THROW_MIN_DEG"], h["THROW_MAX_DEG"]),
              "THROW_OUT": (h["THROW_MIN_DEG"], h["THROW_MAX_DEG"])}
    assert {k: ranges[k] for k in expect} == expect
    assert all(len("RMPC_" + name) <= 16 for name in re.findall(r'AP_GROUPINFO\w*\("(\w+)"', text))


def test_check_script_skips_without_a_tree(monkeypatch):
    monkeypatch.delenv("ARDUPILOT_TREE", raising=False)
    proc = subprocess.run(["python3", str(CHECK)], capture_output=True, text=True)
    assert proc.returncode == 0 and "skipped" in proc.stdout and "--ardupilot" in proc.stdout


def ardupilot_tree() -> Path:
    tree = os.environ.get("ARDUPILOT_TREE")
    if not tree:
        pytest.skip("set ARDUPILOT_TREE to an ArduPilot checkout (see docs/integration.md)")
    return Path(tree)


def tree_commit(tree: Path) -> str:
    proc = subprocess.run(["git", "-C", str(tree), "rev-parse", "HEAD"], capture_output=True, text=True)
    if proc.returncode == 0:
        return proc.stdout.strip()
    return (tree / "COMMIT").read_text().strip() if (tree / "COMMIT").exists() else "?"


@pytest.mark.parametrize("patch, directory", PATCHES.items())
def test_patch_applies_to_the_named_commit(patch, directory, tmp_path):
    tree = ardupilot_tree()
    named = re.search(r"\b([0-9a-f]{40})\b", (AP / patch).read_text())[1]
    if tree_commit(tree) != named:
        pytest.skip(f"ARDUPILOT_TREE is not at {named}")
    for sub in ("ArduPlane", "ArduCopter", "libraries/AC_CustomControl"):
        shutil.copytree(tree / sub, tmp_path / sub)
    proc = subprocess.run(["patch", "-p1", "-d", str(tmp_path), "-i", str(AP / patch)],
                          capture_output=True, text=True)
    assert proc.returncode == 0 and "offset" not in proc.stdout and "fuzz" not in proc.stdout, proc.stdout
    if directory == "ArduPlane":
        text = (tmp_path / "ArduPlane/Attitude.cpp").read_text()
        stabilize = text.index("void Plane::stabilize_roll()")
        assert stabilize < text.index("g2.rollmpc.set_command(nav_roll_cd") < text.index(
            "float Plane::stabilize_roll_get_roll_out()")


def test_glue_compiles_in_the_tree_with_wafs_flags(tmp_path):
    """The whole check (both boards) when a tree with its submodules is at hand."""
    tree = ardupilot_tree()
    modules = os.environ.get("ARDUPILOT_MODULES")
    python = os.environ.get("ARDUPILOT_PYTHON", "python3")
    boards = os.environ.get("ARDUPILOT_BOARDS", "sitl,MatekF405")
    cmd = ["python3", str(CHECK), "--ardupilot", str(tree), "--build", str(tmp_path / "build"),
           "--python", python, "--boards", boards, *(["--modules", modules] if modules else [])]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    for board in boards.split(","):
        assert f"{board}: 14 compiled cleanly, 0 failed" in proc.stdout
