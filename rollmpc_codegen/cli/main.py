"""``rollmpc`` command line: generate, simulate, bench, report, testvectors.

Expected failures print one line ``rollmpc: error: ...`` and exit with 2 (bad input:
config or arguments) or 1 (a tool failed, e.g. the C compiler); never a traceback.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..config import PRECISIONS, ConfigError

EXIT_BAD_INPUT = 2
EXIT_TOOL_FAILED = 1


def default_out_dir(config: str, precision: str | None) -> Path:
    stem = Path(config).stem
    return Path("generated") / (f"{stem}_f32" if precision == "float" else stem)


def cmd_generate(args) -> int:
    from ..pipeline import generate

    # `-o ''` reaches the writer, which refuses it (it is not the default directory)
    out = args.output if args.output is not None else default_out_dir(args.config, args.precision)
    model, ctx = generate(args.config, out, args.precision, args.force)
    sizes = ", ".join(f"{m['name']}: n={m['n']} m={m['m']}" for m in ctx["modes"])
    print(f"rollmpc: wrote {out}/ ({ctx['precision']}; {sizes})")
    return 0


def cmd_simulate(args) -> int:
    from .simulate import simulate_command

    return simulate_command(args)


def cmd_report(args) -> int:
    from ..target.report import report_command

    return report_command(args)


def cmd_testvectors(args) -> int:
    from ..host.testvectors import write_test_vectors

    path = write_test_vectors(args.config, args.output, args.precision, args.steps, args.force)
    print(f"rollmpc: wrote {path}")
    return 0


class OneLineArgumentParser(argparse.ArgumentParser):
    """Bad arguments: one line ``rollmpc: error: ...`` and exit 2 (no usage block)."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"rollmpc: error: {' '.join(message.split())}\n")


def cmd_bench(args) -> int:
    from ..host.bench import bench_command

    return bench_command(args)


def _add_build_dir(p: argparse.ArgumentParser) -> None:
    p.add_argument("--build-dir", default=None,
                   help="scratch directory for the host C builds (default: "
                   "$XDG_CACHE_HOME/rollmpc/build or ~/.cache/rollmpc/build, cached by "
                   "content hash; must be writable by you only)")


def _add_force(p: argparse.ArgumentParser) -> None:
    p.add_argument("--force", action="store_true",
                   help="also write into a directory rollmpc did not write: files named like "
                   "a generated file are overwritten, no other file is touched")


def _add_precision(p: argparse.ArgumentParser) -> None:
    p.add_argument("--precision", choices=PRECISIONS, default=None,
                   help="override the config's precision")


def parser() -> argparse.ArgumentParser:
    ap = OneLineArgumentParser(prog="rollmpc", description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)

    g = sub.add_parser("generate", help="render the C controller for a YAML config")
    g.add_argument("config")
    g.add_argument("-o", "--output", help="output directory (default generated/<config "
                   "name>, with _f32 for float)")
    _add_force(g)
    _add_precision(g)
    g.set_defaults(func=cmd_generate)

    s = sub.add_parser("simulate", help="closed loop of the generated C on the paper scenario")
    s.add_argument("config")
    _add_precision(s)
    s.add_argument("--csv", help="per-sample log")
    s.add_argument("--json", help="summary metrics")
    s.add_argument("--plot", help="Fig. 2 style PNG")
    s.add_argument("--baseline", choices=["none", "lqr"], default="none",
                   help="also simulate an LQR-with-saturation baseline (plotted alongside)")
    s.add_argument("--noise", type=float, default=0.0, help="measurement noise std (output units)")
    s.add_argument("--disturbance", type=float, default=0.0,
                   help="constant input disturbance on every actuator (actuator units)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--steps", type=int, default=None, help="samples (default: whole scenario)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_build_dir(s)
    s.set_defaults(func=cmd_simulate)

    b = sub.add_parser("bench", help="Table 2: replay the scenario's QPs through the "
                       "generated solver variants and the PyPI peers")
    b.add_argument("config")
    _add_precision(b)
    b.add_argument("--json", help="write the table and the machine description as JSON")
    b.add_argument("--plot", help="per-QP solve times (Fig. 3 style) as a PNG")
    b.add_argument("--variants", default=None,
                   help="comma-separated rows to run (default: all): "
                   "hildreth,hildreth_plus,hildreth_plus_prime,default,quadprog,daqp,osqp,"
                   "osqp_tight (quadprog, the reference, always runs)")
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
    b.add_argument("--quiet", action="store_true", help="no progress on stderr")
    _add_build_dir(b)
    b.set_defaults(func=cmd_bench)

    rp = sub.add_parser("report", help="flash, RAM, stack and cycles on an emulated "
                        "Cortex-M4F, bit-exact against the host build")
    rp.add_argument("config")
    _add_precision(rp)
    rp.add_argument("--json", help="write the report as JSON")
    rp.add_argument("--horizons", default=None,
                    help="comma-separated horizons (e.g. 25,50,100,200): tabulate generation "
                    "time, flash, RAM and cycles per horizon instead")
    rp.add_argument("--steps", type=int, default=None,
                    help="scenario samples to replay (default: the whole scenario)")
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
    rp.add_argument("--quiet", action="store_true", help="no progress on stderr")
    _add_build_dir(rp)
    rp.set_defaults(func=cmd_report)

    t = sub.add_parser("testvectors", help="emit the host C test program with reference vectors")
    t.add_argument("config")
    t.add_argument("-o", "--output", required=True, help="output directory")
    _add_force(t)
    _add_precision(t)
    t.add_argument("--steps", type=int, default=6000,
                   help="closed-loop steps to record (default: the whole scenario)")
    t.set_defaults(func=cmd_testvectors)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return args.func(args)
    except ConfigError as exc:
        print(f"rollmpc: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("rollmpc: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a tool failed: one line (ROLLMPC_DEBUG=1 re-raises)
        import os

        from ..host.build import BuildError

        if os.environ.get("ROLLMPC_DEBUG"):
            raise
        lines = str(exc).strip().splitlines() or [type(exc).__name__]
        kind = "build failed" if isinstance(exc, BuildError) else type(exc).__name__
        print(f"rollmpc: error: {kind}: {lines[0]}", file=sys.stderr)
        if isinstance(exc, BuildError) and len(lines) > 1:  # the compiler's output, once
            print("\n".join(lines[1:]), file=sys.stderr)
        return EXIT_TOOL_FAILED


if __name__ == "__main__":
    sys.exit(main())
