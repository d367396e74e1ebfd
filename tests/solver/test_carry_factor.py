"""carry_factor() (templates/solver/seeds.c.j2, reference/seeds.py) when the budget cuts it
and a row of the shifted guess depends on the rows before it: the row leaves the guess and
the factor built so far stands, so the next sample goes on from it. Kept, the row's
breakdown dropped the factor at every sample, and each sample of the run stopped where the
one before it had: on examples/quad_attitude's random flight 108 (float, noise 0.05,
mismatch 0.2) 250 samples in a row stopped at TIME_LIMIT after exactly 10,025 of their
42,000 units, a quarter of the budget left unused (issue 44: "never parks on a fraction of
its budget"). C and reference stay bit for bit, work included."""
from __future__ import annotations

import numpy as np

from conftest import ROOT, Built, lockstep_closed_loop
from rollmpc_codegen.sim.flight_plan import FlightPlan
from rollmpc_codegen.sim.scenario import scenario_reference
from rollmpc_codegen.status import TIME_LIMIT

QUAD = ROOT / "examples" / "quad_attitude.yaml"
SAMPLES = 830  # the parking began at sample 800
PARKED = 10  # samples in a row stopping at the same work: a stall


def _parked_runs(statuses, works) -> int:
    """The longest run of TIME_LIMIT samples that each stopped at the same work count."""
    longest = run = 0
    for k in range(1, len(works)):
        same = statuses[k] == statuses[k - 1] == TIME_LIMIT and works[k] == works[k - 1]
        run = run + 1 if same else 0
        longest = max(longest, run + 1 if same else 0)
    return longest


def test_a_cut_carry_goes_on_where_it_stopped(build_root):
    built = Built(QUAD, "float", build_root)
    cfg = built.model.config
    plan = FlightPlan(flights=1, seed=108, noise_std=0.05, mismatch=0.2)
    flight = plan.plan(cfg, len(scenario_reference(cfg)))[0]
    bad, seen = lockstep_closed_loop(built, SAMPLES, **plan.loop_options(flight))
    statuses, works = [st for st, _ in seen], [work for _, work in seen]
    assert bad == []
    assert np.count_nonzero(np.array(statuses[800:]) == TIME_LIMIT) >= 20  # the budget binds
    assert _parked_runs(statuses, works) < PARKED
