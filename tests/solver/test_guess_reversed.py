"""A reversed guess is given up from a sample of its multipliers.

After a reference step every multiplier of the shifted guess can be negative (the paper
config's steps 941 and 3070: the saturation ends earlier than the guess's), and
given_up() gives it up. guess_reversed() decides that from the middle, first and last
rows (templates/solver/guess.c.j2) instead of paying
free_multipliers() for all of them. It is a shortcut, so it must never give up a guess
that the full rule would keep; the C and the reference must agree on its work.
"""
from __future__ import annotations

import numpy as np
import pytest

from rollmpc_codegen.qp.work import (GUESS_SAMPLE_MIN, UNIT_CALL_WORK, guess_sample_work,
                                     multipliers_work)
from rollmpc_codegen.reference.guess import GuessMixin
from rollmpc_codegen.sim.simulate import run_closed_loop


@pytest.fixture(scope="module")
def reversals(uav_double):
    """Every guess_reversed() call of the paper's nominal scenario up to its reversals at
    steps 941 and 3070 (reference, double):
    (rows, sampled verdict, given_up() on all multipliers, work the sample charged, the
    mode's data)."""
    calls = []
    sample = GuessMixin.guess_reversed

    def recording(self, W):
        before = self.work
        verdict = sample(self, W)
        z = self.signed_multiplier(W)  # uncharged: the full rule's view
        full = self.given_up(int(np.count_nonzero(z >= 0)), W.size, True)
        calls.append((W.size, verdict, full, self.work - before, self.md))
        return verdict

    GuessMixin.guess_reversed = recording
    try:
        ref = uav_double.reference()
        run_closed_loop(uav_double.model.config, ref, steps=3072)
    finally:
        GuessMixin.guess_reversed = sample
    return uav_double, calls


def test_sample_never_gives_up_a_guess_the_full_rule_keeps(reversals):
    _, calls = reversals
    given = [c for c in calls if c[1]]
    assert len(given) >= 2, "steps 941 and 3070 (guesses too long) take the shortcut"
    assert all(full for _, _, full, _, _ in given)
    assert not any(verdict for nw, verdict, *_ in calls if nw < GUESS_SAMPLE_MIN)


def test_sample_is_charged_by_the_row_and_costs_less_than_all_multipliers(reversals):
    _, calls = reversals
    for nw, verdict, _, work, md in calls:
        one, call = guess_sample_work(md, 1), UNIT_CALL_WORK  # afford()'s grant
        assert work in ((0,) if nw < GUESS_SAMPLE_MIN else (call + one, call + 2 * one,
                                                             call + 3 * one))
        if verdict:
            assert work == call + 3 * one < multipliers_work(md, nw)
