"""One measurement of ``rollmpc report`` (:mod:`rollmpc_codegen.target.report`): the target
image's flash, RAM and stack, then the scenario or each flight of a
:class:`~rollmpc_codegen.sim.flight_plan.FlightPlan` recorded on the host and replayed on
the emulated core of the config's target (parts.py), with the cycles of the counted steps
judged against the config's own sample time and its ``target:`` section (clock; flash and
RAM when given).
"""
from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np

from .. import __version__
from ..qp.work import STEP_FIXED_UNITS
from ..sim.flight_plan import FlightPlan, by_kind
from ..sim.metrics import longest_run, status_counts
from .build import (CROSS_CC, build_target, core_of, image_sizes, target_cflags,
                    largest_symbols, worst_stack)
from .flights import FlightRun, fly
from .replay import INFO_FIELDS, HostRecord
from .build import target_layout


def _toolchain_version() -> str:
    try:
        out = subprocess.run([CROSS_CC, "--version"], capture_output=True, text=True).stdout
        return out.splitlines()[0].strip()
    except (OSError, IndexError):
        return "unknown"


def _top_functions(counts, limit: int = 20) -> list[dict]:
    rows = sorted(counts.by_function.items(), key=lambda kv: -kv[1][1])[:limit]
    return [{"function": name, "cycles": int(cyc), "instructions": int(ins),
             "share": round(cyc / counts.cycles, 4) if counts.cycles else 0.0}
            for name, (ins, cyc) in rows]


def _other_share(counts, top: list[dict]) -> float:
    """The share of the step's cycles in the functions _top_functions() left out (``top``)."""
    rest = sum(cyc for _ins, cyc in counts.by_function.values()) - sum(f["cycles"] for f in top)
    return round(rest / counts.cycles, 4) if counts.cycles else 0.0


def budget_verdict(cfg, worst_cycles: int) -> dict:
    """The worst step against one sample time at the config's ``target.cpu_mhz``."""
    budget = cfg.cycles_per_sample
    return {"target": cfg.target.label, "part": cfg.target.part, "core": cfg.target.core,
            "cpu_mhz": cfg.target.cpu_mhz, "sample_time": cfg.sample_time,
            "cycles_per_sample": budget, "worst_fits": bool(worst_cycles <= budget),
            "worst_load_percent": round(100.0 * worst_cycles / budget, 1)}


def memory_goals(cfg, flash_bytes: int, ram_bytes: int, ctrl_bytes: int) -> dict:
    """The flash and RAM limits the config's ``target:`` section declares, met or not
    (none declared: no verdict); RAM bounds the image and the instance alone."""
    goals = {}
    if cfg.target.flash_kib is not None:
        limit = int(cfg.target.flash_kib * 1024)
        goals[f"flash_bytes<={limit}"] = bool(flash_bytes <= limit)
    if cfg.target.ram_kib is not None:
        limit = int(cfg.target.ram_kib * 1024)
        goals[f"ram_bytes<={limit}"] = bool(ram_bytes <= limit)
        goals[f"ctrl_bytes<={limit}"] = bool(ctrl_bytes <= limit)
    return goals


def cycle_model_text(core) -> str:
    """What the cycles are (docs/target.md "Parts": what each model includes)."""
    return (f"{core.label}: cycle model {core.cycle_model} (target/cycle_models.py), zero "
            f"wait states; treat as {core.cycle_band}")


def cycles_by_mode(run: FlightRun, ctx: dict) -> dict:
    """Per mode of one flight: the worst counted step and the median of the sampled steps
    (what ``--peer`` sets beside the peer's figures)."""
    out = {}
    for j, mode in enumerate(ctx["modes"]):
        counted = [k for k in run.run.counts if run.record.info[k]["mode"] == j]
        if not counted:
            continue
        sampled = [run.run.counts[k].cycles for k in run.sweep
                   if run.record.info[k]["mode"] == j]
        worst = max(counted, key=lambda k: (run.run.counts[k].cycles, -k))
        out[mode["name"]] = {"worst_cycles": int(run.run.counts[worst].cycles),
                             "worst_step": int(worst),
                             "median_cycles": int(np.median(sampled)) if sampled else None,
                             "steps_counted": len(counted)}
    return out


