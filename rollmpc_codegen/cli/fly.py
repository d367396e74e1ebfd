"""``rollmpc fly``: the generated C flies a JSBSim aircraft
(:func:`rollmpc_codegen.flight.run.run_flight`), printed and written.

Outputs (each optional):

* ``--csv``: one row per sample: the columns of ``rollmpc simulate --csv`` for the
  controller (``y`` is the roll it was given, ``rho`` the airspeed, ``r`` the reference;
  ``rollmpc report --flight`` replays them), then ``roll_rate_fed`` and the aircraft's
  true signals ``true_<signal>`` (flight.loop.AIRCRAFT_SIGNALS).
* ``--json``: the metrics of :mod:`rollmpc_codegen.flight.metrics` (with ``--baseline
  pid``, ``no_preview`` holds the MPC's without the preview and ``baseline`` the PID's,
  with its gains).
* ``--plot``: the flight in the style of Fig. 2 (:mod:`rollmpc_codegen.flight.plot`).
"""
from __future__ import annotations

import csv
import sys
from pathlib import Path

from ..config.errors import ConfigError
from ..flight.aircraft import DEFAULT_AIRCRAFT, TURBULENCE
from .options import (add_build_dir, add_command, add_config, add_outputs, add_precision,
                      add_quiet, check_outputs, progress_of, require_plot, write_json)
from ..sim.metrics import work_text
from ..sim.simulate import csv_header, work_cell
from .simulate import solver_text

OUTPUTS = ("csv", "json", "plot")


def add_parser(sub) -> None:
    f = add_command(sub, "fly", "fly the generated C on a JSBSim aircraft (needs the flight "
                    "extra)", "Closes the loop of the generated roll controller on a nonlinear "
                    "6-DOF JSBSim aircraft in turbulence, with IMU noise and latency, "
                    "optionally beside a PX4-style PID (docs/flight.md).")
    add_config(f)
    f.add_argument("--aircraft", default=None,
                   help="a JSBSim aircraft of the jsbsim wheel (default: the config's "
                   f"aircraft section, else {DEFAULT_AIRCRAFT})")
    f.add_argument("--airspeed", type=float, default=None,
                   help="trim airspeed at the start, kts (default: the config's design point)")
    f.add_argument("--altitude", type=float, default=None,
                   help="trim altitude, held, ft (default: the config's)")
    f.add_argument("--turbulence", choices=list(TURBULENCE), default="none",
                   help="MIL-F-8785C Dryden turbulence (JSBSim's reference intensities)")
    f.add_argument("--noise", type=float, default=0.0,
                   help="IMU noise std on roll (deg) and roll rate (deg/s)")
    f.add_argument("--delay", type=int, default=0, help="sensor latency in samples")
    f.add_argument("--seed", type=int, default=0, help="turbulence and noise seed")
    f.add_argument("--duration", type=float, default=None,
                   help="seconds to fly (default: the whole reference)")
    f.add_argument("--reference", default=None,
                   help="a peak bank angle in deg (the paper's levels scaled to it; default "
                   "30) or a CSV file with columns t,roll[,airspeed]")
    add_precision(f)
    add_outputs(f, csv="per-sample log (the controller's inputs and the aircraft)",
                json="write the flight metrics as JSON",
                plot="write the flight as a PNG: bank, reference, aileron")
    f.add_argument("--baseline", choices=["none", "pid"], default="none",
                   help="also fly the MPC without its preview and the PX4-style PID, tuned "
                   "for the aircraft, on the same flight (the PID plotted dashed)")
    add_quiet(f, "no progress bar")
    add_build_dir(f)
    f.set_defaults(func=run)


def flight_csv_header(ctx: dict) -> list[str]:
    from ..flight.loop import AIRCRAFT_SIGNALS

    return csv_header(ctx) + ["roll_rate_fed"] + [f"true_{s}" for s in AIRCRAFT_SIGNALS]


def write_flight_csv(path: str | Path, ctx: dict, log) -> Path:
    from ..flight.loop import AIRCRAFT_SIGNALS

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    c, ns = log.controller, ctx["n_schedule"]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(flight_csv_header(ctx))
        for k in range(len(c.t)):
            w.writerow([k, repr(float(c.t[k])), repr(float(c.r[k, 0])), repr(float(c.y[k, 0])),
                        *([repr(float(c.sched[k, 0]))] if ns else []), int(c.mode[k]),
                        repr(float(c.u[k, 0])), int(c.status[k]), int(c.iterations[k]),
                        f"{c.solve_us[k]:.3f}", work_cell(c, k), repr(float(log.rate_fed[k])),
                        *(repr(float(log.aircraft[s][k])) for s in AIRCRAFT_SIGNALS)])
    return path


def _check_args(args) -> None:
    for name in ("noise", "airspeed", "altitude"):
        value = getattr(args, name)
        if value is not None and not (0 <= value < float("inf")):
            raise ConfigError(f"--{name}", f"must be finite and >= 0, got {value}")
    if args.delay < 0:
        raise ConfigError("--delay", f"must be >= 0, got {args.delay}")
    if args.duration is not None and not 0 < args.duration < float("inf"):
        raise ConfigError("--duration", f"must be > 0, got {args.duration}")
    check_outputs(args, OUTPUTS)


