"""The polish hands the dual active set's final set back to it (SET_HANDED_BACK,
templates/solver/polish.c.j2 and active_set.c.j2, reference/polish.py and active_set.py)
when the exact solve's point violates a row outside the set that the dual active set's own
point did not: a row the set leaves no room for (40 rows of n = 40, a vertex) or one the
refinement's point violates. The dual active set goes on from the polish's point,
multipliers and factor, and makes room for it (or proves the QP infeasible).

examples/thermal_zones_rate.yaml, envelope flight 111, in float with the default budget:
at sample 223 the dual active set ends on all 40 rows; the polish's point violates row 4,
which the full set cannot take, and the polish gave the set up. The sweeps then spent the
budget (about 21 M units) and the sample ended at TIME_LIMIT (unbudgeted: MAX_ITER at
sample 226, 157 M units). Handed back, every sample of the flight is OPTIMAL, C and
reference bit for bit."""
from __future__ import annotations

from conftest import ROOT, Built, lockstep_closed_loop
from rollmpc_codegen.sim.flight_plan import FlightPlan
from rollmpc_codegen.sim.scenario import scenario_reference
from rollmpc_codegen.solver_codes import SET_HANDED_BACK
from rollmpc_codegen.status import OPTIMAL

THERMAL_RATE = ROOT / "examples" / "thermal_zones_rate.yaml"
SAMPLES = 240


def test_a_full_final_set_is_handed_back_and_solved(build_root):
    built = Built(THERMAL_RATE, "float", build_root)
    cfg = built.model.config
    plan = FlightPlan(flights=1, seed=111, noise_std=0.05, mismatch=0.2)
    flight = plan.plan(cfg, len(scenario_reference(cfg)))[0]
    ref = built.reference()
    handed = []
    for solver in ref.solvers:
        original = solver.polish

        def recording_polish(*args, _original=original, **kwargs):
            out = _original(*args, **kwargs)
            handed.append(out[0] == SET_HANDED_BACK)
            return out
        solver.polish = recording_polish
    bad, seen = lockstep_closed_loop(built, SAMPLES, ref=ref, **plan.loop_options(flight))
    assert bad == []
    assert any(handed)
    assert [k for k, (status, _) in enumerate(seen) if status != OPTIMAL] == []
