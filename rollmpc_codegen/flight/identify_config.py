"""``rollmpc identify``'s config: the identified modes (:mod:`.identify`) as a Design, the
aircraft and its envelope (the top-level ``aircraft`` section, config/aircraft.py), the
part the image is sized for (``target.part``), and the header that says where every
number comes from.

The envelope: the trim airspeeds and altitude, the aileron's steady travel and rate
(:func:`.aircraft.measure_travel`), the angle of attack of maximum lift at the slowest
trim (:func:`.airframe.stall_alpha_deg`), the modelled latency and the JSBSim settings
the trims need. Warnings, returned with the text: a doublet the model misses
(identify.doublet_warning), a trim that does not hold (airframe.trim_drift_kts), and the
generated controller's delay margin on its own model (model/delay_margin.py).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from ..config import DesignWarning
from ..config.aircraft_types import AircraftConfig
from ..parts import DEFAULT_PART
from .aircraft import Aircraft, Travel
from .airframe import TRIM_HOLD_KTS, TRIM_HOLD_S, stall_alpha_deg, trim_drift_kts
from .identify import (BAND_EPSILON_KTS, DOUBLET_DEG, FDM_DT, HORIZON, SAMPLE_TIME,
                       SIMULATION, STATES, TRAVEL_MARGIN_DEG, LateralModel, bands,
                       doublet_check, doublet_warning, identify_modes, mode_name, plant,
                       weights_for)


@dataclass
class Identified:
    """What ``rollmpc identify`` writes and prints."""

    text: str  # the YAML config with its header
    models: list[LateralModel]
    checks: list[dict]  # per mode: the doublet's peak roll and errors
    aircraft: AircraftConfig
    delay_margins: list[int | None]  # per mode, samples (model/delay_margin.py)
    warnings: list[DesignWarning] = field(default_factory=list)


def prefix_of(aircraft_name: str) -> str:
    """The C prefix: the aircraft's name as a lower-case identifier, then ``_roll``."""
    stem = re.sub(r"[^a-z0-9_]", "_", aircraft_name.lower())
    return (stem if stem[:1].isalpha() else f"ac{stem}") + "_roll"


def aileron_bounds(travel_deg) -> tuple[float, float]:
    """The input bounds: the travel, TRAVEL_MARGIN_DEG inwards, rounded to 0.01 deg."""
    return (math.ceil((travel_deg[0] + TRAVEL_MARGIN_DEG) * 100) / 100,
            math.floor((travel_deg[1] - TRAVEL_MARGIN_DEG) * 100) / 100)


def build_design(aircraft: AircraftConfig, models: list[LateralModel], initial: str,
                 part: str = DEFAULT_PART):
    """The :class:`rollmpc_codegen.Design` of the identified modes (sorted by airspeed)."""
    from ..api import Design, Mode

    bounds = aileron_bounds(aircraft.aileron_travel_deg)
    weights, observer = weights_for(next(m for m in models if mode_name(m) == initial))
    modes = [Mode(mode_name(m), plant(m, aircraft.latency_samples), u_bounds=bounds,
                  observer=dict(observer), **weights) for m in models]
    scheduler = None
    if len(models) > 1:
        scheduler = {"signal": "airspeed", "epsilon": BAND_EPSILON_KTS, "initial": initial,
                     "bands": bands(models)}
    return Design(SAMPLE_TIME, HORIZON, ["roll"], ["aileron"], modes,
                  prefix=prefix_of(aircraft.name), scheduler=scheduler,
                  units={"outputs": "deg", "actuators": "deg", "schedule": "kts"},
                  simulation=SIMULATION if scheduler else None, target={"part": part},
                  aircraft=aircraft.to_yaml_data())


