"""The closed loops a design is judged on beyond its own scenario: ``--flights K`` random
flights, each perturbed as ``rollmpc simulate`` can be (``rollmpc simulate --flights`` on
the host C, ``rollmpc report --flights`` on the emulated Cortex-M4F: target/flights.py).

A :class:`FlightPlan` holds the perturbations (measurement noise, input disturbance, plant
mismatch: sim/simulate.py, sim/mismatch.py), the flight count and the kinds of flights.
Without flights it is the config's scenario once, seeded ``seed`` (its noise is that of
``rollmpc simulate --seed``).  Flight i (0-based) is seeded ``seed + i``: its reference,
its plant mismatch and its noise are drawn from that seed's streams (``random_stream``),
so ``--flights 1 --seed S+i`` flies flight i of ``--seed S`` again.  The scenario itself
is not among the flights.

Two kinds of flights (:data:`FLIGHT_KINDS`), by the parity of the seed with the default
``kinds="both"``: an even seed flies an *inside* flight (sim/scenario.py
``random_reference``: the scenario's segments, each level uniform within the range the
scenario spans, inside the output bounds), an odd seed an *envelope* flight, which
presses the envelope as users command (sim/envelope.py: half its levels beyond that range,
up to the hard output bounds and past the soft ones).  ``kinds="inside"`` or
``"envelope"`` flies every flight of that kind.  The reports give their figures by kind.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mismatch import PlantMismatch
from .envelope import envelope_levels
from .scenario import (inside_levels, plant_mismatch, random_reference, random_stream,
                       scenario_reference)

FLIGHT_KINDS = ("inside", "envelope")  # an even seed's, an odd seed's (kinds="both")
KINDS_CHOICES = ("both", *FLIGHT_KINDS)
LEVEL_DRAWS = {"inside": inside_levels, "envelope": envelope_levels}


@dataclass(frozen=True)
class Flight:
    """One closed loop: ``index`` None is the config's scenario (``reference`` None)."""

    index: int | None
    seed: int
    reference: np.ndarray | None
    levels: np.ndarray | None
    mismatch: PlantMismatch | None
    kind: str | None = None  # one of FLIGHT_KINDS; None: the scenario


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
    kinds: str = "both"  # "both" (by the seed's parity) or one of FLIGHT_KINDS

    def __post_init__(self):
        if self.flights < 0 or not self.noise_std >= 0:
            raise ValueError(f"flights and noise_std must be >= 0, got {self.flights} and "
                             f"{self.noise_std}")
        if self.kinds not in KINDS_CHOICES:
            raise ValueError(f"kinds must be one of {', '.join(KINDS_CHOICES)}, got {self.kinds!r}")

    def kind_of(self, seed: int) -> str:
        """The kind of the flight seeded ``seed``."""
        return FLIGHT_KINDS[seed % 2] if self.kinds == "both" else self.kinds

    def plan(self, cfg, steps: int | None) -> list[Flight]:
        """The flights of a config, each long enough for ``steps`` samples."""
        if not self.flights:
            return [Flight(None, self.seed, None, None,
                           plant_mismatch(cfg, self.mismatch, self.seed))]
        samples = steps or len(scenario_reference(cfg))
        out = []
        for i in range(self.flights):
            seed = self.seed + i
            kind = self.kind_of(seed)
            levels, ref = random_reference(cfg, random_stream(seed, "reference"), samples,
                                           LEVEL_DRAWS[kind])
            out.append(Flight(i, seed, ref, levels, plant_mismatch(cfg, self.mismatch, seed),
                              kind))
        return out

    def loop_options(self, flight: Flight) -> dict:
        """The keywords of ``sim.simulate.run_closed_loop`` for one flight."""
        return {"reference": flight.reference, "noise_std": self.noise_std,
                "disturbance": self.disturbance, "seed": flight.seed,
                "mismatch": flight.mismatch}

    def as_dict(self) -> dict:
        return {"flights": self.flights, "seed": self.seed, "noise_std": self.noise_std,
                "disturbance": self.disturbance, "mismatch": self.mismatch,
                "kinds": self.kinds}


def by_kind(items, kind_of) -> dict:
    """``items`` grouped by flight kind, in FLIGHT_KINDS' order (the kinds present only)."""
    groups = {k: [x for x in items if kind_of(x) == k] for k in FLIGHT_KINDS}
    return {k: v for k, v in groups.items() if v}
