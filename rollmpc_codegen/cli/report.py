"""``rollmpc report``: the target report (:func:`rollmpc_codegen.target.report.run_report`)
as a short summary on stdout (with ``--flights``, a line per flight), or with
``--horizons`` the per-horizon table (markdown, as docs/target.md shows it) and the fits;
``--json`` writes the whole report."""
from __future__ import annotations

from ..config.errors import ConfigError
from ..qp.work import STEP_FIXED_UNITS
from .options import (add_build_dir, add_command, add_config, add_flights, add_outputs,
                      add_part,
                      add_perturbations,
                      add_precision, add_quiet, check_flights, check_perturbations, check_steps,
                      progress_of, write_json)


def add_parser(sub) -> None:
    rp = add_command(sub, "report", "flash, RAM, stack and cycles on the emulated core of "
                     "the design's part, bit-exact against the host build", "Cross-compiles the controller with "
                     "the firmware flags, replays the config's scenario (or random flights, or "
                     "a recorded flight) on the emulated core of the target part (--part or target:), checks every output bit "
                     "for bit against the host build and counts the cycles of the hardest and "
                     "sampled steps; judges them against sample_time at target.cpu_mhz and "
                     "flash and RAM against the target: section.",
                     epilog="exit codes: 0 every verdict met; 3 a verdict failed (Ts, flash, "
                     "RAM, instance, bit-exactness), or with --check the report warned; 1 a "
                     "tool failed; 2 bad input (docs/checks.md, \"Exit codes\")")
    add_config(rp)
    add_precision(rp)
    add_part(rp)
    add_outputs(rp, json="write the report as JSON")
    rp.add_argument("--horizons", default=None,
                    help="comma-separated horizons (e.g. 25,50,100,200): tabulate generation "
                    "time, flash, RAM and cycles per horizon instead")
    rp.add_argument("--steps", type=int, default=None,
                    help="samples to replay, of the scenario or of each flight (default: the "
                    "scenario's length)")
    add_flights(rp, "each replayed on the target, its worst and median step")
    add_perturbations(rp)
    rp.add_argument("--sample-every", type=int, default=20,
                    help="count cycles on every n-th step besides the hardest (default 20)")
    rp.add_argument("--hardest", type=int, default=10,
                    help="count the top 3n steps by host solve time and the top n by polish "
                    "corrections, active rows and sweeps (default 10)")
    rp.add_argument("--host-repeats", type=int, default=5,
                    help="host runs whose smallest solve time per step ranks the hardest "
                    "steps (default 5)")
    rp.add_argument("--extra-cflags", default=None,
                    help="extra flags for the target build, appended to the firmware flags "
                    "(e.g. --extra-cflags=-fno-builtin or --extra-cflags=-ffp-contract=fast)")
    rp.add_argument("--flight", default=None, help="replay the controller inputs of a "
                    "`rollmpc fly --csv` flight instead of the scenario")
    rp.add_argument("--peer", choices=["daqp"], default=None,
                    help="also replay the scenario's QPs through DAQP's own C, single "
                    "precision, on the same emulated target, and set the two side by side")
    rp.add_argument("--check", action="store_true",
                    help="exit 3 on a warning too (TIME_LIMIT steps, a double build on the "
                    "single-precision target), not only on a failed verdict")
    add_quiet(rp)
    add_build_dir(rp)
    rp.set_defaults(func=run)


def parse_horizons(text: str) -> list[int]:
    try:
        values = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise ConfigError("--horizons", f"must be a comma-separated list of integers, "
                          f"got {text!r}") from None
    if not values or min(values) < 1:
        raise ConfigError("--horizons", "needs at least one horizon >= 1")
    return sorted(set(values))


def bit_exact_text(rep: dict) -> str:
    """``yes`` or ``NO`` with what differed: the commands, statuses and diagnostics, and
    the instance after every step (the host built with the target's kernels)."""
    kernels = rep.get("kernels")
    what = "commands and instance, every step" + (f"; {kernels} kernels on both"
                                                  if kernels else "")
    if rep["bit_exact_vs_host"]:
        return f"yes ({what})"
    found = [f"{rep['mismatches']} output mismatches"]
    state = rep.get("state_mismatch")
    if state:
        where = ("" if state.get("flight") is None else f" of flight {state['flight']}")
        members = ", ".join(state["members"]) or "a member"
        steps = f"{state['steps']} step{'s' if state['steps'] != 1 else ''}"
        found.append(f"the instance differs on {steps} from step "
                     f"{state['step']}{where}: {members}")
    return f"NO ({'; '.join(found)}; {what})"


