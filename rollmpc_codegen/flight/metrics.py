"""The metrics of one flight (``rollmpc fly --json``), judged on the true roll angle.

Everything of :func:`rollmpc_codegen.sim.metrics.summarize` (per segment: settled error,
overshoot and the 2 % settling time; switches, statuses, iterations, max |u|, total
variation, constraint violations), and for flights:

* ``settling_time_10pct_s`` per segment: from the step until |roll - r| stays within
  10 % of the step size, up to the anticipation cut-off (None: it never does). In
  turbulence the 2 % band (0.3 deg for a 15 deg step) is narrower than the gusts' roll.
* ``rms_roll_error_deg``: over the whole flight.
* ``aileron``: travel (sum of |du|, deg), largest and RMS rate (deg/s), samples at a
  travel bound.
* ``altitude_excursion_ft`` (largest |h - h_trim|), airspeed range, largest |sideslip|
  and angle of attack, samples with the stall hysteresis engaged.
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


def aileron_usage(u: np.ndarray, sample_time: float, travel: tuple[float, float]) -> dict:
    rate = np.diff(u) / sample_time
    return {"max_abs_deg": float(np.abs(u).max()),
            "travel_deg": float(np.abs(np.diff(u)).sum()),
            "max_rate_dps": float(np.abs(rate).max()) if rate.size else 0.0,
            "rms_rate_dps": float(np.sqrt(np.mean(rate ** 2))) if rate.size else 0.0,
            "samples_at_travel_bound": int(np.count_nonzero((u <= travel[0]) | (u >= travel[1])))}


def flight_summary(cfg: ControllerConfig, log: FlightLog, travel_bounds: tuple[float, float],
                   trim_altitude_ft: float) -> dict:
    """Every metric of one flight (the module docstring); ``travel_bounds`` are the
    controller's aileron bounds."""
    truth = log.truth()
    ts, N = cfg.sample_time, cfg.horizon
    summary = summarize(cfg, truth)
    error = truth.y[:, 0] - truth.r[:, 0]
    segs = reference_segments(truth.r)
    for i, ((start, end), seg) in enumerate(zip(segs, summary["segments"])):
        cut = end if i == len(segs) - 1 else max(start + 1, end - N)
        seg["settling_time_10pct_s"] = settling_time(error[start:cut], seg["step"], ts)
    a = log.aircraft
    summary.update({
        "rms_roll_error_deg": float(np.sqrt(np.mean(error ** 2))),
        "max_abs_roll_error_deg": float(np.abs(error).max()),
        "aileron": aileron_usage(truth.u[:, 0], ts, travel_bounds),
        "altitude_excursion_ft": float(np.abs(a["altitude"] - trim_altitude_ft).max()),
        "airspeed_kts": {"min": float(a["airspeed"].min()), "max": float(a["airspeed"].max())},
        "max_abs_sideslip_deg": float(np.abs(a["sideslip"]).max()),
        "max_alpha_deg": float(a["alpha"].max()),
        "max_abs_roll_deg": float(np.abs(a["roll"]).max()),
        "stalled_samples": int(np.count_nonzero(a["stalled"])),
    })
    return summary
