"""templates/solver/soft_rows.c.j2 (a soft row's state, tight or slack, set when it joins
and switched when its multiplier crosses l1; mirrored by reference/soft_rows.py), on the
45 deg roll design with soft bounds at N = 20, which passes 45 deg: the C and the
reference agree bit for bit, work included."""
from __future__ import annotations

from partial_runs import unreached


def test_soft_row_states_match_the_reference(partial_run):
    bad, _, calls = partial_run("soft_roll")
    assert bad == [], bad[0]
    assert unreached(calls, "set_state slack_in_set switch_states switch_row") == []
