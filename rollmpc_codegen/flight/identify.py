"""``rollmpc identify``: the roll controller's config from the aircraft itself.

At each airspeed JSBSim trims straight and level flight, and FGLinearization's method
(JSBSim's own Jacobian of the 6-DOF equations at the trim: 4th-order central differences
with a step of 1e-4, :mod:`.linearise`) gives the lateral linear model: sideslip, roll
rate, yaw rate and roll. We close the yaw damper of the outer loops on it (:func:`outer_loops.yaw_damper_model`, one more state), and scale the aileron column
from JSBSim's normalised command to degrees of left-aileron deflection (the slope of the
aircraft's FCS about the trim, :func:`stencil_slope`). That is the plant the roll loop
sees: aileron -> roll rate -> roll angle, in deg and deg/s.

The config has one mode per airspeed, a k-band scheduler on the measured (calibrated)
airspeed with thresholds half-way between the trim speeds, Ts = 10 ms, N = 100, and the
aileron's real travel as input bounds. :func:`doublet_check` flies an aileron doublet
on JSBSim beside the linear model, so each mode says how well it predicts the aircraft
(:func:`doublet_warning` when badly). The weights, the observer and the margins below are
our choices (docs/flight.md); :mod:`.identify_config` writes the config.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import ConfigError, DesignWarning
from ..sim.scenario import PAPER_SEGMENT_S
from .aircraft import FDM_STEPS_PER_SAMPLE, RAD, Aircraft, Trim
from .linearise import STATES as JSBSIM_STATES, STEP, lateral_jacobian
from .outer_loops import OuterLoops, yaw_damper_model
from .scenario import DEFAULT_PEAK_DEG, paper_levels

SAMPLE_TIME = 0.01
HORIZON = 100
STATES = ("sideslip", "roll_rate", "yaw_rate", "roll", "yaw_washout")  # deg, deg/s
BAND_EPSILON_KTS = 2.0  # scheduler hysteresis
EXAMPLE_AIRSPEEDS_KTS = (90.0, 70.0, 110.0)  # examples/c172_roll.yaml (at 4000 ft)
TRAVEL_MARGIN_DEG = 0.01  # the bounds stay this far inside the measured travel
# MPC weights (deg^-2; R_delta per deg of aileron change per sample) and the Kalman
# predictor of the offset-free model: process noise on the aileron (deg^2), roll
# measurement noise (deg^2: an attitude estimate good to 0.1 deg), random walk of the input
# disturbance (deg^2 per sample), which stands for the trim aileron, turbulence and model
# error. How they were chosen (on the c172p): docs/flight.md, section 1. Another aircraft
# gets them in units of roll acceleration: the aileron's R and R_delta times k^2, Qn and
# Qd divided by it, k = L_da / REFERENCE_AILERON_POWER of its design point (weights_for).
WEIGHTS = {"Q": 1.0, "R": 0.2, "P": 1.0, "R_delta": 1.0}
OBSERVER = {"kind": "kalman", "Qn": 1.0, "Rn": 0.01, "disturbance": "input", "Qd": 0.2}
REFERENCE_AILERON_POWER = 25.64  # L_da of the c172p at 90 kts, deg/s^2 per deg
# `rollmpc simulate`/`report` on the config close the loop on the modes' linear models,
# where no airspeed exists: their scheduling signal is then the roll angle (the band of
# the slowest mode); their scenario is the flights' default roll reference (scenario.py)
SIMULATION = {"schedule_source": "output",
              "reference": {"levels": paper_levels(DEFAULT_PEAK_DEG), "segment": PAPER_SEGMENT_S}}
FDM_DT = SAMPLE_TIME / FDM_STEPS_PER_SAMPLE
DOUBLET_DEG, DOUBLET_S = 2.0, 1.0  # +2 deg for 1 s, then -2 deg for 1 s, then trim
# a doublet whose roll error RMS exceeds this fraction of its peak roll: the linear model
# misses the aircraft there (the c172p's modes: 1 %; the DHC6 at 100 kts: 37 %)
DOUBLET_POOR = 0.10


@dataclass(frozen=True)
class LateralModel:
    """x' = A x + B u (continuous), x = STATES, u = left aileron (deg) from the trim."""

    trim: Trim
    A: np.ndarray
    B: np.ndarray

    @property
    def C(self) -> np.ndarray:
        return np.eye(len(STATES))[[STATES.index("roll")]]


