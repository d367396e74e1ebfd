"""``rollmpc certify``: a work certificate of a design, from its operating region sampled
in closed loop (docs/solver.md, "Work certificate").

1. **Sample** (certify_sampling.py): ``loops`` closed loops of the design as generated,
   ``steps`` samples each, from the random flights of ``rollmpc simulate --flights``
   (references inside the scenario's range and pressing the envelope, the scheduler's
   modes, noise, disturbance, mismatch as given), seeded ``seed``; every sample's QP is
   solved by the NumPy reference (or the host C: the same work, bit for bit).
2. **Measure**: the work per QP (median, p99, p99.9, max) against the work budget, the
   TIME_LIMIT stops, and the QPs that needed the most, each solved again from its state
   with no budget: its loop, step, mode, state estimate and reference.
3. **Bound** (certify_bound.py): the probability of a stop, per loop (independent loops:
   holds as stated for loops drawn like these) and per sample (treats a loop's samples as
   independent: optimistic, see there), at ``confidence``.
4. **Conclude**: the design fits when no sampled QP stopped; when it does not, what
   would fit the most any of them needed (qp/budget.py ``what_fits_need``: the share, the
   clock, the horizon or the move blocking), leaving out the QPs that the solver does not
   finish even without a budget (it ends at its sweep cap, MAX_ITER): they are named
   apart, since no budget fits them.

No exact worst case is computed: the region partition of complexity certification
enumerates the critical regions of a multiparametric QP, which for the examples' QPs
(n = 20-120 variables, m = 40-500 rows) does not fit the time; the sampled bound is what
the certificate states.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..pipeline import config_label, load_model
from ..qp.budget import what_fits_need
from ..qp.work import cycles_per_work_unit
from ..sim.flight_plan import FlightPlan
from ..sim.metrics import longest_run
from ..status import MAX_ITER, STATUS_NAMES, TIME_LIMIT
from .certify_bound import upper_bound
from .certify_sampling import sample

DEFAULT_LOOPS = 20
DEFAULT_STEPS = 600  # per loop, at least 3 of the scenario's segments, at most its length
SEGMENTS_PER_LOOP = 3
DEFAULT_CONFIDENCE = 0.95
WORST_LISTED = 5
UNFINISHED = (MAX_ITER, TIME_LIMIT)  # the statuses of a solve that did not finish


def _quantiles(work: np.ndarray, budget: int) -> dict:
    q = {name: int(np.percentile(work, p, method="higher"))
         for name, p in (("median", 50), ("p99", 99), ("p99_9", 99.9), ("max", 100))}
    return {**q, "budget": int(budget),
            "of_budget": {k: round(v / budget, 4) for k, v in q.items()}}


def _worst(kept, plan: FlightPlan, modes: list[str], budget: int) -> list[dict]:
    return [{"loop": e.loop, "seed": plan.seed + e.loop, "kind": plan.kind_of(plan.seed + e.loop),
             "step": e.step, "mode": modes[e.mode], "status": STATUS_NAMES[e.status],
             "work": e.work, "needed": e.needed,
             "needed_status": STATUS_NAMES[e.needed_status],
             "needed_of_budget": round(e.needed / budget, 3),
             "xhat": e.xhat, "reference": e.reference}
            for e in kept[:WORST_LISTED]]


@dataclass
class Certificate:
    """The certificate as a dict (``data``, the JSON of ``rollmpc certify --json``)."""

    data: dict

    @property
    def fits(self) -> bool:
        return self.data["fits"]

    def line(self) -> str:
        """The one line ``rollmpc generate --certify`` prints."""
        d, w = self.data, self.data["work"]
        b = d["bounds"]
        verdict = "fits" if d["fits"] else f"DOES NOT fit ({d['what_fits']})"
        return (f"work certificate ({d['samples']:,} QPs of {d['loops']} closed loops, seed "
                f"{d['seed']}): max {w['of_budget']['max']:.2f}, p99.9 "
                f"{w['of_budget']['p99_9']:.2f} of the budget; {d['time_limit']['samples']} "
                f"TIME_LIMIT; P(TIME_LIMIT) <= {b['per_sample']:.2g} per sample (samples "
                f"taken as independent), <= {b['per_loop']:.2g} per loop, at "
                f"{100 * d['confidence']:g} %: {verdict}")

    def summary_lines(self) -> list[str]:
        """What ``rollmpc certify`` prints."""
        d, w, b, t = (self.data[k] for k in ("design", "work", "bounds", "time_limit"))
        c = self.data
        lines = [f"rollmpc certify: {d['config']} ({d['precision']}), work budget "
                 f"{w['budget']:,} units (~{w['budget'] * d['cycles_per_work_unit']:,.0f} cycles on the {d['core']}, "
                 f"{d['budget_share']:g} of Ts = {d['sample_time']:g} s at {d['cpu_mhz']:g} MHz)",
                 f"  sampled: {c['samples']:,} QPs, {c['loops']} closed loops of {c['steps']} "
                 f"samples (seed {c['seed']}, flights {', '.join(c['kinds'])}; noise "
                 f"{c['perturbations']['noise_std']:g}, disturbance "
                 f"{c['perturbations']['disturbance']:g}, mismatch "
                 f"{c['perturbations']['mismatch']:g}), solved by the {c['engine']}; modes "
                 + ", ".join(f"{m} {n}" for m, n in c["samples_by_mode"].items()),
                 "  work per QP (units, x budget; a stopped QP's as it needs unbudgeted"
                 + (f", {w['stops_not_solved_again']} stops at the budget: at least" if
                    w["stops_not_solved_again"] else "") + "): " + ", ".join(
                     f"{k.replace('_', '.')} {w[k]:,} ({w['of_budget'][k]:.3g})"
                     for k in ("median", "p99", "p99_9", "max")),
                 f"  TIME_LIMIT: {t['samples']} samples in {t['loops']} of {c['loops']} loops "
                 f"(longest run {t['longest_run']})"]
        for e in c["worst"]:
            lines.append(f"  needs {e['needed']:,} units ({e['needed_of_budget']:.2f} x budget, "
                         f"{e['needed_status']} unbudgeted; {e['status']} with the budget): "
                         f"loop {e['loop']} (seed {e['seed']}, {e['kind']}), step {e['step']}, "
                         f"mode {e['mode']}, reference {_short(e['reference'])}"
                         + ("" if e["xhat"] is None else f", state {_short(e['xhat'])}"))
        lines += [f"  P(TIME_LIMIT) <= {b['per_sample']:.3g} per sample, at "
                  f"{100 * c['confidence']:g} % confidence, if the {c['samples']:,} samples "
                  "were independent (closed-loop samples are not: optimistic)",
                  f"  P(a loop of {c['steps']} samples meets TIME_LIMIT) <= {b['per_loop']:.3g}, "
                  f"at {100 * c['confidence']:g} % ({c['loops']} independent loops)",
                  f"  verdict: {'fits' if c['fits'] else 'DOES NOT fit: ' + c['what_fits']}"]
        return lines

    def as_dict(self) -> dict:
        return self.data


def _what_fits(cfg, needed: int, budget: int, unfinished: int) -> str:
    text = (what_fits_need(cfg, needed) if needed > budget else
            "what fits: the budget, for every stop that more work finishes")
    if unfinished:
        text += (f"; {unfinished} stopped QPs end at {STATUS_NAMES[MAX_ITER]} even without a "
                 "budget: no budget fits them")
    return text


def _short(values) -> str:
    return "[" + ", ".join(f"{v:.4g}" for v in values[:8]) + (", ...]" if len(values) > 8 else "]")


def certify(config, *, loops: int = DEFAULT_LOOPS, steps: int | None = None, seed: int = 0,
            kinds: str = "both", noise_std: float = 0.0, disturbance: float = 0.0,
            mismatch: float = 0.0, confidence: float = DEFAULT_CONFIDENCE,
            engine: str = "reference", precision: str | None = None,
            build_dir: str | Path | None = None, progress=None,
            loaded: tuple | None = None) -> Certificate:
    """The work certificate of ``config`` (a file, a ControllerConfig or a Design; see the
    module docstring). ``steps``: samples per loop (default: :data:`DEFAULT_STEPS`, or
    :data:`SEGMENTS_PER_LOOP` of the scenario's segments when longer, and at most the
    scenario's length); ``loaded``: its (model, ctx) when built already
    (``rollmpc generate --certify``)."""
    from ..sim.scenario import scenario_reference

    if loops < 1:
        raise ValueError(f"loops must be >= 1, got {loops}")
    model, ctx = loaded or load_model(config, precision)
    cfg = model.config
    segment = int(round(cfg.simulation.segment_s / cfg.sample_time))
    steps = steps or min(max(DEFAULT_STEPS, SEGMENTS_PER_LOOP * segment),
                         len(scenario_reference(cfg)))
    plan = FlightPlan(flights=loops, seed=seed, noise_std=noise_std, disturbance=disturbance,
                      mismatch=mismatch, kinds=kinds)
    got = sample(model, ctx, plan, steps, engine=engine, build_dir=build_dir, progress=progress)
    budget = int(ctx["solver"]["work_budget"])
    # a stopped QP solved again counts with the work it needs; the others at the budget,
    # which they need at least
    for e in got.kept:
        if e.status == TIME_LIMIT:
            got.work[e.loop][e.step] = max(e.needed, budget)
    unsolved = sum(int(np.count_nonzero(s == TIME_LIMIT)) for s in got.status) - sum(
        e.status == TIME_LIMIT for e in got.kept)
    work, status, mode = (np.concatenate(x) for x in (got.work, got.status, got.mode))
    stops = [int(np.count_nonzero(s == TIME_LIMIT)) for s in got.status]
    names = [m.name for m in cfg.modes]
    # a QP the solver does not finish even without a budget (it ends at the sweep cap) is
    # not one more budget fits: what fits is sized on the others
    finished = [e.needed for e in got.kept if e.needed_status not in UNFINISHED]
    unfinished = sum(e.needed_status in UNFINISHED for e in got.kept)
    needed = max(finished, default=0)
    fits = sum(stops) == 0
    data = {
        "design": {"config": config_label(config), "precision": ctx["precision"],
                   "sample_time": cfg.sample_time, "cpu_mhz": cfg.target.cpu_mhz,
                   "core": cfg.target.core_decl.label,
                   "cycles_per_work_unit": cycles_per_work_unit(cfg),
                   "budget_share": cfg.solver.budget_share, "horizon": cfg.horizon},
        "loops": loops, "steps": steps, "samples": int(work.size), "seed": seed,
        "kinds": sorted({plan.kind_of(seed + i) for i in range(loops)},
                        key=("inside", "envelope").index),
        "perturbations": {"noise_std": noise_std, "disturbance": disturbance,
                          "mismatch": mismatch},
        "engine": engine, "confidence": confidence,
        "samples_by_mode": {names[j]: int(np.count_nonzero(mode == j))
                            for j in range(len(names)) if np.any(mode == j)},
        "work": {**_quantiles(work, budget), "stops_not_solved_again": unsolved},
        "time_limit": {"samples": sum(stops), "loops": sum(n > 0 for n in stops),
                       "longest_run": max(longest_run(s) for s in got.status)},
        "bounds": {"per_sample": upper_bound(sum(stops), int(work.size), confidence),
                   "per_loop": upper_bound(sum(n > 0 for n in stops), loops, confidence),
                   "assumption": "per loop: independent loops drawn like these; per sample: "
                                 "the samples taken as independent, which closed-loop "
                                 "samples are not"},
        "worst": _worst(got.kept, plan, names, budget),
        "needed_max": int(needed),
        "unfinished_without_budget": int(unfinished),
        "fits": fits,
        "what_fits": None if fits else _what_fits(cfg, needed, budget, unfinished),
    }
    return Certificate(data)
