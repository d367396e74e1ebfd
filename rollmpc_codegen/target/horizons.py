"""``rollmpc report --horizons``: the measurement of :mod:`rollmpc_codegen.target.measure`
repeated with the config's horizon overridden, the growth of each figure in N fitted
(log-log least squares), the horizon that still fits the budget (the config's sample time
at its ``target.cpu_mhz``, measure.budget_verdict), and which declared parts (parts.py)
hold each horizon in memory.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import yaml

from ..codegen.render import render_sources
from ..config.errors import ConfigError
from ..parts import PARTS
from ..pipeline import load_model
from ..sim.simulate import start_phase
from .measure import measure

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
                  progress=None, part: str | None = None, **measure_options) -> dict:
    """Per horizon: generation time, flash, RAM, worst/median cycles; growth fits; parts.
    A horizon the generator refuses (say, the config's explicit work budget is below that
    horizon's unconstrained step) goes to ``refused`` with the error, and the others are
    still measured. ``measure_options`` are the keywords of
    :func:`rollmpc_codegen.target.measure.measure`."""
    rows, refused = [], []
    for h in horizons:
        start_phase(progress, 0, f"report: horizon {h}")
        path = config_with_horizon(config, h, Path(build_root) / "horizons")
        t0 = time.perf_counter()
        try:
            model, ctx = load_model(path, precision, part)
        except ConfigError as exc:  # e.g. a work budget below this horizon's unconstrained step
            refused.append({"horizon": h, "error": str(exc)})
            continue
        render_sources(ctx)
        gen_s = time.perf_counter() - t0
        rep = measure(model, ctx, build_root, progress=progress, **measure_options)
        rows.append({"horizon": h, "generation_s": round(gen_s, 2),
                     **{k: rep[k] for k in ("flash_bytes", "ram_bytes", "ctrl_bytes",
                                            "stack_bytes", "worst_step_cycles",
                                            "worst_step_instructions", "median_step_cycles",
                                            "cpu_mhz_needed", "bit_exact_vs_host")},
                     "budget_cycles": rep["budget"]["cycles_per_sample"],
                     "fits_budget": rep["budget"]["worst_fits"]})
        # the same for every horizon: the config's Ts and target.cpu_mhz
        budget = {k: rep["budget"][k] for k in ("cpu_mhz", "sample_time", "cycles_per_sample")}
    if not rows:
        raise ConfigError("--horizons", "the generator refuses every horizon: "
                          + "; ".join(f"N = {r['horizon']}: {r['error']}" for r in refused))
    ns = [r["horizon"] for r in rows]
    keys = ("generation_s", "flash_bytes", "ram_bytes", "worst_step_cycles",
            "median_step_cycles")
    fits = {key: loglog_fit(ns, [r[key] for r in rows]) for key in keys}
    for key in keys:  # the slope between the two largest horizons (the asymptotic trend)
        fits[key]["exponent_last_pair"] = (loglog_fit(ns[-2:], [r[key] for r in rows[-2:]])
                                           ["exponent"] if len(rows) > 1 else None)
    n_max = horizon_limit(ns, [r["worst_step_cycles"] for r in rows], budget["cycles_per_sample"])
    parts = []  # the declared parts' flash and the region a static instance lives in
    for part in PARTS.values():
        ok = [r["horizon"] for r in rows if r["flash_bytes"] <= part.flash.kib * 1024
              and r["ram_bytes"] <= part.ram.kib * 1024]
        parts.append({"part": part.label, "flash_kib": part.flash.kib,
                      "ram_kib": part.ram.kib, "ram_region": part.ram.name,
                      "horizons_that_fit_memory": ok})
    fitting = [r["horizon"] for r in rows if r["fits_budget"]]
    return {"rows": rows, "refused": refused, "fits": fits, "parts": parts, "budget": budget,
            "largest_measured_horizon_within_budget": max(fitting) if fitting else None,
            "fitted_horizon_limit": n_max}
