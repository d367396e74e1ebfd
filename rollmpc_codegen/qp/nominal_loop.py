"""Design warning at generation: a controller that does not stabilise its own model.

With no bound active the MPC law is linear: the first move of theta0 = Kx x + Kr R, so
u_0 = K x + (reference terms) with K the first nu rows of Kx.  If A + B K has an
eigenvalue outside the unit circle, the nominal closed loop diverges wherever the bounds
are inactive, and no solver setting or bound rescues it.  A cart-pole written as a new
user would (N = 40, Ts = 10 ms, the terminal weight P = Q; tests/data/newuser/
cart_pole.yaml) had spectral radius 1.007: every QP was solved OPTIMAL and the cart ran
130 m off (README, generate's warnings).  An output cost over a short horizon does not
guarantee stability on an unstable or slow plant; a longer horizon or a larger P does
(there: N = 80 gave 0.993, P = 100 Q 0.995).

The states of the model: the plant's, then the disturbance states of offset-free tracking,
then the previous input of Δu weighting (model/plant.py).  The disturbance states are
constant by construction (eigenvalue 1) and nothing feeds them, so they are left out; the
previous input stays in (u_prev+ = u_0).  Only the nominal model is judged: not the
observer (its own Riccati gain) nor the switching between modes.
"""
from __future__ import annotations

import numpy as np

from ..config.diagnostics import DesignWarning
from ..model.controller import ControllerModel

# rho > 1 + this: outside the unit circle beyond the eigenvalue solver's roundoff, so a
# marginal mode (an integrator no output weight regulates) does not warn by chance
UNSTABLE_BEYOND = 1e-9
# a state-feedback gain no larger than this everywhere is zero: the exact zeros of C B = 0
# or Q = P = 0 survive condensing as zeros or roundoff of this size
ZERO_GAIN = 1e-15


def closed_loop_eigenvalues(model: ControllerModel, j: int) -> np.ndarray:
    """The eigenvalues of mode ``j``'s nominal closed loop A + B K, without the
    disturbance states."""
    plant, qp = model.modes[j].plant, model.modes[j].qp
    a_cl = plant.A + plant.B @ qp.Kx[:qp.nu]
    keep = plant.non_disturbance_states
    return np.linalg.eigvals(a_cl[np.ix_(keep, keep)])


def closed_loop_radius(model: ControllerModel, j: int) -> float:
    """Spectral radius of mode ``j``'s nominal closed loop (closed_loop_eigenvalues)."""
    return float(np.abs(closed_loop_eigenvalues(model, j)).max())


def state_feedback_is_zero(model: ControllerModel, j: int) -> bool:
    """Mode ``j``'s first move does not depend on the state: no weighted output responds
    to the inputs within the horizon (a horizon shorter than the plant's delay from input
    to output, or Q = P = 0), so the controller commands the same whatever the plant does
    (found on a new user's double integrator at N = 1, where C B = 0)."""
    qp = model.modes[j].qp
    return not np.any(np.abs(qp.Kx[:qp.nu]) > ZERO_GAIN)


def unstable_law_warnings(model: ControllerModel) -> list[DesignWarning]:
    """One warning per mode whose controller, with no bound active, does not stabilise
    it (``unstable_nominal_loop``), or does not read its state at all (``state_ignored``)."""
    lines = []
    for j, mode in enumerate(model.config.modes):
        if state_feedback_is_zero(model, j):
            lines.append(DesignWarning(
                "state_ignored", "horizon",
                f"modes[{j}] ({mode.name}): the first move does not depend on the state: no "
                "weighted output responds to the inputs within the horizon, so the "
                "controller ignores the plant; lengthen the horizon past the plant's delay "
                "from input to output, or give weights.Q / weights.P a nonzero weight"))
            continue
        rho = closed_loop_radius(model, j)
        if rho > 1.0 + UNSTABLE_BEYOND:
            lines.append(DesignWarning(
                "unstable_nominal_loop", f"modes[{j}].weights.P",
                f"modes[{j}] ({mode.name}): with no bound active this controller does not "
                f"stabilise its model (the nominal closed loop has an eigenvalue of "
                f"magnitude {rho:.6g}, outside the unit circle), so the loop diverges "
                "wherever the bounds are inactive; lengthen the horizon or raise the "
                "terminal weight (weights.P)"))
    return lines
