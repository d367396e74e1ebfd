"""Each output's innovation is clipped at its own limit, in the C and in the reference.

Planted by the audit and caught by no behavioural test: every output clipped at output
0's limit, in the C (only the byte comparison of generated/ saw it) and in the NumPy
reference alone (nothing saw it). Every test so far gave all outputs one limit. Here the
chain of masses has limits 1, 2, ... 6 m: from a zero estimate (C x̂ = 0, so the
innovation is y) a measurement of 3.5 m on output a is clipped exactly when its limit
is below 3.5, and a clipped one moves the estimate as the limit itself would.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT, Built, edited_config
from rollmpc_codegen.status import MEASUREMENT_CLIPPED, OPTIMAL

LIMITS = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
SPIKE = 3.5


@pytest.fixture(scope="module", params=["double", "float"])
def chain(request, build_root, tmp_path_factory) -> Built:
    def edit(data):
        data["modes"][0].setdefault("observer", {})["innovation_limit"] = LIMITS
    config = edited_config(tmp_path_factory.mktemp("limits"),
                           ROOT / "examples" / "chain_of_masses.yaml", "limits", edit)
    return Built(config, request.param, build_root)


def _commands_after(controller, ctx, y) -> tuple[int, bytes]:
    """P_observe's status for y from rest, and the estimate it leaves (the reference's
    own; the C's seen through the next command)."""
    status = controller.observe(y, None, np.zeros(ctx["n_actuators"]))
    if hasattr(controller, "xhat"):
        return status, controller.xhat[0].tobytes()
    r = np.zeros(ctx["horizon"] * ctx["n_outputs"])
    return status, controller.step(np.zeros(ctx["n_outputs"]), None, r)[1].tobytes()


def _restarted(controller):
    """The controller after P_init (the reference's reset())."""
    (controller.init if hasattr(controller, "init") else controller.reset)()
    return controller


@pytest.mark.parametrize("side", ["c", "reference"])
def test_each_output_is_clipped_at_its_own_limit(chain, side):
    controller = chain.c if side == "c" else chain.reference()

    def make():
        return _restarted(controller)

    for a, limit in enumerate(LIMITS):
        y = np.zeros(6)
        y[a] = SPIKE
        status, after_spike = _commands_after(make(), chain.ctx, y)
        assert status == (MEASUREMENT_CLIPPED if limit < SPIKE else OPTIMAL), (a, status)
        y[a] = min(SPIKE, limit)  # the clipped innovation is the limit, not another's
        assert _commands_after(make(), chain.ctx, y) == (OPTIMAL, after_spike), a


def test_step_reports_each_outputs_clip(chain):
    """P_step counts the clipped outputs (P_last_info()->clipped): those above 3.5 m are
    not; C and reference agree bit for bit."""
    c, ref = chain.fresh_c(), chain.reference()
    r = np.zeros(chain.ctx["horizon"] * 6)
    for _ in range(2):
        st_c, u_c = c.step(np.full(6, SPIKE), None, r)
        st_r, u_r = ref.step(np.full(6, SPIKE), None, r)
        assert st_c == st_r and u_c.tobytes() == u_r.tobytes()
        assert c.info()["clipped"] == ref.last["clipped"]
    fresh = _restarted(c)
    assert fresh.step(np.full(6, SPIKE), None, r)[0] == MEASUREMENT_CLIPPED
    assert fresh.info()["clipped"] == 3  # outputs 0, 1, 2 (limits 1, 2, 3)
