"""``rollmpc simulate``: the paper's closed loop (section 4.1, Fig. 2) on the generated C.

The controller is the generated C, compiled on the host and called through cffi; the
plant is :class:`rollmpc_codegen.sim.scenario.SimulatedPlant`; the loop is
:func:`rollmpc_codegen.sim.simulate.run_closed_loop`.

Outputs (each optional):

* ``--csv``: one row per sample, columns ``k,t,r,y,rho,mode,u_<actuator>...,status,
  iterations,solve_us``.  With several outputs the ``r`` and ``y`` columns become
  ``r_<output>`` and ``y_<output>`` for every output (in config order); without a
  scheduler there is no ``rho`` column.  ``mode`` is the 0-based mode index (config
  order, as in the C API); ``solve_us`` is measured inside the C around the solve.
* ``--json``: the metrics of :mod:`rollmpc_codegen.sim.metrics` (with
  ``baseline`` holding the LQR's when ``--baseline lqr``).
* ``--plot``: Fig. 2 (:mod:`rollmpc_codegen.sim.figures`).

A short summary goes to stdout, with the config's ``units`` (none unless given); the
progress bar to stderr (``--quiet`` disables it).
"""
from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

from ..host.build import build_host_controller
from ..sim.metrics import summarize
from ..config.errors import ConfigError
from ..pipeline import load_model
from ..sim.simulate import ClosedLoopLog, progress_printer, run_closed_loop


def csv_header(ctx: dict) -> list[str]:
    outputs = ctx["outputs"]
    if len(outputs) == 1:
        r_cols, y_cols = ["r"], ["y"]
    else:
        r_cols, y_cols = [f"r_{o}" for o in outputs], [f"y_{o}" for o in outputs]
    rho = ["rho"] if ctx["n_schedule"] else []
    return (["k", "t", *r_cols, *y_cols, *rho, "mode"]
            + [f"u_{a}" for a in ctx["actuators"]] + ["status", "iterations", "solve_us"])


def write_csv(path: str | Path, ctx: dict, log: ClosedLoopLog) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    ns = ctx["n_schedule"]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(csv_header(ctx))
        for k in range(len(log.t)):
            w.writerow([k, repr(float(log.t[k])), *map(repr, map(float, log.r[k])),
                        *map(repr, map(float, log.y[k])),
                        *map(repr, map(float, log.sched[k][:ns])), int(log.mode[k]),
                        *map(repr, map(float, log.u[k])), int(log.status[k]),
                        int(log.iterations[k]), f"{log.solve_us[k]:.3f}"])
    return path


def _check_args(args) -> None:
    if args.steps is not None and args.steps < 1:
        raise ConfigError("--steps", f"must be >= 1, got {args.steps}")
    if not args.noise >= 0:
        raise ConfigError("--noise", f"must be >= 0, got {args.noise}")
    if not abs(args.disturbance) < float("inf"):
        raise ConfigError("--disturbance", f"must be finite, got {args.disturbance}")
    for opt in ("csv", "json", "plot"):
        target = getattr(args, opt)
        if target is not None and Path(target).is_dir():
            raise ConfigError(f"--{opt}", f"{target} is a directory")


def _run(cfg, controller, args, label: str) -> ClosedLoopLog:
    from ..sim.scenario import scenario_reference

    steps = args.steps if args.steps is not None else len(scenario_reference(cfg))
    progress = None if args.quiet else progress_printer(steps, label)
    return run_closed_loop(cfg, controller, steps=steps, noise_std=args.noise,
                           disturbance=args.disturbance, seed=args.seed, progress=progress,
                           info=controller.info)


