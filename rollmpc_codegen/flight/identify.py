"""``rollmpc identify``: the roll controller's config from the aircraft itself.

At each airspeed JSBSim trims straight and level flight, and ``FGLinearization`` (JSBSim's
own Jacobian of the 6-DOF equations at the trim: 4th-order central differences with a
step of 1e-4 in every state and input) gives the full linear model. We keep its lateral
part, sideslip, roll rate, yaw rate and roll, close the yaw damper of the outer loops on
it (:func:`outer_loops.yaw_damper_model`, one more state), and scale the aileron column
from JSBSim's normalised command to degrees of left-aileron deflection (the slope of the
aircraft's FCS at the trim). That is the plant the roll loop sees: aileron -> roll rate
-> roll angle, in deg and deg/s.

The config has one mode per airspeed, a k-band scheduler on the measured (calibrated)
airspeed with thresholds half-way between the trim speeds, Ts = 10 ms, N = 100, and the
aileron's real travel as input bounds. :func:`doublet_check` flies an aileron doublet
on JSBSim beside the linear model, so each mode says how well it predicts the aircraft.
The weights, the observer and the margins below are our choices (docs/flight.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import ConfigError
from ..sim.scenario import PAPER_SEGMENT_S
from .aircraft import FDM_STEPS_PER_SAMPLE, RAD, Aircraft, Trim
from .outer_loops import OuterLoops, yaw_damper_model
from .scenario import DEFAULT_PEAK_DEG, paper_levels

SAMPLE_TIME = 0.01
HORIZON = 100
STATES = ("sideslip", "roll_rate", "yaw_rate", "roll", "yaw_washout")  # deg, deg/s
JSBSIM_STATES = ("Beta", "P", "R", "Phi")  # FGLinearization's names of the first four
BAND_EPSILON_KTS = 2.0  # scheduler hysteresis
EXAMPLE_AIRSPEEDS_KTS = (90.0, 70.0, 110.0)  # examples/c172_roll.yaml (at 4000 ft)
TRAVEL_MARGIN_DEG = 0.01  # the bounds stay this far inside the measured travel
# MPC weights (deg^-2; R_delta per deg of aileron change per sample) and the Kalman
# predictor of the offset-free model: process noise on the aileron (deg^2), roll
# measurement noise (deg^2: an attitude estimate good to 0.1 deg), random walk of the input
# disturbance (deg^2 per sample), which stands for the trim aileron, turbulence and model
# error. How they were chosen: docs/flight.md, section 1.
WEIGHTS = {"Q": 1.0, "R": 0.2, "P": 1.0, "R_delta": 1.0}
OBSERVER = {"kind": "kalman", "Qn": 1.0, "Rn": 0.01, "disturbance": "input", "Qd": 0.2}
# `rollmpc simulate`/`report` on the config close the loop on the modes' linear models,
# where no airspeed exists: their scheduling signal is then the roll angle (the band of
# the slowest mode); their scenario is the flights' default roll reference (scenario.py)
SIMULATION = {"schedule_source": "output",
              "reference": {"levels": paper_levels(DEFAULT_PEAK_DEG), "segment": PAPER_SEGMENT_S}}
FDM_DT = SAMPLE_TIME / FDM_STEPS_PER_SAMPLE
DOUBLET_DEG, DOUBLET_S = 2.0, 1.0  # +2 deg for 1 s, then -2 deg for 1 s, then trim


@dataclass(frozen=True)
class LateralModel:
    """x' = A x + B u (continuous), x = STATES, u = left aileron (deg) from the trim."""

    trim: Trim
    A: np.ndarray
    B: np.ndarray

    @property
    def C(self) -> np.ndarray:
        return np.eye(len(STATES))[[STATES.index("roll")]]


