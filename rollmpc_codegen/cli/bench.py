"""``rollmpc bench``: the paper's Table 2 (:func:`rollmpc_codegen.host.bench.run_bench`) as
a markdown table on stdout, with the run's header and the check of the paper's reduced
set; ``--json`` writes the whole result, ``--plot`` Fig. 3 (every QP's solve time)."""
from __future__ import annotations

import sys

from ..config import ConfigError
from .options import (add_build_dir, add_command, add_config, add_outputs, add_precision,
                      add_quiet, check_outputs, check_steps, progress_of, require_plot,
                      write_json)

# the rows of host.bench (ROWS, OURS_AND_PEERS, PAPER_VARIANTS); only the parser's help
# text repeats them (building the parser must not import the library)
VARIANTS_HELP = ("comma-separated rows to run, of hildreth, hildreth_plus, "
                 "hildreth_plus_prime, default, quadprog, daqp, daqp_c, daqp_c_solve, osqp, "
                 "osqp_tight (default: default,quadprog,daqp,osqp, each peer where "
                 "installed; quadprog, the reference, always runs; daqp_c and daqp_c_solve "
                 "build DAQP's C from its sdist and time it like ours)")
PAPER_HELP = ("also run the paper's variants hildreth, hildreth_plus, hildreth_plus_prime "
              "(slow: up to 2 s per QP on the UAV)")


def add_parser(sub) -> None:
    b = add_command(sub, "bench", "time the design's QPs: our solver against DAQP, quadprog "
                    "and OSQP", "Records the QPs of the config's scenario and replays them "
                    "through the generated solver (and, with --paper or --variants, its other "
                    "variants) and the installed peers, all checked against quadprog; prints "
                    "a markdown table of solve times, iterations and accuracy (the paper's "
                    "Table 2 on examples/uav_roll.yaml).")
    add_config(b)
    add_precision(b)
    add_outputs(b, json="write the table and the machine description as JSON",
                plot="per-QP solve times (Fig. 3 style) as a PNG")
    b.add_argument("--variants", default=None, help=VARIANTS_HELP)
    b.add_argument("--paper", action="store_true", help=PAPER_HELP)
    b.add_argument("--max-qps", type=int, default=None,
                   help="replay at most this many QPs: evenly spread blocks of 20 "
                   "consecutive ones (default: every QP)")
    b.add_argument("--repeat", type=int, default=1,
                   help="replay R times from a fresh start and keep each QP's minimum time "
                   "(removes OS preemption from the maxima)")
    b.add_argument("--include-transient", action="store_true",
                   help="also replay samples 1-32 (the paper's Table 2 skips them)")
    b.add_argument("--steps", type=int, default=None,
                   help="scenario samples to record (default: the whole scenario)")
    add_quiet(b)
    add_build_dir(b)
    b.set_defaults(func=run)


def parse_variants(text: str | None) -> list[str]:
    """The rows of ``--variants`` in the table's order, with the reference (None: every row)."""
    from ..host.bench import ROWS, table_rows

    if text is None:
        return list(ROWS)
    keys = [k.strip() for k in text.split(",") if k.strip()]
    try:
        rows = table_rows(keys)
    except ValueError as exc:
        raise ConfigError("--variants", str(exc)) from None
    if not keys:
        raise ConfigError("--variants", "give at least one row")
    return rows


def _check_args(args) -> list[str] | None:
    """The rows of ``--variants`` (None: the default rows); ConfigError on a bad option."""
    from ..host.bench_record import TRANSIENT_SAMPLES

    keys = None if args.variants is None else parse_variants(args.variants)
    if args.repeat < 1:
        raise ConfigError("--repeat", f"must be >= 1, got {args.repeat}")
    if args.max_qps is not None and args.max_qps < 1:
        raise ConfigError("--max-qps", f"must be >= 1, got {args.max_qps}")
    check_steps(args)
    if args.steps is not None and args.steps <= TRANSIENT_SAMPLES and not args.include_transient:
        raise ConfigError("--steps", f"leaves no QP to replay after skipping the first "
                          f"{TRANSIENT_SAMPLES} samples (use --include-transient)")
    check_outputs(args, ("json", "plot"))
    return keys


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


def header(s: dict) -> str:
    """What was replayed, how it was timed, on which machine."""
    from ..host.bench_record import SAMPLE_BLOCK

    skipped = s["skipped_transient_samples"]
    samples = "all samples" if not skipped else f"samples {skipped + 1}-{s['scenario_samples']}"
    machine = s["machine"]
    return (f"rollmpc bench: {s['qps']} QPs of the {s['scenario_samples']}-sample scenario "
            f"({samples}"
            f"{f', in blocks of {SAMPLE_BLOCK} consecutive QPs' if s['sampled'] else ''}); "
            f"{s['timing']}; {machine['cpu']} ({machine['cores']} "
            f"cores, load {machine['load_average'][0]:.1f}), {s['precision']}")


def reduced_set_text(rs: dict) -> str:
    return (f"\nPaper's reduced set {{K < sigma = {rs['sigma']:g}}} alone, solved exactly: "
            f"{rs['violating_qps']} of {rs['constrained_qps']} constrained QPs violate rows "
            f"outside the set (max violation {rs['max_row_violation']:.3g}; max |u0| "
            f"{rs['max_abs_u0']:.3g}; planned inputs up to {rs['max_U_beyond_limit']:.3g} "
            f"beyond their limits; first move within {rs['max_abs_err_u0_vs_quadprog']:.2g} "
            f"of quadprog)"
            + (f"; {rs['infeasible_qps']} infeasible QPs left out (their reduced rows are "
               f"inconsistent)" if rs.get("infeasible_qps") else "") + ".")


def note_missing_peers() -> None:
    """The default rows leave out the peers that are not installed: say so on stderr."""
    from ..host.bench import OURS_AND_PEERS, default_variants

    for key in sorted(set(OURS_AND_PEERS) - set(default_variants()), key=OURS_AND_PEERS.index):
        print(f"rollmpc bench: {key} is not installed, its row is left out "
              "(pip install 'rollmpc-codegen[peers]')", file=sys.stderr)


def run(args) -> int:
    from ..host.bench import run_bench

    keys = _check_args(args)
    require_plot(args)
    if keys is None:
        note_missing_peers()
    result = run_bench(args.config, precision=args.precision, variants=keys,
                       paper=args.paper, max_qps=args.max_qps, repeat=args.repeat,
                       include_transient=args.include_transient, steps=args.steps,
                       build_dir=args.build_dir, progress=progress_of(args))
    s = result.summary
    print(header(s))
    print()
    print(markdown_table(result.rows, s["sample_time"]))
    print(reduced_set_text(s["reduced_set_check"]))
    if args.json:
        print(f"rollmpc: wrote {write_json(args.json, s)}")
    if args.plot:
        from ..sim.figures import plot_solve_times

        plot_solve_times(args.plot, result.rows, result.replays, result.samples,
                         s["sample_time"])
        print(f"rollmpc: wrote {args.plot}")
    sys.stdout.flush()
    return 0
