"""Random flights of both kinds (sim/flight_plan.py): inside flights draw within the range
the scenario spans (as before envelope flights existed, draw for draw), envelope flights
press it: half their levels beyond that range, up to the hard output bounds and past the
soft ones (sim/envelope.py), seeded and reproducible."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT
from rollmpc_codegen.pipeline import load_config
from rollmpc_codegen.sim.envelope import PRESS, SOFT_REACH, envelope_levels, envelope_range
from rollmpc_codegen.sim.flight_plan import FlightPlan
from rollmpc_codegen.sim.scenario import random_stream, reference_range

QUAD = ROOT / "examples" / "quad_attitude.yaml"  # hard ±30 deg tilt, yaw and climb open
SOFT = ROOT / "tests" / "data" / "newuser" / "dc_motor_soft.yaml"  # speed soft at ±0.8


def test_the_envelope_reaches_hard_bounds_and_passes_soft_ones():
    quad = load_config(QUAD)
    lo, hi = reference_range(quad)
    lo_e, hi_e = envelope_range(quad)
    assert np.array_equal(lo_e[:2], [-30, -30]) and np.array_equal(hi_e[:2], [30, 30])
    assert np.array_equal(lo_e[2:], lo[2:]) and np.array_equal(hi_e[2:], hi[2:])  # open
    motor = load_config(SOFT)
    lo, hi = reference_range(motor)
    lo_e, hi_e = envelope_range(motor)
    assert (lo[1], hi[1]) == (-0.8, 0.8)  # the scenario's range stops at the soft bound
    assert (lo_e[1], hi_e[1]) == pytest.approx((-0.8 * (1 + SOFT_REACH), 0.8 * (1 + SOFT_REACH)))
    assert lo_e[0] == lo[0] and hi_e[0] == hi[0]  # theta: no bound to press


def test_envelope_levels_press_beyond_the_inside_range_within_the_envelope():
    cfg = load_config(QUAD)
    lo, hi = reference_range(cfg)
    lo_e, hi_e = envelope_range(cfg)
    levels = envelope_levels(cfg, random_stream(3, "reference"), 4000)
    assert np.all(levels >= lo_e) and np.all(levels <= hi_e)
    beyond = (levels < lo) | (levels > hi)
    assert not beyond[:, 2:].any()  # yaw and climb have no envelope of their own
    assert abs(beyond[:, :2].mean() - PRESS) < 0.03  # measured 0.50 of 8,000 levels
    assert (levels[:, 0] < lo[0]).any() and (levels[:, 0] > hi[0]).any()  # both sides
    again = envelope_levels(cfg, random_stream(3, "reference"), 4000)
    assert np.array_equal(levels, again)


def test_kinds_follow_the_seed_and_inside_flights_draw_as_before():
    cfg = load_config(QUAD)
    both = FlightPlan(flights=4, seed=10).plan(cfg, 300)
    assert [(f.seed, f.kind) for f in both] == [(10, "inside"), (11, "envelope"),
                                                (12, "inside"), (13, "envelope")]
    lo, hi = reference_range(cfg)
    for f in both:
        within = np.all((f.levels >= lo) & (f.levels <= hi))
        assert within == (f.kind == "inside")
        # the levels an inside flight drew before the envelope existed: uniform in the range
        if f.kind == "inside":
            old = random_stream(f.seed, "reference").uniform(lo, hi, size=f.levels.shape)
            assert np.array_equal(f.levels, old)
    alone = FlightPlan(flights=1, seed=13).plan(cfg, 300)[0]
    assert alone.kind == "envelope" and np.array_equal(alone.reference, both[3].reference)
    assert {f.kind for f in FlightPlan(flights=3, kinds="envelope").plan(cfg, 300)} == {"envelope"}
    assert {f.kind for f in FlightPlan(flights=3, kinds="inside").plan(cfg, 300)} == {"inside"}
    with pytest.raises(ValueError):
        FlightPlan(flights=1, kinds="outside")
