"""What the work budget costs in hard bounds: ``rollmpc simulate --flights K
--against-unbudgeted`` flies every flight twice, with the design's budget and with a copy
that has none (``solver.work_budget`` at its largest, UNBOUNDED_WORK), and compares how far
each flight passed each hard bound.

A plan keeps the bounds on the model, so under noise and mismatch even the unbudgeted loop
passes some; what the budget adds is the difference (a TIME_LIMIT sample's point need not
meet the output bounds: docs/solver.md, "Work budget").  A bound is *lost to the budget* on
a flight where the budgeted loop passed it by more than LOST_RATIO beyond the unbudgeted
loop's excursion on the same flight, and by more than the solver's tolerance (the two
loops' trajectories part at their first differing command, so equal excursions are rare
but close).  This is issue 44's goal, as a command: "no hard output bound passed by more
than the unbudgeted loop passes it on the same flight".
"""
from __future__ import annotations

from dataclasses import replace

from ..config import ControllerConfig
from ..config.diagnostics import DesignWarning
from ..qp.work import UNBOUNDED_WORK

LOST_RATIO = 0.01  # of the unbudgeted excursion: closer than this is the same excursion


def unbudgeted(cfg: ControllerConfig) -> ControllerConfig:
    """``cfg`` with no work budget (UNBOUNDED_WORK: in effect none)."""
    return replace(cfg, solver=replace(cfg.solver, work_budget=UNBOUNDED_WORK))


def bounds_lost(budgeted: dict, free: dict, tol: float) -> dict:
    """{bound name: [budgeted excursion, unbudgeted excursion]} of the bounds the budgeted
    flight passed further (``y_max_beyond`` of each: metrics.constraint_violations)."""
    return {name: [v, free.get(name, 0.0)] for name, v in budgeted.items()
            if v - free.get(name, 0.0) > max(tol, LOST_RATIO * free.get(name, 0.0))}


def flight_against_unbudgeted(entry: dict, free: dict, tol: float) -> None:
    """Add the unbudgeted flight's figures and the bounds lost to one flight's entry."""
    entry["unbudgeted"] = free
    entry["bounds_lost_to_budget"] = bounds_lost(
        entry["constraint_violations"]["y_max_beyond"],
        free["constraint_violations"]["y_max_beyond"], tol)


def totals_against_unbudgeted(entries: list[dict]) -> dict:
    """Over the flights: how many lost a bound to the budget, and the unbudgeted loops'
    own figures."""
    free = [e["unbudgeted"] for e in entries]
    samples = sum(f["samples"] for f in free)
    optimal = sum(f["status_counts"].get("optimal", 0) for f in free)
    return {"flights_losing_bounds": sum(bool(e["bounds_lost_to_budget"]) for e in entries),
            "unbudgeted_flights_with_violations": sum(
                f["constraint_violations"]["total"] > 0 for f in free),
            "unbudgeted_optimal_percent": round(100.0 * optimal / samples, 2)}


def budget_cost_check(entries: list[dict], unit: dict) -> list[DesignWarning]:
    """``bound_lost_to_budget`` (docs/checks.md) when some flight lost a bound, naming the
    flight that lost the most; ``unit``: each output's unit ("" for a signal)."""
    losing = [e for e in entries if e["bounds_lost_to_budget"]]
    if not losing:
        return []
    worst = max(losing, key=lambda e: max(v - u for v, u in e["bounds_lost_to_budget"].values()))
    name, (v, u) = max(worst["bounds_lost_to_budget"].items(), key=lambda kv: kv[1][0] - kv[1][1])
    sep = f" {unit[name]}" if unit.get(name) else ""
    return [DesignWarning(
        "bound_lost_to_budget", "solver.budget_share",
        f"on {len(losing)} of {len(entries)} flights the work budget let a hard bound go "
        f"further than the same flight without a budget (flight {worst['flight']}, seed "
        f"{worst['seed']}: {name} {v:.3g}{sep} past it, against {u:.3g}{sep}): the samples "
        f"that stop at TIME_LIMIT cost it. Give the solver more of Ts (solver.budget_share, "
        f"a faster target.part) or a smaller QP; `rollmpc certify` says what fits")]