def stencil_slope(aircraft: Aircraft, command: float) -> float:
    """Degrees of left aileron per unit command as FGLinearization's differences see them
    about ``command``: its stencil (8 (f(c+h) - f(c-h)) - (f(c+2h) - f(c-2h))) / 12h on the
    FCS's deflection, which is piecewise linear with its kink at 0. On one side of the kink
    (|command| >= 2h) that side's slope; across it, the stencil's mix of the two, exactly
    (a trim at 0 on a symmetric aileron is no kink at all)."""
    h, g = STEP, aircraft.aileron_deg
    return (8 * (g(command + h) - g(command - h)) - (g(command + 2 * h) - g(command - 2 * h))) \
        / (12 * h)


def linearise(aircraft: Aircraft, trim: Trim) -> LateralModel:
    """The lateral model at ``trim`` (the FDM must be at it, as Aircraft.trim leaves it)."""
    A_lat, b_aileron, b_rudder = lateral_jacobian(aircraft)
    A_closed = yaw_damper_model(A_lat, b_rudder, JSBSIM_STATES.index("R"))
    # x in deg: x_deg' = A x_deg + RAD b u_norm, with u_norm = u_deg / slope
    B_deg = np.append(RAD * b_aileron / stencil_slope(aircraft, trim.aileron), 0.0)[:, None]
    return LateralModel(trim=trim, A=A_closed, B=B_deg)


def identify_modes(aircraft_name: str, airspeeds_kts, altitude_ft: float,
                   settings=()) -> list[LateralModel]:
    """Trim and linearise at each airspeed (a fresh FDM each: FGLinearization moves the
    initial conditions)."""
    models = []
    for v in airspeeds_kts:
        ac = Aircraft(aircraft_name, FDM_DT, settings)
        models.append(linearise(ac, ac.trim(v, altitude_ft)))
    return models


def doublet_check(aircraft_name: str, model: LateralModel, settings=()) -> dict:
    """An aileron doublet about the trim, flown on JSBSim (with the outer loops holding
    altitude and airspeed) and on the ZOH-sampled linear model: the largest roll, the RMS
    and largest difference (deg) over 4 s."""
    from ..model.plant import ContinuousPlant, zoh

    trim = model.trim
    ac = Aircraft(aircraft_name, FDM_DT, settings)
    ac.trim(trim.airspeed_kts, trim.altitude_ft)
    loops = OuterLoops(trim, SAMPLE_TIME)
    disc = zoh(ContinuousPlant(A=model.A, B=model.B, C=model.C, Cr=None, Dr=None), SAMPLE_TIME)
    per = int(round(DOUBLET_S / SAMPLE_TIME))
    du = np.zeros(4 * per)
    du[:per], du[per:2 * per] = DOUBLET_DEG, -DOUBLET_DEG
    x = np.zeros(len(STATES))
    roll_jsbsim, roll_model = [], []
    for k, delta in enumerate(du):
        s = ac.sensors()
        roll_jsbsim.append(s.roll_deg - trim.roll_deg)  # the model's roll is from the trim's
        roll_model.append(float((disc.C @ x)[0]))
        ac.command(trim.aileron_deg + delta, *loops.step(s, trim.altitude_ft, trim.airspeed_kts))
        ac.advance(FDM_STEPS_PER_SAMPLE)
        x = disc.A @ x + disc.B[:, 0] * delta
    diff = np.array(roll_jsbsim) - np.array(roll_model)
    return {"peak_roll_deg": float(np.abs(roll_jsbsim).max()),
            "rms_error_deg": float(np.sqrt(np.mean(diff ** 2))),
            "max_error_deg": float(np.abs(diff).max())}


