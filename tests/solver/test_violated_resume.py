"""With no warm start left (the shifted set empty), a polish of the rows th0 violates that
fails (its factor breaks down on dependent rows) no longer leaves the dual active set to
start cold: violated_resume() seeds those rows again, and resume_working_set() makes them
dual feasible from their independent rows (docs/solver.md, "The default method", step 5).
thermal_zones_rate's sample 220 is the case, the host bench's worst QP. C and reference
stay bit for bit, work included."""
from __future__ import annotations

import numpy as np

from conftest import ROOT, Built, lockstep_closed_loop, reference_closed_loop

ZRATE = ROOT / "examples" / "thermal_zones_rate.yaml"
STEPS = 222  # sample 220 is among them


def test_failed_violated_polish_resumes_from_its_rows(build_root):
    from rollmpc_codegen.status import OPTIMAL

    built = Built(ZRATE, "double", build_root)
    bad, seen = lockstep_closed_loop(built, STEPS)
    assert bad == [] and len(seen) == STEPS

    ref = built.reference()
    solver = ref.solvers[0]
    resumed = []  # (sample, rows seeded again)
    violated_resume = solver.violated_resume

    def recording(K):
        nw = violated_resume(K)
        resumed.append((len(steps_so_far), nw, int(np.count_nonzero(K < 0))))
        return nw

    steps_so_far: list = []

    class Counting:  # the sample index the resume happened at
        def __init__(self, inner):
            self.inner = inner

        @property
        def last(self):
            return self.inner.last

        def step(self, y, s, r):
            out = self.inner.step(y, s, r)
            steps_so_far.append(out)
            return out

    solver.violated_resume = recording
    steps = reference_closed_loop(built, Counting(ref), STEPS)
    assert [w for _, w in steps] == [w for _, w in seen]
    # every resume seeds exactly the rows th0 violates, and sample 220 takes one
    assert resumed and all(rows == violated for _, rows, violated in resumed), resumed
    assert 220 in [sample for sample, _, _ in resumed]
    # from th0 it was 102,369 units (bcd21ec)
    status, work = steps[220]
    assert status == OPTIMAL and work < 90_000, (status, work)