def linearise(aircraft: Aircraft, trim: Trim) -> LateralModel:
    """The lateral model at ``trim`` (the FDM must be at it, as Aircraft.trim leaves it)."""
    import jsbsim

    lin = jsbsim.FGLinearization(aircraft.fdm)
    A, B = np.asarray(lin.system_matrix), np.asarray(lin.input_matrix)
    x_names, u_names = list(lin.x_names), list(lin.u_names)
    lat = [x_names.index(n) for n in JSBSIM_STATES]
    A_lat = A[np.ix_(lat, lat)]
    b_aileron = B[lat, u_names.index("DaCmd")]
    b_rudder = B[lat, u_names.index("DrCmd")]
    A_closed = yaw_damper_model(A_lat, b_rudder, JSBSIM_STATES.index("R"))
    # x in deg: x_deg' = A x_deg + RAD b u_norm, u_norm = u_deg / slope; the 1e-4 steps of
    # FGLinearization stay on one side of 0 unless the trim command is within 2e-4 of it
    if abs(trim.aileron) < 2e-4:
        raise ConfigError("airspeed", f"the trim aileron command at {trim.airspeed_kts:g} kts "
                          f"({trim.aileron:g}) is too close to 0: FGLinearization's "
                          "differences would straddle the FCS's kink")
    slope = aircraft.aileron_slope_deg(trim.aileron)
    B_deg = np.append(RAD * b_aileron / slope, 0.0)[:, None]
    return LateralModel(trim=trim, A=A_closed, B=B_deg)


def identify_modes(aircraft_name: str, airspeeds_kts, altitude_ft: float) -> list[LateralModel]:
    """Trim and linearise at each airspeed (a fresh FDM each: FGLinearization moves the
    initial conditions)."""
    models = []
    for v in airspeeds_kts:
        ac = Aircraft(aircraft_name, FDM_DT)
        models.append(linearise(ac, ac.trim(v, altitude_ft)))
    return models


def doublet_check(aircraft_name: str, model: LateralModel) -> dict:
    """An aileron doublet about the trim, flown on JSBSim (with the outer loops holding
    altitude and airspeed) and on the ZOH-sampled linear model: the largest roll, the RMS
    and largest difference (deg) over 4 s."""
    from ..model.plant import ContinuousPlant, zoh

    trim = model.trim
    ac = Aircraft(aircraft_name, FDM_DT)
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
        roll_jsbsim.append(s.roll_deg)
        roll_model.append(float((disc.C @ x)[0]))
        ac.command(trim.aileron_deg + delta, *loops.step(s, trim.altitude_ft, trim.airspeed_kts))
        ac.advance(FDM_STEPS_PER_SAMPLE)
        x = disc.A @ x + disc.B[:, 0] * delta
    diff = np.array(roll_jsbsim) - np.array(roll_model)
    return {"peak_roll_deg": float(np.abs(roll_jsbsim).max()),
            "rms_error_deg": float(np.sqrt(np.mean(diff ** 2))),
            "max_error_deg": float(np.abs(diff).max())}


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


def build_design(aircraft_name: str, models: list[LateralModel], travel_deg, initial: str,
                 latency: int = 0):
    """The :class:`rollmpc_codegen.Design` of the identified modes (sorted by airspeed)."""
    from ..api import Design, Mode

    lo = math.ceil((travel_deg[0] + TRAVEL_MARGIN_DEG) * 100) / 100
    hi = math.floor((travel_deg[1] - TRAVEL_MARGIN_DEG) * 100) / 100
    modes = [Mode(mode_name(m), plant(m, latency), u_bounds=(lo, hi), observer=dict(OBSERVER),
                  **WEIGHTS) for m in models]
    scheduler = None
    if len(models) > 1:
        scheduler = {"signal": "airspeed", "epsilon": BAND_EPSILON_KTS, "initial": initial,
                     "bands": bands(models)}
    return Design(SAMPLE_TIME, HORIZON, ["roll"], ["aileron"], modes,
                  prefix=aircraft_name.lower().replace("-", "_") + "_roll", scheduler=scheduler,
                  units={"outputs": "deg", "actuators": "deg", "schedule": "kts"},
                  simulation=SIMULATION if scheduler else None)


