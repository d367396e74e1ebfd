"""The PID baseline's gains per aircraft, by one rule from the identified model
(docs/flight.md, "The baseline").

PX4's way: the attitude loop's time constant is the airframe class's (FW_R_TC is 0.4 s
on every plane by default), the rate gains are the aircraft's. Here the closed loops are
those of the c172p's grid optimum (docs/flight.md: at 90 kts FF 0.24, P 0.3, I 0.5,
tau 0.25 s, 60 deg/s), placed on every aircraft through the roll mode of its design point
(the scheduler's initial mode): its roll damping L_p and aileron power L_da, the
roll-rate row p' = L_p p + L_da u of the identified lateral model. With the rate PI on
that mode the closed rate loop is s^2 + (P L_da - L_p) s + I L_da: P L_da is the damping
the gyro feedback adds to the aircraft's own (what rejects a gust), I L_da the
integral's stiffness; the grid optimum has P L_da = RATE_FEEDBACK and I L_da =
RATE_STIFFNESS, and every aircraft gets the same.

* feed-forward FF = -L_p / L_da: the aileron that holds a roll rate against the roll
  damping (PX4's FW_RR_FF);
* rate P = RATE_FEEDBACK / L_da, rate I = RATE_STIFFNESS / L_da;
* angle time constant tau = ANGLE_TIME_CONSTANT_S;
* max roll rate = the steady roll rate at the smaller full deflection, travel / FF;
* integrator limit = INTEGRAL_SHARE of the smaller full deflection;
* airspeed scaling s = V_trim / max(V, V_min): V_trim the design point's trim, V_min the
  slowest identified trim (the envelope's floor).

On the c172p the rule gives its grid optimum back. Then the margins are checked on the
design point's discrete model (ZOH at Ts, with the modelled latency): while the rate
loop or the angle loop has less than MIN_PHASE_MARGIN or MIN_GAIN_MARGIN_DB, P, I and
1/tau are scaled by BACK_OFF.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..config import ControllerConfig

# the c172p grid optimum's rate loop at 90 kts (L_da = 25.64 deg/s^2 per deg): P L_da, I L_da
RATE_FEEDBACK = 0.3 * 25.64  # rad/s
RATE_STIFFNESS = 0.5 * 25.64  # rad^2/s^2
ANGLE_TIME_CONSTANT_S = 0.25
INTEGRAL_SHARE = 1.0 / 3.0
MIN_PHASE_MARGIN = 45.0  # deg
MIN_GAIN_MARGIN_DB = 6.0
BACK_OFF, MAX_BACK_OFFS = 0.8, 20
ROLL_RATE, ROLL = 1, 3  # identify.STATES: [sideslip, roll_rate, yaw_rate, roll, yaw_washout]
FREQUENCIES = 2000  # of the margin check's grid, log-spaced up to Nyquist


@dataclass(frozen=True)
class PidGains:
    """PX4's roll controller parameters in our units (deg, deg/s, kts)."""

    time_constant_s: float  # FW_R_TC
    max_rate_dps: float  # FW_R_RMAX
    feed_forward: float  # FW_RR_FF, deg of aileron per deg/s of rate setpoint
    rate_p: float  # FW_RR_P, deg per deg/s
    rate_i: float  # FW_RR_I, deg per deg (deg/s integrated)
    integral_limit_deg: float  # FW_RR_IMAX
    trim_airspeed_kts: float  # the scaling's reference
    min_airspeed_kts: float  # FW_AIRSPD_MIN, the scaling's floor
    rule: str = "grid"  # how they were found: "grid" (the c172p's) or "model"
    back_offs: int = 0  # BACK_OFF steps the margin check took


# the c172p's grid optimum (docs/flight.md), for a config without an aircraft section
C172P_GRID = PidGains(time_constant_s=0.25, max_rate_dps=60.0, feed_forward=0.24,
                      rate_p=0.3, rate_i=0.5, integral_limit_deg=5.0,
                      trim_airspeed_kts=90.0, min_airspeed_kts=50.0)


def design_mode(cfg: ControllerConfig) -> int:
    return 0 if cfg.scheduler is None else cfg.scheduler.initial


def roll_plant(cfg: ControllerConfig, j: int) -> tuple[np.ndarray, np.ndarray]:
    """Mode ``j``'s discrete (A, B) at Ts: the identified lateral model sampled by ZOH, with
    its latency states when ``identify --latency`` wrote it discrete."""
    from ..model.plant import ContinuousPlant, zoh

    p = cfg.modes[j].plant
    if p.discrete:
        return np.asarray(p.A, float), np.asarray(p.B, float)
    d = zoh(ContinuousPlant(A=np.asarray(p.A, float), B=np.asarray(p.B, float),
                            C=np.asarray(p.C, float), Cr=None, Dr=None), cfg.sample_time)
    return d.A, d.B


