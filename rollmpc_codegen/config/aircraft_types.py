"""The ``aircraft`` section's dataclass and keys (config/aircraft.py parses it): the JSBSim
aircraft and the envelope ``rollmpc identify`` measured the modes on (docs/flight.md, "The
config").  ``rollmpc fly`` takes its defaults from it and checks a flight against it; the
generated C never sees it.

Declared apart from schema.py because only the flight commands read it; schema.py imports
it for ControllerConfig's field (so it imports nothing of the reader, which imports
schema.py)."""
from __future__ import annotations

from dataclasses import dataclass

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
