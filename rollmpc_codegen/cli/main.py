"""``rollmpc`` command line: generate, simulate, bench, report, certify, testvectors,
identify, fly.

Expected failures print one line ``rollmpc: error: ...`` and exit with 2 (bad input:
config or arguments) or 1 (a tool failed, e.g. the C compiler); never a traceback.

Each subcommand is one module of this package (``add_parser`` and ``run``): it parses,
calls the library and prints or writes what it returns; the option groups several share
are in :mod:`rollmpc_codegen.cli.options`.
"""
from __future__ import annotations

import argparse
import sys

from ..config import ConfigError
from . import bench, certify, fly, generate, identify, report, simulate, testvectors

EXIT_BAD_INPUT = 2
EXIT_TOOL_FAILED = 1
SUBCOMMANDS = (generate, simulate, bench, report, certify, testvectors, identify, fly)  # --help order


class OneLineArgumentParser(argparse.ArgumentParser):
    """Bad arguments: one line ``rollmpc: error: ...`` and exit 2 (no usage block)."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"rollmpc: error: {' '.join(message.split())}\n")


DESCRIPTION = ("rollmpc turns a YAML description of a (switched) linear MPC controller into "
               "static C99 for a microcontroller, and checks that C: on the host, in closed "
               "loop, against other QP solvers and on an emulated Cortex-M4F.  "
               "`rollmpc COMMAND --help` describes each command.")


def parser() -> argparse.ArgumentParser:
    from .. import __version__
    from .options import EXIT_CODES

    ap = OneLineArgumentParser(prog="rollmpc", description=DESCRIPTION,
                               epilog=f"{EXIT_CODES}; 3 `rollmpc report`: a verdict failed, "
                               "`rollmpc certify`: the design does not fit its work budget")
    ap.add_argument("--version", action="version", version=f"rollmpc {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND",
                            title="commands")
    for subcommand in SUBCOMMANDS:
        subcommand.add_parser(sub)
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
    except BrokenPipeError:  # `rollmpc ... | head`: the reader left, as the shell expects
        import os

        try:  # the interpreter's flush at exit would fail on the closed pipe again
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):  # no real file descriptor (a captured stdout)
            pass
        return 141  # 128 + SIGPIPE
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
