"""Steps 1 to 3 of ``rollmpc report`` (:mod:`rollmpc_codegen.target.report`): record a
host run, choose the steps to count, and replay the run on the emulated Cortex-M4F.

1. Host run: the host build of the same precision (through cffi) closes the loop on the
   scenario, or on a flight (``loop_options``: its reference and perturbations, see
   :mod:`rollmpc_codegen.target.flights`), or steps through a flown flight's recorded
   inputs (:mod:`.flight_replay`); every input it was given (y, sched, r) and every
   output (u, status, diagnostics, solve time) is recorded.
2. Step choice: the hardest steps by the host's solve time (the smallest of several runs:
   the host clock is noisy), polish corrections, active rows and sweeps, plus a sampled
   sweep (every ``sample_every``-th step).
3. Target run: the target image (``target.build_target``) replays the recorded inputs from
   step 0 on Unicorn (``emulate.CortexM``), so the observers and warm starts carry the same
   state as on the host. Every step is compared bit for bit with the host; instructions
   and estimated cycles are counted on the chosen steps only (the block hook is slow).

``progress`` is a factory as in ``sim.simulate.start_phase`` (None or False: silent).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..host.build import build_host_controller, c_values
from ..info_struct import COMPARED_FIELDS
from ..sim.scenario import scenario_reference
from ..sim.simulate import run_closed_loop, start_phase
from .emulate import CortexM
from .build import target_layout
from .state_layout import StateLayout

# the diagnostics compared per step, in the order of the harness' {prefix}_target_info
INFO_FIELDS = COMPARED_FIELDS


@dataclass
class HostRecord:
    """Everything the host build saw and returned, per step."""

    y: list = field(default_factory=list)
    sched: list = field(default_factory=list)
    r: list = field(default_factory=list)
    u: list = field(default_factory=list)
    info: list = field(default_factory=list)
    final_state: bytes = b""
    # with a target's layout (state_layout.py): the instance after each step, one digest
    # per member, from a host build with the target's kernels
    layout: StateLayout | None = None
    states: list = field(default_factory=list)


class _RecordingController:
    """Wraps a HostController: records the exact (dtype-converted) inputs and outputs."""

    def __init__(self, host, record: HostRecord):
        self.host, self.record = host, record

    def step(self, y, sched, r):
        dt = self.host.dtype
        y, r = c_values(y, dt), c_values(r, dt)
        sched = c_values(sched if sched is not None else [], dt)
        status, u = self.host.step(y, sched, r)
        info = self.host.info()
        self.record.y.append(y)
        self.record.sched.append(sched)
        self.record.r.append(r)
        self.record.u.append(np.asarray(u, dt).copy())
        self.record.info.append(info)
        if self.record.layout is not None:
            self.record.states.append(self.record.layout.digests(self.host.instance()))
        return status, u


def record_host_run(model, ctx: dict, build_root: Path, steps: int | None,
                    progress=None, repeats: int = 1, loop_options: dict | None = None,
                    label: str = "report", layout: StateLayout | None = None) -> HostRecord:
    """Close the loop with the host build and record every step; ``loop_options`` are
    keywords of ``run_closed_loop`` (reference, noise_std, disturbance, seed, mismatch);
    ``layout``: the target's (:func:`.state_layout.target_layout`), whose kernels the host
    build runs and whose members each step's instance is recorded by."""
    loop_options = loop_options or {}
    reference = loop_options.get("reference")
    total = steps or len(scenario_reference(model.config) if reference is None else reference)

    def drive(controller, progress_cb):
        run_closed_loop(model.config, controller, steps=steps, progress=progress_cb,
                        **loop_options)

    return record_host_runs(ctx, build_root, total, drive, progress, repeats,
                            f"{label}: host run", layout)


def record_host_runs(ctx: dict, build_root: Path, total: int, drive, progress=None,
                     repeats: int = 1, label: str = "report: host run",
                     layout: StateLayout | None = None) -> HostRecord:
    """Record every step of ``drive(controller, progress_cb)``, which calls
    ``controller.step`` ``total`` times, on a fresh host build (a closed loop, or the
    recorded inputs of a flight: :mod:`.flight_replay`).

    With ``repeats`` > 1 the (deterministic) run is driven again and each step keeps its
    smallest solve time: the host clock on a shared machine is noisy, and the minimum is
    what ranks the hardest steps.
    """
    record = HostRecord(layout=layout)
    flags = () if layout is None else layout.host_flags(ctx)
    for run in range(max(1, repeats)):
        host = build_host_controller(ctx, build_root, extra=flags)
        cb = start_phase(progress, total, f"{label} {run + 1}/{max(1, repeats)}")
        if run == 0:
            drive(_RecordingController(host, record), cb)
            record.final_state = host.instance()
            continue
        timings = HostRecord()  # no layout: the instances are recorded once
        drive(_RecordingController(host, timings), cb)
        for info, again in zip(record.info, timings.info):
            info["solve_ticks"] = min(info["solve_ticks"], again["solve_ticks"])
    return record


