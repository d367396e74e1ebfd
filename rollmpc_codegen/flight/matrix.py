"""The tables of docs/flight.md.

1. Every turbulence level x seed: the MPC, the MPC without its reference preview and the
   PID baseline on the same flight (``run_flight(baseline="pid")``), and each MPC flight
   replayed on the emulated Cortex-M4F (``rollmpc report --flight``), with the image's
   flash on the config's part.
2. Sensor latency (moderate turbulence, IMU noise 0.1): the config as given (and whether
   ``fly`` warned before the flight), the same modes identified with the latency modelled
   (``rollmpc identify --latency``), the PID.
3. Five aircraft of different classes (:mod:`.matrix_aircraft`).

    python -m rollmpc_codegen.flight.matrix [--config examples/c172_roll.yaml]
        [--seeds 1,2,3] [--precision float] [--no-target] [--latencies 0,2,5,10]
        [--no-aircraft] [--json matrix.json]

prints the markdown on stdout and progress on stderr (``make flight-matrix``). The MPC
flies in ``--precision`` (default float: the build that runs on the M4F, so the replay
reproduces the flown commands bit for bit).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from .aircraft import TURBULENCE

DEFAULT_CONFIG = "examples/c172_roll.yaml"
DEFAULT_SEEDS = (1, 2, 3)
DEFAULT_LATENCIES = (0, 2, 5, 10)  # samples
LATENCY_TURBULENCE, LATENCY_NOISE = "moderate", 0.1


def _flight_row(s: dict) -> dict:
    """The numbers of one controller's flight summary that the table shows."""
    return {"rms": s["rms_roll_error_deg"],
            "settled": [x["settled_error"] for x in s["segments"]],
            "overshoot": [x["overshoot"] for x in s["segments"]],
            "settling": [x["transition_time_s"] for x in s["segments"]],
            "aileron_travel": s["aileron"]["travel_deg"],
            "aileron_max_rate": s["aileron"]["max_rate_dps"],
            "altitude_excursion": s["altitude_excursion_ft"],
            "stalled": s["stalled_samples"], "statuses": s["status_counts"],
            "switches": s["switches"], "max_iterations": s["max_iterations"]}


def fly_condition(config: str, turbulence: str, seed: int, precision: str, target: bool,
                  work: Path, build_dir=None, progress=None) -> dict:
    """One cell: MPC + PID, the MPC without preview, and the M4F replay."""
    from ..cli.fly import write_flight_csv
    from ..target.report import run_report
    from .run import run_flight

    run = run_flight(config, baseline="pid", turbulence=turbulence, seed=seed,
                     precision=precision, build_dir=build_dir, progress=progress)
    cell = {"turbulence": turbulence, "seed": seed, "mpc": _flight_row(run.summary),
            "pid": _flight_row(run.summary["baseline"]),
            "mpc_no_preview": _flight_row(run.summary["no_preview"])}
    if target:
        csv_path = write_flight_csv(work / f"{turbulence}_{seed}.csv", run.ctx, run.log)
        rep = run_report(config, precision=precision, flight=csv_path, host_repeats=3,
                         build_dir=build_dir, progress=progress)
        cell["m4f"] = {"worst_cycles": rep["worst_step_cycles"],
                       "median_cycles": rep["median_step_cycles"],
                       "bit_exact_vs_host": rep["bit_exact_vs_host"],
                       "commands_match_flight": rep["flight"]["commands_match"],
                       "flash_bytes": rep["flash_bytes"], "part": rep["budget"]["target"],
                       "flash_fits": rep["verdicts"].get("flash")}
    return cell


def latency_rows(config: str, latencies, seeds, precision: str, work: Path, build_dir=None,
                 progress=None) -> list[dict]:
    """Per latency K and seed: the config, the example's modes identified with K samples
    of latency (identify.EXAMPLE_AIRSPEEDS_KTS at aircraft.DEFAULT_ALTITUDE_FT) and the
    PID, each flying with K samples of delay and LATENCY_NOISE."""
    from .aircraft import DEFAULT_AIRCRAFT, DEFAULT_ALTITUDE_FT
    from .identify import EXAMPLE_AIRSPEEDS_KTS
    from .identify_config import identify_config
    from .run import run_flight

    rows = []
    for K in latencies:
        modelled = config
        if K:
            modelled = work / f"latency{K}.yaml"
            modelled.write_text(identify_config(DEFAULT_AIRCRAFT, EXAMPLE_AIRSPEEDS_KTS,
                                                DEFAULT_ALTITUDE_FT, K).text)
        for seed in seeds:
            common = dict(turbulence=LATENCY_TURBULENCE, noise_std=LATENCY_NOISE, delay=K,
                          seed=seed, precision=precision, build_dir=build_dir,
                          progress=progress)
            given = run_flight(config, baseline="pid", **common)
            rows.append({"latency": K, "seed": seed, "mpc": _flight_row(given.summary),
                         "warned": "delay_beyond_margin" in {w["code"] for w in
                                                             given.summary["warnings"]},
                         "pid": _flight_row(given.summary["baseline"]),
                         "mpc_latency_model": _flight_row(
                             run_flight(modelled, **common).summary)})
    return rows