def doublet_warning(model: LateralModel, check: dict) -> DesignWarning | None:
    """A warning when the doublet's roll error RMS exceeds DOUBLET_POOR of its peak."""
    ratio = check["rms_error_deg"] / max(check["peak_roll_deg"], 1e-9)
    if ratio <= DOUBLET_POOR:
        return None
    return DesignWarning(
        "doublet_poor", "--airspeed",
        f"{mode_name(model)}: the linear model misses the aircraft's doublet by "
        f"{check['rms_error_deg']:.2f} deg RMS on a {check['peak_roll_deg']:.2f} deg peak "
        f"({100 * ratio:.0f} %, more than {100 * DOUBLET_POOR:.0f} %): the trim is near an "
        "edge of the envelope or the aircraft is nonlinear there; trim elsewhere or expect "
        "worse tracking in this band")


def _rounded(a: np.ndarray, digits: int = 6) -> list:
    """Six significant digits (of a continuous model: finer than FGLinearization's
    differences resolve); entries below 1e-5 are their noise (e.g. the roll angle's effect
    on the moments, which is none at the wings-level trim): 0."""
    return [[0.0 if abs(v) < 1e-5 else float(f"{v:.{digits}g}") for v in row]
            for row in np.atleast_2d(a)]


def plant(model: LateralModel, latency: int = 0) -> dict:
    """The mode's ``state_space`` entry: the continuous model, or with ``latency`` > 0
    samples of sensor delay the discrete one (ZOH) with the delay as a chain of input
    states, x+ = A x + B u_{k-latency} (for a SISO loop the same as delaying y), 10
    significant digits (the discrete A is close to I)."""
    if latency == 0:
        return {"A": _rounded(model.A), "B": _rounded(model.B), "C": _rounded(model.C)}
    from ..model.plant import ContinuousPlant, zoh

    disc = zoh(ContinuousPlant(A=model.A, B=model.B, C=model.C, Cr=None, Dr=None),
               SAMPLE_TIME)
    n = disc.nx
    A = np.zeros((n + latency, n + latency))
    A[:n, :n], A[:n, -1] = disc.A, disc.B[:, 0]
    A[n + 1:, n:-1] = np.eye(latency - 1)
    B = np.zeros((n + latency, 1))
    B[n, 0] = 1.0
    C = np.hstack([model.C, np.zeros((1, latency))])
    return {"A": _rounded(A, 10), "B": _rounded(B, 10), "C": _rounded(C, 10),
            "discrete": True}


def mode_name(model: LateralModel) -> str:
    return f"kts{model.trim.airspeed_kts:.0f}"


def bands(models: list[LateralModel]) -> list[dict]:
    """One band per mode, split half-way between neighbouring trim speeds."""
    speeds = [m.trim.airspeed_kts for m in models]
    out = [{"mode": mode_name(m), "below": round((a + b) / 2, 3)}
           for m, a, b in zip(models, speeds, speeds[1:])]
    return out + [{"mode": mode_name(models[-1])}]


def weights_for(model: LateralModel) -> tuple[dict, dict]:
    """(weights, observer) of a mode for the aircraft whose design point is ``model``:
    WEIGHTS and OBSERVER in units of roll acceleration (their comment), the factor k^2
    rounded to two digits (1 on the c172p)."""
    k2 = float(f"{(float(model.B[1, 0]) / REFERENCE_AILERON_POWER) ** 2:.2g}")
    weights = dict(WEIGHTS, R=round(WEIGHTS["R"] * k2, 6), R_delta=round(WEIGHTS["R_delta"] * k2, 6))
    observer = dict(OBSERVER, Qn=float(f"{OBSERVER['Qn'] / k2:.3g}"),
                    Qd=float(f"{OBSERVER['Qd'] / k2:.3g}"))
    return weights, observer
