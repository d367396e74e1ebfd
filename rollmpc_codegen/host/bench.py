"""``rollmpc bench``: the paper's Table 2 on the generated C and on PyPI peers, one run.

1. **Record** the QP sequence of the scenario: the default controller (the config as
   given, compiled C through cffi) runs the closed loop of ``rollmpc simulate``; every
   sample contributes (mode, xhat of that mode before the solve, reference preview).
   The estimate comes from the context's observers
   (:class:`rollmpc_codegen.sim.switched_observer.SwitchedObserver`, double), the mode from
   the C (``P_last_info``).
2. **Select**: samples 1-32 are skipped, as in the paper's Table 2 (its start-up
   transient); ``--include-transient`` keeps them.  ``--max-qps`` keeps evenly spread
   blocks of 20 consecutive QPs (warm starts carry over as in the closed loop inside a
   block; the first QP of a block warm-starts from the end of the previous block).
3. **Replay** the same QPs, in order, through
   * the generated solver variants, each built from a config variant with
     ``build_host_controller`` and called through ``P_solve_qp``: plain Hildreth (cold),
     Hildreth+ W and Hildreth+' W exactly as the paper describes them (``polish: false``),
     and the default config as shipped.  Warm starts carry over from QP to QP; when the
     mode changes the controller is re-initialised, which is what ``P_step`` does on a
     switch (the incoming mode starts cold).  Time: ``solve_ticks`` measured inside the C
     around the solve (host monotonic clock, ns);
   * quadprog (the reference for the error columns), DAQP and OSQP
     (:mod:`rollmpc_codegen.qp.peers`), each timed by its own in-C timer where it has one.
   Every row also gets the wall time around its Python call ("call" columns), so the C
   variants can be compared like for like with the Python-called peers.
   ``--repeat R`` replays everything R times, each from a fresh start (the replays are
   deterministic), and keeps each QP's minimum time: on a shared machine this removes
   the OS preemptions that otherwise dominate the maxima of the fast rows.
4. **Report** per row: average / median / max solve time, max < Ts, average / max
   |u(k) - u_quadprog(k)| on the applied first move, status counts, per-mode medians.

Also measured (``reduced_set_check``): the paper's Hildreth+' restricts the dual to the
rows with K = gamma - M theta0 < sigma and never re-checks the others.  Solving that
reduced QP *exactly* (quadprog on those rows) shows what the reduced set alone returns,
whatever the sweeps: rows outside it end up violated, inputs beyond their limits.
"""
from __future__ import annotations

import dataclasses
import json
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np

from .build import EXACT_MATH, HostController, build_host_controller
from ..config import ConfigError, ControllerConfig
from ..codegen.context import build_context
from ..model.controller import ControllerModel
from ..pipeline import build_model, load_model
from ..qp.peers import DaqpPeer, OsqpPeer, QuadprogPeer, c_stdout_silenced, qp_vectors
from ..sim.scenario import scenario_reference
from ..sim.simulate import progress_printer, run_closed_loop
from ..cli.simulate import require_module
from ..status import STATUS_NAMES
from ..sim.switched_observer import SwitchedObserver

TRANSIENT_SAMPLES = 32  # the paper's Table 2 uses samples 33..6000
SAMPLE_BLOCK = 20  # --max-qps keeps blocks of this many consecutive QPs
C_VARIANTS = {  # row key: (label, solver.method or None for the config as given)
    "hildreth": ("Hildreth (cold) [C]", "hildreth"),
    "hildreth_plus": ("Hildreth+ W [C]", "hildreth_plus"),
    "hildreth_plus_prime": ("Hildreth+' W [C]", "hildreth_plus_prime"),
    "default": ("default as configured [C]", None),
}
OSQP_TIGHT = {"eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": True}
PEERS = {
    "quadprog": "quadprog",
    "daqp": "DAQP (Model, warm)",
    "osqp": "OSQP (default)",
    "osqp_tight": "OSQP (eps 1e-9, polish)",
}
ROWS = (*C_VARIANTS, *PEERS)


@dataclass
class QpSequence:
    """The QPs of one closed loop: sample k solved mode[k] at x[k] with preview r[k]."""

    k: np.ndarray
    mode: np.ndarray
    x: list
    r: np.ndarray
    u_applied: np.ndarray  # (K, n_actuators) what the closed loop applied


@dataclass
class Replay:
    """Per-QP results of one row of the table."""

    status: list  # status names ("optimal", "max_iter", ...)
    u0: np.ndarray  # (Q, nu_max) the first move, NaN-padded for smaller modes
    solver_s: np.ndarray
    call_s: np.ndarray
    iterations: np.ndarray