def roll_mode(cfg: ControllerConfig, j: int) -> tuple[float, float]:
    """(L_p, L_da) of mode ``j``: of the continuous model, or recovered from the discrete
    one's roll-rate row (a = e^{L_p Ts}, b = L_da (a - 1) / L_p)."""
    p = cfg.modes[j].plant
    A, B = np.asarray(p.A, float), np.asarray(p.B, float)
    if not p.discrete:
        return float(A[ROLL_RATE, ROLL_RATE]), float(B[ROLL_RATE, 0])
    a = float(A[ROLL_RATE, ROLL_RATE])
    n = cfg.aircraft.latency_samples if cfg.aircraft else 0
    b = float(A[ROLL_RATE, -1] if n else B[ROLL_RATE, 0])  # the last delay state feeds it
    L_p = np.log(a) / cfg.sample_time
    return float(L_p), float(b * L_p / (a - 1.0))


def tune_pid(cfg: ControllerConfig) -> PidGains:
    """The rule of the module docstring, for an identified config; the c172p's grid gains
    for one without an ``aircraft`` section."""
    ac = cfg.aircraft
    if ac is None:
        return C172P_GRID
    j = design_mode(cfg)
    L_p, L_da = roll_mode(cfg, j)
    ff = -L_p / L_da
    full = min(-ac.aileron_travel_deg[0], ac.aileron_travel_deg[1])
    gains = PidGains(time_constant_s=ANGLE_TIME_CONSTANT_S, max_rate_dps=full / ff,
                     feed_forward=ff, rate_p=RATE_FEEDBACK / L_da, rate_i=RATE_STIFFNESS / L_da,
                     integral_limit_deg=INTEGRAL_SHARE * full,
                     trim_airspeed_kts=ac.airspeeds_kts[j],
                     min_airspeed_kts=ac.airspeed_range_kts[0], rule="model")
    A, B = roll_plant(cfg, j)
    for steps in range(MAX_BACK_OFFS + 1):
        if all(pm >= MIN_PHASE_MARGIN and gm >= MIN_GAIN_MARGIN_DB
               for pm, gm in loop_margins(A, B, gains, cfg.sample_time)):
            return replace(gains, back_offs=steps)
        gains = replace(gains, rate_p=gains.rate_p * BACK_OFF, rate_i=gains.rate_i * BACK_OFF,
                        time_constant_s=gains.time_constant_s / BACK_OFF)
    return replace(gains, back_offs=MAX_BACK_OFFS)


def loop_margins(A: np.ndarray, B: np.ndarray, g: PidGains,
                 ts: float) -> list[tuple[float, float]]:
    """(phase margin deg, gain margin dB) of the rate loop (broken at the aileron, angle
    loop open) and of the angle loop (broken at the rate setpoint, rate loop closed), on
    the discrete plant (A, B) with the PID as ``pid_roll`` computes it."""
    w = np.logspace(-2, np.log10(0.999 * np.pi / ts), FREQUENCIES)
    z = np.exp(1j * w * ts)
    n = A.shape[0]
    states = np.array([np.linalg.solve(zk * np.eye(n) - A, B[:, 0]) for zk in z])
    g_rate, g_roll = states[:, ROLL_RATE], states[:, ROLL]
    pi = g.rate_p + g.rate_i * ts / (z - 1.0)  # the integral adds e_k dt after u_k
    rate_loop = pi * g_rate
    angle_loop = g_roll * (pi + g.feed_forward) / (1.0 + rate_loop) / g.time_constant_s
    return [margins(w, rate_loop), margins(w, angle_loop)]


def margins(w: np.ndarray, loop: np.ndarray) -> tuple[float, float]:
    """The smallest phase margin over the gain crossovers and the smallest gain margin
    over the phase crossovers (-180 deg) of a negative-feedback loop; inf where there is
    no crossover."""
    mag = np.abs(loop)
    cross = np.flatnonzero(np.diff(np.sign(mag - 1.0)) != 0)
    pm = min((180.0 + np.degrees(np.angle(loop[k])) for k in cross), default=np.inf)
    flips = np.flatnonzero((np.diff(np.sign(loop.imag)) != 0) & (loop.real[:-1] < 0))
    gm = min((-20.0 * np.log10(mag[k]) for k in flips), default=np.inf)
    return float(pm), float(gm)