def header(command: str, aircraft_name: str, models: list[LateralModel], checks: list[dict],
           travel_deg, latency: int = 0) -> str:
    """The YAML comment that says where every number comes from (``command``: the
    ``rollmpc identify`` command line that writes it)."""
    lines = [f"# Roll-angle MPC of the JSBSim {aircraft_name} (docs/flight.md), written by",
             f"#   {command}",
             "# Plant per mode: JSBSim's FGLinearization at a straight and level trim, "
             "lateral part,",
             f"#   x = [{', '.join(STATES)}] (deg, deg/s),",
             "#   with the outer loops' yaw damper closed on it (yaw_washout: its washout "
             "state);",
             "#   input: left-aileron deflection in deg (the FCS's travel: "
             f"{travel_deg[0]:.3f} .. {travel_deg[1]:.3f} deg);",
             "#   output: roll angle in deg.",
             *([f"#   Sampled (ZOH), with {latency} samples of sensor latency as input-delay "
                "states."] if latency else []),
             "# Scheduler: the measured calibrated airspeed (kts), thresholds half-way "
             "between the trims.",
             "# Weights, observer, margins: rollmpc_codegen/flight/identify.py. `rollmpc "
             "fly` flies it;",
             "# `rollmpc simulate` has no airspeed: it schedules on the roll angle "
             "(simulation below).",
             "# Per mode: the trim (calibrated airspeed, altitude, throttle, pitch, aileron), "
             "and a",
             f"# +-{DOUBLET_DEG:g} deg aileron doublet flown on JSBSim beside the model "
             "(peak roll, roll error):"]
    for m, c in zip(models, checks):
        t = m.trim
        lines.append(f"#   {mode_name(m)}: {t.airspeed_kts:.1f} kts, {t.altitude_ft:.0f} ft, "
                     f"throttle {t.throttle:.3f}, pitch {t.pitch_deg:.2f}, aileron "
                     f"{t.aileron_deg:.3f} deg;")
        lines.append(f"#     doublet: peak {c['peak_roll_deg']:.2f} deg, error RMS "
                     f"{c['rms_error_deg']:.3f} max {c['max_error_deg']:.3f} deg")
    return "\n".join(lines) + "\n"


def identify_config(aircraft_name: str, airspeeds_kts, altitude_ft: float, latency: int = 0,
                    progress=None) -> tuple[str, list[LateralModel], list[dict]]:
    """(YAML text of the config, the modes' models, their doublet checks) for ``rollmpc
    identify``; ``progress(text)`` is told what runs. The first airspeed is the design
    point: the scheduler's initial mode; ``latency`` samples of sensor delay are modelled
    (:func:`plant`)."""
    if not airspeeds_kts:
        raise ValueError("needs at least one airspeed")
    speeds = sorted(set(float(v) for v in airspeeds_kts))
    models = identify_modes(aircraft_name, speeds, altitude_ft)
    checks = []
    for m in models:
        if progress:
            progress(f"identify: doublet check at {m.trim.airspeed_kts:.0f} kts")
        checks.append(doublet_check(aircraft_name, m))
    travel = Aircraft(aircraft_name, FDM_DT).travel_deg
    initial = mode_name(models[speeds.index(float(airspeeds_kts[0]))])
    design = build_design(aircraft_name, models, travel, initial, latency)
    command = (f"rollmpc identify --aircraft {aircraft_name} "
               + " ".join(f"--airspeed {float(v):g}" for v in airspeeds_kts)
               + f" --altitude {altitude_ft:g}" + (f" --latency {latency}" if latency else ""))
    return (header(command, aircraft_name, models, checks, travel, latency) + design.to_yaml(),
            models, checks)
