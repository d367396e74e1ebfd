"""``rollmpc fly`` as one library call: :func:`run_flight` flies the generated C (through
cffi, :class:`.loop.MpcRoll`) on the JSBSim aircraft and, if asked, the PID baseline on
the same flight (same trim, reference, turbulence seed, noise seed and delay); returns
the logs and the JSON summary, prints nothing (progress through the optional factory of
``sim.simulate.start_phase``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..config import ConfigError, ControllerConfig
from ..host.build import build_host_controller
from ..pipeline import load_model
from ..sim.simulate import start_phase
from .aircraft import (DEFAULT_AIRCRAFT, DEFAULT_AIRSPEED_KTS, DEFAULT_ALTITUDE_FT,
                       FDM_STEPS_PER_SAMPLE, TURBULENCE, Aircraft, Trim, check_aircraft)
from .loop import FlightLog, MpcRoll, fly
from .metrics import flight_summary
from .pid_roll import PidRoll
from .scenario import FlightReference, flight_reference

BASELINES = ("pid",)
SCHEDULE_SIGNAL = "airspeed"  # what a flight feeds a scheduler: the measured airspeed


@dataclass
class FlightRun:
    config: ControllerConfig
    ctx: dict
    trim: Trim
    reference: FlightReference
    log: FlightLog
    summary: dict
    baseline_log: FlightLog | None = None


def check_flyable(cfg: ControllerConfig) -> None:
    """The config must be a roll controller: one output (roll, deg), one actuator (the
    aileron, deg), and a scheduler, if any, on the airspeed (kts)."""
    if cfg.n_outputs != 1 or len(cfg.actuators) != 1:
        raise ConfigError("outputs", "rollmpc fly needs one output (the roll angle, deg) "
                          "and one actuator (the aileron, deg)")
    if cfg.scheduler is not None and cfg.scheduler.signal != SCHEDULE_SIGNAL:
        raise ConfigError("scheduler.signal", f"rollmpc fly feeds the measured airspeed "
                          f"(kts): name the signal {SCHEDULE_SIGNAL!r}, got "
                          f"{cfg.scheduler.signal!r}")


def aileron_bounds(cfg: ControllerConfig) -> tuple[float, float]:
    """The tightest aileron bounds of the modes (the baseline's limits too)."""
    return (max(float(m.u_min[0]) for m in cfg.modes), min(float(m.u_max[0]) for m in cfg.modes))


def check_travel(cfg: ControllerConfig, aircraft: str, travel_deg) -> None:
    """Every mode's aileron bounds within the aircraft's travel, before a flight rather
    than at the first command past it, 40 s into one (a new user's u_max = 15 deg on a
    travel ending at 14.997)."""
    lo, hi = travel_deg
    for j, mode in enumerate(cfg.modes):
        for side, value in (("u_min", float(mode.u_min[0])), ("u_max", float(mode.u_max[0]))):
            if not lo <= value <= hi:
                raise ConfigError(f"modes[{j}].bounds.{side}",
                                  f"{value:g} deg is past the {aircraft}'s aileron travel "
                                  f"({lo:g} .. {hi:g} deg): the MPC could command a deflection "
                                  "the aircraft does not have")


def run_flight(config: str | Path, *, aircraft: str = DEFAULT_AIRCRAFT,
               airspeed_kts: float = DEFAULT_AIRSPEED_KTS,
               altitude_ft: float = DEFAULT_ALTITUDE_FT, turbulence: str = "none",
               noise_std: float = 0.0, delay: int = 0, seed: int = 0,
               duration_s: float | None = None, reference: str | None = None,
               precision: str | None = None, baseline: str | None = None,
               preview_reference: bool = True, build_dir: str | Path | None = None,
               progress=None) -> FlightRun:
    """Fly ``config`` on ``aircraft`` from a trim at ``airspeed_kts``/``altitude_ft``.

    ``reference``: None (the paper's levels scaled to +-30 deg), a peak bank angle or a
    CSV file (:mod:`.scenario`); ``turbulence`` a key of aircraft.TURBULENCE, seeded with
    ``seed`` (so is the sensor noise); ``baseline="pid"`` also flies the PX4-style PID;
    ``preview_reference=False`` gives the MPC r_k over its whole horizon (docs/flight.md:
    what the preview is worth; ``rollmpc report --flight`` replays only previewed flights).
    """
    if turbulence not in TURBULENCE:
        raise ConfigError("--turbulence", f"choose from {', '.join(TURBULENCE)}")
    if baseline is not None and baseline not in BASELINES:
        raise ConfigError("--baseline", f"choose from {', '.join(BASELINES)}")
    check_aircraft(aircraft)
    model, ctx = load_model(config, precision)
    cfg = model.config
    check_flyable(cfg)
    ts = cfg.sample_time
    ref = flight_reference(reference, ts, airspeed_kts, duration_s)

    def one_flight(controller, label: str) -> tuple[FlightLog, Trim, Aircraft]:
        ac = Aircraft(aircraft, ts / FDM_STEPS_PER_SAMPLE)
        check_travel(cfg, aircraft, ac.travel_deg)
        trim = ac.trim(airspeed_kts, altitude_ft)
        ac.set_turbulence(turbulence, seed)
        log = fly(ac, trim, controller, ref, ts, cfg.horizon, noise_std=noise_std,
                  delay=delay, seed=seed, preview_reference=preview_reference,
                  progress=start_phase(progress, len(ref), label))
        return log, trim, ac

    host = build_host_controller(ctx, Path(build_dir) if build_dir else None)
    log, trim, ac = one_flight(MpcRoll(host), f"fly {aircraft} ({ctx['precision']})")
    bounds = aileron_bounds(cfg)
    summary = {"config": str(config), "aircraft": aircraft, "precision": ctx["precision"],
               "solver": dict(ctx["solver"]), "modes": [m.name for m in cfg.modes],
               "sample_time": ts, "horizon": cfg.horizon,
               "fdm_rate_hz": round(FDM_STEPS_PER_SAMPLE / ts, 6),
               "trim": {"airspeed_kts": trim.airspeed_kts, "altitude_ft": trim.altitude_ft,
                        "aileron_deg": trim.aileron_deg, "pitch_deg": trim.pitch_deg,
                        "throttle": trim.throttle},
               "aileron_travel_deg": list(ac.travel_deg), "turbulence": turbulence,
               "noise_std": noise_std, "delay_samples": delay, "seed": seed,
               "preview": preview_reference,
               "reference": ref.source, **flight_summary(cfg, log, bounds, altitude_ft)}
    base_log = None
    if baseline == "pid":
        base_log, _, _ = one_flight(PidRoll(trim.airspeed_kts, bounds, ts), "PID baseline")
        summary["baseline"] = {"kind": "pid_px4_style",
                               **flight_summary(cfg, base_log, bounds, altitude_ft)}
    return FlightRun(config=cfg, ctx=ctx, trim=trim, reference=ref, log=log, summary=summary,
                     baseline_log=base_log)
