"""The metrics of one flight (``rollmpc fly --json``), judged on the true roll angle.

Everything of :func:`rollmpc_codegen.sim.metrics.summarize` (per segment: settled error,
overshoot and the 2 % settling time; switches, statuses, iterations, max |u|, total
variation, constraint violations), and for flights:

* ``transition_time_s`` per segment: from the roll's last departure from the old level
  (the last sample, from N samples before the step, still short of 10 % of the step) to
  the first sample from which |roll - r| stays within 10 % of the step, up to the
  anticipation cut-off (None: it never does). The same measure for every controller: an
  MPC that sees the step coming and starts early is timed from when it starts, as a PID
  is; ``settling_time_10pct_s`` (from the step) is kept beside it.
* ``rms_roll_error_deg``: over the whole flight.
* ``aileron``: travel (sum of |du|, deg), largest and RMS rate (deg/s), samples at a
  travel bound.
* ``altitude_excursion_ft`` (largest |h - h_trim|), airspeed range, largest |sideslip|
  and angle of attack; ``stalled_samples``: angle of attack above the aircraft's
  maximum-lift angle (``stall_alpha_deg``), ``stall_hysteresis_samples``: the model's
  own stall flag engaged (the c172p has one);
* ``engines``: how many, the fewest running, and when the first stopped (None: none).
"""
from __future__ import annotations

import numpy as np

from ..config import ControllerConfig
from ..sim.metrics import reference_segments, summarize
from .loop import FlightLog

SETTLING_BAND = 0.10  # of the step size


def settling_time(error: np.ndarray, step: float, sample_time: float) -> float | None:
    """Seconds from the step until |error| stays within SETTLING_BAND |step|."""
    if step == 0:
        return 0.0
    outside = np.flatnonzero(np.abs(error) > SETTLING_BAND * abs(step))
    if outside.size and outside[-1] == error.size - 1:
        return None
    return round(float(outside[-1] + 1) * sample_time, 9) if outside.size else 0.0


def transition_time(roll: np.ndarray, old: float, new: float, step_at: int,
                    sample_time: float) -> float | None:
    """Seconds from the last departure from ``old`` (progress towards ``new`` below
    SETTLING_BAND) to settling within SETTLING_BAND of the step; ``roll`` is the window
    that starts before the step, ``step_at`` the step's index in it (module docstring)."""
    step = new - old
    if step == 0:
        return 0.0
    outside = np.flatnonzero(np.abs(roll - new) > SETTLING_BAND * abs(step))
    if outside.size and outside[-1] == roll.size - 1:
        return None
    settled = int(outside[-1]) + 1 if outside.size else step_at
    short = np.flatnonzero((roll[:settled] - old) / step < SETTLING_BAND)
    start = int(short[-1]) + 1 if short.size else 0
    return round(max(settled - start, 0) * sample_time, 9)


def aileron_usage(u: np.ndarray, sample_time: float, travel: tuple[float, float]) -> dict:
    rate = np.diff(u) / sample_time
    return {"max_abs_deg": float(np.abs(u).max()),
            "travel_deg": float(np.abs(np.diff(u)).sum()),
            "max_rate_dps": float(np.abs(rate).max()) if rate.size else 0.0,
            "rms_rate_dps": float(np.sqrt(np.mean(rate ** 2))) if rate.size else 0.0,
            "samples_at_travel_bound": int(np.count_nonzero((u <= travel[0]) | (u >= travel[1])))}


def engine_summary(running: np.ndarray, engines: int, sample_time: float) -> dict:
    lost = np.flatnonzero(running < engines)
    return {"count": engines, "min_running": int(running.min()) if running.size else engines,
            "first_loss_s": round(float(lost[0]) * sample_time, 9) if lost.size else None}


def flight_summary(cfg: ControllerConfig, log: FlightLog, travel_bounds: tuple[float, float],
                   trim_altitude_ft: float, stall_alpha_deg: float | None = None,
                   engines: int = 1) -> dict:
    """Every metric of one flight (the module docstring); ``travel_bounds`` are the
    controller's aileron bounds."""
    truth = log.truth()
    ts, N = cfg.sample_time, cfg.horizon
    summary = summarize(cfg, truth)
    roll = truth.y[:, 0]
    error = roll - truth.r[:, 0]
    segs = reference_segments(truth.r)
    for i, ((start, end), seg) in enumerate(zip(segs, summary["segments"])):
        cut = end if i == len(segs) - 1 else max(start + 1, end - N)
        seg["settling_time_10pct_s"] = settling_time(error[start:cut], seg["step"], ts)
        before = max(segs[i - 1][0], start - N) if i else start
        seg["transition_time_s"] = transition_time(
            roll[before:cut], float(truth.r[before, 0]), float(truth.r[start, 0]),
            start - before, ts) if i else 0.0
    a = log.aircraft
    stalled = a["alpha"] > stall_alpha_deg if stall_alpha_deg is not None else \
        np.zeros(len(roll), bool)
    summary.update({
        "rms_roll_error_deg": float(np.sqrt(np.mean(error ** 2))),
        "max_abs_roll_error_deg": float(np.abs(error).max()),
        "aileron": aileron_usage(truth.u[:, 0], ts, travel_bounds),
        "altitude_excursion_ft": float(np.abs(a["altitude"] - trim_altitude_ft).max()),
        "altitude_loss_ft": float(max(0.0, trim_altitude_ft - a["altitude"].min())),
        "airspeed_kts": {"min": float(a["airspeed"].min()), "max": float(a["airspeed"].max())},
        "max_abs_sideslip_deg": float(np.abs(a["sideslip"]).max()),
        "max_alpha_deg": float(a["alpha"].max()),
        "stall_alpha_deg": stall_alpha_deg,
        "max_abs_roll_deg": float(np.abs(a["roll"]).max()),
        "stalled_samples": int(np.count_nonzero(stalled)),
        "stall_hysteresis_samples": int(np.count_nonzero(a["stall_hysteresis"])),
        "engines": engine_summary(a["engines_running"], engines, ts),
    })
    return summary
