"""One measurement of ``rollmpc report`` (:mod:`rollmpc_codegen.target.report`): the target
image's flash, RAM and stack, then the host run replayed on the emulated Cortex-M4F
(:mod:`rollmpc_codegen.target.replay`), with the cycles of the counted steps and the
verdict against a 168 MHz part.
"""
from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np

from .. import __version__
from .build import (CORTEX_M4F, CROSS_CC, TARGET_CFLAGS, build_target, image_sizes,
                    largest_symbols, worst_stack)
from .replay import INFO_FIELDS, record_host_run, replay_on_target, select_steps

CPU_MHZ = 168.0
GOALS = {"flash_bytes": 256 * 1024, "ram_bytes": 32 * 1024, "worst_step_cycles": 1_680_000}


def _toolchain_version() -> str:
    try:
        out = subprocess.run([CROSS_CC, "--version"], capture_output=True, text=True).stdout
        return out.splitlines()[0].strip()
    except (OSError, IndexError):
        return "unknown"


def _top_functions(counts, limit: int = 16) -> list[dict]:
    rows = sorted(counts.by_function.items(), key=lambda kv: -kv[1][1])[:limit]
    return [{"function": name, "cycles": int(cyc), "instructions": int(ins),
             "share": round(cyc / counts.cycles, 4) if counts.cycles else 0.0}
            for name, (ins, cyc) in rows]


def cycles_per_work(counts: dict, info: list) -> dict:
    """Estimated cycles per work unit (qp/work.py) on the counted steps that solved a QP:
    its largest and median ratio, and the step of the largest (the calibration of
    CYCLES_PER_WORK_UNIT, docs/solver.md "Work budget")."""
    ratios = {k: c.cycles / info[k]["work"] for k, c in counts.items() if info[k]["work"] > 0}
    if not ratios:
        return {"max": None, "median": None, "step_of_max": None, "steps": 0}
    worst = max(ratios, key=lambda k: (ratios[k], -k))
    return {"max": round(ratios[worst], 2), "median": round(float(np.median(list(ratios.values()))), 2),
            "step_of_max": int(worst), "steps": len(ratios)}


def measure(model, ctx: dict, build_root: Path, *, steps: int | None = None,
            sample_every: int = 20, hardest: int = 10, progress=None,
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
        "work_budget": int(ctx["solver"]["work_budget"]),
        "cycles_per_work_unit": cycles_per_work(run.counts, record.info),
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
             **{f: int(record.info[k][f]) for f in ("mode", "status", "iterations",
                                                   "polish_iterations", "active", "work")},
             "host_solve_us": round(record.info[k]["solve_ticks"] / 1000.0, 1)}
            for k in sorted(hard, key=lambda k: -run.counts[k].cycles)],
        "cycle_model": "Cortex-M4 TRM weights, zero wait states, taken branch +2 "
                       "(shared/notes/mcu-cycle-counting.md); treat as +/-20 %",
    }
    return report
