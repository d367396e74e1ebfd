"""A shifted guess whose polish spends every round switching soft states or dropping rows
(GUESS_CAPPED) is not resumed by the dual active set: resume_working_set() would repeat it
round for round before starting cold (docs/solver.md, "The default method", step 5). The
soft 45 deg roll design (conftest.ROLL45) without a budget meets it on its
plateau beyond the bound; C and reference stay bit for bit."""
from __future__ import annotations

import json

import yaml

from conftest import ROLL45, ROLL45_SOFT, Built, lockstep_closed_loop

STEPS = 900  # the plateau beyond 45 deg starts near sample 600


def test_capped_guess_is_not_repeated(tmp_path, build_root):
    from rollmpc_codegen.qp.work import UNBOUNDED_WORK
    from rollmpc_codegen.reference import solver as solver_mod

    data = json.loads(json.dumps(ROLL45))
    data.update(precision="float", solver={"work_budget": UNBOUNDED_WORK})
    data["modes"][0]["bounds"]["soft"] = ROLL45_SOFT
    path = tmp_path / "roll45_soft.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    built = Built(path, "float", build_root)
    ref = built.reference()
    calls = {"seed": 0, "capped": 0, "seeds_in_capped": []}
    solver = ref.solvers[0]
    seed, polish, step = solver.seed_shifted, solver.polish, ref.step

    def counting_seed(lam, *truncate):
        calls["seed"] += 1
        return seed(lam, *truncate)

    def counting_polish(*args, **kwargs):
        out = polish(*args, **kwargs)
        calls["capped"] += out[0] == solver_mod.GUESS_CAPPED
        return out

    def counting_step(y, s, r):
        before = (calls["seed"], calls["capped"])
        out = step(y, s, r)
        if calls["capped"] > before[1]:
            calls["seeds_in_capped"].append(calls["seed"] - before[0])
        return out

    solver.seed_shifted, solver.polish, ref.step = counting_seed, counting_polish, counting_step
    bad, seen = lockstep_closed_loop(built, STEPS, ref)
    assert bad == [] and len(seen) == STEPS
    assert calls["capped"] > 20  # measured 148 in the first 1000 samples
    assert set(calls["seeds_in_capped"]) == {1}  # the guess is seeded once, never again
