"""``rollmpc report``: flash, RAM, stack and cycles of the generated controller on an
emulated Cortex-M4F, bit-exact against the host build.

Pipeline:
1. Host run: the host build of the same precision (through cffi) closes the loop on the
   scenario; every input it was given (y, sched, r) and every output (u, status,
   diagnostics, solve time) is recorded.
2. Step choice: the hardest steps by the host's solve time (the smallest of several runs:
   the host clock is noisy), polish corrections, active rows and sweeps, plus a sampled
   sweep (every ``sample_every``-th step).
3. Target run: the target image (``target.build_target``) replays the recorded inputs from
   step 0 on Unicorn (``emulate.CortexM4``), so the observers and warm starts carry the same
   state as on the host. Every step is compared bit for bit with the host; instructions
   and estimated cycles are counted on the chosen steps only (the block hook is slow).

``--horizons`` repeats the measurement for the config with the horizon overridden and
fits the growth of each figure in N (log-log least squares).
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from .. import __version__
from ..host.build import build_host_controller
from ..host.build_cache import private_root
from .emulate import CortexM4
from ..pipeline import load_model
from ..codegen.render import render_sources
from ..sim.scenario import scenario_reference
from ..sim.simulate import progress_printer, run_closed_loop
from .build import (CORTEX_M4F, CROSS_CC, TARGET_CFLAGS, build_target, image_sizes,
                     largest_symbols, worst_stack)

CPU_MHZ = 168.0
GOALS = {"flash_bytes": 256 * 1024, "ram_bytes": 32 * 1024, "worst_step_cycles": 1_680_000}
# Memory assumed for common autopilot parts: flash, and the largest contiguous RAM region
# a statically allocated controller instance can live in (the instance is one struct).
PARTS = (
    {"part": "STM32F405/F407 (M4F, 168 MHz)", "flash_kib": 1024, "ram_kib": 128,
     "ram_note": "192 KiB = 128 KiB SRAM + 64 KiB CCM; one struct must fit 128 KiB"},
    {"part": "STM32F427/F429 (M4F, 180 MHz; Pixhawk FMUv2/v3)", "flash_kib": 2048,
     "ram_kib": 192, "ram_note": "256 KiB = 192 KiB SRAM + 64 KiB CCM"},
    {"part": "STM32F765/F767 (M7 double FPU, 216 MHz; FMUv5)", "flash_kib": 2048,
     "ram_kib": 512, "ram_note": "512 KiB (DTCM + SRAM1 + SRAM2, contiguous)"},
    {"part": "STM32H743/H753 (M7 double FPU, 480 MHz; FMUv6)", "flash_kib": 2048,
     "ram_kib": 512, "ram_note": "1 MiB total; largest region AXI SRAM 512 KiB"},
)
# the diagnostics compared per step, in the order of the harness' {prefix}_target_info
INFO_FIELDS = ("status", "mode", "iterations", "polish_iterations", "active", "mode_switches")


@dataclass
class HostRecord:
    """Everything the host build saw and returned, per step."""

    y: list = field(default_factory=list)
    sched: list = field(default_factory=list)
    r: list = field(default_factory=list)
    u: list = field(default_factory=list)
    info: list = field(default_factory=list)
    final_state: bytes = b""


class _RecordingController:
    """Wraps a HostController: records the exact (dtype-converted) inputs and outputs."""

    def __init__(self, host, record: HostRecord):
        self.host, self.record = host, record

    def step(self, y, sched, r):
        dt = self.host.dtype
        y = np.ascontiguousarray(y, dt)
        r = np.ascontiguousarray(r, dt)
        sched = np.ascontiguousarray(sched if sched is not None else [], dt)
        status, u = self.host.step(y, sched, r)
        info = self.host.info()
        self.record.y.append(y)
        self.record.sched.append(sched)
        self.record.r.append(r)
        self.record.u.append(np.asarray(u, dt).copy())
        self.record.info.append(info)
        return status, u


def record_host_run(model, ctx: dict, build_root: Path, steps: int | None,
                    progress: bool, repeats: int = 1) -> HostRecord:
    """Close the loop with the host build and record every step.

    With ``repeats`` > 1 the (deterministic) closed loop runs again and each step keeps its
    smallest solve time: the host clock on a shared machine is noisy, and the minimum is
    what ranks the hardest steps.
    """
    record = HostRecord()
    total = steps or len(scenario_reference(model.config))
    for run in range(max(1, repeats)):
        host = build_host_controller(ctx, build_root)
        label = f"report: host run {run + 1}/{max(1, repeats)}"
        cb = progress_printer(total, label) if progress else None
        if run == 0:
            run_closed_loop(model.config, _RecordingController(host, record), steps=steps,
                            progress=cb)
            record.final_state = bytes(host.ffi.buffer(host.ctrl))
            continue
        timings = HostRecord()
        run_closed_loop(model.config, _RecordingController(host, timings), steps=steps,
                        progress=cb)
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


@dataclass
class TargetRun:
    counts: dict  # step -> emulate.Counts
    mismatches: list  # (step, what, host, target)
    steps: int
    state_equal: bool
    stack_measured: int


def replay_on_target(build, ctx: dict, record: HostRecord, count_steps: set[int],
                     progress: bool) -> TargetRun:
    """Replay the recorded inputs from step 0 on the emulated M4F; compare every output."""
    p = ctx["prefix"]
    dt = np.float32 if ctx["real"] == "float" else np.float64
    em = CortexM4(build.elf)
    ctrl_size, real_size, info_at, info_size = map(
        int, np.frombuffer(em.read(f"{p}_target_layout"), np.uint32))
    if ctrl_size != len(record.final_state) or real_size != np.dtype(dt).itemsize:
        raise RuntimeError(f"{p}_ctrl differs between host ({len(record.final_state)} B) and "
                           f"target ({ctrl_size} B)")
    em.call(f"{p}_target_init")
    n = len(record.u)
    cb = progress_printer(n, "report: target run ") if progress else None
    counts, mismatches = {}, []
    for k in range(n):
        em.write(f"{p}_target_y", record.y[k])
        if ctx["n_schedule"]:
            em.write(f"{p}_target_sched", record.sched[k])
        em.write(f"{p}_target_r", record.r[k])
        status, c = em.call(f"{p}_target_step", count=k in count_steps)
        if c is not None:
            counts[k] = c
        u = np.frombuffer(em.read(f"{p}_target_u"), dt)
        info = np.frombuffer(em.read(f"{p}_target_info"), np.int32)
        host_info = record.info[k]
        if u.tobytes() != record.u[k].tobytes():
            mismatches.append((k, "u", record.u[k].tolist(), u.tolist()))
        if int(np.int32(status)) != host_info["status"]:
            mismatches.append((k, "status", host_info["status"], int(np.int32(status))))
        for i, name in enumerate(INFO_FIELDS):
            if int(info[i]) != host_info[name]:
                mismatches.append((k, name, host_info[name], int(info[i])))
        if cb:
            cb(k)
    # the whole instance after the last step, but for the diagnostics (compared above;
    # their solve time is the host's clock)
    target_state = bytearray(em.read(f"{p}_target_ctrl"))
    host_state = bytearray(record.final_state)
    target_state[info_at:info_at + info_size] = host_state[info_at:info_at + info_size] = \
        bytes(info_size)
    return TargetRun(counts=counts, mismatches=mismatches, steps=n,
                     state_equal=target_state == host_state,
                     stack_measured=em.stack_high_water())


def _toolchain_version() -> str:
    try:
        out = subprocess.run([CROSS_CC, "--version"], capture_output=True, text=True).stdout
        return out.splitlines()[0].strip()
    except (OSError, IndexError):
        return "unknown"


def _top_functions(counts, limit: int = 12) -> list[dict]:
    rows = sorted(counts.by_function.items(), key=lambda kv: -kv[1][1])[:limit]
    return [{"function": name, "cycles": int(cyc), "instructions": int(ins),
             "share": round(cyc / counts.cycles, 4) if counts.cycles else 0.0}
            for name, (ins, cyc) in rows]


def measure(model, ctx: dict, build_root: Path, steps: int | None = None,
            sample_every: int = 20, hardest: int = 10, progress: bool = True,
            extra_cflags: tuple[str, ...] = (), host_repeats: int = 5) -> dict:
    """The full report of one generated controller (see the module docstring)."""
    build = build_target(ctx, build_root, extra_cflags=extra_cflags)
    sizes = image_sizes(build.elf)
    stack = worst_stack(build, f"{ctx['prefix']}_step")
    stack_entry = worst_stack(build, f"{ctx['prefix']}_target_step")  # + the harness frame
    record = record_host_run(model, ctx, build_root, steps, progress, host_repeats)
    hard, sweep = select_steps(record, hardest, sample_every)
    run = replay_on_target(build, ctx, record, set(hard) | set(sweep), progress)
    worst_k = max(run.counts, key=lambda k: (run.counts[k].cycles, -k))
    worst = run.counts[worst_k]
    sweep_cycles = np.array([run.counts[k].cycles for k in sweep])
    sweep_instr = np.array([run.counts[k].instructions for k in sweep])
    ts = ctx["sample_time"]
    budget = int(round(CPU_MHZ * 1e6 * ts))
    bit_exact = not run.mismatches and run.state_equal
    info_w = record.info[worst_k]
    report = {
        "config_hash": ctx["config_hash"],
        "generator": f"rollmpc-codegen {__version__}",
        "precision": ctx["precision"],
        "horizon": ctx["horizon"],
        "sample_time": ts,
        "toolchain": _toolchain_version(),
        "cflags": " ".join([*CORTEX_M4F, *TARGET_CFLAGS, *extra_cflags]),
        "flash_bytes": sizes["flash_bytes"],
        "ram_bytes": sizes["ram_bytes"],
        "ctrl_bytes": len(record.final_state),
        "stack_bytes": stack["bytes"],
        "stack_path": stack["path"],
        "stack_entry_bytes": stack_entry["bytes"],
        "stack_measured_bytes": run.stack_measured,
        "largest_symbols": largest_symbols(build.elf, 10),
        "steps_emulated": run.steps,
        "steps_counted": len(run.counts),
        "hardest_steps": hard,
        "sample_every": sample_every,
        "host_repeats": host_repeats,
        "bit_exact_vs_host": bool(bit_exact),
        "state_bit_exact": bool(run.state_equal),
        "mismatches": len(run.mismatches),
        "first_mismatches": [list(m) for m in run.mismatches[:5]],
        "worst_step": int(worst_k),
        "worst_step_mode": int(info_w["mode"]),
        "worst_step_host": {k: int(info_w[k]) for k in (*INFO_FIELDS, "solve_ticks")},
        "worst_step_instructions": int(worst.instructions),
        "worst_step_cycles": int(worst.cycles),
        "median_step_cycles": int(np.median(sweep_cycles)),
        "median_step_instructions": int(np.median(sweep_instr)),
        "cpu_mhz_for_10ms": round(worst.cycles / ts / 1e6, 2),
        "budget": {"cpu_mhz": CPU_MHZ, "cycles_per_sample": budget,
                   "worst_fits": bool(worst.cycles <= budget),
                   "worst_load_percent": round(100.0 * worst.cycles / budget, 1)},
        "goals": {
            "flash_bytes<=262144": bool(sizes["flash_bytes"] <= GOALS["flash_bytes"]),
            "ram_bytes<=32768": bool(sizes["ram_bytes"] <= GOALS["ram_bytes"]),
            "ctrl_bytes<=32768": bool(len(record.final_state) <= GOALS["ram_bytes"]),
            "worst_step_cycles<=1680000": bool(worst.cycles <= GOALS["worst_step_cycles"]),
            "bit_exact_vs_host": bool(bit_exact),
        },
        "worst_step_top_functions": _top_functions(worst),
        "hardest_step_cycles": [
            {"step": k, "cycles": int(run.counts[k].cycles),
             "instructions": int(run.counts[k].instructions),
             **{f: int(record.info[k][f]) for f in ("mode", "iterations", "polish_iterations",
                                                   "active")},
             "host_solve_us": round(record.info[k]["solve_ticks"] / 1000.0, 1)}
            for k in sorted(hard, key=lambda k: -run.counts[k].cycles)],
        "cycle_model": "Cortex-M4 TRM weights, zero wait states, taken branch +2 "
                       "(shared/notes/mcu-cycle-counting.md); treat as +/-20 %",
    }
    return report


def summary(rep: dict) -> str:
    """Short human summary with the verdict at 168 MHz."""
    b = rep["budget"]
    verdict = "fits" if b["worst_fits"] else "DOES NOT fit"
    top = ", ".join(f"{r['function']} {100 * r['share']:.0f}%"
                    for r in rep["worst_step_top_functions"][:4])
    lines = [
        f"rollmpc report: {rep['precision']}, N = {rep['horizon']}, {rep['toolchain']}",
        f"  flash {rep['flash_bytes']:,} B   static RAM {rep['ram_bytes']:,} B "
        f"(controller instance {rep['ctrl_bytes']:,} B)   stack {rep['stack_bytes']} B "
        f"(-fstack-usage worst path; measured {rep['stack_measured_bytes']} B of "
        f"{rep['stack_entry_bytes']} B predicted with the harness)",
        f"  steps emulated {rep['steps_emulated']}, counted {rep['steps_counted']} "
        f"({len(rep['hardest_steps'])} hardest + every {rep['sample_every']}th); "
        f"bit-exact vs host: {'yes' if rep['bit_exact_vs_host'] else 'NO'}"
        + ("" if rep["bit_exact_vs_host"] else f" ({rep['mismatches']} mismatches)"),
        f"  worst step {rep['worst_step']} (mode {rep['worst_step_mode']}): "
        f"{rep['worst_step_cycles']:,} cycles, {rep['worst_step_instructions']:,} "
        f"instructions; median {rep['median_step_cycles']:,} cycles",
        f"  needs {rep['cpu_mhz_for_10ms']} MHz for Ts = {1000 * rep['sample_time']:g} ms; "
        f"at {b['cpu_mhz']:g} MHz the worst step {verdict} "
        f"({b['worst_load_percent']}% of {b['cycles_per_sample']:,} cycles)",
        f"  worst step by function: {top}",
    ]
    goals = ", ".join(f"{k}: {'met' if v else 'MISSED'}" for k, v in rep["goals"].items())
    lines.append(f"  goals (issue 7, paper config in float): {goals}")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- horizons
def config_with_horizon(config: Path, horizon: int, out_dir: Path) -> Path:
    """A copy of ``config`` with ``horizon`` overridden, written to ``out_dir``."""
    data = yaml.safe_load(Path(config).read_text())
    data["horizon"] = int(horizon)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{Path(config).stem}_N{horizon}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def loglog_fit(n: list[float], values: list[float]) -> dict:
    """values ~ a * n^b by least squares on the logs; {"a", "exponent"}."""
    x, y = np.log(np.asarray(n, float)), np.log(np.asarray(values, float))
    if len(x) < 2:
        return {"a": float(values[0]) if values else 0.0, "exponent": None}
    b, log_a = np.polyfit(x, y, 1)
    return {"a": float(np.exp(log_a)), "exponent": round(float(b), 3)}


def horizon_limit(ns: list[int], cycles: list[int], budget: float) -> int | None:
    """Horizon whose worst step just meets ``budget``: log-log interpolation between the
    two measured horizons that bracket it (else extrapolation from the nearest pair)."""
    pts = sorted(zip(ns, cycles))
    if len(pts) < 2:
        return None
    pairs = list(zip(pts, pts[1:]))
    pair = next(((a, b) for a, b in pairs if a[1] <= budget < b[1]),
                pairs[-1] if pts[-1][1] <= budget else pairs[0])
    (n0, c0), (n1, c1) = pair
    slope = math.log(c1 / c0) / math.log(n1 / n0)
    return int(n0 * (budget / c0) ** (1.0 / slope)) if slope > 0 else None


def horizon_table(config: Path, horizons: list[int], precision: str | None, build_root: Path,
                  steps: int | None, sample_every: int, hardest: int,
                  progress: bool, extra_cflags: tuple[str, ...] = (),
                  host_repeats: int = 5) -> dict:
    """Per horizon: generation time, flash, RAM, worst/median cycles; growth fits; parts."""
    rows = []
    for h in horizons:
        if progress:
            print(f"report: horizon {h}", file=sys.stderr)
        path = config_with_horizon(config, h, Path(build_root) / "horizons")
        t0 = time.perf_counter()
        model, ctx = load_model(path, precision)
        render_sources(ctx)
        gen_s = time.perf_counter() - t0
        rep = measure(model, ctx, build_root, steps, sample_every, hardest, progress,
                      extra_cflags, host_repeats)
        rows.append({"horizon": h, "generation_s": round(gen_s, 2),
                     **{k: rep[k] for k in ("flash_bytes", "ram_bytes", "ctrl_bytes",
                                            "stack_bytes", "worst_step_cycles",
                                            "worst_step_instructions", "median_step_cycles",
                                            "cpu_mhz_for_10ms", "bit_exact_vs_host")},
                     "budget_cycles": rep["budget"]["cycles_per_sample"],
                     "fits_10ms_at_168MHz": rep["budget"]["worst_fits"]})
    ns = [r["horizon"] for r in rows]
    keys = ("generation_s", "flash_bytes", "ram_bytes", "worst_step_cycles",
            "median_step_cycles")
    fits = {key: loglog_fit(ns, [r[key] for r in rows]) for key in keys}
    for key in keys:  # the slope between the two largest horizons (the asymptotic trend)
        fits[key]["exponent_last_pair"] = (loglog_fit(ns[-2:], [r[key] for r in rows[-2:]])
                                           ["exponent"] if len(rows) > 1 else None)
    n_max = horizon_limit(ns, [r["worst_step_cycles"] for r in rows], rows[0]["budget_cycles"])
    parts = []
    for part in PARTS:
        ok = [r["horizon"] for r in rows if r["flash_bytes"] <= part["flash_kib"] * 1024
              and r["ram_bytes"] <= part["ram_kib"] * 1024]
        parts.append({**part, "horizons_that_fit_memory": ok})
    fitting = [r["horizon"] for r in rows if r["fits_10ms_at_168MHz"]]
    return {"rows": rows, "fits": fits, "parts": parts,
            "largest_measured_horizon_within_10ms_at_168MHz": max(fitting) if fitting else None,
            "fitted_horizon_limit_10ms_at_168MHz": n_max}


def horizons_markdown(table: dict) -> str:
    """The per-horizon table and the fits as markdown (what docs/target.md shows)."""
    lines = ["| N | generation (s) | flash (B) | static RAM (B) | stack (B) | worst step "
             "(cycles) | median step (cycles) | MHz for 10 ms | bit-exact |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|:---:|"]
    for r in table["rows"]:
        lines.append(f"| {r['horizon']} | {r['generation_s']:.2f} | {r['flash_bytes']:,} | "
                     f"{r['ram_bytes']:,} | {r['stack_bytes']} | {r['worst_step_cycles']:,} | "
                     f"{r['median_step_cycles']:,} | {r['cpu_mhz_for_10ms']} | "
                     f"{'yes' if r['bit_exact_vs_host'] else 'NO'} |")
    lines.append("")
    lines.append("Fitted growth (least squares on log-log over all horizons; in brackets "
                 "the slope between the two largest): " + ", ".join(
                     f"{k} ∝ N^{v['exponent']} [{v['exponent_last_pair']}]"
                     for k, v in table["fits"].items()))
    return "\n".join(lines)


# ----------------------------------------------------------------------------- CLI
def _parse_horizons(text: str) -> list[int]:
    from ..config.errors import ConfigError

    try:
        values = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise ConfigError("--horizons", f"must be a comma-separated list of integers, "
                          f"got {text!r}") from None
    if not values or min(values) < 1:
        raise ConfigError("--horizons", "needs at least one horizon >= 1")
    return sorted(set(values))


def report_command(args) -> int:
    """Entry point of ``rollmpc report`` (see cli.py)."""
    from .. import config as config_mod
    from ..config.errors import ConfigError

    if args.steps is not None and args.steps < 1:
        raise ConfigError("--steps", "must be >= 1")
    if args.sample_every < 1 or args.hardest < 0 or args.host_repeats < 1:
        raise ConfigError("--sample-every/--hardest/--host-repeats", "must be >= 1, >= 0, >= 1")
    for module, package in (("unicorn", "unicorn"), ("capstone", "capstone"),
                            ("elftools", "pyelftools")):
        try:
            __import__(module)
        except ImportError:
            raise RuntimeError(f"{package} is missing; install with: pip install "
                               "'rollmpc-codegen[target]'") from None
    root = private_root(args.build_dir or None)  # it receives configs too, not only builds
    progress = not args.quiet
    extra = tuple(args.extra_cflags.split()) if args.extra_cflags else ()
    if args.horizons:
        horizons = _parse_horizons(args.horizons)
        config_mod.load(args.config, args.precision)  # validate before the long run
        table = horizon_table(Path(args.config), horizons, args.precision, root, args.steps,
                              args.sample_every, args.hardest, progress, extra,
                              args.host_repeats)
        print(horizons_markdown(table))
        last = table["largest_measured_horizon_within_10ms_at_168MHz"]
        print(f"\nlargest measured horizon within 10 ms at {CPU_MHZ:g} MHz: {last}; "
              f"fitted limit N ~ {table['fitted_horizon_limit_10ms_at_168MHz']}")
        for part in table["parts"]:
            print(f"  {part['part']}: fits memory for N in {part['horizons_that_fit_memory']}")
        result = {"horizons": table}
    else:
        model, ctx = load_model(args.config, args.precision)
        result = measure(model, ctx, root, args.steps, args.sample_every, args.hardest,
                         progress, extra, args.host_repeats)
        print(summary(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1) + "\n")
    return 0
