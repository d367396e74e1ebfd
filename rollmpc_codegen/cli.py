"""``rollmpc`` command line: generate, simulate, bench, report, testvectors.

Expected failures print one line ``rollmpc: error: ...`` and exit with 2 (bad input:
config or arguments) or 1 (a tool failed, e.g. the C compiler); never a traceback.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .config import PRECISIONS, ConfigError

EXIT_BAD_INPUT = 2
EXIT_TOOL_FAILED = 1


def default_out_dir(config: str, precision: str | None) -> Path:
    stem = Path(config).stem
    return Path("generated") / (f"{stem}_f32" if precision == "float" else stem)


def cmd_generate(args) -> int:
    from .generate import generate

    out = Path(args.output) if args.output else default_out_dir(args.config, args.precision)
    model, ctx = generate(args.config, out, args.precision)
    sizes = ", ".join(f"{m['name']}: n={m['n']} m={m['m']}" for m in ctx["modes"])
    print(f"rollmpc: wrote {out}/ ({ctx['precision']}; {sizes})")
    return 0


def cmd_simulate(args) -> int:
    from .simulate_cli import simulate_command

    return simulate_command(args)


def cmd_testvectors(args) -> int:
    from .testvectors import write_test_vectors

    path = write_test_vectors(args.config, Path(args.output), args.precision, args.steps)
    print(f"rollmpc: wrote {path}")
    return 0


def _add_precision(p: argparse.ArgumentParser) -> None:
    p.add_argument("--precision", choices=PRECISIONS, default=None,
                   help="override the config's precision")


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="rollmpc", description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)

    g = sub.add_parser("generate", help="render the C controller for a YAML config")
    g.add_argument("config")
    g.add_argument("-o", "--output", help="output directory (default generated/<config "
                   "name>, with _f32 for float)")
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
    s.add_argument("--noise", type=float, default=0.0, help="measurement noise std (deg)")
    s.add_argument("--disturbance", type=float, default=0.0,
                   help="constant input disturbance on every actuator (deg)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--steps", type=int, default=None, help="samples (default: whole scenario)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_simulate)

    t = sub.add_parser("testvectors", help="emit the host C test program with reference vectors")
    t.add_argument("config")
    t.add_argument("-o", "--output", required=True, help="output directory")
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

        from .build import BuildError

        if os.environ.get("ROLLMPC_DEBUG"):
            raise
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        kind = "build failed" if isinstance(exc, BuildError) else type(exc).__name__
        print(f"rollmpc: error: {kind}: {first}", file=sys.stderr)
        if isinstance(exc, BuildError):
            print(str(exc), file=sys.stderr)
        return EXIT_TOOL_FAILED


if __name__ == "__main__":
    sys.exit(main())
