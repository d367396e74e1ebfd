"""The applied command P_observe takes is plausibility-checked like the measurements.

The audit: one sample of u_applied = 1e8 (a servo feedback glitch, a unit mix-up in the
glue) left the UAV non-OPTIMAL for the 2,999 samples that followed, at -738 deg; 1e30 at
-301 deg. P_observe now clips each entry to its actuator's range (the lowest u_min to the
highest u_max of the modes that drive it, widened by the live bounds of a runtime build)
and returns APPLIED_CLIPPED. Checked: C == reference bit for bit through hostile applied
commands (both precisions; the UAV and the chain with run-time bounds), the clip equals
the command at the bound, the precedence of the statuses, and the closed loop after one
hostile sample of every input recovers within the samples docs/reliability.md states.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import ROOT, Built, short_uav_config
from rollmpc_codegen.status import (APPLIED_CLIPPED, MEASUREMENT_CLIPPED, NONFINITE_INPUT,
                                    OPTIMAL)
from rollmpc_codegen.verify.spike_recovery import (HOSTILE_CASES, HOSTILE_INPUTS,
                                                   HOSTILE_VALUES, hostile_design,
                                                   hostile_runs)

RUNTIME = ROOT / "examples" / "chain_runtime_bounds.yaml"


@pytest.fixture(scope="module", params=["double", "float"])
def short_uav(request, build_root, tmp_path_factory) -> Built:
    """The UAV at N = 20: the reference's solves are fast."""
    return Built(short_uav_config(tmp_path_factory.mktemp("uav")), request.param, build_root)


def _same_next_commands(built, c, ref, y, sched, samples=3):
    """The estimates agree bit for bit: the next solves give the same commands."""
    r = np.full(built.ctx["horizon"] * built.ctx["n_outputs"], 0.3)
    for _ in range(samples):
        st_c, u_c = c.step(y, sched, r)
        st_r, u_r = ref.step(y, sched, r)
        assert st_c == st_r and u_c.tobytes() == u_r.astype(c.dtype).tobytes()
    return u_c


def test_hostile_applied_command_is_clipped_bit_exact(short_uav):
    built = short_uav
    huge = 3.4e38 if built.ctx["precision"] == "float" else 1e308
    c, ref = built.c, built.reference()
    for value in (1e7, 1e8, 1e30, -huge, huge, 15.0, -15.0, 14.5):
        c.init()
        ref.init()
        u = np.array([value, -value])
        expected = APPLIED_CLIPPED if abs(value) > 15.0 else OPTIMAL
        assert c.observe([1.0], [0.0], u) == ref.observe([1.0], [0.0], u) == expected, value
        _same_next_commands(built, c, ref, [1.0], [0.0])


def test_the_clip_is_the_command_at_the_bound(short_uav):
    """1e8 is taken as 15 deg (the outer and inner pairs' bound), nothing else."""
    built = short_uav
    clipped, at_bound = built.fresh_c(), built.fresh_c()
    assert clipped.observe([2.0], [0.0], [1e8, -1e8]) == APPLIED_CLIPPED
    assert at_bound.observe([2.0], [0.0], [15.0, -15.0]) == OPTIMAL
    r = np.full(built.ctx["horizon"], 5.0)
    assert clipped.step([2.0], [0.0], r)[1].tobytes() == at_bound.step([2.0], [0.0], r)[1].tobytes()


def test_statuses_of_p_observe(short_uav):
    """NaN in y wins (open loop, with the clipped command); the applied command's clip
    wins over a measurement's; a non-finite command changes nothing."""
    built = short_uav
    c, ref = built.fresh_c(), built.reference()
    for y, u, expected in (([np.nan], [1e8, 0.0], NONFINITE_INPUT),
                           ([1e30], [1e8, 0.0], APPLIED_CLIPPED),
                           ([1e30], [1.0, 0.0], MEASUREMENT_CLIPPED),
                           ([1.0], [np.inf, 0.0], NONFINITE_INPUT),
                           ([1.0], [1.0, 0.0], OPTIMAL)):
        assert c.observe(y, [0.0], u) == ref.observe(y, [0.0], u) == expected, (y, u)
    _same_next_commands(built, c, ref, [1.0], [0.0])


