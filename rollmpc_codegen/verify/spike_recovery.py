"""Recovery from one huge but finite measurement (docs/reliability.md, "Hostile input").

Issue 15's audit: a single y = 1e308 left the controller INFEASIBLE or NUMERICAL for the
rest of the flight.  The observers now clip each innovation y - C x̂ to
``modes[].observer.innovation_limit``; this module measures what is left of a spike.

The scenario runs twice in closed loop on the host C: without a spike, and with output
``output`` replaced by the spike at sample ``at`` (the plant itself is untouched).  The
spiked run *recovers* at the first sample from which every status is OPTIMAL and every
command is within :data:`RECOVERY_TOL` of the largest input span of the spike-free run's
command; :attr:`SpikeRun.recovery` counts the samples from the spike to there.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..host.build import build_host_controller
from ..pipeline import load_model
from ..sim.simulate import run_closed_loop
from ..status import MEASUREMENT_CLIPPED, OPTIMAL

RECOVERY_TOL = 1e-3  # of the largest input span (u_max - u_min) of the config
# (example, sample of the spike, samples run): the spike lands while a level is held
CASES = (("uav_roll", 1500, 3000), ("chain_of_masses", 60, 200), ("quadruple_tank", 120, 400))
# the audit's values, both signs, and the largest finite number of each precision
SPIKES = {"double": (1e30, -1e30, 1e308, -1e308), "float": (1e30, -1e30, 3.4e38, -3.4e38)}


@dataclass(frozen=True)
class SpikeRun:
    """What one spike did to the closed loop."""

    spike: float
    status_at_spike: int  # P_step's status for the spiked sample
    clipped_at_spike: int  # P_last_info()->clipped there
    command_at_spike_unchanged: bool  # predictor form: y(k) enters the command of k + 1
    not_optimal_after: int  # samples after the spike whose status is not OPTIMAL
    recovery: int | None  # samples from the spike to recovery (None: not by the end)
    finite: bool  # every command finite
    within_limits: bool  # every command inside the envelope of the modes' input bounds


def _input_envelope(ctx: dict) -> tuple[np.ndarray, np.ndarray]:
    """Per actuator, the lowest u_min and highest u_max of the modes that drive it (0 for
    an actuator no mode drives)."""
    lo, hi = np.zeros(ctx["n_actuators"]), np.zeros(ctx["n_actuators"])
    for m in ctx["modes"]:
        act = np.asarray(m["actuator_index"])
        lo[act] = np.minimum(lo[act], m["u_min"])
        hi[act] = np.maximum(hi[act], m["u_max"])
    return lo, hi


class Spiked:
    """``controller`` (anything with ``step``) whose measured output ``output`` is replaced
    by ``spikes[k]`` at each sample k of ``spikes``; the plant itself is untouched."""

    def __init__(self, controller, spikes: dict[int, float], output: int = 0):
        self.controller, self.spikes, self.output = controller, spikes, output
        self.k = 0

    def step(self, y, sched, r):
        if self.k in self.spikes:
            y = np.array(y, float)
            y[self.output] = self.spikes[self.k]
        self.k += 1
        return self.controller.step(y, sched, r)


def spiked_runs(config: str | Path, precision: str, spikes, at: int, steps: int,
                output: int = 0, build_root: Path | None = None) -> list[SpikeRun]:
    """One :class:`SpikeRun` per value of ``spikes``, each against the spike-free run."""
    model, ctx = load_model(config, precision)

    def run(spike: float | None):
        c = build_host_controller(ctx, build_root)
        clipped = []

        def info():
            clipped.append(c.info()["clipped"])
            return c.info()

        loop = Spiked(c, {} if spike is None else {at: spike}, output)
        return run_closed_loop(model.config, loop, steps=steps, info=info), clipped

    free, _ = run(None)
    lo, hi = _input_envelope(ctx)
    tol = RECOVERY_TOL * float(np.max(hi - lo))
    out = []
    for spike in spikes:
        log, clipped = run(spike)
        after = np.arange(len(log.status)) > at
        bad = (log.status != OPTIMAL) | (np.abs(log.u - free.u).max(axis=1) > tol)
        bad[:at] = False
        last_bad = int(np.flatnonzero(bad)[-1]) if bad.any() else at - 1
        out.append(SpikeRun(
            spike=spike, status_at_spike=int(log.status[at]), clipped_at_spike=clipped[at],
            command_at_spike_unchanged=log.u_raw[at].tobytes() == free.u_raw[at].tobytes(),
            not_optimal_after=int(np.count_nonzero(after & (log.status != OPTIMAL))),
            recovery=None if last_bad == len(bad) - 1 else last_bad - at + 1,
            finite=bool(np.all(np.isfinite(log.u))),
            within_limits=bool(np.all((log.u >= lo) & (log.u <= hi)))))
    return out


def measure_spikes(examples: Path, build_root: Path | None = None) -> dict:
    """Every case of :data:`CASES` in both precisions (``make reliability``, ``spikes``)."""
    out: dict = {"recovery_tol": RECOVERY_TOL, "cases": {}}
    for name, at, steps in CASES:
        for precision, spikes in SPIKES.items():
            runs = spiked_runs(examples / f"{name}.yaml", precision, spikes, at, steps,
                               build_root=build_root)
            out["cases"][f"{name}/{precision}"] = {"at": at, "steps": steps,
                                                   "runs": [asdict(r) for r in runs]}
            worst = [r.recovery for r in runs]
            out["cases"][f"{name}/{precision}"]["worst_recovery"] = (
                None if None in worst else max(worst))
            out["cases"][f"{name}/{precision}"]["reported"] = all(
                r.status_at_spike == MEASUREMENT_CLIPPED for r in runs)
    return out
