"""The glue core and ArduPilot's unit layer never raise a floating-point exception: ArduPilot's
SITL traps FE_INVALID, FE_DIVBYZERO and FE_OVERFLOW (SIGFPE, "Floating point exception -
aborting"), and its first flight with the MPC enabled died on an ordered comparison with
the NaN that marks a channel which is not an aileron. tests/glue/data/fpe_driver.c drives
NaN channels, a NaN attitude burst, a NaN airspeed, an engage and a hand-over with the
traps on, for a roll-rate and an airspeed-scheduled tree."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from conftest import ROOT

GLUE = ROOT / "firmware_stub" / "integration"
DRIVER = Path(__file__).parent / "data" / "fpe_driver.c"


@pytest.mark.parametrize("tree, prefix", [("uav_roll_f32", "rollmpc"),
                                          ("c172_roll_f32", "c172p_roll")])
def test_no_floating_point_exception_with_sitl_traps(tree, prefix, tmp_path):
    gen = ROOT / "generated" / tree
    exe = tmp_path / "fpe"
    build = subprocess.run(
        ["gcc", "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", f"-I{GLUE / 'common'}",
         f"-I{GLUE / 'ardupilot/AP_RollMPC'}", f"-I{gen}", f"-DROLLGLUE_PREFIX={prefix}",
         f"-DROLLGLUE_PREFIX_UPPER={prefix.upper()}", f'-DROLLGLUE_HEADER="{prefix}.h"',
         str(DRIVER), str(GLUE / "common/rollglue.c"), str(GLUE / "ardupilot/AP_RollMPC/rollglue_ap.c"),
         *map(str, sorted(gen.glob("*.c"))), "-lm", "-o", str(exe)], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, f"trapped (signal {-run.returncode})" if run.returncode < 0 else run.stdout
    assert int(run.stdout.split()[0]) > 100  # it engaged, solved and handed back