def select_steps(record: HostRecord, hardest: int, sample_every: int) -> tuple[list, list]:
    """(hardest steps, sampled sweep). Hardest: the union of the top ``3 * hardest`` steps
    by the host's solve time (the closest proxy of target cycles) and the top ``hardest``
    by polish corrections, active rows and sweeps. Sweep: every ``sample_every``-th step."""
    n = len(record.info)
    hard: set[int] = set()
    for key, top in (("solve_ticks", 3 * hardest), ("polish_iterations", hardest),
                     ("active", hardest), ("iterations", hardest)):
        values = np.array([inf[key] for inf in record.info], dtype=np.int64)
        if values.max(initial=0) <= 0:
            continue
        order = np.argsort(-values, kind="stable")[:top]
        hard.update(int(k) for k in order if values[k] > 0)
    sweep = list(range(0, n, max(1, sample_every)))
    return sorted(hard), sweep


def same_state(host: bytes, target: bytes, real: np.dtype) -> bool:
    """The instances are equal byte for byte, but for reals that are NaN on both sides:
    a NaN's sign and payload are the FPU's (x86 makes -NaN where the M4F makes +NaN), not
    the controller's, and a run whose plant diverged can leave NaN in a state it no
    longer reads."""
    if host == target:
        return True
    if len(host) != len(target):
        return False
    size = real.itemsize
    a, b = np.frombuffer(host, np.uint8), np.frombuffer(target, np.uint8)
    for word in np.unique(np.flatnonzero(a != b) // size):
        lo = word * size
        if len(host) < lo + size:
            return False  # a trailing partial word: not a real
        h, g = (np.frombuffer(bytes(x[lo:lo + size]), real)[0] for x in (host, target))
        if not (np.isnan(h) and np.isnan(g)):
            return False
    return True


@dataclass
class TargetRun:
    counts: dict  # step -> emulate.Counts
    mismatches: list  # (step, what, host, target)
    steps: int
    state_equal: bool
    stack_measured: int
    state_steps: list = field(default_factory=list)  # the steps whose instances differ
    state_members: list = field(default_factory=list)  # the members that differ first
    kernels: str = ""  # the target's kernel variant, which the host build ran

    def state_mismatch(self) -> dict | None:
        """The first step whose instance differs, its members and how many steps differ."""
        if not self.state_steps:
            return None if self.state_equal else {"step": self.steps - 1, "members": [],
                                                  "steps": 1}
        return {"step": int(self.state_steps[0]), "members": list(self.state_members),
                "steps": len(self.state_steps)}


def _compare_outputs(k: int, record: HostRecord, u: np.ndarray, status: int,
                     info: np.ndarray, mismatches: list) -> None:
    host_info = record.info[k]
    if u.tobytes() != record.u[k].tobytes():
        mismatches.append((k, "u", record.u[k].tolist(), u.tolist()))
    if int(np.int32(status)) != host_info["status"]:
        mismatches.append((k, "status", host_info["status"], int(np.int32(status))))
    for i, name in enumerate(INFO_FIELDS):
        if int(info[i]) != host_info[name]:
            mismatches.append((k, name, host_info[name], int(info[i])))


def write_inputs(em, ctx: dict, record: HostRecord, k: int) -> None:
    """Step k's recorded inputs into the emulated harness (y, the schedule, r)."""
    p = ctx["prefix"]
    em.write(f"{p}_target_y", record.y[k])
    if ctx["n_schedule"]:
        em.write(f"{p}_target_sched", record.sched[k])
    em.write(f"{p}_target_r", record.r[k])


def replay_on_target(build, ctx: dict, record: HostRecord, count_steps: set[int],
                     progress=None, label: str = "report") -> TargetRun:
    """Replay the recorded inputs from step 0 on the emulated core; compare every output
    and, when the record has them, every step's instance (member digests)."""
    p = ctx["prefix"]
    dt = np.float32 if ctx["real"] == "float" else np.float64
    layout = record.layout or target_layout(build, ctx)
    em = CortexM(build.elf, build.core)
    if layout.ctrl_size != len(record.final_state):
        raise RuntimeError(f"{p}_ctrl differs between host ({len(record.final_state)} B) and "
                           f"target ({layout.ctrl_size} B)")
    em.call(f"{p}_target_init")
    n = len(record.u)
    cb = start_phase(progress, n, f"{label}: target run ")
    counts, mismatches, state_steps, first_members = {}, [], [], []
    for k in range(n):
        write_inputs(em, ctx, record, k)
        status, c = em.call(f"{p}_target_step", count=k in count_steps)
        if c is not None:
            counts[k] = c
        _compare_outputs(k, record, np.frombuffer(em.read(f"{p}_target_u"), dt), status,
                         np.frombuffer(em.read(f"{p}_target_info"), np.int32), mismatches)
        if record.states:
            differ = layout.differing(record.states[k], layout.digests(em.read(f"{p}_target_ctrl")))
            if differ:
                first_members = first_members or differ
                state_steps.append(k)
        if cb:
            cb(k)
    # the whole instance after the last step, but for the diagnostics (compared above;
    # their solve time is the host's clock)
    target_state = bytearray(em.read(f"{p}_target_ctrl"))
    host_state = bytearray(record.final_state)
    at, size = layout.info_at, layout.info_size
    target_state[at:at + size] = host_state[at:at + size] = bytes(size)
    return TargetRun(counts=counts, mismatches=mismatches, steps=n,
                     state_equal=not state_steps and same_state(host_state, target_state,
                                                                np.dtype(dt)),
                     stack_measured=em.stack_high_water(), state_steps=state_steps,
                     state_members=first_members, kernels=layout.kernels)
