"""templates/solver/seeds.c.j2 (the polish's working-set seeds, mirrored by
reference/seeds.py): the previous working set shifted one stage, the rows th0 violates,
and those rows again as the dual active set's start. thermal_zones_rate's Δu rows take
every one; the C and the reference agree bit for bit, work included."""
from __future__ import annotations

from partial_runs import unreached


def test_every_seed_matches_the_reference(partial_run):
    bad, _, calls = partial_run("zones_rate")
    assert bad == [], bad[0]
    assert unreached(calls, "new_working_set seed_shifted seed_from_violated "
                            "violated_resume") == []
