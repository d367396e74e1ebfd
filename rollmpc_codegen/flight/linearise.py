"""The lateral Jacobian of a trimmed JSBSim aircraft, by FGLinearization's method on the
states and inputs the roll loop needs.

JSBSim's ``FGLinearization`` (``FGStateSpace.{h,cpp}``) perturbs each state and input of
the initial condition by +-h and +-2h (h = 1e-4), re-initialises the FDM and reads the
state derivatives, J = (8 (f(h) - f(-h)) - (f(2h) - f(-2h))) / 12h. Its settling loop
runs the engines' steady state up to 1000 times per perturbation, which never settles
on some aircraft (the c310's constant-speed propellers: an identify that ran for hours).
Here the same components, derivatives and stencil, on the lateral part only (sideslip,
roll rate, yaw rate, roll; aileron and rudder), with the flight control system settled
in trim mode for SETTLE_RUNS runs and the engines held where the trim left them. On the
c172p it gives FGLinearization's lateral block to 2e-5.
"""
from __future__ import annotations

import numpy as np

from .aircraft import Aircraft

STEP = 1e-4  # h of FGStateSpace::linearize
SETTLE_RUNS = 3  # trim-mode runs after each re-initialisation: the FCS reaches its inputs
STATES = ("Beta", "P", "R", "Phi")  # FGStateSpace's names
# each state: the initial condition it is set through, the derivative JSBSim reports
STATE_IC = {"Beta": "ic/beta-rad", "P": "ic/p-rad_sec", "R": "ic/r-rad_sec",
            "Phi": "ic/phi-rad"}
DERIVATIVE = {"Beta": "aero/betadot-rad_sec", "P": "accelerations/pdot-rad_sec2",
              "R": "accelerations/rdot-rad_sec2", "Phi": "velocities/phidot-rad_sec"}
INPUTS = {"DaCmd": "fcs/aileron-cmd-norm", "DrCmd": "fcs/rudder-cmd-norm"}


def hold_state_as_ic(aircraft: Aircraft) -> None:
    """Write the FDM's current state into its initial condition (JSBSim's trim leaves
    the trimmed state in the FDM, not in the IC), in FGStateSpace's order: airspeed,
    angle of attack (sideslip, heading and pitch kept), flight path, rates, attitude."""
    f = aircraft.fdm
    alpha, theta = float(f["aero/alpha-rad"]), float(f["attitude/theta-rad"])
    for ic, value in (("vt-fps", f["velocities/vt-fps"]), ("alpha-rad", alpha),
                      ("beta-rad", f["aero/beta-rad"]), ("psi-true-rad", f["attitude/psi-rad"]),
                      ("theta-rad", theta), ("gamma-rad", theta - alpha),
                      ("q-rad_sec", f["velocities/q-rad_sec"]), ("phi-rad", f["attitude/phi-rad"]),
                      ("p-rad_sec", f["velocities/p-rad_sec"]),
                      ("r-rad_sec", f["velocities/r-rad_sec"]), ("h-sl-ft", f["position/h-sl-ft"])):
        f[f"ic/{ic}"] = float(value)


def settle(aircraft: Aircraft) -> np.ndarray:
    """Re-initialise from the IC, let the FCS follow in trim mode, and return the lateral
    state derivatives."""
    f = aircraft.fdm
    f.run_ic()
    for _ in range(SETTLE_RUNS):
        f.set_trim_status(True)
        f.suspend_integration()
        f.run()
        f.set_trim_status(False)
        f.resume_integration()
    return np.array([float(f[DERIVATIVE[name]]) for name in STATES])


def column(aircraft: Aircraft, prop: str) -> np.ndarray:
    """The derivatives' 4th-order central difference in the property ``prop``."""
    f = aircraft.fdm
    base = float(f[prop])
    values = {}
    for multiple in (1, 2, -1, -2):
        f[prop] = base + multiple * STEP
        values[multiple] = settle(aircraft)
    f[prop] = base
    return (8 * (values[1] - values[-1]) - (values[2] - values[-2])) / (12 * STEP)


def lateral_jacobian(aircraft: Aircraft) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A 4x4 over STATES, b of the aileron command, b of the rudder command), rad and
    normalised commands, at the trim the FDM is at; leaves the FDM re-initialised there."""
    hold_state_as_ic(aircraft)
    A = np.column_stack([column(aircraft, STATE_IC[name]) for name in STATES])
    b_aileron, b_rudder = (column(aircraft, INPUTS[name]) for name in ("DaCmd", "DrCmd"))
    settle(aircraft)
    return A, b_aileron, b_rudder