def run_matrix(config: str = DEFAULT_CONFIG, seeds=DEFAULT_SEEDS, precision: str = "float",
               conditions=tuple(TURBULENCE), target: bool = True,
               latencies=DEFAULT_LATENCIES, aircraft: bool = True, build_dir=None,
               progress=None) -> dict:
    from .matrix_aircraft import run_cases

    with tempfile.TemporaryDirectory(prefix="rollmpc-flights-") as work:
        cells = [fly_condition(config, t, seed, precision, target, Path(work), build_dir,
                               progress) for t in conditions for seed in seeds]
        latency = latency_rows(config, latencies, seeds, precision, Path(work), build_dir,
                               progress)
        cases = run_cases(seeds, precision, Path(work), build_dir=build_dir,
                          progress=progress) if aircraft else []
    return {"config": config, "precision": precision, "seeds": list(seeds), "cells": cells,
            "latency": latency, "aircraft": cases}


def _mean(values) -> float:
    return float(np.mean(values))


def _range(values, fmt: str = "{:.2f}") -> str:
    """mean [min, max] over the seeds."""
    v = np.asarray(values, float)
    return f"{fmt.format(v.mean())} [{fmt.format(v.min())}, {fmt.format(v.max())}]"


def _statuses(cells, who: str) -> str:
    total: dict = {}
    for c in cells:
        for k, v in c[who]["statuses"].items():
            total[k] = total.get(k, 0) + v
    return ", ".join(f"{k} {v}" for k, v in sorted(total.items()))


def _settling(values) -> str:
    """Mean settling time over the seeds, '-' if a seed never settles."""
    return "-" if any(v is None for v in values) else f"{np.mean(values):.2f}"


def _seed_mean(cells, who: str, key: str, segments=slice(None)) -> float | None:
    """Mean over the seeds of a scalar, or of a per-segment list's mean over ``segments``;
    None if a seed has a None there (a segment that never settles)."""
    values = []
    for c in cells:
        v = c[who][key]
        if isinstance(v, list):
            v = v[segments]
            if None in v:
                return None
            v = np.mean(v)
        values.append(v)
    return float(np.mean(values))


def latency_markdown(rows: list[dict]) -> str:
    """Table 2, means over the seeds."""
    who = ("mpc", "mpc_latency_model", "pid")
    out = ["| latency (samples) | fly warned | RMS roll error (deg) | settled error, mean of "
           "segments (deg) | transition, mean of segments 2-6 (s) | aileron travel (deg) |",
           "|---|---|---|---|---|---|"]
    for K in dict.fromkeys(r["latency"] for r in rows):
        cells = [r for r in rows if r["latency"] == K]

        def triple(key, segments=slice(None), fmt="{:.2f}"):
            values = (_seed_mean(cells, w, key, segments) for w in who)
            return " / ".join("-" if v is None else fmt.format(v) for v in values)
        warned = "yes" if all(c["warned"] for c in cells) else (
            "no" if not any(c["warned"] for c in cells) else "some")
        out.append(f"| {K} | {warned} | {triple('rms')} | {triple('settled')} | "
                   f"{triple('settling', slice(1, None))} | "
                   f"{triple('aileron_travel', fmt='{:.0f}')} |")
    out.append("")
    out.append("Each cell: MPC as configured / MPC identified with the latency modelled / PID; "
               "'fly warned': the delay_beyond_margin warning before the flight of the "
               "config as configured.")
    return "\n".join(out)


def _flash(cells) -> str:
    m4f = [c["m4f"] for c in cells if "m4f" in c]
    if not m4f:
        return ""
    m = m4f[0]
    fits = {True: "fits", False: "does NOT fit", None: "no flash declared"}[m["flash_fits"]]
    return f"Float image: {m['flash_bytes']:,} B of flash on the config's part ({m['part']}): {fits}."


