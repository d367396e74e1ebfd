"""Random-QP campaigns through the compiled C solver (issue 4, items 1 and 2).

Each campaign draws seeded random controllers (:mod:`rollmpc_codegen.verify.random_configs`),
builds each once per precision, and pushes many QPs (states and previews) of it through
``P_solve_qp``.  Every QP is checked against an independent extended-precision solution
(:mod:`rollmpc_codegen.qp.exact`).

* Feasible campaign: status must be OPTIMAL and the error
  ``max|U_c - U*| / max(1, max|U*|)`` within :func:`error_bound`.  A failing float QP
  also gets its stored-data floor (:mod:`rollmpc_codegen.verify.float_floor`).  QPs come in pairs: a
  cold solve (fresh ``P_init``) and a warm one, the next sample (state moved, preview
  shifted), solved right after it as in closed loop.
* Infeasible campaign: output bounds no input sequence in the box can meet (by a phase-1
  LP margin).  No OPTIMAL allowed; U finite and inside the input bounds; and the next
  feasible QP on the same controller must give exactly (bit for bit, same status and
  iterations) what a freshly initialised controller gives: no sticky warm start.

The YAML of every drawn config is written next to the builds, so any failure can be
replayed with ``rollmpc generate`` and the recorded (x, r).
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..host.build import build_host_controller
from ..qp.exact import infeasibility_margin, qp_data, relative_error, solve_exact
from .float_floor import FLOOR_CLASSES, floor_class, stored_data_floor
from ..pipeline import load_model
from .random_configs import COND_DECADES, RandomConfig, draw_instance, random_config
from ..status import OPTIMAL, STATUS_NAMES

PRECISIONS = ("double", "float")
FLOAT_BOUND = 1e-3


def error_bound(cond: float, precision: str) -> float:
    """Issue 4, item 1: 1e-8 (double, cond <= 1e4), 1e-6 (double, <= 1e7), 1e-3 (float)."""
    if precision == "float":
        return FLOAT_BOUND
    return 1e-8 if cond <= 1e4 else 1e-6


def cond_band(cond: float) -> str:
    d = int(np.clip(np.floor(np.log10(max(cond, 1.0))), 0, COND_DECADES - 1))
    return f"1e{d}-1e{d + 1}"


@dataclass
class SolvedQP:
    """One QP solved by the C in one precision: what every campaign records."""

    config: str  # config file name (in the campaign's config directory)
    seed: int
    precision: str
    index: int
    n: int
    m: int
    status: int
    iterations: int
    finite: bool  # U all finite
    in_limits: bool  # U inside the input bounds

    @property
    def safe(self) -> bool:
        """A documented status and U finite inside the input bounds."""
        return self.status in STATUS_NAMES and self.finite and self.in_limits


@dataclass
class QPRecord(SolvedQP):
    """A feasible QP, scored against the extended-precision solution."""

    kind: str = ""
    warm: bool = False
    cond: float = 1.0
    error: float = float("nan")  # relative to max(1, |U*|); nan when not optimal
    n_active: int = 0
    n_independent: int = 0
    # failing float QPs only (float_floor): status and error of the double solver on the
    # float build's stored numbers; -1 / nan when not measured
    floor_status: int = -1
    floor: float = float("nan")
    x: list = field(default_factory=list)
    r: list = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return (self.safe and self.status == OPTIMAL
                and self.error <= error_bound(self.cond, self.precision))


@dataclass
class Controller:
    """A drawn config, written to disk, built in each precision."""

    rc: RandomConfig
    path: Path
    models: dict  # precision -> ControllerModel
    c: dict  # precision -> HostController
    solver_ctx: dict  # precision -> the context's "solver" settings

    @property
    def qp(self):
        return self.models["double"].modes[0].qp


def build_controller(rc: RandomConfig, root: Path, precisions=PRECISIONS,
                     max_iterations: int | None = None) -> Controller:
    cfg_dir = Path(root) / "configs"
    cfg_dir.mkdir(parents=True, exist_ok=True)
    if max_iterations is not None:
        rc.data["solver"] = {**rc.data.get("solver", {}), "max_iterations": max_iterations}
    path = cfg_dir / f"{rc.data['prefix']}_seed{rc.seed}.yaml"
    path.write_text(rc.yaml())
    models, cs, solver_ctx = {}, {}, {}
    for prec in precisions:
        model, ctx = load_model(path, prec)
        models[prec], solver_ctx[prec] = model, ctx["solver"]
        cs[prec] = build_host_controller(ctx, Path(root))
    return Controller(rc=rc, path=path, models=models, c=cs, solver_ctx=solver_ctx)


def snapshot_state(c) -> bytes:
    """The whole controller instance of a loaded host build, as bytes."""
    return bytes(c.ffi.buffer(c.ctrl))


def restore_state(c, state: bytes) -> None:
    c.ffi.memmove(c.ctrl, state, len(state))


def _as(prec: str, a: np.ndarray) -> np.ndarray:
    return np.asarray(a, dtype=np.float64 if prec == "double" else np.float32)


def _next_sample(rng: np.random.Generator, qp, x: np.ndarray, r: np.ndarray):
    """The following sample: the state moved a little, the preview shifted by one step."""
    ny = qp.ny
    x2 = x + 0.02 * (np.abs(x).max() + 1e-3) * rng.normal(size=x.size)
    r2 = np.concatenate([r[ny:], r[-ny:]])
    return x2, r2


def _exact(ctrl: Controller, prec: str, x, r, cache: dict):
    """Extended-precision solution of the QP the C sees (inputs rounded to ``prec``)."""
    xs, rs = _as(prec, x), _as(prec, r)
    key = (prec, xs.tobytes(), rs.tobytes())
    if key not in cache:
        cache[key] = solve_exact(qp_data(ctrl.qp, xs.astype(np.float64), rs.astype(np.float64)))
    return cache[key]


def _solve_and_score(ctrl: Controller, prec: str, x, r, cold: bool, cache: dict):
    c = ctrl.c[prec]
    if cold:
        c.init()
    status, U, its = c.solve_qp(0, _as(prec, x), _as(prec, r))
    sol = _exact(ctrl, prec, x, r, cache)
    err = float("nan")
    if sol.status == "optimal" and status == OPTIMAL:
        err = relative_error(U, sol.U)
    return status, U, its, sol, err


def feasible_campaign(n_configs: int, qps_per_config: int, root: Path, seed0: int = 0,
                      precisions=PRECISIONS, n_max: int = 100, progress=None) -> list[QPRecord]:
    """``n_configs`` random controllers x ``qps_per_config`` feasible QPs, each precision.

    Config i targets cond(E) decade i mod 7, so every band is populated, and is a delay
    plant when i mod 5 = 3 and a twin-output plant when i mod 5 = 4 (dependent rows);
    ``n_max`` caps the number of decision variables.
    """
    records: list[QPRecord] = []
    for i in range(n_configs):
        seed = seed0 + i
        kind = {3: "delay", 4: "twin_outputs"}.get(i % 5, "generic")
        rc = random_config(seed, prefix=f"rq{i}", kind=kind, cond_decade=i % COND_DECADES,
                           n_max=n_max)
        ctrl = build_controller(rc, root, precisions)
        qp = ctrl.qp
        ev = np.linalg.eigvalsh(qp.E)
        cond = float(ev.max() / ev.min())
        rng = np.random.default_rng(10_000 + seed)
        cache: dict = {}
        got, attempts = 0, 0
        while got < qps_per_config and attempts < 20 * qps_per_config:
            attempts += 1
            x, r = draw_instance(rng, qp, rc.y_scale)
            pair = [(x, r, False)]
            if got + 1 < qps_per_config:
                pair.append((*_next_sample(rng, qp, x, r), True))
            # both samples must be feasible, with the inputs rounded to every precision
            if any(_exact(ctrl, p, xx, rr, cache).status != "optimal"
                   for xx, rr, _ in pair for p in precisions):
                continue
            for xx, rr, warm in pair:
                for prec in precisions:
                    status, U, its, sol, err = _solve_and_score(ctrl, prec, xx, rr, not warm,
                                                                cache)
                    records.append(QPRecord(
                        config=ctrl.path.name, seed=seed, kind=rc.kind, precision=prec,
                        index=got, warm=warm, n=qp.n, m=qp.m, cond=cond, status=int(status),
                        iterations=int(its), error=err, n_active=sol.n_active,
                        n_independent=int(sol.active.size),
                        finite=bool(np.all(np.isfinite(U))),
                        in_limits=_in_limits(U, ctrl.models[prec]),
                        x=_as(prec, xx).astype(float).tolist(),
                        r=_as(prec, rr).astype(float).tolist()))
                    _measure_floor(ctrl, records[-1], sol)
                got += 1
        if progress is not None:
            progress(i)
    return records


def _measure_floor(ctrl: Controller, rec: QPRecord, sol) -> None:
    """For a failing float QP, the stored-data floor (float_floor), when double is built."""
    if rec.ok or rec.precision != "float" or "double" not in ctrl.solver_ctx:
        return
    rec.floor_status, rec.floor = stored_data_floor(
        ctrl.models["float"].modes[0].data, ctrl.solver_ctx["double"], rec.x, rec.r, sol.U)


def summarise_feasible(records: list[QPRecord]) -> dict:
    """Per precision and cond(E) band: counts, statuses, max/median error, worst case."""
    out: dict = {"qps": len({(r.config, r.index) for r in records}), "bands": {}}
    for prec in sorted({r.precision for r in records}):
        rows = [r for r in records if r.precision == prec]
        bands: dict = {}
        for band in sorted({cond_band(r.cond) for r in rows}, key=lambda b: float(b[2:b.index("-")])):
            rs = [r for r in rows if cond_band(r.cond) == band]
            errs = np.array([r.error for r in rs if r.status == OPTIMAL])
            worst = max(rs, key=lambda r: (r.status != OPTIMAL, np.nan_to_num(r.error, nan=np.inf)))
            bands[band] = {
                "qps": len(rs), "configs": len({r.config for r in rs}),
                "not_optimal": sum(r.status != OPTIMAL for r in rs),
                "max_error": float(errs.max()) if errs.size else None,
                "median_error": float(np.median(errs)) if errs.size else None,
                "bound": error_bound(10.0 ** float(band[2:band.index("-")]) * 9.99, prec),
                "failures": sum(not r.ok for r in rs),
                "max_iterations": int(max(r.iterations for r in rs)),
                "worst": {"config": worst.config, "index": worst.index, "warm": worst.warm,
                          "status": STATUS_NAMES.get(worst.status, worst.status),
                          "error": worst.error},
            }
        out["bands"][prec] = bands
        out.setdefault("totals", {})[prec] = {
            "qps": len(rows), "not_optimal": sum(r.status != OPTIMAL for r in rows),
            "failures": sum(not r.ok for r in rows),
            "optimal_over_bound": sum(r.status == OPTIMAL and not r.ok for r in rows),
            "unsafe": sum(not r.safe for r in rows),
            "dependent_active_sets": sum(r.n_active > r.n_independent for r in rows),
            "max_active": max(r.n_active for r in rows),
        }
        if prec == "float":
            failed = [r for r in rows if not r.ok and r.floor_status >= 0]
            out["totals"][prec]["failures_by_stored_data_floor"] = {
                c: sum(floor_class(r.floor_status, r.floor) == c for r in failed)
                for c in FLOOR_CLASSES}
    out["kinds"] = {k: len({r.config for r in records if r.kind == k})
                    for k in sorted({r.kind for r in records})}
    out["max_n"] = max(r.n for r in records)
    out["max_rows_per_n"] = max(r.m / r.n for r in records)
    return out


@dataclass
class InfeasibleRecord(SolvedQP):
    """An infeasible QP and the feasible one solved right after it."""

    margin: float = 0.0  # phase-1 LP: scaled violation no U in the box can avoid
    recovery_status: int = OPTIMAL
    recovery_same_as_cold: bool = True
    x: list = field(default_factory=list)
    r: list = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """Not reported optimal, safe, and the next feasible QP solved exactly as from a
        cold start (no sticky warm start); in double that solve must also be optimal (in
        float it is whatever area 1 measures for that QP cold)."""
        return (self.safe and self.status != OPTIMAL and self.recovery_same_as_cold
                and (self.precision == "float" or self.recovery_status == OPTIMAL))


def _in_limits(U: np.ndarray, model) -> bool:
    d = model.modes[0].data
    lo, hi = np.tile(d.u_min, d.N), np.tile(d.u_max, d.N)
    return bool(np.all(U >= lo) and np.all(U <= hi))


def infeasible_campaign(n_configs: int, qps_per_config: int, root: Path, seed0: int = 5000,
                        precisions=PRECISIONS, min_margin: float = 1e-3,
                        max_iterations: int | None = None,
                        progress=None) -> list[InfeasibleRecord]:
    """QPs whose output bounds cannot be met, each followed by a feasible recovery QP.

    ``max_iterations`` overrides the solver's cap (default: the product's 1000).
    """
    records: list[InfeasibleRecord] = []
    for i in range(n_configs):
        seed = seed0 + i
        rc = _config_with_output_bounds(seed, f"ri{i}")
        ctrl = build_controller(rc, root, precisions, max_iterations)
        qp = ctrl.qp
        rng = np.random.default_rng(20_000 + seed)
        got, attempts = 0, 0
        while got < qps_per_config and attempts < 50 * qps_per_config:
            attempts += 1
            x, r = draw_instance(rng, qp, rc.y_scale)
            x = x * 10.0 ** rng.uniform(0.0, 3.0)  # push the free response out of reach
            margins = {p: infeasibility_margin(qp_data(qp, _as(p, x).astype(float),
                                                       _as(p, r).astype(float)))
                       for p in precisions}
            if min(margins.values()) <= min_margin:
                continue
            x_ok, r_ok = _feasible_instance(rng, qp, rc, precisions)
            for prec in precisions:
                c = ctrl.c[prec]
                before = snapshot_state(c)  # the cold reference solve, then back
                c.init()
                st3, U3, its3 = c.solve_qp(0, _as(prec, x_ok), _as(prec, r_ok))
                restore_state(c, before)
                st, U, its = c.solve_qp(0, _as(prec, x), _as(prec, r))
                st2, U2, its2 = c.solve_qp(0, _as(prec, x_ok), _as(prec, r_ok))
                records.append(InfeasibleRecord(
                    config=ctrl.path.name, seed=seed, precision=prec, index=got, n=qp.n,
                    m=qp.m, margin=margins[prec], status=int(st), iterations=int(its),
                    finite=bool(np.all(np.isfinite(U))),
                    in_limits=_in_limits(U, ctrl.models[prec]), recovery_status=int(st2),
                    recovery_same_as_cold=(st2 == st3 and its2 == its3
                                           and U2.tobytes() == U3.tobytes()),
                    x=_as(prec, x).astype(float).tolist(), r=_as(prec, r).astype(float).tolist()))
            got += 1
        if progress is not None:
            progress(i)
    return records


def _config_with_output_bounds(seed: int, prefix: str) -> RandomConfig:
    """A small generic controller (n <= 40) with finite output bounds on both sides."""
    for k in range(100):
        rc = random_config(seed * 100 + k, prefix=prefix, kind="generic", n_max=40)
        b = rc.data["modes"][0]["bounds"]
        if "y_min" in b and "y_max" in b:
            return rc
    raise RuntimeError(f"seed {seed}: no config with output bounds")


def _feasible_instance(rng, qp, rc, precisions):
    for _ in range(200):
        x, r = draw_instance(rng, qp, rc.y_scale)
        x = 0.2 * x
        if all(solve_exact(qp_data(qp, _as(p, x).astype(float), _as(p, r).astype(float)))
               .status == "optimal" for p in precisions):
            return x, r
    return np.zeros(qp.nx), np.zeros(qp.N * qp.ny)


def summarise_infeasible(records: list[InfeasibleRecord]) -> dict:
    out: dict = {"qps": len({(r.config, r.index) for r in records})}
    for prec in sorted({r.precision for r in records}):
        rows = [r for r in records if r.precision == prec]
        statuses: dict = {}
        for r in rows:
            name = STATUS_NAMES.get(r.status, str(r.status))
            statuses[name] = statuses.get(name, 0) + 1
        out[prec] = {
            "qps": len(rows), "reported_optimal": sum(r.status == OPTIMAL for r in rows),
            "non_finite": sum(not r.finite for r in rows),
            "outside_limits": sum(not r.in_limits for r in rows),
            "recovery_not_optimal": sum(r.recovery_status != OPTIMAL for r in rows),
            "recovery_differs_from_cold": sum(not r.recovery_same_as_cold for r in rows),
            "statuses": statuses,
            "min_margin": float(min(r.margin for r in rows)),
            "max_margin": float(max(r.margin for r in rows)),
            "max_n": max(r.n for r in rows), "max_m": max(r.m for r in rows),
        }
    return out


def write_json(path: Path, payload: dict) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(payload, indent=1, sort_keys=True, default=float) + "\n")


def failures_json(records) -> list[dict]:
    """Reproducers of every failing record (config file, x, r, what went wrong)."""
    return [asdict(r) for r in records if not r.ok]
