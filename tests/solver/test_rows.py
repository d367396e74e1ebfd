"""templates/solver/rows.c.j2 and violated_rows.c.j2 (a row's value, slack and excess, the
violated test at its tolerance, the certificate that spares predicting the outputs, and
the scan for violated rows outside the working set; mirrored by reference/rows.py), on
thermal_zones_rate: the C and the reference agree bit for bit, work included."""
from __future__ import annotations

from partial_runs import unreached


def test_rows_match_the_reference(partial_run):
    bad, _, calls = partial_run("zones_rate")
    assert bad == [], bad[0]
    assert unreached(calls, "row_value slacks output_slacks row_excess row_violated "
                            "outputs_certified outputs_uncertified outputs_to_check "
                            "violated_outside") == []
