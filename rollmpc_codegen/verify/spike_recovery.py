"""Recovery from one huge but finite measurement (docs/reliability.md, "Hostile input").

Issue 15's audit: a single y = 1e308 left the controller INFEASIBLE or NUMERICAL for the
rest of the flight.  The observers now clip each innovation y - C x̂ to
``modes[].observer.innovation_limit``; this module measures what is left of a spike.

The scenario runs twice in closed loop on the host C: without a spike, and with output
``output`` replaced by the spike at sample ``at`` (the plant itself is untouched).  The
spiked run *recovers* at the first sample from which every status is OPTIMAL and every
command is within :data:`RECOVERY_TOL` of the largest input span of the spike-free run's
command; :attr:`SpikeRun.recovery` counts the samples from the spike to there.

:func:`hostile_runs` does the same for one hostile sample of *each* input of the C API
(issue 49): the first output y, the schedule signal, the whole reference preview r, and
the applied command ``u_applied`` of ``P_observe`` (a sample that another controller flies
holding the last command, while the feedback reports the hostile value for every
actuator), each at 1e7, 1e8, 1e30, NaN and Inf, on a single-output design (the paper's
UAV) and a scheduled MIMO one (:func:`scheduled_tank`).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import yaml

from ..config import ControllerConfig, load, parse
from ..host.build import build_host_controller
from ..pipeline import load_model, load_model_from_config
from ..sim.simulate import run_closed_loop
from ..status import MEASUREMENT_CLIPPED, OPTIMAL

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

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
    """Per actuator, the lowest u_min and highest u_max of the modes that drive it
    (codegen.context.actuator_range)."""
    return np.array(ctx["actuator_min"]), np.array(ctx["actuator_max"])


def _recovery(log, free, at: int, tol: float) -> int | None:
    """Samples from ``at`` until every status is OPTIMAL and every command within ``tol``
    of the undisturbed run ``free``'s, for good (None: not by the end of the run)."""
    bad = (log.status != OPTIMAL) | (np.abs(log.u - free.u).max(axis=1) > tol)
    bad[:at] = False
    last_bad = int(np.flatnonzero(bad)[-1]) if bad.any() else at - 1
    return None if last_bad == len(bad) - 1 else last_bad - at + 1


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
        out.append(SpikeRun(
            spike=spike, status_at_spike=int(log.status[at]), clipped_at_spike=clipped[at],
            command_at_spike_unchanged=log.u_raw[at].tobytes() == free.u_raw[at].tobytes(),
            not_optimal_after=int(np.count_nonzero(after & (log.status != OPTIMAL))),
            recovery=_recovery(log, free, at, tol),
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


# --------------------------------------------------------------------------- every input
HOSTILE_VALUES = (1e7, 1e8, 1e30, math.nan, math.inf)  # issue 49's: huge, and no number
HOSTILE_INPUTS = ("y", "sched", "r", "u_applied")
# (design, sample of the hostile value, samples run): a level is held there
HOSTILE_CASES = (("uav_roll", 1500, 3000), ("quadruple_tank_scheduled", 280, 400))


@dataclass(frozen=True)
class HostileRun:
    """What one hostile value of one input did to the closed loop."""

    input: str
    value: float
    status_at: int  # P_step's (u_applied: P_observe's) status for the hostile sample
    not_optimal_after: int
    recovery: int | None  # samples from the hostile one to rejoining the clean run
    finite: bool
    within_limits: bool


class Hostile:
    """``controller`` (anything with ``step`` and ``observe``) given ``value`` in place of
    input ``which`` at sample ``at``: the first output of y, the schedule signal, every
    entry of the preview r; or, for ``u_applied``, a sample flown by another controller
    that holds the last command while ``P_observe`` is told ``value`` for every actuator
    (``value`` None: told the command it really held, the clean run of that input)."""

    def __init__(self, controller, which: str, value: float | None, at: int):
        self.controller, self.which, self.value, self.at = controller, which, value, at
        self.k, self.held = 0, None

    def step(self, y, sched, r):
        k, self.k = self.k, self.k + 1
        if k == self.at and self.which == "u_applied":
            told = self.held if self.value is None else np.full_like(self.held, self.value)
            return self.controller.observe(y, sched, told), self.held
        if k == self.at and self.value is not None:
            y, sched, r = (np.array(v, float) for v in (y, sched, r))
            target = {"y": y[:1], "sched": sched[:1], "r": r}[self.which]
            target[...] = self.value
        status, u = self.controller.step(y, sched, r)
        self.held = np.array(u, float)
        return status, u


def scheduled_tank(precision: str = "double") -> ControllerConfig:
    """quadruple_tank with a second operating mode (the same plant, twice the input
    weight) scheduled on the first level (above 2.5 cm: "high", below 1.5 cm: "low"), so
    that a MIMO design has a schedule signal to be hostile in."""
    data = yaml.safe_load((EXAMPLES / "quadruple_tank.yaml").read_text())
    low = data["modes"][0]
    low["name"] = "low"
    high = {**low, "name": "high", "weights": {**low["weights"], "R": 0.02}}
    data["modes"] = [low, high]
    data["scheduler"] = {"signal": "h1", "epsilon": 0.5, "initial": "low",
                         "bands": [{"mode": "low", "below": 2.0}, {"mode": "high"}]}
    data["simulation"]["schedule_source"] = "output"
    data["precision"] = precision
    return parse(data)


def hostile_runs(cfg: ControllerConfig, at: int, steps: int, inputs=HOSTILE_INPUTS,
                 values=HOSTILE_VALUES, build_root: Path | None = None) -> list[HostileRun]:
    """One :class:`HostileRun` per input and value (an input the design lacks, a schedule
    signal without a scheduler, is skipped), each against its clean run."""
    model, ctx = load_model_from_config(cfg)
    lo, hi = _input_envelope(ctx)
    tol = RECOVERY_TOL * float(np.max(hi - lo))

    def run(which: str, value: float | None):
        loop = Hostile(build_host_controller(ctx, build_root), which, value, at)
        return run_closed_loop(model.config, loop, steps=steps)

    out = []
    for which in inputs:
        if which == "sched" and ctx["n_schedule"] == 0:
            continue
        free = run(which, None)
        for value in values:
            log = run(which, value)
            after = np.arange(len(log.status)) > at
            out.append(HostileRun(
                input=which, value=value, status_at=int(log.status[at]),
                not_optimal_after=int(np.count_nonzero(after & (log.status != OPTIMAL))),
                recovery=_recovery(log, free, at, tol),
                finite=bool(np.all(np.isfinite(log.u))),
                within_limits=bool(np.all((log.u >= lo) & (log.u <= hi)))))
    return out


def hostile_design(name: str, precision: str) -> ControllerConfig:
    """A design of :data:`HOSTILE_CASES` by name, in ``precision``."""
    if name == "quadruple_tank_scheduled":
        return scheduled_tank(precision)
    return load(EXAMPLES / f"{name}.yaml", precision)


def measure_hostile(build_root: Path | None = None) -> dict:
    """Every case of :data:`HOSTILE_CASES` in both precisions (``--only hostile``)."""
    out: dict = {"recovery_tol": RECOVERY_TOL, "cases": {}}
    for name, at, steps in HOSTILE_CASES:
        for precision in ("double", "float"):
            runs = hostile_runs(hostile_design(name, precision), at, steps,
                                build_root=build_root)
            worst = {}
            for r in runs:  # None: some value was not recovered by the end of the run
                before = worst.get(r.input, 0)
                worst[r.input] = (None if None in (before, r.recovery)
                                  else max(before, r.recovery))
            out["cases"][f"{name}/{precision}"] = {
                "at": at, "steps": steps, "worst_recovery": worst,
                "runs": [{**asdict(r), "value": repr(r.value)} for r in runs]}
    return out
