"""``rollmpc testvectors``: the host C test program with reference vectors
(:func:`rollmpc_codegen.host.testvectors.write_test_vectors`)."""
from __future__ import annotations

from .options import add_force, add_precision, check_steps


def add_parser(sub) -> None:
    t = sub.add_parser("testvectors", help="emit the host C test program with reference vectors")
    t.add_argument("config")
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
