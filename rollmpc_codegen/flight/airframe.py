"""What ``rollmpc identify`` measures of the airframe besides its linear models and the
aileron's travel (aircraft.measure_travel, run by every Aircraft it makes): the angle of
attack of maximum lift, and whether a trim holds once the FDM integrates.

* **Stall angle.** Lift against angle of attack at the trim's speed and altitude, from
  JSBSim's own aerodynamics (the initial condition re-run at each angle, nothing
  integrated): the first maximum of C_L is the aircraft's maximum-lift angle. Only a few
  models (the c172p) have a stall hysteresis flag; every model has a lift table.
* **A trim that holds.** JSBSim trims with the integration suspended, so an engine whose
  state needs time (a constant-speed propeller's governor, a turboprop's spool) can give
  a trim that flies away at once (the c310 at 120 kts, 4000 ft: -5.5 kts in 10 s; the
  DHC6's thrust rises by 60 % within 5 s of its trims). Flown hands-off for TRIM_HOLD_S,
  the airspeed should stay within TRIM_HOLD_KTS.
"""
from __future__ import annotations

from .aircraft import Aircraft

ALPHA_STEP_DEG = 0.5  # the lift sweep's resolution
ALPHA_MAX_DEG = 45.0
LIFT_DROP = 0.005  # C_L below its running maximum by this: past the maximum-lift angle
TRIM_HOLD_S, TRIM_HOLD_KTS = 2.0, 1.0


def stall_alpha_deg(aircraft: Aircraft, airspeed_kts: float, altitude_ft: float) -> float | None:
    """The first maximum of the lift coefficient over angle of attack at ``airspeed_kts``
    and ``altitude_ft`` (deg), from the FDM's aerodynamics with the controls where they
    are (call it on a trimmed FDM); None when lift grows up to ALPHA_MAX_DEG. Leaves the
    FDM re-initialised, not trimmed."""
    f = aircraft.fdm
    best, best_alpha = -float("inf"), None
    alpha = 0.0
    while alpha <= ALPHA_MAX_DEG:
        f["ic/h-sl-ft"], f["ic/vc-kts"] = altitude_ft, airspeed_kts
        f["ic/alpha-deg"], f["ic/beta-deg"] = alpha, 0.0
        f.run_ic()
        # JSBSim's wind-axis Z force of the aerodynamics is the lift, positive up
        lift = float(f["forces/fwz-aero-lbs"]) / (float(f["aero/qbar-psf"])
                                                  * float(f["metrics/Sw-sqft"]))
        if lift > best:
            best, best_alpha = lift, alpha
        elif lift < best - LIFT_DROP:
            return best_alpha
        alpha += ALPHA_STEP_DEG
    return None


def trim_drift_kts(aircraft: Aircraft, airspeed_kts: float, altitude_ft: float) -> float:
    """Trim, then fly hands-off for TRIM_HOLD_S: the largest airspeed change (kts). More
    than TRIM_HOLD_KTS: JSBSim found the trim with an engine state that the integration
    then changes (a propeller governor's pitch, a turbine's spool)."""
    trim = aircraft.trim(airspeed_kts, altitude_ft)
    f = aircraft.fdm
    drift = 0.0
    for _ in range(int(round(TRIM_HOLD_S / float(f.get_delta_t())))):
        f.run()
        drift = max(drift, abs(float(f["velocities/vc-kts"]) - trim.airspeed_kts))
    return drift
