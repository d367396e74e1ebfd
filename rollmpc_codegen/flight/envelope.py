"""What ``rollmpc fly`` knows before it flies: the defaults a config's ``aircraft``
section gives (config/aircraft.py: the aircraft, the design point's airspeed, the
altitude, the JSBSim settings, the stall angle) and the warnings of a flight that leaves
the identified envelope, printed before the flight:

* ``aircraft_mismatch``: ``--aircraft`` is not the aircraft the modes were identified on;
* ``airspeed_outside_envelope``: the start or a commanded airspeed more than
  ENVELOPE_MARGIN_KTS outside the modes' trim airspeeds (the models extrapolate there);
* ``airspeed_not_trimmable``: JSBSim cannot trim the aircraft at a commanded airspeed
  (the outer loops then trade altitude for it: the pa28 lost 608 ft below its range);
* ``delay_beyond_margin``: ``--delay`` beyond the latency the modes model by more than
  the controller's delay margin on its own model (model/delay_margin.py): the loop is
  unstable wherever no bound is active, and oscillates (the c172p example at 5 samples);
* ``delay_at_margin``: that unmodelled delay equals the margin: stable on the model but
  barely damped, the loop rings (the J3Cub config of docs/flight.md at 5 samples).
"""
from __future__ import annotations

from dataclasses import dataclass

from ..config import ConfigError, ControllerConfig, DesignWarning
from .aircraft import (DEFAULT_AIRCRAFT, DEFAULT_AIRSPEED_KTS, DEFAULT_ALTITUDE_FT,
                       FDM_STEPS_PER_SAMPLE, Aircraft)

ENVELOPE_MARGIN_KTS = 5.0


@dataclass(frozen=True)
class FlightPoint:
    """Where a flight starts and what it holds: the aircraft, its JSBSim settings, the
    trim airspeed and altitude, and the range of airspeeds the modes were identified on
    (None without an ``aircraft`` section)."""

    aircraft: str
    airspeed_kts: float
    altitude_ft: float
    settings: tuple = ()
    airspeed_range_kts: tuple[float, float] | None = None
    stall_alpha_deg: float | None = None


def flight_point(cfg: ControllerConfig, aircraft: str | None, airspeed_kts: float | None,
                 altitude_ft: float | None) -> FlightPoint:
    """The given values, else the config's ``aircraft`` section's (the design point: the
    scheduler's initial mode), else the c172p's defaults."""
    from .pid_tuning import design_mode

    ac = cfg.aircraft
    if ac is None:
        return FlightPoint(aircraft or DEFAULT_AIRCRAFT,
                           DEFAULT_AIRSPEED_KTS if airspeed_kts is None else airspeed_kts,
                           DEFAULT_ALTITUDE_FT if altitude_ft is None else altitude_ft)
    return FlightPoint(aircraft or ac.name,
                       ac.airspeeds_kts[design_mode(cfg)] if airspeed_kts is None
                       else airspeed_kts,
                       ac.altitude_ft if altitude_ft is None else altitude_ft,
                       ac.settings, ac.airspeed_range_kts, ac.stall_alpha_deg)


def envelope_warnings(cfg: ControllerConfig, point: FlightPoint, commanded_kts,
                      travel) -> list[DesignWarning]:
    """The aircraft and airspeed warnings of the module docstring (``commanded_kts``: the
    reference's airspeeds; ``travel``: the aircraft's measured one, so that the trial
    trims skip measuring it again)."""
    found = []
    ac = cfg.aircraft
    if ac is not None and point.aircraft != ac.name:
        found.append(DesignWarning(
            "aircraft_mismatch", "--aircraft",
            f"the config's modes were identified on the {ac.name}, not the {point.aircraft}"))
    speeds = sorted({round(float(v), 6) for v in commanded_kts} | {point.airspeed_kts})
    if point.airspeed_range_kts is not None:
        lo, hi = point.airspeed_range_kts
        out = [v for v in speeds
               if not lo - ENVELOPE_MARGIN_KTS <= v <= hi + ENVELOPE_MARGIN_KTS]
        if out:
            found.append(DesignWarning(
                "airspeed_outside_envelope", "--airspeed",
                f"the flight starts at or commands {', '.join(f'{v:g}' for v in out)} kts, "
                f"outside the {lo:g}-{hi:g} kts the modes were identified at (+-"
                f"{ENVELOPE_MARGIN_KTS:g} kts): their models extrapolate there"))
    for v in speeds:
        if v == point.airspeed_kts:
            continue  # the start trim itself is an error, not a warning
        try:
            Aircraft(point.aircraft, cfg.sample_time / FDM_STEPS_PER_SAMPLE, point.settings,
                     travel).trim(v, point.altitude_ft)
        except ConfigError as exc:
            why = str(exc).split(": ", 2)[-1]
            found.append(DesignWarning(
                "airspeed_not_trimmable", "--reference",
                f"the reference commands {v:g} kts, where JSBSim cannot trim the "
                f"{point.aircraft} at {point.altitude_ft:g} ft ({why}): the outer loops "
                "will trade altitude for airspeed there"))
    return found


def delay_warning(cfg: ControllerConfig, margins: list[int | None],
                  delay: int) -> DesignWarning | None:
    """``delay_beyond_margin`` or ``delay_at_margin`` (module docstring), naming the
    weakest mode."""
    modelled = cfg.aircraft.latency_samples if cfg.aircraft else 0
    unmodelled = delay - modelled
    known = [(d, m.name) for d, m in zip(margins, cfg.modes) if d is not None]
    if unmodelled <= 0 or not known or unmodelled < min(known)[0]:
        return None
    margin, name = min(known)
    head = (f"--delay {delay}: {unmodelled} samples of delay the modes do not model (they "
            f"model {modelled})")
    where = f"the controller's delay margin on its model ({margin} samples, mode {name})"
    if unmodelled == margin:
        return DesignWarning(
            "delay_at_margin", "--delay",
            f"{head} reach {where}: stable on the model but barely damped, expect the roll "
            f"to ring; identify with --latency {delay}")
    return DesignWarning(
        "delay_beyond_margin", "--delay",
        f"{head} exceed {where}: expect a sustained oscillation; identify with "
        f"--latency {delay}")
