"""The closed loops ``rollmpc report`` replays on the emulated Cortex-M4F: the config's
scenario, or ``--flights K`` random flights, each perturbed as ``rollmpc simulate`` can be.

A :class:`FlightPlan` holds the perturbations (measurement noise, input disturbance, plant
mismatch: sim/simulate.py, sim/mismatch.py) and the flight count.  Without flights the
report flies the config's scenario once, seeded ``seed`` (its noise is that of ``rollmpc
simulate --seed``).  Flight i (0-based) is seeded ``seed + i``: its reference
(sim/scenario.py ``random_reference``: the scenario's segments, each level uniform within
the output bounds), its plant mismatch and its noise are drawn from that seed's streams
(``random_stream``), so ``--flights 1 --seed S+i`` flies flight i of ``--seed S`` again.
The scenario itself is not among the flights.

Each flight is recorded on the host, its hardest and sampled steps chosen, and replayed
from step 0 on the target, bit for bit (:mod:`rollmpc_codegen.target.replay`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sim.metrics import status_counts
from ..sim.mismatch import PlantMismatch
from ..sim.scenario import plant_mismatch, random_reference, random_stream, scenario_reference
from ..sim.simulate import start_phase
from .replay import HostRecord, TargetRun, record_host_run, replay_on_target, select_steps


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


@dataclass
class FlightRun:
    """One flight recorded on the host and replayed on the target."""

    flight: Flight
    record: HostRecord
    hard: list  # the hardest steps (replay.select_steps)
    sweep: list  # the sampled steps
    run: TargetRun

    @property
    def worst_step(self) -> int:
        """The counted step with the most cycles (the earliest on a tie)."""
        return max(self.run.counts, key=lambda k: (self.run.counts[k].cycles, -k))

    @property
    def worst_cycles(self) -> int:
        return int(self.run.counts[self.worst_step].cycles)

    @property
    def bit_exact(self) -> bool:
        return not self.run.mismatches and self.run.state_equal

    def sweep_counts(self, what: str) -> np.ndarray:
        """``cycles`` or ``instructions`` of the sampled steps."""
        return np.array([getattr(self.run.counts[k], what) for k in self.sweep], dtype=np.int64)

    @property
    def statuses(self) -> dict:
        """The flight's solver statuses by name, over every recorded step."""
        return status_counts([info["status"] for info in self.record.info])

    def summary(self) -> dict:
        """The flight's entry of the report's ``flights`` list."""
        k = self.worst_step
        return {"flight": self.flight.index, "seed": self.flight.seed,
                "levels": None if self.flight.levels is None else self.flight.levels.tolist(),
                "plant_mismatch": (None if self.flight.mismatch is None
                                   else self.flight.mismatch.as_dict()),
                "steps": self.run.steps, "steps_counted": len(self.run.counts),
                "worst_step": int(k), "worst_step_mode": int(self.record.info[k]["mode"]),
                "worst_step_cycles": self.worst_cycles,
                "median_step_cycles": int(np.median(self.sweep_counts("cycles"))),
                "statuses": self.statuses,
                "bit_exact_vs_host": self.bit_exact, "mismatches": len(self.run.mismatches),
                "first_mismatches": [list(m) for m in self.run.mismatches[:5]]}


def fly(model, ctx: dict, build, build_root, flight: Flight, plan: FlightPlan, *,
        steps: int | None, hardest: int, sample_every: int, host_repeats: int,
        progress=None, label: str = "report", record: HostRecord | None = None) -> FlightRun:
    """Record ``flight`` on the host (unless ``record`` holds a recorded run already:
    ``rollmpc report --flight``), choose the steps to count, replay it on the target;
    a line on ``progress`` gives the flight's worst and median step."""
    if record is None:
        record = record_host_run(model, ctx, build_root, steps, progress, host_repeats,
                                 plan.loop_options(flight), label)
    hard, sweep = select_steps(record, hardest, sample_every)
    run = replay_on_target(build, ctx, record, set(hard) | set(sweep), progress, label)
    result = FlightRun(flight, record, hard, sweep, run)
    start_phase(progress, 0, f"{label}: worst step {result.worst_step} "
                f"({result.worst_cycles:,} cycles), median "
                f"{int(np.median(result.sweep_counts('cycles'))):,} cycles, bit-exact vs "
                f"host: {'yes' if result.bit_exact else 'NO'}")
    return result
