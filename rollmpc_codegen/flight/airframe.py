"""What ``rollmpc identify`` measures of the airframe besides its linear models: the
aileron's travel and rate through the aircraft's FCS, the angle of attack of maximum
lift, and whether a trim holds once the FDM integrates.

* **Travel at steady state.** A full command (-1, then +1) is held on the ground until
  the left aileron stops moving (its actuator may lag or be rate-limited: the f15's and
  f16's kinematic actuators take 0.3 s end to end, and one step moved them 1 deg of 20).
  The largest rate seen on those steps is the actuator's rate limit; an aileron that
  reaches its end within one step has none.
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

from dataclasses import dataclass

from ..config import ConfigError
from .aircraft import Aircraft

SETTLE_MAX_S = 5.0  # the longest an aileron may take to reach its end
SETTLED_DEG = 1e-6  # a step that moves the surface less than this: it has arrived
ALPHA_STEP_DEG = 0.5  # the lift sweep's resolution
ALPHA_MAX_DEG = 45.0
LIFT_DROP = 0.005  # C_L below its running maximum by this: past the maximum-lift angle
TRIM_HOLD_S, TRIM_HOLD_KTS = 2.0, 1.0


@dataclass(frozen=True)
class Travel:
    travel_deg: tuple[float, float]  # (at command -1, at +1), steady state
    rate_dps: float | None  # the largest rate on those steps; None: one step reaches the end
    settle_s: float  # the longer of the two steps' times to arrive


def measure_travel(aircraft: Aircraft) -> Travel:
    """The left aileron's steady deflection at commands -1 and +1 (deg) and its rate, on
    the ground (module docstring). ConfigError when it does not move both ways."""
    f = aircraft.fdm
    f.run_ic()
    dt = float(f.get_delta_t())
    ends, rates, settle = [], [], 0.0
    for command in (-1.0, 1.0):
        f["fcs/aileron-cmd-norm"] = command
        before = float(f["fcs/left-aileron-pos-deg"])
        steps, fastest = 0, 0.0
        while steps * dt < SETTLE_MAX_S:
            f.run()
            steps += 1
            now = float(f["fcs/left-aileron-pos-deg"])
            if abs(now - before) < SETTLED_DEG:
                break
            fastest = max(fastest, abs(now - before) / dt)
            before = now
        ends.append(before)
        rates.append(None if steps <= 2 else fastest)
        settle = max(settle, (steps - 1) * dt)
    f["fcs/aileron-cmd-norm"] = 0.0
    if not ends[0] < 0.0 < ends[1]:
        raise ConfigError("aircraft", f"{aircraft.name}: the left aileron moves "
                          f"{ends[0]:g} .. {ends[1]:g} deg for commands -1 .. +1 at steady "
                          "state (fcs/left-aileron-pos-deg); rollmpc flies an aircraft whose "
                          "positive command rolls right through that deflection")
    limited = [r for r in rates if r is not None]
    return Travel(travel_deg=(ends[0], ends[1]), rate_dps=min(limited) if limited else None,
                  settle_s=settle)


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
