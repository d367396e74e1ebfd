"""``rollmpc simulate``: the paper's closed loop (section 4.1, Fig. 2) on the generated C
(:func:`rollmpc_codegen.sim.scenario_run.run_scenario`), printed and written.

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
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from .options import (add_build_dir, add_outputs, add_perturbations, add_precision, add_quiet,
                      check_outputs, check_perturbations, check_steps, progress_of,
                      require_plot, write_json)

if TYPE_CHECKING:
    from ..sim.simulate import ClosedLoopLog

OUTPUTS = ("csv", "json", "plot")


def add_parser(sub) -> None:
    s = sub.add_parser("simulate", help="closed loop of the generated C on the paper scenario")
    s.add_argument("config")
    add_precision(s)
    add_outputs(s, csv="per-sample log", json="summary metrics", plot="Fig. 2 style PNG")
    s.add_argument("--baseline", choices=["none", "lqr"], default="none",
                   help="also simulate an LQR-with-saturation baseline (plotted alongside)")
    add_perturbations(s)
    s.add_argument("--steps", type=int, default=None, help="samples (default: whole scenario)")
    add_quiet(s, "no progress bar")
    add_build_dir(s)
    s.set_defaults(func=run)


def write_csv(path: str | Path, ctx: dict, log: ClosedLoopLog) -> Path:
    from ..sim.simulate import csv_header

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
    check_steps(args)
    check_perturbations(args)
    check_outputs(args, OUTPUTS)


def solver_text(ctx: dict) -> str:
    """The solver as configured, e.g. ``hildreth_plus_prime + polish``."""
    return f"{ctx['solver']['method']}{' + polish' if ctx['solver']['polish'] else ''}"


def print_summary(cfg, ctx: dict, s: dict) -> None:
    from ..sim.metrics import time_limit_warning

    names = [m.name for m in cfg.modes]
    y_unit, u_unit = cfg.units.label("outputs"), cfg.units.label("actuators")
    print(f"rollmpc simulate: {s['samples']} samples ({s['duration_s']:g} s), "
          f"{ctx['precision']}, solver {solver_text(ctx)}")
    errs = ", ".join(f"{x['settled_error']:.3g}"  # *: the window includes the preview
                     + ("*" if x["settled_window_includes_preview"] else "")
                     for x in s["segments"])
    top = s["max_settled_error"]
    print(f"  settled |y - r| per segment{y_unit}: {errs} "
          f"(max {'-' if top is None else f'{top:.3g}'})")
    for warning in s["warnings"]:  # * marks the segments it names
        print(f"  warning: * {warning}")
    over = ", ".join(f"{x['overshoot']:.3g}" for x in s["segments"])
    print(f"  overshoot per segment{y_unit}: {over}")
    modes = ", ".join(f"{n} {s['by_mode'][n]['samples']}" for n in names)
    print(f"  switches: {s['switches']} (samples per mode: {modes})")
    umax = ", ".join(f"{a} {v:g}" for a, v in s["max_abs_u"].items())
    cv = s["constraint_violations"]
    far = ", ".join(f"{name} {v:.3g}" for name, v in cv["y_max_beyond"].items())
    print(f"  max |u|{u_unit}: {umax}; constraint violations: {cv['total']} "
          f"(u {cv['u']}, inactive {cv['inactive_actuator_nonzero']}, y {cv['y']}"
          f"{f' by up to {far}{y_unit}' if far else ''}; hard "
          f"bounds, beyond {s['violation_tolerance']:g} max(1, |bound|))")
    if s.get("soft_bounds"):
        sb = s["soft_bounds"]
        print(f"  soft output bounds: a plan exceeds one (slack > 0) in "
              f"{sb['samples_with_slack']} samples, max slack {sb['max_slack']:.3g}{y_unit}; "
              f"the output is beyond one in {sb['samples_beyond']} samples, max "
              f"{sb['max_beyond']:.3g}{y_unit} (not violations)")
    st = s["solve_us"]
    if st["median"] is not None:
        print(f"  non-optimal: {s['non_optimal']}; max iterations: {s['max_iterations']}; "
              f"solve time median {st['median']:.1f} us, max {st['max']:.1f} us")
    warning = time_limit_warning(s["status_counts"], s["samples"])
    if warning:
        print(f"  warning: {warning}")
    base = s.get("baseline")
    if base is not None:
        errs = ", ".join(f"{x['settled_error']:.3g}" for x in base["segments"])
        print(f"  LQR baseline: settled |y - r| per segment{y_unit}: {errs}; "
              f"switches {base['switches']}; "
              f"constraint violations {base['constraint_violations']['total']}")


def run(args) -> int:
    from ..sim.scenario_run import run_scenario

    _check_args(args)
    require_plot(args)
    result = run_scenario(args.config, precision=args.precision, steps=args.steps,
                          noise_std=args.noise, disturbance=args.disturbance,
                          mismatch=args.mismatch, seed=args.seed,
                          baseline=None if args.baseline == "none" else args.baseline,
                          build_dir=args.build_dir, progress=progress_of(args))
    ctx = result.ctx
    if args.csv:
        write_csv(args.csv, ctx, result.log)
    if args.json:
        write_json(args.json, result.summary)
    if args.plot:
        from ..sim.figures import plot_closed_loop

        plot_closed_loop(args.plot, result.config, result.log, result.baseline_log,
                         title=f"{Path(args.config).name}: closed loop of the generated C "
                               f"({ctx['precision']}, {solver_text(ctx)})")
    print_summary(result.config, ctx, result.summary)
    for opt in OUTPUTS:
        if getattr(args, opt):
            print(f"rollmpc: wrote {getattr(args, opt)}")
    sys.stdout.flush()
    return 0