def summary_text(rep: dict) -> str:
    """Short human summary with the verdict at the config's clock and sample time."""
    b = rep["budget"]
    verdict = "fits" if b["worst_fits"] else "DOES NOT fit"
    top = ", ".join(f"{r['function']} {100 * r['share']:.0f}%"
                    for r in rep["worst_step_top_functions"][:4])
    where = ("" if rep["worst_flight"] is None else f"flight {rep['worst_flight']}, ") + \
        f"step {rep['worst_step']}"
    lines = [
        f"rollmpc report: {rep['precision']}, N = {rep['horizon']}, {rep['toolchain']}",
        f"  flash {rep['flash_bytes']:,} B   static RAM {rep['ram_bytes']:,} B "
        f"(controller instance {rep['ctrl_bytes']:,} B)   stack {rep['stack_bytes']} B "
        f"(-fstack-usage worst path; measured {rep['stack_measured_bytes']} B of "
        f"{rep['stack_entry_bytes']} B predicted with the harness)",
        f"  steps emulated {rep['steps_emulated']}, counted {rep['steps_counted']} "
        f"({len(rep['hardest_steps'])} hardest + every {rep['sample_every']}th); "
        f"bit-exact vs host: {bit_exact_text(rep)}",
    ]
    for f in rep.get("flights", []):
        lines.append(f"  flight {f['flight']} (seed {f['seed']}, {f['kind']}): worst step "
                     f"{f['worst_step']} {f['worst_step_cycles']:,} cycles, median "
                     f"{f['median_step_cycles']:,}"
                     + ("" if f["bit_exact_vs_host"] else ", NOT bit-exact"))
    for kind, k in rep.get("by_kind", {}).items():
        lines.append(f"  {kind} flights ({k['flights']}): worst step {k['worst_step_cycles']:,} "
                     f"cycles (flight {k['worst_flight']}), optimal {k['optimal_percent']:g} %, "
                     f"longest TIME_LIMIT run {k['longest_time_limit_run']}")
    lines += [
        f"  worst step ({where}, mode {rep['worst_step_mode']}): "
        f"{rep['worst_step_cycles']:,} cycles, {rep['worst_step_instructions']:,} "
        f"instructions; median {rep['median_step_cycles']:,} cycles",
        f"  needs {rep['cpu_mhz_needed']} MHz for Ts = {1000 * rep['sample_time']:g} ms; "
        f"on {b.get('target') or str(b['cpu_mhz']) + ' MHz'} the worst step {verdict} "
        f"({b['worst_load_percent']}% of {b['cycles_per_sample']:,} cycles)",
        f"  worst step by function: {top}",
    ]
    cpw = rep.get("cycles_per_work_unit")
    if cpw and cpw["steps"]:
        flight = "" if cpw["flight_of_max"] is None else f"flight {cpw['flight_of_max']}, "
        lines.append(f"  cycles per work unit (each step over its work + the {STEP_FIXED_UNITS} "
                     f"outside the solver) on {cpw['steps']} counted steps: max {cpw['max']} "
                     f"({flight}step {cpw['step_of_max']}), median {cpw['median']}; work budget "
                     f"{rep['work_budget']:,} units")
    counts = rep.get("statuses", {})
    longest = rep.get("longest_time_limit_run", 0)
    lines.append(f"  solver statuses over {sum(counts.values())} steps: "
                 + ", ".join(f"{n} {c}" for n, c in counts.items())
                 + (f" (longest TIME_LIMIT run {longest})" if longest else ""))
    if rep["goals"]:
        goals = ", ".join(f"{k}: {'met' if v else 'MISSED'}" for k, v in rep["goals"].items())
        lines.append(f"  memory goals (the config's target: section): {goals}")
    lines += [f"  warning: {w['message']}" for w in rep.get("checks", [])]
    if "verdicts" in rep:
        failed = [k for k, v in rep["verdicts"].items() if not v]
        lines.append(f"  verdict: {'FAILED (' + ', '.join(failed) + ')' if failed else 'passed'}"
                     f" ({', '.join(rep['verdicts'])})")
    return "\n".join(lines)


