"""What a flight is asked to do: a roll reference and an airspeed command, one value per
controller sample, at the trim altitude.

Default: the paper's level sequence (section 4.1: 0, -20, 20, -40, 40, 0 deg, 10 s each)
scaled so that its largest level is ``peak_deg`` (30 deg: 0, -15, 15, -30, 30, 0), with
the airspeed commanded at the trim speed, 15 kts below it and 15 kts above it for two
segments each (from a 90 kts trim: 90, 75, 105 kts, through all three airspeed bands of
the c172p example), kept within the identified airspeeds when the config has them (an
aircraft identified at 90 kts alone holds 90 kts). Or a CSV file with a header ``t,roll`` or
``t,roll,airspeed`` (s, deg, kts): each row's values hold from its time until the next
row's; without an airspeed column the trim airspeed is held.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import ConfigError
from ..sim.scenario import PAPER_LEVELS_DEG, PAPER_SEGMENT_S, paper_reference

DEFAULT_PEAK_DEG = 30.0
AIRSPEED_STEPS_KTS = (0.0, 0.0, -15.0, -15.0, 15.0, 15.0)  # from the trim, per segment


@dataclass(frozen=True)
class FlightReference:
    roll_deg: np.ndarray  # (K,)
    airspeed_kts: np.ndarray  # (K,)
    source: str

    def __len__(self) -> int:
        return len(self.roll_deg)

    def truncated(self, samples: int) -> "FlightReference":
        return FlightReference(self.roll_deg[:samples], self.airspeed_kts[:samples],
                               self.source)


def paper_levels(peak_deg: float) -> list[float]:
    """The paper's levels scaled so that the largest is ``peak_deg``."""
    scale = peak_deg / max(abs(v) for v in PAPER_LEVELS_DEG)
    return [scale * v + 0.0 for v in PAPER_LEVELS_DEG]


def paper_flight(sample_time: float, trim_airspeed_kts: float,
                 peak_deg: float = DEFAULT_PEAK_DEG, airspeed_range=None) -> FlightReference:
    """The default scenario; ``airspeed_range`` (lo, hi) clips the commanded airspeeds."""
    lo, hi = airspeed_range or (-math.inf, math.inf)
    roll = paper_reference(sample_time, paper_levels(peak_deg))
    speed = paper_reference(sample_time, [min(hi, max(lo, trim_airspeed_kts + v))
                                          for v in AIRSPEED_STEPS_KTS])
    return FlightReference(roll, speed, f"paper levels scaled to +-{peak_deg:g} deg")


def reference_file(path: str | Path, sample_time: float, trim_airspeed_kts: float,
                   duration_s: float | None) -> FlightReference:
    """The piecewise-constant reference of a CSV file (module docstring), sampled at
    ``sample_time`` up to ``duration_s`` (default: 10 s past the last row)."""
    key = "--reference"
    try:
        with open(path, newline="") as fh:
            rows = list(csv.DictReader(fh))
    except OSError as exc:
        raise ConfigError(key, f"cannot read {path}: {exc.strerror}") from None
    if not rows or not {"t", "roll"} <= set(rows[0]):
        raise ConfigError(key, f"{path}: needs a header with columns t,roll[,airspeed]")
    try:
        table = np.array([[float(r["t"]), float(r["roll"]),
                           float(r.get("airspeed") or trim_airspeed_kts)] for r in rows])
    except (TypeError, ValueError):
        raise ConfigError(key, f"{path}: every t, roll and airspeed must be a number") from None
    t = table[:, 0]
    if not np.all(np.isfinite(table)) or t[0] != 0.0 or np.any(np.diff(t) <= 0):
        raise ConfigError(key, f"{path}: finite values, t from 0 and increasing")
    end = duration_s if duration_s is not None else t[-1] + PAPER_SEGMENT_S
    times = np.arange(int(round(end / sample_time))) * sample_time
    row = np.searchsorted(t, times + 1e-9, side="right") - 1
    return FlightReference(table[row, 1], table[row, 2], str(path))


def flight_reference(spec: str | None, sample_time: float, trim_airspeed_kts: float,
                     duration_s: float | None, airspeed_range=None) -> FlightReference:
    """``--reference``: None (the default), a peak bank angle in degrees, or a CSV file;
    truncated to ``duration_s`` when given; ``airspeed_range``: paper_flight's."""
    if spec is not None and not Path(spec).exists():
        try:
            peak = float(spec)
        except ValueError:
            raise ConfigError("--reference", f"{spec}: neither a file nor a bank angle") from None
        if not 0 < peak < 90 or not math.isfinite(peak):
            raise ConfigError("--reference", f"the peak bank angle must be in (0, 90) deg, "
                              f"got {spec}")
        ref = paper_flight(sample_time, trim_airspeed_kts, peak, airspeed_range)
    elif spec is None:
        ref = paper_flight(sample_time, trim_airspeed_kts, airspeed_range=airspeed_range)
    else:
        return reference_file(spec, sample_time, trim_airspeed_kts, duration_s)
    if duration_s is None:
        return ref
    samples = int(round(duration_s / sample_time))
    if samples > len(ref):  # hold the last values
        pad = samples - len(ref)
        return FlightReference(np.pad(ref.roll_deg, (0, pad), mode="edge"),
                               np.pad(ref.airspeed_kts, (0, pad), mode="edge"), ref.source)
    return ref.truncated(samples)
