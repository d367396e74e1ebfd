"""P_qp_solve() (templates/solver/qp_solve.c.j2, reference/solver.py) when the polish of
the rows th0 violates runs out of work: the dual active set goes on from where that polish
stopped, a row at a time. The polish appends every violated row at once, and after a
saturation that block costs more than the budget has left. When the sample ended there,
each sample stopped after the same quarter of its budget: on
tests/data/heavy/hexa_attitude.yaml's random flight 101 (float, noise 0.05, mismatch 0.2)
samples 180-193 all stopped at TIME_LIMIT after 10,149 or 10,208 of their 42,000 units
(issue 44: "never parks on a fraction of its budget"). C and reference stay bit for bit,
work included."""
from __future__ import annotations

from conftest import ROOT, Built, lockstep_closed_loop
from rollmpc_codegen.sim.flight_plan import FlightPlan
from rollmpc_codegen.sim.scenario import scenario_reference
from rollmpc_codegen.status import TIME_LIMIT

HEXA = ROOT / "tests" / "data" / "heavy" / "hexa_attitude.yaml"
SAMPLES = 200  # the saturation comes at sample 176
WINDOW = slice(170, SAMPLES)


def _short_stops_in_a_row(seen, budget) -> int:
    """The longest run of TIME_LIMIT samples that each stopped below half the budget
    (``seen``: (status, work) of each)."""
    longest = run = 0
    for st, work in seen:
        run = run + 1 if st == TIME_LIMIT and work < budget // 2 else 0
        longest = max(longest, run)
    return longest


def test_a_polish_out_of_work_hands_over_to_the_dual_active_set(build_root):
    built = Built(HEXA, "float", build_root)
    cfg = built.model.config
    budget = built.ctx["solver"]["work_budget"]
    plan = FlightPlan(flights=1, seed=101, noise_std=0.05, mismatch=0.2)
    flight = plan.plan(cfg, len(scenario_reference(cfg)))[0]
    bad, seen = lockstep_closed_loop(built, SAMPLES, **plan.loop_options(flight))
    assert bad == []
    window = seen[WINDOW]
    statuses = [st for st, _ in window]
    assert statuses.count(TIME_LIMIT) >= 1  # the budget binds here
    assert statuses.count(TIME_LIMIT) <= 5  # 15 when the sample ended at the polish's stop
    assert _short_stops_in_a_row(window, budget) <= 1  # 14 before
