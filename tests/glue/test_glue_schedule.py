"""The glue core feeds the schedule the generated config.h names: c172_roll is scheduled on
the airspeed (kts), which the adapters hand over in m/s from the autopilot's estimate;
its age and NaN then hand the servos back like the attitude's. And glue_fit.py says, in
one line before any build, which designs the glue cannot fly."""
from __future__ import annotations

import math
import subprocess
import sys

import pytest

from conftest import ROOT
from glue_harness import ENGAGED, NONFINITE, STALE_SCHED, Glue, build_glue

C172 = ROOT / "generated" / "c172_roll_f32"
GLUE_FIT = ROOT / "firmware_stub" / "integration" / "check" / "glue_fit.py"
ONE_PAIR = dict(channel=((0, -1),), sign=((1, 1),), throw_deg=(20.0,),
                frozen_samples=0)  # level flight repeats roll and rate exactly
KTS = 1852.0 / 3600.0  # m/s per knot
US = 10_000


@pytest.fixture(scope="module")
def c172_lib(tmp_path_factory):
    defines = ("-DROLLGLUE_PREFIX=c172p_roll", "-DROLLGLUE_PREFIX_UPPER=C172P_ROLL",
               '-DROLLGLUE_HEADER="c172p_roll.h"')
    return build_glue(C172, tmp_path_factory.mktemp("glue_c172"), defines=defines)


def fly(glue: Glue, airspeeds_kts, stale_from: int | None = None):
    """Level flight at the given airspeeds, one per sample; (mode, reasons) per sample."""
    seen = []
    for k, kts in enumerate(airspeeds_kts):
        now = (k + 1) * US
        glue.input.airspeed_mps = kts * KTS
        glue.input.airspeed_us = now if stale_from is None or k < stale_from else stale_from * US
        glue.step(now, True, 0.0, 0.0, 0.0, now, now, now, {0: 0.0})
        tm = glue.telemetry()
        seen.append((tm.mode if tm.state == ENGAGED else None, tm.reasons))
    return seen


def test_airspeed_in_m_s_schedules_the_knots_bands(c172_lib):
    """68 kts flies kts70 (mode 0), 110 kts kts110 (mode 2): the core scales the adapters'
    m/s to the design's knots; the rate (0 here) plays no part."""
    g = Glue(c172_lib, 1)
    assert g.set_params(**ONE_PAIR, warmup_samples=5) == 0
    seen = fly(g, [68.0] * 30 + [110.0] * 30)
    assert seen[29][0] == 0 and seen[-1][0] == 2, seen[25:35]


@pytest.mark.parametrize("fault, bit", [("stale", STALE_SCHED), ("nan", NONFINITE)])
def test_a_stale_or_nan_airspeed_hands_over(c172_lib, fault, bit):
    g = Glue(c172_lib, 1)
    assert g.set_params(**ONE_PAIR, warmup_samples=5) == 0
    if fault == "stale":  # the estimate stops at sample 20; the timeout is 25 ms
        seen = fly(g, [90.0] * 40, stale_from=20)
    else:
        seen = fly(g, [90.0] * 20 + [math.nan] * 20)
    assert seen[19][0] == 1  # kts90, engaged
    assert all(m is None and r & bit for m, r in seen[24:]), seen[18:30]


@pytest.mark.parametrize("tree, fits, says", [
    ("uav_roll_f32", True, ""), ("c172_roll", True, ""),
    ("three_drives", False, "scheduled on speed"), ("chain_of_masses", False, "6 outputs"),
])
def test_glue_fit_says_in_one_line_what_the_glue_cannot_fly(tree, fits, says):
    proc = subprocess.run([sys.executable, str(GLUE_FIT), str(ROOT / "generated" / tree)],
                          capture_output=True, text=True)
    assert proc.returncode == (0 if fits else 2) and proc.stdout == ""
    assert (proc.stderr == "") if fits else (says in proc.stderr
                                             and proc.stderr.count("\n") == 1
                                             and "make firmware FW_GEN=" in proc.stderr)
