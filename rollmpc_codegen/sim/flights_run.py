"""``rollmpc simulate --flights K``: K random flights (:mod:`.flight_plan`) of the generated C
on the host, each summarized, and what they add up to.

One scenario says little about a design whose solver can stop at its work budget: where a
run of TIME_LIMIT samples starts depends on the reference, and a long one can let an output
past a hard bound (docs/solver.md, "Limits"). Flights with
random levels show how often, within the scenario's range and pressing the envelope
(flight_plan.py). Per flight: the statuses, the longest run of TIME_LIMIT samples, the
hard-constraint violations (sim/metrics.py); over all of them, and over each kind, the
same and how many flights broke a hard bound. The host C's statuses are
the reference's and the emulated M4F's bit for bit, so ``rollmpc report --flights`` with
the same options flies the same flights with their cycles.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..config import ControllerConfig
from ..config.diagnostics import DesignWarning, messages
from ..host.build import build_host_controller
from ..pipeline import config_label, load_model
from ..qp.sanity import design_warnings
from .budget_cost import (budget_cost_check, flight_against_unbudgeted,
                          totals_against_unbudgeted, unbudgeted)
from .flight_plan import FlightPlan, by_kind
from .metrics import constraint_violations, longest_run, status_counts, work_stats
from .run_checks import infeasible_check, output_units, time_limit_check
from .scenario import scenario_reference
from .simulate import run_closed_loop, start_phase


@dataclass
class FlightsRun:
    """``summary`` is the JSON document: the settings, ``flights`` (one entry each) and
    ``totals``; ``warnings`` what the CLI prints under them (also ``summary["checks"]``)."""

    config: ControllerConfig
    ctx: dict
    summary: dict
    warnings: list[DesignWarning] = field(default_factory=list)


def _totals(entries: list[dict], outputs: list[str], work: dict | None) -> dict:
    counts: dict[str, int] = {}
    beyond = dict.fromkeys(outputs, 0.0)
    for e in entries:
        for name, n in e["status_counts"].items():
            counts[name] = counts.get(name, 0) + n
        for name, v in e["constraint_violations"]["y_max_beyond"].items():
            beyond[name] = max(beyond.get(name, 0.0), v)  # outputs, then signals
    samples = sum(e["samples"] for e in entries)
    return {"flights": len(entries), "samples": samples, "status_counts": counts,
            "optimal_percent": round(100.0 * counts.get("optimal", 0) / samples, 2),
            "longest_time_limit_run": max(e["longest_time_limit_run"] for e in entries),
            "flights_with_violations": sum(e["constraint_violations"]["total"] > 0
                                           for e in entries),
            "y_max_beyond": {name: v for name, v in beyond.items() if v > 0},
            "work": work}


def run_flights(config, *, flights: int, seed: int = 0,
                precision: str | None = None, steps: int | None = None,
                noise_std: float = 0.0, disturbance: float = 0.0, mismatch: float = 0.0,
                kinds: str = "both", build_dir: str | Path | None = None,
                against_unbudgeted: bool = False, progress=None) -> FlightsRun:
    """Fly ``flights`` random flights of ``steps`` samples each (default: the scenario's
    length) through one host build, from P_init() each, flight i seeded ``seed + i``, of
    the ``kinds`` of flight_plan.py; ``config`` a file, a ControllerConfig or a Design
    (pipeline.load_config). ``totals`` adds every flight up, ``by_kind`` each kind's.
    ``against_unbudgeted`` flies each flight again without a work budget and names the
    hard bounds the budget lost (sim/budget_cost.py)."""
    model, ctx = load_model(config, precision)
    cfg = model.config
    steps = steps if steps is not None else len(scenario_reference(cfg))
    plan = FlightPlan(flights=flights, seed=seed, noise_std=noise_std,
                      disturbance=disturbance, mismatch=mismatch, kinds=kinds)
    where = Path(build_dir) if build_dir else None
    controller = build_host_controller(ctx, where)
    free = (build_host_controller(load_model(unbudgeted(cfg))[1], where)
            if against_unbudgeted else None)
    entries, works, statuses, modes = [], [], [], []
    budget = ctx["solver"]["work_budget"]
    for fl in plan.plan(cfg, steps):
        label = f"simulate: flight {fl.index} ({fl.index + 1} of {flights})"
        log, entry = _fly(cfg, controller, plan, fl, steps, start_phase(progress, steps, label))
        entries.append({"flight": fl.index, "seed": fl.seed, "kind": fl.kind,
                        "levels": fl.levels.tolist(),
                        "plant_mismatch": None if fl.mismatch is None else fl.mismatch.as_dict(),
                        **entry, "work": work_stats(log.work, budget)})
        if free is not None:
            flight_against_unbudgeted(entries[-1], _fly(cfg, free, plan, fl, steps, start_phase(
                progress, steps, f"{label}, unbudgeted"))[1], cfg.feasibility_tol)
        works.append(log.work)
        statuses.append(log.status)
        modes.append(log.mode)
    design = design_warnings(model)
    summary = {"config": config_label(config), "precision": ctx["precision"],
               "solver": dict(ctx["solver"]), "sample_time": cfg.sample_time,
               "horizon": cfg.horizon, "flight_plan": plan.as_dict(), "steps": steps,
               "design_warnings": messages(design),
               "flights": entries,
               "totals": _totals(entries, list(cfg.outputs),
                                 work_stats(np.concatenate(works), budget)),
               "by_kind": {kind: _totals([entries[i] for i in group], list(cfg.outputs),
                                         work_stats(np.concatenate([works[i] for i in group]),
                                                    budget))
                           for kind, group in by_kind(range(len(entries)),
                                                      lambda i: entries[i]["kind"]).items()}}
    if free is not None:
        summary["totals"]["against_unbudgeted"] = totals_against_unbudgeted(entries)
    t = summary["totals"]
    found = [*time_limit_check(t["status_counts"], t["samples"], t["longest_time_limit_run"],
                               cfg.horizon),
             *infeasible_check(cfg, np.concatenate(statuses), np.concatenate(modes),
                               t["y_max_beyond"]),
             *(budget_cost_check(entries, output_units(cfg)) if free is not None else []),
             *design]
    summary["checks"] = [w.as_dict() for w in found]
    return FlightsRun(config=cfg, ctx=ctx, summary=summary, warnings=found)


def _fly(cfg: ControllerConfig, controller, plan: FlightPlan, fl, steps: int, progress):
    """One flight of ``controller`` from P_init(): (log, its figures)."""
    controller.init()
    log = run_closed_loop(cfg, controller, steps=steps, info=controller.info,
                          progress=progress, **plan.loop_options(fl))
    return log, {"samples": int(len(log.t)), "status_counts": status_counts(log.status),
                 "longest_time_limit_run": longest_run(log.status),
                 "constraint_violations": constraint_violations(cfg, log)}
