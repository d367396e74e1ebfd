"""templates/solver/polish_dual.c.j2 (the dual polish: factor a working set, append and
remove rows, fall back to its independent rows, solve for the multipliers; mirrored by
reference/polish_dual.py). thermal_zones_rate's dependent Δu and input rows take every
function; the C and the reference agree bit for bit, work included."""
from __future__ import annotations

from partial_runs import unreached


def test_the_dual_polish_matches_the_reference(partial_run):
    bad, _, calls = partial_run("zones_rate")
    assert bad == [], bad[0]
    assert unreached(calls, "factor_working_set factor_pivot factor_append append_row "
                            "independent_rows remove_row dual_solve") == []
