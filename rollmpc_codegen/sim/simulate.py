"""Closed-loop simulation of a generated controller (through cffi) against the plant.

The controller is anything with ``step(y, sched, r) -> (status, u)``: the compiled C
(:class:`rollmpc_codegen.host.build.HostController`) or the NumPy reference
(:class:`rollmpc_codegen.reference.controller.ControllerRef`), so the same loop serves the
demo, the bit-exactness tests and the benchmarks.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from ..config import ControllerConfig
from .mismatch import PlantMismatch
from .scenario import SimulatedPlant, preview, random_stream, scenario_reference
from .signal_bounds import plant_signals, read_signals


@dataclass
class ClosedLoopLog:
    """One row per sample; arrays are float64 copies of what the controller saw/returned."""

    t: np.ndarray
    r: np.ndarray  # (K, n_outputs) reference at k
    y: np.ndarray  # (K, n_outputs) measured outputs
    sched: np.ndarray  # (K, n_schedule)
    u: np.ndarray  # (K, n_actuators)
    u_raw: list = field(default_factory=list)  # controller outputs, native dtype
    status: np.ndarray = None
    mode: np.ndarray = None
    iterations: np.ndarray = None
    solve_us: np.ndarray = None
    work: np.ndarray | None = None  # the solver's work units (a controller that counts them)
    slack_max: np.ndarray | None = None  # soft output bounds: the plan's largest slack
    signals: list = field(default_factory=list)  # the hard signals read (signal_bounds.py)
    z: np.ndarray | None = None  # (K, len(signals)) their values on the simulated plant

    def record_work(self, k: int, info: dict) -> None:
        """Sample k's work count from the controller's ``info``, when it counts one."""
        if "work" in info:
            if self.work is None:
                self.work = np.zeros(len(self.t), np.int64)
            self.work[k] = info["work"]


def progress_printer(total: int, label: str, stream=None):
    """A callback(k) that prints a progress bar to stderr: redrawn in place about every 5 %
    on a terminal, or a line of its own about every 25 % elsewhere (a CI log or a file,
    where carriage returns would pile twenty bars onto one line).

    This is also the progress factory the long-running library functions take (their
    ``progress`` keyword, see :func:`start_phase`).  A phase of ``total`` 0 has no steps:
    its label is printed at once, on a line of its own.
    """
    stream = stream or sys.stderr
    if total == 0:
        stream.write(f"{label}\n")
        stream.flush()
        return None
    tty = bool(getattr(stream, "isatty", lambda: False)())
    step = max(1, total // (20 if tty else 4))

    def report(k: int) -> None:
        if k % step == 0 or k == total - 1:
            done = (k + 1) / total
            bar = "#" * int(done * 20)
            line = f"{label} [{bar:<20}] {done * 100:5.1f}% ({k + 1}/{total})"
            if tty:
                stream.write("\r" + line + ("\n" if k == total - 1 else ""))
            else:
                stream.write(line + "\n")
            stream.flush()

    return report


def start_phase(progress, total: int, label: str):
    """The per-step callback(k) of one phase of a long run, or None.

    ``progress`` is a factory ``progress(total, label) -> callback(k) | None`` (e.g.
    :func:`progress_printer`) or None (silent): library functions report progress only
    through it and print nothing themselves.
    """
    return progress(total, label) if progress else None


def run_closed_loop(cfg: ControllerConfig, controller, reference: np.ndarray | None = None,
                    steps: int | None = None, noise_std: float = 0.0,
                    disturbance: float = 0.0, seed: int = 0,
                    mismatch: PlantMismatch | None = None, progress=None,
                    info=None) -> ClosedLoopLog:
    """Simulate ``steps`` samples of the scenario (default: the config's reference,
    scenario.scenario_reference: the paper's 60 s reference unless simulation.reference).

    ``noise_std`` adds seeded Gaussian noise to the measured outputs and the scheduling
    signal; ``disturbance`` is a constant input disturbance added to every actuator;
    ``mismatch`` perturbs the simulated plant (:mod:`rollmpc_codegen.sim.mismatch`).
    ``info`` (optional) is a callable returning the controller's last-solve diagnostics.
    """
    ref = scenario_reference(cfg) if reference is None else np.asarray(reference)
    K = len(ref) if steps is None else int(steps)
    rng = random_stream(seed, "noise")
    plant = SimulatedPlant(cfg, mismatch)
    ny, na, ns, N = cfg.n_outputs, len(cfg.actuators), cfg.n_schedule, cfg.horizon
    log = ClosedLoopLog(t=np.arange(K) * cfg.sample_time, r=np.zeros((K, ny)),
                        y=np.zeros((K, ny)), sched=np.zeros((K, ns)), u=np.zeros((K, na)),
                        status=np.zeros(K, int), mode=np.zeros(K, int),
                        iterations=np.zeros(K, int), solve_us=np.zeros(K))
    log.signals = plant_signals(cfg, [ch.A.shape[0] for ch in plant.channels])
    log.z = np.zeros((K, len(log.signals)))
    dist = np.full(na, float(disturbance))
    for k in range(K):
        y = plant.outputs()
        s = plant.schedule_signal()
        if noise_std > 0:
            y = y + rng.normal(0.0, noise_std, size=y.shape)
            s = s + rng.normal(0.0, noise_std, size=s.shape)
        r = preview(ref, k, N, ny)
        status, u = controller.step(y, s, r)
        log.r[k] = ref[min(k, len(ref) - 1)]
        log.y[k], log.sched[k], log.u[k] = y, s, u
        log.u_raw.append(u)
        log.status[k] = status
        if log.signals:
            log.z[k] = read_signals(log.signals, plant.x, log.u[k])
        if info is not None:
            d = info()
            log.mode[k], log.iterations[k] = d["mode"], d["iterations"]
            log.solve_us[k] = d.get("solve_ticks", 0) / 1000.0
            log.record_work(k, d)
            if "slack_max" in d:
                if log.slack_max is None:
                    log.slack_max = np.zeros(K)
                log.slack_max[k] = d["slack_max"]
        plant.advance(np.asarray(u, float), dist if disturbance else None)
        if progress is not None:
            progress(k)
    return log


def csv_header(ctx: dict) -> list[str]:
    """The columns of a closed-loop log (`rollmpc simulate --csv`, and the controller
    columns of `rollmpc fly --csv` that `rollmpc report --flight` reads back); ``work`` is
    last, so that the columns before it are where they were before it was added."""
    outputs = ctx["outputs"]
    if len(outputs) == 1:
        r_cols, y_cols = ["r"], ["y"]
    else:
        r_cols, y_cols = [f"r_{o}" for o in outputs], [f"y_{o}" for o in outputs]
    rho = ["rho"] if ctx["n_schedule"] else []
    return (["k", "t", *r_cols, *y_cols, *rho, "mode"]
            + [f"u_{a}" for a in ctx["actuators"]] + ["status", "iterations", "solve_us", "work"])


def work_cell(log: ClosedLoopLog, k: int) -> str:
    """Sample k's ``work`` column: blank for a controller that counts none (a baseline)."""
    return "" if log.work is None else str(int(log.work[k]))