def record_qp_sequence(model: ControllerModel, controller: HostController,
                       steps: int | None = None, progress=None) -> QpSequence:
    """Run the scenario with ``controller`` and record every QP it solved."""
    ctx = controller.ctx
    observer = SwitchedObserver(ctx)
    modes, xs, rs = [], [], []

    class Recorder:
        def step(self, y, sched, r):
            before = [x.copy() for x in observer.xhat]
            status, u = controller.step(y, sched, r)
            mode = controller.info()["mode"]
            modes.append(mode)
            xs.append(before[mode])
            rs.append(np.array(r, float))
            observer.observe(y, u)
            return status, u

    controller.init()
    log = run_closed_loop(model.config, Recorder(), steps=steps, progress=progress)
    controller.init()
    return QpSequence(k=np.arange(len(modes)), mode=np.array(modes), x=xs,
                      r=np.array(rs), u_applied=log.u.copy())


def select_qps(seq: QpSequence, include_transient: bool, max_qps: int | None,
               block: int = SAMPLE_BLOCK) -> np.ndarray:
    """Indices into ``seq`` to replay (see the module docstring).

    A sample (``max_qps``) is made of evenly spread blocks of ``block`` consecutive QPs,
    the first block at the start and the last at the end, so that within a block the
    warm starts carry over exactly as in the closed loop.
    """
    idx = seq.k if include_transient else seq.k[TRANSIENT_SAMPLES:]
    if max_qps is None or idx.size <= max_qps:
        return idx
    b = min(block, max_qps)
    starts = np.linspace(0, idx.size - b, max_qps // b).round().astype(int)
    return idx[np.unique((starts[:, None] + np.arange(b)).ravel())]


def variant_context(cfg: ControllerConfig, method: str) -> dict:
    """The context of ``cfg`` with the paper's ``method`` and no polish."""
    solver = dataclasses.replace(cfg.solver, method=method, polish=False)
    return build_context(build_model(dataclasses.replace(cfg, solver=solver)))


def _first_moves(model: ControllerModel) -> tuple[list[int], int]:
    nus = [mm.qp.nu for mm in model.modes]
    return nus, max(nus)


def replay_c(controller: HostController, model: ControllerModel, seq: QpSequence,
             idx: np.ndarray, progress=None) -> Replay:
    nus, nu_max = _first_moves(model)
    dtype = controller.dtype
    out = Replay(status=[], u0=np.full((idx.size, nu_max), np.nan), solver_s=np.zeros(idx.size),
                 call_s=np.zeros(idx.size), iterations=np.zeros(idx.size, int))
    controller.init()
    previous = None
    for q, i in enumerate(idx):
        mode = int(seq.mode[i])
        if mode != previous:
            controller.init()  # as P_step on a switch: the incoming mode starts cold
            previous = mode
        x = np.ascontiguousarray(seq.x[i], dtype)
        r = np.ascontiguousarray(seq.r[i], dtype)
        t0 = time.perf_counter_ns()
        status, U, its = controller.solve_qp(mode, x, r)
        t1 = time.perf_counter_ns()
        info = controller.info()
        out.status.append(STATUS_NAMES.get(status, str(status)))
        out.u0[q, :nus[mode]] = U[:nus[mode]]
        out.solver_s[q] = info["solve_ticks"] * 1e-9
        out.call_s[q] = (t1 - t0) * 1e-9
        out.iterations[q] = its
        if progress is not None:
            progress(q)
    controller.init()
    return out


def replay_peer(peer, model: ControllerModel, seq: QpSequence, idx: np.ndarray,
                progress=None) -> Replay:
    nus, nu_max = _first_moves(model)
    out = Replay(status=[], u0=np.full((idx.size, nu_max), np.nan), solver_s=np.zeros(idx.size),
                 call_s=np.zeros(idx.size), iterations=np.zeros(idx.size, int))
    for q, i in enumerate(idx):
        mode = int(seq.mode[i])
        t0 = time.perf_counter_ns()
        res = peer.solve(mode, seq.x[i], seq.r[i])
        t1 = time.perf_counter_ns()
        out.status.append(res.status)
        out.u0[q, :nus[mode]] = res.U[:nus[mode]]
        out.call_s[q] = (t1 - t0) * 1e-9
        out.solver_s[q] = res.solver_s if res.solver_s is not None else out.call_s[q]
        out.iterations[q] = res.iterations
        if progress is not None:
            progress(q)
    return out


def _stats(v: np.ndarray) -> tuple[float | None, float | None, float | None]:
    if v.size == 0:
        return None, None, None
    return float(v.mean()), float(np.median(v)), float(v.max())


def row_summary(key: str, label: str, timer: str, rep: Replay, ref: Replay,
                seq: QpSequence, idx: np.ndarray, model: ControllerModel) -> dict:
    ts = model.config.sample_time
    err = np.nanmax(np.abs(rep.u0 - ref.u0), axis=1) if len(idx) else np.zeros(0)
    compared = np.isfinite(err)
    avg_s, med_s, max_s = _stats(rep.solver_s)
    call_avg, call_med, call_max = _stats(rep.call_s)
    names, counts = np.unique(np.array(rep.status, dtype=object).astype(str), return_counts=True)
    modes = seq.mode[idx]
    by_mode = {}
    for j, mm in enumerate(model.config.modes):
        sel = modes == j
        if sel.any():
            by_mode[mm.name] = sel
    optimal = int(sum(s == "optimal" for s in rep.status))
    return {
        "solver": label,
        "key": key,
        "timer": timer,
        "avg_s": avg_s,
        "max_s": max_s,
        "max_lt_ts": bool(max_s is not None and max_s < ts),
        "avg_abs_err": float(err[compared].mean()) if compared.any() else None,
        "max_abs_err": float(err[compared].max()) if compared.any() else None,
        "median_s": med_s,
        "call_avg_s": call_avg,
        "call_median_s": call_med,
        "call_max_s": call_max,
        "qps": int(len(idx)),
        "optimal": optimal,
        "not_optimal": int(len(idx)) - optimal,
        "status_counts": {str(n): int(c) for n, c in zip(names, counts)},
        "compared_qps": int(compared.sum()),
        "max_iterations": int(rep.iterations.max()) if len(idx) else 0,
        "median_iterations": float(np.median(rep.iterations)) if len(idx) else 0.0,
        "qps_by_mode": {m: int(sel.sum()) for m, sel in by_mode.items()},
        "median_s_by_mode": {m: float(np.median(rep.solver_s[sel])) for m, sel in by_mode.items()},
        "max_s_by_mode": {m: float(rep.solver_s[sel].max()) for m, sel in by_mode.items()},
        "call_median_s_by_mode": {m: float(np.median(rep.call_s[sel]))
                                  for m, sel in by_mode.items()},
        "not_optimal_by_mode": {m: int(sum(rep.status[q] != "optimal"
                                           for q in np.flatnonzero(sel)))
                                for m, sel in by_mode.items()},
    }


def reduced_set_check(model: ControllerModel, seq: QpSequence, idx: np.ndarray,
                      reference: Replay) -> dict:
    """The paper's reduced set {K < sigma} alone, solved exactly, on the constrained QPs."""
    import quadprog

    sigma = model.config.solver.sigma
    nus, _ = _first_moves(model)
    constrained = violating = 0
    worst_row = worst_u = worst_beyond = worst_U_beyond = worst_err = 0.0
    for q, i in enumerate(idx):
        mode = int(seq.mode[i])
        qp = model.modes[mode].qp
        x, r = seq.x[i], seq.r[i]
        theta0 = qp.theta0(x, r)
        gamma = qp.gamma(x)
        K = gamma - qp.L @ theta0
        if K.min() >= 0:  # unconstrained: nothing to reduce
            continue
        constrained += 1
        rows = np.flatnonzero(K < sigma)
        f, _ = qp_vectors(qp, x, r)
        theta = quadprog.solve_qp(qp.E, -f, -qp.L[rows].T, -gamma[rows], 0)[0]
        viol = float((qp.L @ theta - gamma).max())
        scale = max(1.0, float(np.abs(gamma).max()))
        if viol > 1e-9 * scale:
            violating += 1
        mode_cfg = model.config.modes[mode]
        u0 = theta[:nus[mode]]
        beyond = float(max(0.0, (u0 - mode_cfg.u_max).max(), (mode_cfg.u_min - u0).max()))
        moves = qp.n // qp.nu  # stages, or blocks with move blocking
        U_beyond = max(0.0, float((theta - np.tile(mode_cfg.u_max, moves)).max()),
                       float((np.tile(mode_cfg.u_min, moves) - theta).max()))
        worst_U_beyond = max(worst_U_beyond, U_beyond)
        worst_row = max(worst_row, viol)
        worst_u = max(worst_u, float(np.abs(u0).max()))
        worst_beyond = max(worst_beyond, beyond)
        worst_err = max(worst_err, float(np.nanmax(np.abs(u0 - reference.u0[q, :nus[mode]]))))
    return {"sigma": sigma, "constrained_qps": constrained, "violating_qps": violating,
            "max_row_violation": worst_row, "max_abs_u0": worst_u,
            "max_u0_beyond_limit": worst_beyond, "max_U_beyond_limit": worst_U_beyond,
            "max_abs_err_u0_vs_quadprog": worst_err}


def machine_info() -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    versions = {}
    for pkg in ("numpy", "scipy", "cffi", "quadprog", "daqp", "osqp"):
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None
    try:
        cc = subprocess.run(["gcc", "--version"], capture_output=True, text=True,
                            timeout=10).stdout.splitlines()[0]
    except (OSError, IndexError, subprocess.SubprocessError):
        cc = None
    return {"cpu": cpu, "cores": os.cpu_count(), "load_average": list(os.getloadavg()),
            "platform": platform.platform(), "python": platform.python_version(),
            "c_compiler": cc, "c_flags": " ".join(("-O2", *EXACT_MATH)), **versions}


def _fmt(v, digits: int = 3) -> str:
    return "-" if v is None else f"{v:.{digits}e}"


def markdown_table(rows: list[dict], ts: float) -> str:
    head = ("| solver | timer | avg [s] | median [s] | max [s] | max < Ts | "
            "call avg [s] | call max [s] | avg abs err u | max abs err u | optimal / QPs |")
    lines = [head, "|" + "---|" * 11]
    for r in rows:
        lines.append(
            f"| {r['solver']} | {r['timer']} | {_fmt(r['avg_s'])} | {_fmt(r['median_s'])} | "
            f"{_fmt(r['max_s'])} | {'yes' if r['max_lt_ts'] else 'no'} | "
            f"{_fmt(r['call_avg_s'])} | {_fmt(r['call_max_s'])} | "
            f"{_fmt(r['avg_abs_err'], 2)} | {_fmt(r['max_abs_err'], 2)} | "
            f"{r['optimal']} / {r['qps']} |")
    return "\n".join(lines) + f"\n\nTs = {ts:g} s; errors are |u(k) - u_quadprog(k)| on the " \
        "applied first move."


def parse_variants(text: str | None) -> list[str]:
    if text is None:
        return list(ROWS)
    keys = [k.strip() for k in text.split(",") if k.strip()]
    for k in keys:
        if k not in ROWS:
            raise ConfigError("--variants", f"unknown row {k!r}; choose from {', '.join(ROWS)}")
    if not keys:
        raise ConfigError("--variants", "give at least one row")
    return [k for k in ROWS if k in keys or k == "quadprog"]


def _check_args(args) -> list[str]:
    keys = parse_variants(args.variants)
    if args.repeat < 1:
        raise ConfigError("--repeat", f"must be >= 1, got {args.repeat}")
    if args.max_qps is not None and args.max_qps < 1:
        raise ConfigError("--max-qps", f"must be >= 1, got {args.max_qps}")
    if args.steps is not None and args.steps < 1:
        raise ConfigError("--steps", f"must be >= 1, got {args.steps}")
    if args.steps is not None and args.steps <= TRANSIENT_SAMPLES and not args.include_transient:
        raise ConfigError("--steps", f"leaves no QP to replay after skipping the first "
                          f"{TRANSIENT_SAMPLES} samples (use --include-transient)")
    for opt in ("json", "plot"):
        target = getattr(args, opt)
        if target is not None and Path(target).is_dir():
            raise ConfigError(f"--{opt}", f"{target} is a directory")
    return keys


def bench_command(args) -> int:
    keys = _check_args(args)
    for key in keys:
        if key in PEERS:
            require_module(key.split("_")[0], "peers", f"the {key} row")
    if args.plot:
        require_module("matplotlib", "plot", "--plot")
    model, ctx = load_model(args.config, args.precision)
    cfg = model.config
    build_root = Path(args.build_dir) if getattr(args, "build_dir", None) else None
    quiet = args.quiet

    def progress(total: int, label: str):
        return None if quiet else progress_printer(total, label)

    default_c = build_host_controller(ctx, build_root)
    steps = args.steps if args.steps is not None else len(scenario_reference(cfg))
    seq = record_qp_sequence(model, default_c, steps, progress(steps, "bench: record scenario"))
    idx = select_qps(seq, args.include_transient, args.max_qps)
    qps = [mm.qp for mm in model.modes]
    replays, rows = {}, []
    repeat = args.repeat

    def repeated(key: str, run_once) -> Replay:
        """``run_once(progress)`` ``repeat`` times from a fresh start; per-QP minimum times."""
        runs = [run_once(progress(idx.size, f"bench {key}"
                                  + (f" ({n + 1}/{repeat})" if repeat > 1 else "")))
                for n in range(repeat)]
        best = runs[0]
        best.solver_s = np.min([r.solver_s for r in runs], axis=0)
        best.call_s = np.min([r.call_s for r in runs], axis=0)
        return best

    ref = repeated("quadprog", lambda pr: replay_peer(QuadprogPeer(qps), model, seq, idx, pr))
    replays["quadprog"] = ref
    for key in keys:
        if key in C_VARIANTS:
            label, method = C_VARIANTS[key]
            if method is None:
                c = default_c
                s = ctx["solver"]
                label = f"default: {s['method']}{' + polish' if s['polish'] else ''} [C]"
            else:
                c = build_host_controller(variant_context(cfg, method), build_root)
            rep = repeated(key, lambda pr, c=c: replay_c(c, model, seq, idx, pr))
            timer = "C (solve_ticks)"
        elif key == "quadprog":
            label, rep, timer = PEERS[key], ref, "wall (Python call)"
        else:
            settings = OSQP_TIGHT if key == "osqp_tight" else {}

            def once(pr, key=key, settings=settings):
                peer = DaqpPeer(qps) if key == "daqp" else OsqpPeer(qps, **settings)
                with c_stdout_silenced():
                    return replay_peer(peer, model, seq, idx, pr)

            rep = repeated(key, once)
            label, timer = PEERS[key], f"C ({key.split('_')[0]} info)"
        replays[key] = rep
        rows.append(row_summary(key, label, timer, rep, ref, seq, idx, model))
    default_rep = replays.get("default")
    result = {
        "machine": machine_info(),
        "config": str(args.config),
        "precision": ctx["precision"],
        "sample_time": cfg.sample_time,
        "horizon": cfg.horizon,
        "solver_default": dict(ctx["solver"]),
        "scenario_samples": int(seq.k.size),
        "qps": int(idx.size),
        "skipped_transient_samples": 0 if args.include_transient else TRANSIENT_SAMPLES,
        "repeat": repeat,
        "timing": "one replay" if repeat == 1 else
                  f"per-QP minimum over {repeat} replays, each from a fresh start",
        "sampled": bool(args.max_qps is not None and idx.size < seq.k.size - (
            0 if args.include_transient else TRANSIENT_SAMPLES)),
        "qps_by_mode": {m.name: int((seq.mode[idx] == j).sum())
                        for j, m in enumerate(cfg.modes)},
        "rows": rows,
        "reduced_set_check": reduced_set_check(model, seq, idx, ref),
    }
    if default_rep is not None:  # the replay reproduces the recorded closed loop
        applied = np.array([seq.u_applied[i, model.modes[seq.mode[i]].data.actuator_index]
                            for i in idx])
        diff = np.abs(default_rep.u0[:, :applied.shape[1]] - applied)
        result["replay_max_abs_diff_vs_closed_loop"] = float(np.nanmax(diff))
    print(f"rollmpc bench: {idx.size} QPs of the {seq.k.size}-sample scenario "
          f"({'all samples' if args.include_transient else f'samples {TRANSIENT_SAMPLES + 1}-'}"
          f"{'' if args.include_transient else seq.k.size}"
          f"{f', in blocks of {SAMPLE_BLOCK} consecutive QPs' if result['sampled'] else ''}); "
          f"{result['timing']}; {result['machine']['cpu']} ({result['machine']['cores']} "
          f"cores, load {result['machine']['load_average'][0]:.1f}), {ctx['precision']}")
    print()
    print(markdown_table(rows, cfg.sample_time))
    rs = result["reduced_set_check"]
    print(f"\nPaper's reduced set {{K < sigma = {rs['sigma']:g}}} alone, solved exactly: "
          f"{rs['violating_qps']} of {rs['constrained_qps']} constrained QPs violate rows "
          f"outside the set (max violation {rs['max_row_violation']:.3g}; max |u0| "
          f"{rs['max_abs_u0']:.3g}; planned inputs up to {rs['max_U_beyond_limit']:.3g} "
          f"beyond their limits; first move within {rs['max_abs_err_u0_vs_quadprog']:.2g} "
          f"of quadprog).")
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(result, indent=1) + "\n")
        print(f"rollmpc: wrote {path}")
    if args.plot:
        from ..sim.figures import plot_solve_times

        plot_solve_times(args.plot, rows, replays, seq.k[idx], cfg.sample_time)
        print(f"rollmpc: wrote {args.plot}")
    sys.stdout.flush()
    return 0
