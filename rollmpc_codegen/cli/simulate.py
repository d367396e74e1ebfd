"""``rollmpc simulate``: the paper's closed loop (section 4.1, Fig. 2) on the generated C
(:func:`rollmpc_codegen.sim.scenario_run.run_scenario`), printed and written.

Outputs (each optional):

* ``--csv``: one row per sample, columns ``k,t,r,y,rho,mode,u_<actuator>...,status,
  iterations,solve_us,work``.  With several outputs the ``r`` and ``y`` columns become
  ``r_<output>`` and ``y_<output>`` for every output (in config order); without a
  scheduler there is no ``rho`` column.  ``mode`` is the 0-based mode index (config
  order, as in the C API); ``solve_us`` is measured inside the C around the solve (host time);
  ``work`` is the solver's deterministic work count, in the units of
  ``solver.work_budget`` (the same on the host and the MCU: docs/solver.md, "Work budget").
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

from ..config import ConfigError
from .options import (add_build_dir, add_command, add_config, add_flights, add_outputs,
                      add_perturbations,
                      add_precision, add_quiet, check_flights, check_outputs,
                      check_perturbations, check_steps, progress_of, require_plot, write_json)

if TYPE_CHECKING:
    from ..sim.simulate import ClosedLoopLog

OUTPUTS = ("csv", "json", "plot")


def add_parser(sub) -> None:
    s = add_command(sub, "simulate", "closed loop of the generated C on the config's scenario",
                    "Compiles the controller on the host and closes the loop on the config's "
                    "own plant models over its simulation.reference (levels held segment "
                    "seconds each; the paper's roll steps when absent), optionally with "
                    "measurement noise, an input disturbance and a mismatched plant; prints "
                    "the tracking, constraint, status and work figures and the warnings "
                    "(docs/checks.md).  --flights flies random references instead.")
    add_config(s)
    add_precision(s)
    add_outputs(s, csv="write one row per sample (columns: docs in the module)",
                json="write the summary metrics and warnings as JSON",
                plot="write the closed loop as a PNG: outputs with references and bounds, "
                "inputs with limits, the scheduling signal")
    s.add_argument("--baseline", choices=["none", "lqr"], default="none",
                   help="also simulate an LQR-with-saturation baseline (plotted alongside)")
    add_perturbations(s)
    add_flights(s, "statuses, TIME_LIMIT runs and hard-bound violations per flight, as "
                "`rollmpc report --flights` flies them; of the output files only --json")
    s.add_argument("--against-unbudgeted", action="store_true",
                   help="with --flights: fly each flight again without a work budget and "
                   "name the hard bounds the budget lost (passed further than the "
                   "unbudgeted loop on the same flight; warning bound_lost_to_budget)")
    s.add_argument("--steps", type=int, default=None,
                   help="samples (default: whole scenario; with --flights, per flight)")
    add_quiet(s, "no progress bar")
    add_build_dir(s)
    s.set_defaults(func=run)


def write_csv(path: str | Path, ctx: dict, log: ClosedLoopLog) -> Path:
    from ..sim.simulate import csv_header, work_cell

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
                        int(log.iterations[k]), f"{log.solve_us[k]:.3f}",
                        work_cell(log, k)])
    return path


def _check_args(args) -> None:
    check_steps(args)
    check_perturbations(args)
    check_outputs(args, OUTPUTS)
    check_flights(args)
    if args.flights:
        for opt in ("csv", "plot"):
            if getattr(args, opt):
                raise ConfigError(f"--{opt}", "writes one closed loop: drop --flights "
                                  "(rerun one flight with --flights 1 --seed <its seed>)")
        if args.baseline != "none":
            raise ConfigError("--baseline", "runs on the scenario only: drop --flights")
    elif args.against_unbudgeted:
        raise ConfigError("--against-unbudgeted", "compares random flights: add --flights K")


def solver_text(ctx: dict) -> str:
    """The solver as configured, e.g. ``hildreth_plus_prime + polish``."""
    return f"{ctx['solver']['method']}{' + polish' if ctx['solver']['polish'] else ''}"


def signals_text(cfg, violations: dict) -> str:
    """``, signals N`` (samples past a hard signal bound) for a design with constrained
    signals, else empty."""
    if not any(m.signals for m in cfg.modes):
        return ""
    return f", signals {violations.get('z', 0)}"


def non_optimal_text(counts: dict, before: str = "", after: str = "") -> str:
    """The statuses other than optimal with their counts, e.g. ``time_limit 63``, between
    ``before`` and ``after``; empty when every sample was optimal."""
    others = ", ".join(f"{name} {n}" for name, n in counts.items() if name != "optimal")
    return f"{before}{others}{after}" if others else ""


def print_warnings(found) -> None:
    """The run's warnings (ScenarioRun.warnings: its own, then generate's), one line
    each; ``*`` marks the short segments the first names."""
    for w in found:
        print(f"  warning: {'* ' if w.code == 'short_segment' else ''}{w.message}")


def _unit(cfg, names) -> str:
    """`` [u]`` when every output of ``names`` has the unit u, else "" (a signal has none)."""
    from ..sim.run_checks import output_units

    units = output_units(cfg)
    found = {units.get(n, "") for n in names}
    return f" [{found.pop()}]" if len(found) == 1 and "" not in found else ""


def _settled(value: float, seg: dict) -> str:  # *: the window includes the preview
    return f"{value:.3g}" + ("*" if seg["settled_window_includes_preview"] else "")


def print_tracking(cfg, s: dict) -> None:
    """Settled error and overshoot per segment: one line each when every output is
    weighted and they share a unit (or none has one), else a line per output with its
    unit, an unweighted one marked as left out of the max."""
    weighted, segments = s["weighted_outputs"], s["segments"]
    unit = _unit(cfg, weighted)
    top = "-" if s["max_settled_error"] is None else f"{s['max_settled_error']:.3g}"
    if len(weighted) == cfg.n_outputs and (unit or not any(cfg.units.outputs)):
        errs = ", ".join(_settled(x["settled_error"], x) for x in segments)
        print(f"  settled |y - r| per segment{unit}: {errs} (max {top})")
        over = ", ".join(f"{x['overshoot']:.3g}" for x in segments)
        print(f"  overshoot per segment{unit}: {over}")
        return
    for name in cfg.outputs:
        errs = ", ".join(_settled(x["settled_error_by_output"][name], x) for x in segments)
        over = ", ".join(f"{x['overshoot_by_output'][name]:.3g}" for x in segments)
        note = "" if name in weighted else " (Q = P = 0: not weighted, not in the max)"
        print(f"  {name}{_unit(cfg, [name])}{note}: settled |y - r| per segment {errs}; "
              f"overshoot {over}")
    print(f"  max settled |y - r| of the weighted outputs{unit}: {top}")


def print_summary(cfg, ctx: dict, s: dict, found=()) -> None:
    from ..sim.metrics import work_text
    from ..sim.run_checks import beyond_text

    names = [m.name for m in cfg.modes]
    y_unit, u_unit = cfg.units.label("outputs"), cfg.units.label("actuators")
    print(f"rollmpc simulate: {s['samples']} samples ({s['duration_s']:g} s), "
          f"{ctx['precision']}, solver {solver_text(ctx)}")
    print_tracking(cfg, s)
    modes = ", ".join(f"{n} {s['by_mode'][n]['samples']}" for n in names)
    print(f"  switches: {s['switches']} (samples per mode: {modes})")
    umax = ", ".join(f"{a} {v:g}" for a, v in s["max_abs_u"].items())
    cv = s["constraint_violations"]
    far = beyond_text(cfg, cv["y_max_beyond"])
    print(f"  max |u|{u_unit}: {umax}; constraint violations: {cv['total']} "
          f"(u {cv['u']}, inactive {cv['inactive_actuator_nonzero']}, y {cv['y']}"
          f"{signals_text(cfg, cv)}"
          f"{f' by up to {far}' if far else ''}; hard "
          f"bounds, beyond {s['violation_tolerance']:g} max(1, |bound|))")
    if s.get("soft_bounds"):
        sb = s["soft_bounds"]
        print(f"  soft output bounds: a plan exceeds one (slack > 0) in "
              f"{sb['samples_with_slack']} samples, max slack {sb['max_slack']:.3g}{y_unit}; "
              f"the output is beyond one in {sb['samples_beyond']} samples, max "
              f"{sb['max_beyond']:.3g}{y_unit} (not violations)")
    st = s["solve_us"]
    if st["median"] is not None:
        print(f"  non-optimal: {s['non_optimal']}{non_optimal_text(s['status_counts'], ' (', ')')}"
              f"; longest "
              f"TIME_LIMIT run {s['longest_time_limit_run']}; "
              f"max fallback sweeps: {s['max_iterations']}; "
              f"host solve time median {st['median']:.1f} us, max {st['max']:.1f} us (wall clock: "
              "preemption included; the work line and `rollmpc report` are deterministic)")
    if s.get("work"):
        print(f"  solver work per sample (units): {work_text(s['work'])}")
    print_warnings(found)
    base = s.get("baseline")
    if base is not None:
        errs = ", ".join(f"{x['settled_error']:.3g}" for x in base["segments"])
        print(f"  LQR baseline: settled |y - r| per segment{_unit(cfg, s['weighted_outputs'])}: "
              f"{errs}; switches {base['switches']}; "
              f"constraint violations {base['constraint_violations']['total']}")


def print_flights(cfg, ctx: dict, s: dict, found=()) -> None:
    """A line per flight, then the totals and the warnings (FlightsRun.warnings)."""
    from ..sim.metrics import work_text
    from ..sim.run_checks import beyond_text

    t = s["totals"]
    print(f"rollmpc simulate: {t['flights']} random flights of {s['steps']} samples, "
          f"{ctx['precision']}, solver {solver_text(ctx)}")
    for f in s["flights"]:
        cv = f["constraint_violations"]
        far = beyond_text(cfg, cv["y_max_beyond"])
        print(f"  flight {f['flight']} (seed {f['seed']}, {f['kind']}): optimal "
              f"{f['status_counts'].get('optimal', 0)} of {f['samples']}"
              f"{non_optimal_text(f['status_counts'], ' (', ')')}, longest TIME_LIMIT "
              f"run {f['longest_time_limit_run']}; constraint violations {cv['total']}"
              f"{f' (by up to {far})' if far else ''}{_against_unbudgeted(cfg, f)}")
    for label, t in [("all flights", s["totals"])] + [
            (f"{kind} flights", k) for kind, k in s.get("by_kind", {}).items()]:
        far = beyond_text(cfg, t["y_max_beyond"])
        print(f"  {label}: optimal {t['status_counts'].get('optimal', 0)} of {t['samples']} "
              f"({t['optimal_percent']:g} %), longest TIME_LIMIT run "
              f"{t['longest_time_limit_run']}; {t['flights_with_violations']} of "
              f"{t['flights']} flights break a hard bound{f' (by up to {far})' if far else ''}")
        if t["work"]:
            print(f"    solver work per sample (units): {work_text(t['work'])}")
    free = s["totals"].get("against_unbudgeted")
    if free:
        print(f"  without a budget: optimal {free['unbudgeted_optimal_percent']:g} %, "
              f"{free['unbudgeted_flights_with_violations']} of {s['totals']['flights']} flights "
              f"break a hard bound; the budget lost one on {free['flights_losing_bounds']}")
    print_warnings(found)


def _against_unbudgeted(cfg, flight: dict) -> str:
    """``; unbudgeted: violations N (...)``, and the bounds the budget lost, with
    --against-unbudgeted; else empty."""
    from ..sim.run_checks import beyond_text

    free = flight.get("unbudgeted")
    if free is None:
        return ""
    far = beyond_text(cfg, free["constraint_violations"]["y_max_beyond"])
    lost = ", ".join(f"{name} {v:.3g} against {u:.3g}"
                     for name, (v, u) in flight["bounds_lost_to_budget"].items())
    return (f"; unbudgeted: violations {free['constraint_violations']['total']}"
            f"{f' (by up to {far})' if far else ''}{f'; LOST to the budget: {lost}' if lost else ''}")


def run_flights_cli(args) -> int:
    from ..sim.flights_run import run_flights

    result = run_flights(args.config, flights=args.flights, seed=args.seed,
                         precision=args.precision, steps=args.steps, noise_std=args.noise,
                         disturbance=args.disturbance, mismatch=args.mismatch,
                         kinds=args.flight_kinds, build_dir=args.build_dir,
                         against_unbudgeted=args.against_unbudgeted,
                         progress=progress_of(args))
    if args.json:
        write_json(args.json, result.summary)
    print_flights(result.config, result.ctx, result.summary, result.warnings)
    if args.json:
        print(f"rollmpc: wrote {args.json}")
    sys.stdout.flush()
    return 0


def run(args) -> int:
    from ..sim.scenario_run import run_scenario

    _check_args(args)
    if args.flights:
        return run_flights_cli(args)
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
    print_summary(result.config, ctx, result.summary, result.warnings)
    for opt in OUTPUTS:
        if getattr(args, opt):
            print(f"rollmpc: wrote {getattr(args, opt)}")
    sys.stdout.flush()
    return 0
