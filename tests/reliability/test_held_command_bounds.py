"""A held command above its new range is clamped to the upper bound, below it to the lower.

Planted by the audit and caught only by the byte comparison of generated/: the C's
hold_for_mode() clamping a command above the range to the *lower* bound.  On
chain_runtime_bounds, after P_set_bounds tightened the inputs to +-0.05, a held +0.12
became -0.05 instead of +0.05 (test_runtime_bounds's held-command test only exercised
the lower clamp).  Here the held command has entries above and below the new range.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import ROOT, Built
from rollmpc_codegen.status import NONFINITE_INPUT, OPTIMAL

INF = math.inf
TIGHT = 0.05


@pytest.fixture(scope="module", params=["double", "float"])
def chain(request, build_root) -> Built:
    return Built(ROOT / "examples" / "chain_runtime_bounds.yaml", request.param, build_root)


def test_held_command_is_clamped_to_the_nearer_bound(chain):
    c, ref = chain.c, chain.reference()
    c.init()
    N, ny = chain.ctx["horizon"], chain.ctx["n_outputs"]
    # masses 1-3 pulled to +0.5, 4-6 to -0.5: forces of both signs beyond +-0.05
    r = np.tile(np.array([0.5, 0.5, 0.5, -0.5, -0.5, -0.5]), N)
    y = np.zeros(ny)
    for _ in range(2):
        st_c, u = c.step(y, None, r)
        st_r, u_r = ref.step(y, None, r)
    assert st_c == st_r == OPTIMAL and u.tobytes() == u_r.tobytes()
    assert u.max() > TIGHT and u.min() < -TIGHT, u  # both clamps are exercised
    tight = {"u_min": [-TIGHT] * 4, "u_max": [TIGHT] * 4,
             "y_min": [-0.6] * 4 + [-INF, -INF], "y_max": [0.6] * 5 + [INF]}
    assert c.set_bounds(0, **tight) == ref.set_bounds(0, **tight) == OPTIMAL
    st_c, held = c.step(np.full(ny, np.nan), None, r)
    st_r, held_r = ref.step(np.full(ny, np.nan), None, r)
    assert st_c == st_r == NONFINITE_INPUT
    t = c.dtype(TIGHT)
    expected = np.where(u > t, t, np.where(u < -t, -t, u))
    assert np.array_equal(held, expected), (u, held)
    assert np.array_equal(held_r, expected), (u, held_r)
