"""The baseline: PX4's fixed-wing roll controller (the roll-angle P loop of
FixedwingAttitudeControl, the roll-rate PI with feed-forward and airspeed scaling of
FixedwingRateControl), in our units: roll in deg, rates in deg/s, the aileron in degrees
of left-aileron deflection, the MPC's actuator and bounds.

    p_sp = clip((phi_sp - phi) / TIME_CONSTANT_S, +-MAX_RATE_DPS)
    s    = V_trim / max(V, MIN_AIRSPEED_KTS)                       (airspeed scaling)
    u    = clip(s^2 (RATE_P e + integral) + s FEED_FORWARD p_sp, bounds),  e = p_sp - p
    integral += RATE_I e dt, within +-INTEGRAL_LIMIT_DEG, frozen while u is saturated in
    the direction of e

as PX4 computes ``roll_u`` (s^2 on the PI, s on the feed-forward). Gains for the c172p
(docs/flight.md, "The baseline"): FEED_FORWARD is the inverse of the roll rate one
degree of aileron holds against roll damping at 90 kts (-L_da / L_p of the identified
model: 25.6 / 6.08 = 4.2 deg/s per deg); TIME_CONSTANT_S, MAX_RATE_DPS, RATE_P and RATE_I
come from a grid search on flights at 90 kts (calm air, and moderate turbulence with two
seeds): a point of the plateau, RMS roll error within 1 % of the best, overshoot < 3 %.
"""
from __future__ import annotations

TIME_CONSTANT_S = 0.25  # PX4 FW_R_TC (default 0.4; the grid's best is its floor 0.2)
MAX_RATE_DPS = 60.0  # FW_R_RMAX
FEED_FORWARD = 0.24  # deg of aileron per deg/s of roll-rate setpoint (FW_RR_FF)
RATE_P = 0.3  # deg per deg/s (FW_RR_P)
RATE_I = 0.5  # deg per deg (FW_RR_I)
INTEGRAL_LIMIT_DEG = 5.0  # FW_RR_IMAX
MIN_AIRSPEED_KTS = 50.0  # the scaling's floor (FW_AIRSPD_MIN)


class PidRoll:
    """One roll controller; ``step`` has the signature of :class:`.loop.MpcRoll`'s."""

    name = "PID (PX4 style)"

    def __init__(self, trim_airspeed_kts: float, bounds_deg: tuple[float, float], dt: float):
        self.trim_airspeed = trim_airspeed_kts
        self.lo, self.hi = bounds_deg
        self.dt = dt
        self.integral = 0.0

    def step(self, roll_deg: float, roll_rate_dps: float, airspeed_kts: float,
             reference_deg: float, preview_deg) -> tuple[float, int, dict]:
        """(aileron deg, status 0, diagnostics); the preview is not used."""
        p_sp = min(MAX_RATE_DPS, max(-MAX_RATE_DPS, (reference_deg - roll_deg) / TIME_CONSTANT_S))
        s = self.trim_airspeed / max(airspeed_kts, MIN_AIRSPEED_KTS)
        error = p_sp - roll_rate_dps
        u = s * s * (RATE_P * error + self.integral) + s * FEED_FORWARD * p_sp
        if not ((u >= self.hi and error > 0) or (u <= self.lo and error < 0)):
            self.integral = min(INTEGRAL_LIMIT_DEG, max(-INTEGRAL_LIMIT_DEG,
                                                        self.integral + RATE_I * error * self.dt))
        return min(self.hi, max(self.lo, u)), 0, {"mode": 0, "iterations": 0, "solve_us": 0.0}
