"""templates/solver/polish.c.j2 (the polish's rounds: give up a guess, drop negative
multipliers, check and keep a working set, stop or keep the progress when the budget ends;
mirrored by reference/polish.py), on thermal_zones_rate and on the UAV at N = 20 under a
budget that binds (TIME_LIMIT samples). The C and the reference agree bit for bit, work
included."""
from __future__ import annotations

from partial_runs import unreached
from rollmpc_codegen.status import TIME_LIMIT


def test_the_polish_matches_the_reference(partial_run):
    bad, _, calls = partial_run("zones_rate")
    assert bad == [], bad[0]
    assert unreached(calls, "polish given_up drop_negative working_set_holds "
                            "keep_working_set converged stopped") == []


def test_a_polish_the_budget_stops_keeps_its_progress(partial_run):
    bad, statuses, calls = partial_run("uav20_budget")
    assert bad == [], bad[0]
    assert statuses[TIME_LIMIT] > 0 and calls["keep_progress"] > 0