def header(command: str, identified: Identified) -> str:
    """The YAML comment that says where every number comes from (``command``: the
    ``rollmpc identify`` command line that writes it)."""
    ac = identified.aircraft
    lo, hi = ac.aileron_travel_deg
    rate = "no rate limit" if ac.aileron_rate_dps is None else \
        f"at most {ac.aileron_rate_dps:.0f} deg/s"
    stall = "none found" if ac.stall_alpha_deg is None else f"{ac.stall_alpha_deg:g} deg"
    margins = ", ".join(f"{mode_name(m)} {'>30' if d is None else d}"
                        for m, d in zip(identified.models, identified.delay_margins))
    lines = [f"# Roll-angle MPC of the JSBSim {ac.name} (docs/flight.md), written by",
             f"#   {command}",
             "# Plant per mode: FGLinearization's Jacobian at a straight and level trim "
             "(flight/linearise.py),",
             f"#   lateral part x = [{', '.join(STATES)}] (deg, deg/s),",
             "#   with the outer loops' yaw damper closed on it (yaw_washout: its washout "
             "state);",
             f"#   input: left-aileron deflection in deg (the FCS's steady travel {lo:.3f} .. "
             f"{hi:.3f} deg,",
             f"#   {rate});",
             "#   output: roll angle in deg.",
             *([f"#   Sampled (ZOH), with {ac.latency_samples} samples of sensor latency as "
                "input-delay states."] if ac.latency_samples else []),
             "# Scheduler: the measured calibrated airspeed (kts), thresholds half-way "
             "between the trims.",
             "# Weights, observer, margins: rollmpc_codegen/flight/identify.py. `rollmpc "
             "fly` flies it;",
             "# `rollmpc simulate` has no airspeed: it schedules on the roll angle "
             "(simulation below).",
             f"# Envelope (aircraft: below): maximum lift at alpha {stall}; delay margin of "
             "the controller",
             f"#   on its model, samples of unmodelled delay it stays stable with: {margins}.",
             "# Per mode: the trim (calibrated airspeed, altitude, throttle, pitch, aileron), "
             "and a",
             f"# +-{DOUBLET_DEG:g} deg aileron doublet flown on JSBSim beside the model "
             "(peak roll, roll error):"]
    for m, c in zip(identified.models, identified.checks):
        t = m.trim
        lines.append(f"#   {mode_name(m)}: {t.airspeed_kts:.1f} kts, {t.altitude_ft:.0f} ft, "
                     f"throttle {t.throttle:.3f}, pitch {t.pitch_deg:.2f}, aileron "
                     f"{t.aileron_deg:.3f} deg;")
        lines.append(f"#     doublet: peak {c['peak_roll_deg']:.2f} deg, error RMS "
                     f"{c['rms_error_deg']:.3f} max {c['max_error_deg']:.3f} deg")
    lines += [f"# warning: {w.message}" for w in identified.warnings]
    return "\n".join(lines) + "\n"


def command_line(aircraft_name: str, airspeeds_kts, altitude_ft: float, latency: int,
                 settings, part: str) -> str:
    """The ``rollmpc identify`` command that writes the config (its header's second line)."""
    words = ["rollmpc identify --aircraft", aircraft_name,
             *(f"--airspeed {float(v):g}" for v in airspeeds_kts), f"--altitude {altitude_ft:g}"]
    words += [f"--latency {latency}"] if latency else []
    words += [f"--set {k}={v:g}" for k, v in settings]
    words += [f"--part {part}"] if part != DEFAULT_PART else []
    return " ".join(words)


def identify_config(aircraft_name: str, airspeeds_kts, altitude_ft: float, latency: int = 0,
                    settings=(), part: str = DEFAULT_PART, progress=None) -> Identified:
    """Everything ``rollmpc identify`` writes and prints; ``progress(text)`` is told what
    runs. The first airspeed is the design point: the scheduler's initial mode;
    ``latency`` samples of sensor delay are modelled (identify.plant); ``settings``
    ((JSBSim property, value) pairs) are applied before every trim."""
    from ..model.delay_margin import delay_margins

    if not airspeeds_kts:
        raise ValueError("needs at least one airspeed")
    settings = tuple(settings)
    speeds = sorted(set(float(v) for v in airspeeds_kts))
    travel: Travel = Aircraft(aircraft_name, FDM_DT, settings).travel
    models = identify_modes(aircraft_name, speeds, altitude_ft, settings)
    checks, warnings = [], []
    for m in models:
        v = m.trim.airspeed_kts
        if progress:
            progress(f"identify: doublet check at {v:.0f} kts")
        checks.append(doublet_check(aircraft_name, m, settings))
        poor = doublet_warning(m, checks[-1])
        warnings += [poor] if poor else []
        drift = trim_drift_kts(Aircraft(aircraft_name, FDM_DT, settings, travel), v, altitude_ft)
        if drift > TRIM_HOLD_KTS:
            warnings.append(DesignWarning(
                "trim_does_not_hold", "--airspeed",
                f"{mode_name(m)}: JSBSim's trim at {v:g} kts does not hold: flown hands-off, "
                f"the airspeed moves {drift:.1f} kts in {TRIM_HOLD_S:g} s (an engine state "
                "the trim cannot see: a propeller's governor, a turbine's spool); the outer "
                "loops' throttle absorbs it, at the price of an altitude excursion"))
    slowest = Aircraft(aircraft_name, FDM_DT, settings, travel)
    slowest.trim(speeds[0], altitude_ft)
    aircraft = AircraftConfig(
        name=aircraft_name, altitude_ft=float(altitude_ft), airspeeds_kts=tuple(speeds),
        aileron_travel_deg=tuple(round(v, 6) for v in travel.travel_deg),
        aileron_rate_dps=None if travel.rate_dps is None else round(travel.rate_dps, 3),
        stall_alpha_deg=stall_alpha_deg(slowest, speeds[0], altitude_ft),
        latency_samples=latency, settings=settings)
    initial = mode_name(models[speeds.index(float(airspeeds_kts[0]))])
    design = build_design(aircraft, models, initial, part)
    if progress:
        progress("identify: delay margin of the controller on its model")
    margins = delay_margins(design.build()[0])
    identified = Identified(text="", models=models, checks=checks, aircraft=aircraft,
                            delay_margins=margins, warnings=warnings)
    command = command_line(aircraft_name, airspeeds_kts, altitude_ft, latency, settings, part)
    identified.text = header(command, identified) + design.to_yaml()
    return identified