def cycles_per_work(runs) -> dict:
    """Cycles per work unit (qp/work.py) on the counted steps that solved a QP, over every
    flight: its largest and median ratio, and the flight and step of the largest (the
    calibration of the core's cycles per work unit, parts.py; docs/solver.md "Work budget").
    A step's ratio is its cycles over its work plus STEP_FIXED_UNITS: the auto budget is
    the share of Ts over the core's rate less those units, left for the step outside the
    solver, so a step fits the share whenever its ratio is within the rate."""
    ratios = {(f.flight.index, k): c.cycles / (f.record.info[k]["work"] + STEP_FIXED_UNITS)
              for f in runs for k, c in f.run.counts.items() if f.record.info[k]["work"] > 0}
    if not ratios:
        return {"max": None, "median": None, "flight_of_max": None, "step_of_max": None,
                "steps": 0}
    worst = max(ratios, key=lambda fk: (ratios[fk], -fk[1]))
    return {"max": round(ratios[worst], 2),
            "median": round(float(np.median(list(ratios.values()))), 2),
            "flight_of_max": worst[0], "step_of_max": int(worst[1]), "steps": len(ratios)}


def state_mismatch(runs) -> dict | None:
    """The first flight whose instance differs from the host's: the step, the members
    and how many of its steps differ (None: every instance equal, every step)."""
    for f in runs:
        found = f.run.state_mismatch()
        if found is not None:
            return {"flight": f.flight.index, **found}
    return None


