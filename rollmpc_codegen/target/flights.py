"""The closed loops ``rollmpc report`` replays on the emulated Cortex-M4F: the config's
scenario, or the random flights of a :class:`~rollmpc_codegen.sim.flight_plan.FlightPlan`.
Each flight is recorded on the host, its hardest and sampled steps chosen, and replayed
from step 0 on the target, bit for bit (:mod:`rollmpc_codegen.target.replay`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sim.flight_plan import Flight, FlightPlan
from ..sim.metrics import status_counts
from ..sim.simulate import start_phase
from .replay import HostRecord, TargetRun, record_host_run, replay_on_target, select_steps
from .state_layout import StateLayout


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
        return {"flight": self.flight.index, "seed": self.flight.seed, "kind": self.flight.kind,
                "levels": None if self.flight.levels is None else self.flight.levels.tolist(),
                "plant_mismatch": (None if self.flight.mismatch is None
                                   else self.flight.mismatch.as_dict()),
                "steps": self.run.steps, "steps_counted": len(self.run.counts),
                "worst_step": int(k), "worst_step_mode": int(self.record.info[k]["mode"]),
                "worst_step_cycles": self.worst_cycles,
                "median_step_cycles": int(np.median(self.sweep_counts("cycles"))),
                "statuses": self.statuses,
                "bit_exact_vs_host": self.bit_exact, "mismatches": len(self.run.mismatches),
                "first_mismatches": [list(m) for m in self.run.mismatches[:5]],
                "state_bit_exact": self.run.state_equal,
                "state_mismatch": self.run.state_mismatch()}


def fly(model, ctx: dict, build, build_root, flight: Flight, plan: FlightPlan, *,
        steps: int | None, hardest: int, sample_every: int, host_repeats: int,
        progress=None, label: str = "report", record: HostRecord | None = None,
        layout: StateLayout | None = None) -> FlightRun:
    """Record ``flight`` on the host (unless ``record`` holds a recorded run already:
    ``rollmpc report --flight``), with the kernels and instance ``layout`` of the
    target, choose the steps to count, replay it on the target; a line on ``progress``
    gives the flight's worst and median step."""
    if record is None:
        record = record_host_run(model, ctx, build_root, steps, progress, host_repeats,
                                 plan.loop_options(flight), label, layout)
    hard, sweep = select_steps(record, hardest, sample_every)
    run = replay_on_target(build, ctx, record, set(hard) | set(sweep), progress, label)
    result = FlightRun(flight, record, hard, sweep, run)
    start_phase(progress, 0, f"{label}: worst step {result.worst_step} "
                f"({result.worst_cycles:,} cycles), median "
                f"{int(np.median(result.sweep_counts('cycles'))):,} cycles, bit-exact vs "
                f"host (commands and instance, every step): "
                f"{'yes' if result.bit_exact else 'NO'}")
    return result
