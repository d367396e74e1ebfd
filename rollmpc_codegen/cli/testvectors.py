"""``rollmpc testvectors``: the host C test program with reference vectors
(:func:`rollmpc_codegen.host.testvectors.write_test_vectors`)."""
from __future__ import annotations

from .options import add_command, add_config, add_force, add_precision, check_steps


def add_parser(sub) -> None:
    t = add_command(sub, "testvectors", "emit the host C test program with reference vectors",
                    "Writes the generated controller and a C test program whose vectors "
                    "(the config's scenario, QPs at each mode's bounds) come from the NumPy "
                    "reference; build it with any C99 compiler and run it, no Python needed "
                    "(make ctest).")
    add_config(t)
    t.add_argument("-o", "--output", required=True, help="output directory")
    add_force(t)
    add_precision(t)
    t.add_argument("--steps", type=int, default=None,
                   help="closed-loop steps to record (default: the whole scenario)")
    t.set_defaults(func=run)


def run(args) -> int:
    from ..host.testvectors import write_test_vectors

    check_steps(args)
    path = write_test_vectors(args.config, args.output, args.precision, args.steps, args.force)
    print(f"rollmpc: wrote {path}")
    return 0
