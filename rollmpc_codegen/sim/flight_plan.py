"""The closed loops a design is judged on beyond its own scenario: ``--flights K`` random
flights, each perturbed as ``rollmpc simulate`` can be (``rollmpc simulate --flights`` on
the host C, ``rollmpc report --flights`` on the emulated Cortex-M4F: target/flights.py).

A :class:`FlightPlan` holds the perturbations (measurement noise, input disturbance, plant
mismatch: sim/simulate.py, sim/mismatch.py) and the flight count.  Without flights it is
the config's scenario once, seeded ``seed`` (its noise is that of ``rollmpc simulate
--seed``).  Flight i (0-based) is seeded ``seed + i``: its reference
(sim/scenario.py ``random_reference``: the scenario's segments, each level uniform within
the output bounds), its plant mismatch and its noise are drawn from that seed's streams
(``random_stream``), so ``--flights 1 --seed S+i`` flies flight i of ``--seed S`` again.
The scenario itself is not among the flights.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mismatch import PlantMismatch
from .scenario import plant_mismatch, random_reference, random_stream, scenario_reference


@dataclass(frozen=True)
class Flight:
    """One closed loop: ``index`` None is the config's scenario (``reference`` None)."""

    index: int | None
    seed: int
    reference: np.ndarray | None
    levels: np.ndarray | None
    mismatch: PlantMismatch | None


@dataclass(frozen=True)
class FlightPlan:
    """What the report flies: ``flights`` random flights (0: the config's scenario) with
    the perturbations of ``rollmpc simulate`` (noise std, constant input disturbance, plant
    mismatch fraction) and the base seed."""

    flights: int = 0
    seed: int = 0
    noise_std: float = 0.0
    disturbance: float = 0.0
    mismatch: float = 0.0

    def __post_init__(self):
        if self.flights < 0 or not self.noise_std >= 0:
            raise ValueError(f"flights and noise_std must be >= 0, got {self.flights} and "
                             f"{self.noise_std}")

    def plan(self, cfg, steps: int | None) -> list[Flight]:
        """The flights of a config, each long enough for ``steps`` samples."""
        if not self.flights:
            return [Flight(None, self.seed, None, None,
                           plant_mismatch(cfg, self.mismatch, self.seed))]
        samples = steps or len(scenario_reference(cfg))
        out = []
        for i in range(self.flights):
            seed = self.seed + i
            levels, ref = random_reference(cfg, random_stream(seed, "reference"), samples)
            out.append(Flight(i, seed, ref, levels, plant_mismatch(cfg, self.mismatch, seed)))
        return out

    def loop_options(self, flight: Flight) -> dict:
        """The keywords of ``sim.simulate.run_closed_loop`` for one flight."""
        return {"reference": flight.reference, "noise_std": self.noise_std,
                "disturbance": self.disturbance, "seed": flight.seed,
                "mismatch": flight.mismatch}

    def as_dict(self) -> dict:
        return {"flights": self.flights, "seed": self.seed, "noise_std": self.noise_std,
                "disturbance": self.disturbance, "mismatch": self.mismatch}
