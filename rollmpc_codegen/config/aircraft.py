"""``aircraft``: the JSBSim aircraft and the envelope ``rollmpc identify`` measured the
modes on (docs/flight.md, "The config").  ``rollmpc fly`` takes its defaults from it and
checks a flight against it; the generated C never sees it.

Declared apart from schema.py because only the flight commands read it; schema.py imports
the dataclass for ControllerConfig's field (this module imports nothing of the parsers:
the reader reaches :func:`parse_aircraft` as an argument)."""
from __future__ import annotations

from dataclasses import dataclass

from .errors import ConfigError
from .keys import section_keys

AIRCRAFT_KEYS = section_keys("aircraft")


@dataclass(frozen=True)
class AircraftConfig:
    name: str
    altitude_ft: float
    airspeeds_kts: tuple[float, ...]  # one per mode, in the modes' order
    aileron_travel_deg: tuple[float, float]  # (at command -1, at +1), steady state
    aileron_rate_dps: float | None = None  # None: no rate limit was measured
    stall_alpha_deg: float | None = None  # the angle of attack of maximum lift
    latency_samples: int = 0  # sensor latency the modes model
    settings: tuple[tuple[str, float], ...] = ()  # JSBSim properties held in every flight

    @property
    def airspeed_range_kts(self) -> tuple[float, float]:
        return min(self.airspeeds_kts), max(self.airspeeds_kts)

    def to_yaml_data(self) -> dict:
        """The section as ``rollmpc identify`` writes it (optional keys at their default
        left out)."""
        data = {"name": self.name, "altitude_ft": self.altitude_ft,
                "airspeeds_kts": list(self.airspeeds_kts),
                "aileron_travel_deg": list(self.aileron_travel_deg)}
        for key in ("aileron_rate_dps", "stall_alpha_deg"):
            if getattr(self, key) is not None:
                data[key] = getattr(self, key)
        if self.latency_samples:
            data["latency_samples"] = self.latency_samples
        if self.settings:
            data["settings"] = dict(self.settings)
        return data


def parse_aircraft(r, n_modes: int) -> AircraftConfig:
    """The ``aircraft`` section (a config/reader.py Reader); its airspeeds one per mode."""
    from .reader import read_number, read_vector

    name = r.string("name")
    speeds = read_vector(r.raw("airspeeds_kts"), r.key("airspeeds_kts"))
    if len(speeds) != n_modes or not all(v > 0 for v in speeds):
        raise ConfigError(r.key("airspeeds_kts"), f"must be {n_modes} positive airspeeds, one "
                          "per mode in the modes' order")
    travel = read_vector(r.raw("aileron_travel_deg"), r.key("aileron_travel_deg"), 2)
    if not travel[0] < 0 < travel[1]:
        raise ConfigError(r.key("aileron_travel_deg"), "must be [min, max] with min < 0 < max")
    settings = r.raw("settings", {})
    if not isinstance(settings, dict) or not all(isinstance(k, str) for k in settings):
        raise ConfigError(r.key("settings"), "must map JSBSim property names to numbers")
    rate = r.number("aileron_rate_dps", positive=True) if r.has("aileron_rate_dps") else None
    stall = r.number("stall_alpha_deg", positive=True) if r.has("stall_alpha_deg") else None
    return AircraftConfig(
        name=name, altitude_ft=r.number("altitude_ft", nonnegative=True),
        airspeeds_kts=tuple(float(v) for v in speeds),
        aileron_travel_deg=(float(travel[0]), float(travel[1])), aileron_rate_dps=rate,
        stall_alpha_deg=stall, latency_samples=r.integer("latency_samples", 0, minimum=0),
        settings=tuple((k, read_number(v, f"{r.key('settings')}.{k}"))
                       for k, v in settings.items()))

