"""``aircraft``: the parser of the section (its dataclass and keys: aircraft_types.py)."""
from __future__ import annotations

from .aircraft_types import AircraftConfig
from .errors import ConfigError
from .reader import read_number, read_vector


def parse_aircraft(r, n_modes: int) -> AircraftConfig:
    """The ``aircraft`` section (a config/reader.py Reader); its airspeeds one per mode."""
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