def peer_markdown(rep: dict) -> str:
    """Ours beside the peer, per mode: median and worst cycles, where each peaks."""
    peer = rep["peer"]
    lines = [f"| mode | ours median | ours worst (step) | {peer['name']} median | "
             f"{peer['name']} worst (step) | {peer['name']} statuses | {peer['name']} max u "
             "beyond limits (QPs) |", "|---|---:|---:|---:|---:|---|---:|"]
    for name, theirs in peer["by_mode"].items():
        ours = rep["by_mode"].get(name, {})
        statuses = ", ".join(f"{n} {c}" for n, c in theirs["statuses"].items())
        lines.append(f"| {name} | {ours.get('median_cycles') or 0:,} | "
                     f"{ours.get('worst_cycles', 0):,} ({ours.get('worst_step')}) | "
                     f"{theirs['median_cycles']:,} | {theirs['worst_cycles']:,} "
                     f"({theirs['worst_qp']}) | {statuses} | "
                     f"{theirs['max_u_beyond_limits']:.3g} ({theirs['qps_beyond_limits']}) |")
    return "\n".join(lines)


def horizons_markdown(table: dict) -> str:
    """The per-horizon table and the fits as markdown (what docs/target.md shows)."""
    lines = ["| N | generation (s) | flash (B) | static RAM (B) | stack (B) | worst step "
             "(cycles) | median step (cycles) | MHz needed | bit-exact |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|:---:|"]
    for r in table["rows"]:
        lines.append(f"| {r['horizon']} | {r['generation_s']:.2f} | {r['flash_bytes']:,} | "
                     f"{r['ram_bytes']:,} | {r['stack_bytes']} | {r['worst_step_cycles']:,} | "
                     f"{r['median_step_cycles']:,} | {r['cpu_mhz_needed']} | "
                     f"{'yes' if r['bit_exact_vs_host'] else 'NO'} |")
    lines.append("")
    lines.append("Fitted growth (least squares on log-log over all horizons; in brackets "
                 "the slope between the two largest): " + ", ".join(
                     f"{k} ∝ N^{v['exponent']} [{v['exponent_last_pair']}]"
                     for k, v in table["fits"].items()))
    return "\n".join(lines)


def print_horizons(table: dict) -> None:
    print(horizons_markdown(table))
    for r in table["refused"]:
        print(f"N = {r['horizon']}: not generated: {r['error']}")
    b = table["budget"]
    print(f"\nlargest measured horizon within Ts = {1000 * b['sample_time']:g} ms at "
          f"{b['cpu_mhz']:g} MHz: {table['largest_measured_horizon_within_budget']}; "
          f"fitted limit N ~ {table['fitted_horizon_limit']}")
    for part in table["parts"]:
        print(f"  {part['part']}: fits memory for N in {part['horizons_that_fit_memory']}")


def run(args) -> int:
    from ..target.report import run_report

    check_steps(args)
    check_perturbations(args)
    check_flights(args)
    if args.sample_every < 1 or args.hardest < 0 or args.host_repeats < 1:
        raise ConfigError("--sample-every/--hardest/--host-repeats", "must be >= 1, >= 0, >= 1")
    horizons = parse_horizons(args.horizons) if args.horizons else None
    result = run_report(args.config, precision=args.precision, part=args.part,
                        horizons=horizons,
                        steps=args.steps, flights=args.flights, seed=args.seed,
                        noise_std=args.noise, disturbance=args.disturbance,
                        mismatch=args.mismatch, kinds=args.flight_kinds,
                        sample_every=args.sample_every,
                        hardest=args.hardest, host_repeats=args.host_repeats,
                        extra_cflags=tuple(args.extra_cflags.split()) if args.extra_cflags
                        else (), build_dir=args.build_dir, flight=args.flight,
                        peer=args.peer, progress=progress_of(args))
    if horizons:
        print_horizons(result["horizons"])
    else:
        print(summary_text(result))
    if "peer" in result:
        print(peer_markdown(result))
    if "flight" in result:
        f = result["flight"]
        print(f"  flight {f['path']}: {f['samples']} samples; host replay == the flight's "
              f"commands: {'yes' if f['commands_match'] else 'NO'} "
              f"({f['mismatching_samples']} samples differ)")
    if args.json:
        write_json(args.json, result)
    return exit_code(result, args.check)


def exit_code(rep: dict, check: bool) -> int:
    """0, or EXIT_VERDICT_FAILED when a verdict failed, or with ``--check`` when the
    report warned (docs/checks.md, "Exit codes"); --horizons tabulates: 0."""
    from ..target.verdicts import EXIT_VERDICT_FAILED

    if "horizons" in rep:
        return 0
    failed = not rep["passed"] or (check and bool(rep["checks"]))
    return EXIT_VERDICT_FAILED if failed else 0
