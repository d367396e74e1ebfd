"""The loops around roll that every flight shares, MPC and baseline alike: altitude ->
pitch -> elevator, airspeed -> throttle, and a washout yaw damper on the rudder.

They are deliberately plain (PX4/ArduPilot-style PI loops, hand-tuned on the c172p at
4000 ft, 70 to 110 kts; docs/flight.md lists the gains), and each output is its trim value
plus a correction. The yaw damper is part of the plant the roll controller sees, so
``identify`` folds it into the lateral model (:func:`yaw_damper_model`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .aircraft import Sensors, Trim

# altitude -> climb-rate setpoint
ALTITUDE_GAIN = 0.25  # (ft/s) per ft of altitude error
CLIMB_LIMIT_FPS = 10.0
# climb-rate error -> pitch setpoint about the trim pitch (PI: the integral supplies the
# extra pitch a banked turn needs)
CLIMB_TO_PITCH = (0.4, 0.2)  # (deg per ft/s, deg per ft)
PITCH_LIMIT_DEG = 15.0  # |pitch setpoint - trim pitch|
# pitch error and pitch rate -> elevator (a positive elevator command pitches nose down)
PITCH_GAIN, PITCH_RATE_GAIN = 0.08, 0.03  # per deg, per deg/s (normalised command)
# airspeed -> throttle about its trim (PI)
AIRSPEED_TO_THROTTLE = (0.1, 0.05)  # per kt, per kt s
# yaw damper: rudder = trim + gain * washout(r), washout r - w with w' = (r - w) / tau.
# The gain raises the Dutch roll damping of the c172p from 0.19 to about 0.4 (70-110 kts);
# the washout leaves the steady yaw rate of a turn alone.
YAW_DAMPER_GAIN = 1.0  # normalised rudder per rad/s (positive rudder yaws left)
YAW_DAMPER_WASHOUT_S = 1.0


@dataclass
class PI:
    """u = kp e + ki integral(e), clipped to [lo, hi]; the integral stops while the output
    is saturated in the direction of the error (no wind-up)."""

    kp: float
    ki: float
    lo: float = -math.inf
    hi: float = math.inf
    integral: float = 0.0

    def update(self, error: float, dt: float, offset: float = 0.0) -> float:
        raw = offset + self.kp * error + self.integral
        if not ((raw >= self.hi and error > 0) or (raw <= self.lo and error < 0)):
            self.integral += self.ki * error * dt
        return min(self.hi, max(self.lo, offset + self.kp * error + self.integral))


def yaw_damper_model(A: np.ndarray, b_rudder: np.ndarray, r_index: int) -> np.ndarray:
    """The lateral A (any angle unit) with the yaw damper closed: the washout state w is
    appended, rudder = YAW_DAMPER_GAIN (r - w) through ``b_rudder`` (per normalised
    rudder, the state's unit per second; the gain's rad cancels in a model that is linear
    in angles)."""
    n = A.shape[0]
    Aa = np.zeros((n + 1, n + 1))
    Aa[:n, :n] = A
    Aa[:n, r_index] += YAW_DAMPER_GAIN * b_rudder
    Aa[:n, n] -= YAW_DAMPER_GAIN * b_rudder
    Aa[n, r_index] = 1.0 / YAW_DAMPER_WASHOUT_S
    Aa[n, n] = -1.0 / YAW_DAMPER_WASHOUT_S
    return Aa


class OuterLoops:
    """Elevator, throttle and rudder for one flight from the trim ``trim``, at ``dt``."""

    def __init__(self, trim: Trim, dt: float):
        self.trim, self.dt = trim, dt
        self.climb = PI(*CLIMB_TO_PITCH, lo=-PITCH_LIMIT_DEG, hi=PITCH_LIMIT_DEG)
        self.speed = PI(*AIRSPEED_TO_THROTTLE, lo=0.0, hi=1.0)
        self.washout = 0.0  # w, deg/s

    def step(self, s: Sensors, altitude_ft: float,
             airspeed_kts: float) -> tuple[float, float, float]:
        """(elevator, throttle, rudder), JSBSim's normalised commands."""
        t, dt = self.trim, self.dt
        climb_sp = min(CLIMB_LIMIT_FPS, max(-CLIMB_LIMIT_FPS,
                                            ALTITUDE_GAIN * (altitude_ft - s.altitude_ft)))
        pitch_sp = t.pitch_deg + self.climb.update(climb_sp - s.climb_fps, dt)
        elevator = t.elevator - PITCH_GAIN * (pitch_sp - s.pitch_deg) \
            + PITCH_RATE_GAIN * s.pitch_rate_dps
        throttle = self.speed.update(airspeed_kts - s.airspeed_kts, dt, offset=t.throttle)
        washed = s.yaw_rate_dps - self.washout
        self.washout += dt / YAW_DAMPER_WASHOUT_S * washed
        rudder = t.rudder + YAW_DAMPER_GAIN * washed / (180.0 / math.pi)
        return (min(1.0, max(-1.0, elevator)), throttle, min(1.0, max(-1.0, rudder)))