def markdown(matrix: dict) -> str:
    conditions = list(dict.fromkeys(c["turbulence"] for c in matrix["cells"]))
    out = ["| turbulence | RMS roll error MPC (deg) | MPC without preview | PID | settled error "
           "MPC / without preview / PID (deg) | transition MPC / without preview / PID (s) | "
           "aileron travel MPC / PID (deg) | max aileron rate MPC / PID (deg/s) | MPC statuses | "
           "switches | M4F worst / median (cycles) | M4F bit-exact |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    who = ("mpc", "mpc_no_preview", "pid")
    for t in conditions:
        cells = [c for c in matrix["cells"] if c["turbulence"] == t]
        mpc = [c["mpc"] for c in cells]
        m4f = [c["m4f"] for c in cells if "m4f" in c]
        cycles = (f"{max(m['worst_cycles'] for m in m4f):,} / "
                  f"{int(_mean([m['median_cycles'] for m in m4f])):,}" if m4f else "-")
        exact = ("yes" if all(m["bit_exact_vs_host"] and m["commands_match_flight"]
                              for m in m4f) else "NO") if m4f else "-"

        def three(key, segments=slice(None)):
            values = (_seed_mean(cells, w, key, segments) for w in who)
            return " / ".join("-" if v is None else f"{v:.2f}" for v in values)
        out.append(f"| {t} | " + " | ".join(_range([c[w]["rms"] for c in cells]) for w in who)
                   + f" | {three('settled')} | {three('settling', slice(1, None))} | "
                   f"{_mean([m['aileron_travel'] for m in mpc]):.0f} / "
                   f"{_mean([c['pid']['aileron_travel'] for c in cells]):.0f} | "
                   f"{_mean([m['aileron_max_rate'] for m in mpc]):.0f} / "
                   f"{_mean([c['pid']['aileron_max_rate'] for c in cells]):.0f} | "
                   f"{_statuses(cells, 'mpc')} | "
                   f"{_range([m['switches'] for m in mpc], '{:.1f}')} | {cycles} | {exact} |")
    out += ["", _flash(matrix["cells"]), ""]
    for t in conditions:
        cells = [c for c in matrix["cells"] if c["turbulence"] == t]
        out.append(f"**{t}** (mean over seeds {', '.join(str(c['seed']) for c in cells)}; "
                   "transition: 10 % to 10 % of the step, '-' if a seed never settles)")
        out.append("")
        out.append("| segment | settled error MPC / without preview / PID (deg) | overshoot "
                   "(deg) | transition (s) |")
        out.append("|---|---|---|---|")
        for i in range(len(cells[0]["mpc"]["settled"])):
            col = {w: {key: [c[w][key][i] for c in cells]
                       for key in ("settled", "overshoot", "settling")} for w in who}
            out.append(f"| {i + 1} | "
                       + " / ".join(f"{_mean(col[w]['settled']):.2f}" for w in who) + " | "
                       + " / ".join(f"{_mean(col[w]['overshoot']):.2f}" for w in who) + " | "
                       + " / ".join(_settling(col[w]["settling"]) for w in who) + " |")
        out.append("")
    if matrix.get("latency"):
        out.append(latency_markdown(matrix["latency"]))
    if matrix.get("aircraft"):
        from .matrix_aircraft import cases_markdown

        out += ["", cases_markdown(matrix["aircraft"])]
    return "\n".join(out)


def main(argv=None) -> int:
    from ..cli.options import write_json
    from ..sim.simulate import progress_printer

    ap = argparse.ArgumentParser(prog="python -m rollmpc_codegen.flight.matrix",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=DEFAULT_CONFIG)
    ap.add_argument("--seeds", default=",".join(map(str, DEFAULT_SEEDS)))
    ap.add_argument("--precision", choices=["double", "float"], default="float")
    ap.add_argument("--turbulence", default=",".join(TURBULENCE),
                    help="comma-separated levels (default: all)")
    ap.add_argument("--no-target", action="store_true", help="skip the M4F replays")
    ap.add_argument("--latencies", default=",".join(map(str, DEFAULT_LATENCIES)),
                    help="sensor delays of table 2, samples ('' for none)")
    ap.add_argument("--no-aircraft", action="store_true",
                    help="skip table 3 (five aircraft identified and flown)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--build-dir", default=None)
    args = ap.parse_args(argv)
    matrix = run_matrix(args.config, [int(s) for s in args.seeds.split(",")], args.precision,
                        tuple(t for t in args.turbulence.split(",") if t), not args.no_target,
                        [int(k) for k in args.latencies.split(",") if k],
                        not args.no_aircraft, args.build_dir, progress_printer)
    if args.json:
        write_json(args.json, matrix)
    print(markdown(matrix))
    return 0


if __name__ == "__main__":
    sys.exit(main())
