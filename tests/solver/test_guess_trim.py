"""A reversed guess that only ran past the edge of its saturation is trimmed, not given up
(docs/solver.md, "The default method", step 4).

Under the paper config's terminal weights (P = 1e6 and 1e9) every multiplier of a shifted
guess whose saturated run lasts a few stages too long is negative: guess_reversed() gives
it up, and the rows th0 violates, a far smaller set, were the next seed (steps 941 and
3070 of the nominal scenario: 89 and 100 guessed rows, 83 and 93 optimal, 50 and 38
violated). trim_guess() (templates/solver/guess.c.j2) keeps the rows carrying at least
half of the largest multiplier carried from the previous sample, when that keeps 3/4 of
the guess and needs a factor of lower order than the violated rows. C and reference stay
bit for bit, work included.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import UAV, Built, lockstep_closed_loop

STEPS = 3072  # steps 941 and 3070 are trimmed
# the work of steps 941 and 3070 when the violated rows were their seed (c01d7a1, float)
UNTRIMMED = {941: 39_217, 3070: 40_808}


@pytest.fixture(scope="module")
def trimmed_run(build_root):
    """The scenario's first STEPS samples (float) in lockstep, every trim_guess() call
    recorded as (step, guess, trimmed rows or None), and the reference's info of each
    step."""
    built = Built(UAV, "float", build_root)
    ref = built.reference()
    trims, infos = [], []  # infos[k]: the reference's P_last_info of step k
    stepping = ref.step

    def counting(y, s, r):
        out = stepping(y, s, r)
        infos.append(dict(ref.last))
        return out

    ref.step = counting
    for solver in ref.solvers:
        def recording(W, lam, K, trim=solver.trim_guess):
            out = trim(W, lam, K)
            trims.append((len(infos), W.copy(), None if out is None else out.copy()))
            return out
        solver.trim_guess = recording

    bad, seen = lockstep_closed_loop(built, STEPS, ref)
    return bad, seen, trims, infos


def test_overrun_guess_is_trimmed_bit_for_bit(trimmed_run):
    from rollmpc_codegen.status import OPTIMAL

    bad, seen, trims, _ = trimmed_run
    assert bad == [] and len(seen) == STEPS

    trimmed = {k: (W, T) for k, W, T in trims if T is not None}
    assert set(UNTRIMMED) <= set(trimmed), sorted(trimmed)
    for k, (W, T) in trimmed.items():
        assert np.all(np.isin(T, W)) and 4 * T.size >= 3 * W.size > 3 * T.size, k
    for k, before in UNTRIMMED.items():
        status, work = seen[k]
        assert status == OPTIMAL and work < 0.65 * before, (k, status, work)


def test_a_reversed_guess_is_judged_at_its_first_point(trimmed_run):
    """uav_roll's step 3071 (float, reference): after a reference step the shifted guess
    (92 bound inputs) has every multiplier negative. It is judged at its first point (1
    correction), trimmed to the rows that carried the larger multipliers (trim_guess()),
    and that polish takes 3: 4 in all. Given up there for the violated rows' polish it took
    7, and growing the guess to 100 rows before testing it took 10."""
    from rollmpc_codegen.status import OPTIMAL

    *_, infos = trimmed_run
    assert infos[3071]["status"] == OPTIMAL and infos[3071]["polish_iterations"] == 4