def _print_summary(cfg, ctx: dict, s: dict, base: dict | None) -> None:
    names = [m.name for m in cfg.modes]
    y_unit, u_unit = cfg.units.label("outputs"), cfg.units.label("actuators")
    print(f"rollmpc simulate: {s['samples']} samples ({s['duration_s']:g} s), "
          f"{ctx['precision']}, solver {ctx['solver']['method']}"
          f"{' + polish' if ctx['solver']['polish'] else ''}")
    errs = ", ".join(f"{x['settled_error']:.3g}" for x in s["segments"])
    print(f"  settled |y - r| per segment{y_unit}: {errs} (max {s['max_settled_error']:.3g})")
    over = ", ".join(f"{x['overshoot']:.3g}" for x in s["segments"])
    print(f"  overshoot per segment{y_unit}: {over}")
    modes = ", ".join(f"{n} {s['by_mode'][n]['samples']}" for n in names)
    print(f"  switches: {s['switches']} (samples per mode: {modes})")
    umax = ", ".join(f"{a} {v:g}" for a, v in s["max_abs_u"].items())
    cv = s["constraint_violations"]
    print(f"  max |u|{u_unit}: {umax}; constraint violations: {cv['total']} "
          f"(u {cv['u']}, inactive {cv['inactive_actuator_nonzero']}, y {cv['y']})")
    if s.get("soft_bounds"):
        sb = s["soft_bounds"]
        print(f"  soft output bounds: a plan exceeds one (slack > 0) in "
              f"{sb['samples_with_slack']} samples, max slack {sb['max_slack']:.3g}{y_unit}")
    st = s["solve_us"]
    if st["median"] is not None:
        print(f"  non-optimal: {s['non_optimal']}; max iterations: {s['max_iterations']}; "
              f"solve time median {st['median']:.1f} us, max {st['max']:.1f} us")
    if base is not None:
        errs = ", ".join(f"{x['settled_error']:.3g}" for x in base["segments"])
        print(f"  LQR baseline: settled |y - r| per segment{y_unit}: {errs}; "
              f"switches {base['switches']}; "
              f"constraint violations {base['constraint_violations']['total']}")


def require_module(module: str, extra: str, what: str) -> None:
    """Fail before any work when an optional dependency is missing (one line, exit 1)."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise RuntimeError(f"{what} needs {module}: pip install 'rollmpc-codegen[{extra}]'")


def simulate_command(args) -> int:
    _check_args(args)
    if args.plot:
        require_module("matplotlib", "plot", "--plot")
    model, ctx = load_model(args.config, args.precision)
    cfg = model.config
    build_root = Path(args.build_dir) if getattr(args, "build_dir", None) else None
    controller = build_host_controller(ctx, build_root)
    log = _run(cfg, controller, args, f"simulate ({ctx['precision']})")
    summary = {"config": str(args.config), "precision": ctx["precision"],
               "solver": dict(ctx["solver"]), "modes": [m.name for m in cfg.modes],
               "sample_time": cfg.sample_time, "horizon": cfg.horizon,
               "noise_std": args.noise, "disturbance": args.disturbance, "seed": args.seed,
               **summarize(cfg, log)}
    base_log = None
    if args.baseline == "lqr":
        from ..sim.lqr_baseline import LqrController

        base_log = _run(cfg, LqrController(model, ctx), args, "LQR baseline")
        summary["baseline"] = {"kind": "lqr_saturated", **summarize(cfg, base_log)}
    if args.csv:
        write_csv(args.csv, ctx, log)
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(summary, indent=1) + "\n")
    if args.plot:
        from ..sim.figures import plot_closed_loop

        plot_closed_loop(args.plot, cfg, log, base_log,
                         title=f"{Path(args.config).name}: closed loop of the generated C "
                               f"({ctx['precision']}, {ctx['solver']['method']}"
                               f"{' + polish' if ctx['solver']['polish'] else ''})")
    _print_summary(cfg, ctx, summary, summary.get("baseline"))
    for opt in ("csv", "json", "plot"):
        if getattr(args, opt):
            print(f"rollmpc: wrote {getattr(args, opt)}")
    sys.stdout.flush()
    return 0