@pytest.mark.parametrize("precision", ["double", "float"])
def test_live_bounds_widen_the_range(build_root, precision):
    """chain_runtime_bounds: +-0.5 in the config. Widened to +-0.8 by P_set_bounds, 0.7 is
    a plausible command; tightened to +-0.05, the config's +-0.5 still is."""
    built = Built(RUNTIME, precision, build_root)
    y = np.zeros(built.ctx["n_outputs"])
    inf = math.inf
    bounds = {"y_min": [-0.6] * 4 + [-inf, -inf], "y_max": [0.6] * 5 + [inf]}
    c, ref = built.c, built.reference()
    for limit, value, expected in ((0.8, 0.7, OPTIMAL), (0.8, 0.9, APPLIED_CLIPPED),
                                   (0.05, 0.5, OPTIMAL), (0.05, 0.51, APPLIED_CLIPPED)):
        c.init()
        ref.init()
        live = dict(bounds, u_min=[-limit] * 4, u_max=[limit] * 4)
        assert c.set_bounds(0, **live) == ref.set_bounds(0, **live) == OPTIMAL
        u = np.array([value, -value, 0.0, 0.0])
        assert c.observe(y, None, u) == ref.observe(y, None, u) == expected, (limit, value)
        _same_next_commands(built, c, ref, y, None, samples=1)


# --------------------------------------------------------------------------- closed loop
# The closed loop after one hostile sample of each input, at 1e7, 1e8, 1e30, NaN and Inf
# (verify/spike_recovery.hostile_runs): the most samples any value takes to rejoin the
# clean run (every status OPTIMAL, every command within 1e-3 of the input span of the
# clean run's), measured with `python -m rollmpc_codegen.verify --only hostile`, both
# precisions, and stated in docs/reliability.md ("Every input, one hostile sample").
# Before (main at 3b76be1) the finite applied commands never recovered (1e7 on the UAV:
# 1,357 samples).
RECOVERY = {
    "uav_roll": {"y": 284, "sched": 1, "r": 128, "u_applied": 101},
    "quadruple_tank_scheduled": {"y": 43, "sched": 3, "r": 15, "u_applied": 24},
}


def _assert_recovers(name, precision, inputs, build_root):
    at, steps = {c[0]: c[1:] for c in HOSTILE_CASES}[name]
    runs = hostile_runs(hostile_design(name, precision), at, steps, inputs=inputs,
                        build_root=build_root)
    assert {r.input for r in runs} == set(inputs) and len(runs) == len(inputs) * len(HOSTILE_VALUES)
    for run in runs:
        assert run.finite and run.within_limits, run
        assert run.recovery is not None and run.recovery <= RECOVERY[name][run.input], run
        if run.input == "u_applied" and math.isfinite(run.value):
            assert run.status_at == APPLIED_CLIPPED, run
        if not math.isfinite(run.value):
            assert run.status_at == NONFINITE_INPUT, run
    for which in inputs:  # the stated figure is the measured one
        assert max(r.recovery for r in runs if r.input == which) == RECOVERY[name][which]


def test_one_hostile_applied_command_is_recovered_uav(build_root):
    """The audit's loop: the UAV holding a level (-20 deg), u_applied = 1e8 (on main it
    never recovered)."""
    _assert_recovers("uav_roll", "double", ("u_applied",), build_root)


def test_one_hostile_sample_of_every_input_is_recovered_mimo(build_root):
    _assert_recovers("quadruple_tank_scheduled", "double", HOSTILE_INPUTS, build_root)


@pytest.mark.slow
@pytest.mark.parametrize("name, precision", [("uav_roll", "double"), ("uav_roll", "float"),
                                             ("quadruple_tank_scheduled", "float")])
def test_one_hostile_sample_of_every_input_is_recovered(build_root, name, precision):
    _assert_recovers(name, precision, HOSTILE_INPUTS, build_root)
