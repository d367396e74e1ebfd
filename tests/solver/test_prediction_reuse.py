"""A dual polish whose corrected point violates no row checks its working set against the
output prediction violated_outside() has just made at that point, instead of predicting
the outputs again (working_set_holds(..., predicted = 1)). chain_of_masses meets it on its
hardest samples; C and reference stay bit for bit, work included, and the same loop with
the check predicting again costs one prediction more per reuse."""
from __future__ import annotations

from conftest import ROOT, Built, lockstep_closed_loop

CHAIN = ROOT / "examples" / "chain_of_masses.yaml"
STEPS = 74
SAMPLE = 72  # one of its hardest samples, where the final check reuses the prediction


def test_the_final_check_reuses_the_prediction(build_root, monkeypatch):
    from rollmpc_codegen.qp.work import predict_work
    from rollmpc_codegen.reference.solver import SolverRef
    from rollmpc_codegen.sim.simulate import run_closed_loop
    from rollmpc_codegen.status import OPTIMAL

    built = Built(CHAIN, "double", build_root)
    bad, seen = lockstep_closed_loop(built, STEPS)
    assert bad == [] and len(seen) == STEPS
    status, work = seen[SAMPLE]
    assert status == OPTIMAL

    holds, reuses, works = SolverRef.working_set_holds, [], []

    def predicting_again(self, W, z, th, gam, predicted=False, tight=False):
        if predicted:
            reuses.append(len(works))
        return holds(self, W, z, th, gam, False, tight)

    monkeypatch.setattr(SolverRef, "working_set_holds", predicting_again)
    ref = built.reference()

    class Recording:
        def step(self, y, s, r):
            out = ref.step(y, s, r)
            works.append(ref.last["work"])
            return out

    run_closed_loop(built.model.config, Recording(), steps=STEPS)
    at_sample = reuses.count(SAMPLE)
    assert at_sample >= 1
    assert works[SAMPLE] - work == at_sample * predict_work(built.model.modes[0].data)
