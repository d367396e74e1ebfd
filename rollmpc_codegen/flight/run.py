"""``rollmpc fly`` as one library call: :func:`run_flight` flies the generated C (through
cffi, :class:`.loop.MpcRoll`) on the JSBSim aircraft and, with ``baseline="pid"``, the
same MPC without its reference preview and the PID baseline (tuned per aircraft,
:mod:`.pid_tuning`) on the same flight (same trim, reference, turbulence seed, noise seed
and delay); returns the logs and the JSON summary, prints nothing (warnings through
``warn`` before the flights, progress through the optional factory of
``sim.simulate.start_phase``). The aircraft, airspeed and altitude default to the
config's ``aircraft`` section (:mod:`.envelope`).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

from ..config import ConfigError, ControllerConfig, DesignWarning
from ..host.build import build_host_controller
from ..pipeline import load_model
from ..sim.metrics import work_stats
from ..sim.simulate import start_phase
from .aircraft import FDM_STEPS_PER_SAMPLE, TURBULENCE, Aircraft, Trim, check_aircraft
from .envelope import delay_warning, envelope_warnings, flight_point
from .loop import FlightLog, MpcRoll, fly
from .metrics import flight_summary
from .pid_roll import PidRoll
from .pid_tuning import tune_pid
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
    baseline_log: FlightLog | None = None  # the PID's
    no_preview_log: FlightLog | None = None  # the MPC's without the preview


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


def run_flight(config: str | Path, *, aircraft: str | None = None,
               airspeed_kts: float | None = None, altitude_ft: float | None = None,
               turbulence: str = "none", noise_std: float = 0.0, delay: int = 0,
               seed: int = 0, duration_s: float | None = None, reference: str | None = None,
               precision: str | None = None, baseline: str | None = None,
               preview_reference: bool = True, build_dir: str | Path | None = None,
               progress=None, warn=None) -> FlightRun:
    """Fly ``config`` on ``aircraft`` from a trim at ``airspeed_kts``/``altitude_ft`` (None:
    the config's aircraft section, envelope.flight_point).

    ``reference``: None (the paper's levels scaled to +-30 deg), a peak bank angle or a
    CSV file (:mod:`.scenario`); ``turbulence`` a key of aircraft.TURBULENCE, seeded with
    ``seed`` (so is the sensor noise); ``baseline="pid"`` also flies the MPC without its
    preview and the PX4-style PID; ``preview_reference=False`` flies only the MPC without
    it (docs/flight.md: what the preview is worth; ``rollmpc report --flight`` replays
    only previewed flights). ``warn(DesignWarning)`` hears the envelope's warnings before
    any flight; they are in the summary too.
    """
    from ..model.delay_margin import delay_margins

    if turbulence not in TURBULENCE:
        raise ConfigError("--turbulence", f"choose from {', '.join(TURBULENCE)}")
    if baseline is not None and baseline not in BASELINES:
        raise ConfigError("--baseline", f"choose from {', '.join(BASELINES)}")
    model, ctx = load_model(config, precision)
    cfg = model.config
    check_flyable(cfg)
    point = flight_point(cfg, aircraft, airspeed_kts, altitude_ft)
    check_aircraft(point.aircraft)
    ts = cfg.sample_time
    ref = flight_reference(reference, ts, point.airspeed_kts, duration_s,
                           point.airspeed_range_kts)
    probe = Aircraft(point.aircraft, ts / FDM_STEPS_PER_SAMPLE, point.settings)
    travel = probe.travel
    check_travel(cfg, point.aircraft, travel.travel_deg)
    probe.trim(point.airspeed_kts, point.altitude_ft)  # an untrimmable start: an error first
    margins = delay_margins(model)
    warnings = envelope_warnings(cfg, point, ref.airspeed_kts, travel)
    late = delay_warning(cfg, margins, delay)
    warnings += [late] if late else []
    for w in warnings if warn else ():
        warn(w)
    bounds = aileron_bounds(cfg)
    stall = point.stall_alpha_deg
    if stall is None:  # a config without an aircraft section: measured at the start
        from .airframe import stall_alpha_deg

        stall = stall_alpha_deg(probe, point.airspeed_kts, point.altitude_ft)

    def one_flight(controller, label: str, preview: bool = True):
        ac = Aircraft(point.aircraft, ts / FDM_STEPS_PER_SAMPLE, point.settings, travel)
        trim = ac.trim(point.airspeed_kts, point.altitude_ft)
        ac.set_turbulence(turbulence, seed)
        log = fly(ac, trim, controller, ref, ts, cfg.horizon, noise_std=noise_std,
                  delay=delay, seed=seed, preview_reference=preview,
                  progress=start_phase(progress, len(ref), label))
        return log, trim, flight_summary(cfg, log, bounds, point.altitude_ft, stall,
                                         ac.engines)

    host = build_host_controller(ctx, Path(build_dir) if build_dir else None)
    log, trim, flown = one_flight(MpcRoll(host), f"fly {point.aircraft} ({ctx['precision']})",
                                  preview_reference)
    summary = {"config": str(config), "aircraft": point.aircraft, "precision": ctx["precision"],
               "solver": dict(ctx["solver"]), "modes": [m.name for m in cfg.modes],
               "sample_time": ts, "horizon": cfg.horizon,
               "fdm_rate_hz": round(FDM_STEPS_PER_SAMPLE / ts, 6),
               "trim": {"airspeed_kts": trim.airspeed_kts, "altitude_ft": trim.altitude_ft,
                        "aileron_deg": trim.aileron_deg, "pitch_deg": trim.pitch_deg,
                        "throttle": trim.throttle},
               "settings": dict(point.settings), "aileron_travel_deg": list(travel.travel_deg),
               "turbulence": turbulence, "noise_std": noise_std, "delay_samples": delay,
               "delay_margins": dict(zip((m.name for m in cfg.modes), margins)),
               "seed": seed, "preview": preview_reference, "reference": ref.source,
               "work": work_stats(log.controller.work, ctx["solver"]["work_budget"]),
               **flown,  # its "warnings" (short segments) join the envelope's, not replace them
               "warnings": [w.as_dict() for w in warnings] + [
                   DesignWarning("short_segment", "--reference", text).as_dict()
                   for text in flown["warnings"]]}
    run = FlightRun(config=cfg, ctx=ctx, trim=trim, reference=ref, log=log, summary=summary)
    if baseline == "pid":
        host.init()
        run.no_preview_log, _, summary["no_preview"] = one_flight(
            MpcRoll(host), "MPC without preview", preview=False)
        gains = tune_pid(cfg)
        run.baseline_log, _, pid = one_flight(PidRoll(gains, bounds, ts), "PID baseline")
        summary["baseline"] = {"kind": "pid_px4_style", "gains": asdict(gains), **pid}
    return run