def _segments(summary: dict, key: str, fmt: str = "{:.3g}") -> str:
    return ", ".join("-" if s[key] is None else fmt.format(s[key]) for s in summary["segments"])


def print_summary(run) -> None:
    s, ctx = run.summary, run.ctx
    print(f"rollmpc fly: {s['aircraft']} from {run.trim.airspeed_kts:.0f} kts, "
          f"{run.trim.altitude_ft:.0f} ft; {s['samples']} samples ({s['duration_s']:g} s), "
          f"JSBSim at {s['fdm_rate_hz']:g} Hz; turbulence {s['turbulence']}, noise "
          f"{s['noise_std']:g}, delay {s['delay_samples']}, seed {s['seed']}; "
          f"{ctx['precision']}, solver {solver_text(ctx)}")
    margins = ", ".join(f"{k} {'>30' if v is None else v}" for k, v in s["delay_margins"].items())
    print(f"  delay margin of the MPC on its model (samples of unmodelled delay): {margins}")
    runs = [("MPC" if s["preview"] else "MPC without preview", s)]
    runs += [("MPC without preview", s["no_preview"])] if "no_preview" in s else []
    runs += [("PID", s["baseline"])] if "baseline" in s else []
    for name, m in runs:
        a, e = m["aileron"], m["engines"]
        print(f"  {name}: RMS roll error {m['rms_roll_error_deg']:.3g} deg; settled |roll - r| "
              f"per segment: {_segments(m, 'settled_error')} deg")
        print(f"       overshoot: {_segments(m, 'overshoot')} deg; transition (10 % to 10 %): "
              f"{_segments(m, 'transition_time_s', '{:.2f}')} s")
        print(f"       aileron: max |u| {a['max_abs_deg']:.3g} deg, travel {a['travel_deg']:.0f} "
              f"deg, rate max {a['max_rate_dps']:.0f} RMS {a['rms_rate_dps']:.1f} deg/s; "
              f"altitude excursion {m['altitude_excursion_ft']:.0f} ft, airspeed "
              f"{m['airspeed_kts']['min']:.0f}-{m['airspeed_kts']['max']:.0f} kts, "
              f"|sideslip| <= {m['max_abs_sideslip_deg']:.1f} deg")
        stall = "-" if m["stall_alpha_deg"] is None else f"{m['stall_alpha_deg']:g}"
        engines = "" if e["first_loss_s"] is None else \
            (f"; ENGINE LOSS: {e['count'] - e['min_running']} of {e['count']} stopped, the "
             f"first at t = {e['first_loss_s']:g} s")
        print(f"       alpha max {m['max_alpha_deg']:.1f} deg (stall {stall}): stalled samples "
              f"{m['stalled_samples']}{engines}")
    if "baseline" in s:
        g = s["baseline"]["gains"]
        print(f"  PID gains ({g['rule']}): tau {g['time_constant_s']:.3f} s, max rate "
              f"{g['max_rate_dps']:.0f} deg/s, FF {g['feed_forward']:.3f}, P {g['rate_p']:.3f}, "
              f"I {g['rate_i']:.3f}, scaling {g['trim_airspeed_kts']:g} kts / floor "
              f"{g['min_airspeed_kts']:g} kts")
    st = s["solve_us"]
    statuses = ", ".join(f"{k} {v}" for k, v in s["status_counts"].items())
    print(f"  MPC: switches {s['switches']}, statuses: {statuses}; longest TIME_LIMIT run "
          f"{s['longest_time_limit_run']}; host solve time median {st['median']:.1f} us, max "
          f"{st['max']:.1f} us")
    if s.get("work"):
        print(f"  solver work per sample (units): {work_text(s['work'])}")


def run(args) -> int:
    from ..flight.aircraft import require_jsbsim
    from ..flight.run import run_flight

    _check_args(args)
    require_jsbsim()
    require_plot(args)
    def warn(w) -> None:
        print(f"rollmpc: warning: {w.message}", file=sys.stderr)
        sys.stderr.flush()

    result = run_flight(args.config, aircraft=args.aircraft, airspeed_kts=args.airspeed,
                        altitude_ft=args.altitude, turbulence=args.turbulence,
                        noise_std=args.noise, delay=args.delay, seed=args.seed,
                        duration_s=args.duration, reference=args.reference,
                        precision=args.precision,
                        baseline=None if args.baseline == "none" else args.baseline,
                        build_dir=args.build_dir, progress=progress_of(args), warn=warn)
    if args.csv:
        write_flight_csv(args.csv, result.ctx, result.log)
    if args.json:
        write_json(args.json, result.summary)
    if args.plot:
        from ..flight.plot import plot_flight

        plot_flight(args.plot, result.config, result.log, result.baseline_log,
                    title=f"{Path(args.config).name} flies the JSBSim "
                          f"{result.summary['aircraft']}: turbulence {args.turbulence}, "
                          f"seed {args.seed} "
                          f"({result.ctx['precision']})")
    print_summary(result)
    for opt in OUTPUTS:
        if getattr(args, opt):
            print(f"rollmpc: wrote {getattr(args, opt)}")
    sys.stdout.flush()
    return 0