def measure(model, ctx: dict, build_root: Path, *, plan: FlightPlan = FlightPlan(),
            steps: int | None = None, sample_every: int = 20, hardest: int = 10,
            progress=None, extra_cflags: tuple[str, ...] = (), host_repeats: int = 5,
            record: HostRecord | None = None) -> dict:
    """The full report of one generated controller (see the module docstring); with
    flights, the step figures are those of the overall worst flight, the cycle figures
    over every flight, and ``flights`` has each flight's. ``record`` replaces the host
    run of the scenario (``rollmpc report --flight``: a flown flight's inputs)."""
    cfg = model.config
    build = build_target(ctx, build_root, extra_cflags=extra_cflags)
    layout = target_layout(build, ctx)
    sizes = image_sizes(build.elf)
    stack = worst_stack(build, f"{ctx['prefix']}_step")
    stack_entry = worst_stack(build, f"{ctx['prefix']}_target_step")  # + the harness frame
    flights = plan.plan(cfg, steps)
    runs: list[FlightRun] = []
    for flight in flights:
        label = ("report" if flight.index is None else
                 f"report: flight {flight.index} ({flight.index + 1} of {len(flights)})")
        runs.append(fly(model, ctx, build, build_root, flight, plan, steps=steps,
                        hardest=hardest, sample_every=sample_every,
                        host_repeats=host_repeats, progress=progress, label=label,
                        record=record, layout=layout))
    worst_run = max(runs, key=lambda f: f.worst_cycles)  # the first flight on a tie
    worst_k, record = worst_run.worst_step, worst_run.record
    worst = worst_run.run.counts[worst_k]
    counts = worst_run.run.counts
    sweep_cycles = np.concatenate([f.sweep_counts("cycles") for f in runs])
    sweep_instr = np.concatenate([f.sweep_counts("instructions") for f in runs])
    ts = cfg.sample_time
    bit_exact = all(f.bit_exact for f in runs)
    mismatched = [f for f in runs if f.run.mismatches]
    ctrl_bytes = len(record.final_state)
    info_w = record.info[worst_k]
    top = _top_functions(worst)
    report = {
        "config_hash": ctx["config_hash"],
        "generator": f"rollmpc-codegen {__version__}",
        "precision": ctx["precision"],
        "horizon": ctx["horizon"],
        "sample_time": ts,
        "toolchain": _toolchain_version(),
        "cflags": " ".join(target_cflags(ctx, extra_cflags)),
        "flash_bytes": sizes["flash_bytes"],
        "ram_bytes": sizes["ram_bytes"],
        "ctrl_bytes": ctrl_bytes,
        "stack_bytes": stack["bytes"],
        "stack_path": stack["path"],
        "stack_entry_bytes": stack_entry["bytes"],
        "stack_measured_bytes": max(f.run.stack_measured for f in runs),
        "largest_symbols": largest_symbols(build.elf, 10),
        "perturbations": plan.as_dict(),
        "plant_mismatch": (None if plan.flights or flights[0].mismatch is None
                           else flights[0].mismatch.as_dict()),
        "steps_emulated": sum(f.run.steps for f in runs),
        "steps_counted": sum(len(f.run.counts) for f in runs),
        "hardest_steps": worst_run.hard,
        "sample_every": sample_every,
        "host_repeats": host_repeats,
        "bit_exact_vs_host": bool(bit_exact),
        "state_bit_exact": all(f.run.state_equal for f in runs),
        "state_mismatch": state_mismatch(runs),
        "kernels": layout.kernels,
        "mismatches": sum(len(f.run.mismatches) for f in runs),
        "first_mismatches": ([list(m) for m in mismatched[0].run.mismatches[:5]]
                             if mismatched else []),
        "worst_flight": worst_run.flight.index,
        "worst_step": int(worst_k),
        "worst_step_mode": int(info_w["mode"]),
        "worst_step_host": {k: int(info_w[k]) for k in (*INFO_FIELDS, "solve_ticks")},
        "work_budget": int(ctx["solver"]["work_budget"]),
        "cycles_per_work_unit": cycles_per_work(runs),
        "statuses": status_counts([info["status"] for f in runs for info in f.record.info]),
        "longest_time_limit_run": max(longest_run([info["status"] for info in f.record.info])
                                      for f in runs),
        "worst_step_instructions": int(worst.instructions),
        "worst_step_cycles": int(worst.cycles),
        "median_step_cycles": int(np.median(sweep_cycles)),
        "median_step_instructions": int(np.median(sweep_instr)),
        "cpu_mhz_needed": round(worst.cycles / ts / 1e6, 2),
        "budget": budget_verdict(cfg, int(worst.cycles)),
        "goals": memory_goals(cfg, sizes["flash_bytes"], sizes["ram_bytes"], ctrl_bytes),
        "worst_step_top_functions": top,
        "worst_step_other_functions_share": _other_share(worst, top),
        "by_mode": cycles_by_mode(worst_run, ctx),
        "hardest_step_cycles": [
            {"step": k, "cycles": int(counts[k].cycles),
             "instructions": int(counts[k].instructions),
             **{f: int(record.info[k][f]) for f in ("mode", "status", "iterations",
                                                   "polish_iterations", "active", "work")},
             "host_solve_us": round(record.info[k]["solve_ticks"] / 1000.0, 1)}
            for k in sorted(worst_run.hard, key=lambda k: -counts[k].cycles)],
        "cycle_model": cycle_model_text(core_of(ctx)),
    }
    if plan.flights:
        report["flights"] = [f.summary() for f in runs]
        report["by_kind"] = {kind: kind_figures(group)
                             for kind, group in by_kind(runs, lambda f: f.flight.kind).items()}
    return report


def kind_figures(runs) -> dict:
    """One kind's flights: their worst counted step, statuses and longest TIME_LIMIT run."""
    worst = max(runs, key=lambda f: f.worst_cycles)
    statuses = [info["status"] for f in runs for info in f.record.info]
    counts = status_counts(statuses)
    return {"flights": len(runs), "worst_step_cycles": worst.worst_cycles,
            "worst_flight": worst.flight.index, "statuses": counts,
            "optimal_percent": round(100.0 * counts.get("optimal", 0) / len(statuses), 2),
            "longest_time_limit_run": max(longest_run([i["status"] for i in f.record.info])
                                          for f in runs),
            "bit_exact_vs_host": all(f.bit_exact for f in runs)}
