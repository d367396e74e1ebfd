"""refine_dual() (templates/solver/polish.c.j2, reference/polish.py) refines the point by a
step, th -= E^-1 M_W' d for the multipliers' change d, not by forming th from th0 again
with the refined multipliers, which cancels the same digits as the first solve did.

tests/data/fast/dcmotor_cur.yaml at N = 8 without a budget, in float: while the motor
brakes at its 6 A current limit, the dual active set ends on 8 current rows (n = 8, a
vertex) with multipliers ~3e3 against an unconstrained optimum of thousands of volts.
Forming th from th0 held those rows only to ~1e-3 A (4 times the tolerance), before and
after the refinement, and 45 of the 2,500 QPs ended at MAX_ITER or INACCURATE, the
current up to 6.4e-4 A past its bound. Refined by steps, every QP is OPTIMAL and no
bound is passed. C and reference stay bit for bit."""
from __future__ import annotations

from conftest import ROOT, Built, edited_config, lockstep_closed_loop
from rollmpc_codegen.sim.scenario import scenario_reference
from rollmpc_codegen.status import OPTIMAL

DCMOTOR = ROOT / "tests" / "data" / "fast" / "dcmotor_cur.yaml"


def test_a_vertex_with_large_multipliers_is_refined_to_optimal(build_root, tmp_path):
    def unbudgeted_n8(d):
        d["horizon"] = 8
        d["solver"] = {"work_budget": 1_000_000_000}
    path = edited_config(tmp_path, DCMOTOR, "dcmotor_n8_unbudgeted", unbudgeted_n8)
    built = Built(path, "float", build_root)
    bad, seen = lockstep_closed_loop(built, len(scenario_reference(built.model.config)))
    statuses = [s for s, _ in seen]
    assert bad == []
    assert len(statuses) == 2500
    assert [k for k, s in enumerate(statuses) if s != OPTIMAL] == []
