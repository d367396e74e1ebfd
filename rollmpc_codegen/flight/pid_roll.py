"""The baseline: PX4's fixed-wing roll controller (the roll-angle P loop of
FixedwingAttitudeControl, the roll-rate PI with feed-forward and airspeed scaling of
FixedwingRateControl), in our units: roll in deg, rates in deg/s, the aileron in degrees
of left-aileron deflection, the MPC's actuator and bounds.

    p_sp = clip((phi_sp - phi) / tau, +-max_rate)
    s    = V_trim / max(V, V_min)                                   (airspeed scaling)
    u    = clip(s^2 (P e + integral) + s FF p_sp, bounds),  e = p_sp - p
    integral += I e dt, within +-integral_limit, frozen while u is saturated in the
    direction of e

as PX4 computes ``roll_u`` (s^2 on the PI, s on the feed-forward). The gains come from
:mod:`.pid_tuning`: per aircraft from its identified model, or the c172p's grid optimum.
"""
from __future__ import annotations

from .pid_tuning import PidGains


class PidRoll:
    """One roll controller; ``step`` has the signature of :class:`.loop.MpcRoll`'s."""

    name = "PID (PX4 style)"

    def __init__(self, gains: PidGains, bounds_deg: tuple[float, float], dt: float):
        self.g = gains
        self.lo, self.hi = bounds_deg
        self.dt = dt
        self.integral = 0.0

    def step(self, roll_deg: float, roll_rate_dps: float, airspeed_kts: float,
             reference_deg: float, preview_deg) -> tuple[float, int, dict]:
        """(aileron deg, status 0, diagnostics); the preview is not used."""
        g = self.g
        p_sp = min(g.max_rate_dps, max(-g.max_rate_dps,
                                       (reference_deg - roll_deg) / g.time_constant_s))
        s = g.trim_airspeed_kts / max(airspeed_kts, g.min_airspeed_kts)
        error = p_sp - roll_rate_dps
        u = s * s * (g.rate_p * error + self.integral) + s * g.feed_forward * p_sp
        if not ((u >= self.hi and error > 0) or (u <= self.lo and error < 0)):
            self.integral = min(g.integral_limit_deg, max(-g.integral_limit_deg,
                                                          self.integral + g.rate_i * error
                                                          * self.dt))
        return min(self.hi, max(self.lo, u)), 0, {"mode": 0, "iterations": 0, "solve_us": 0.0}
