"""``rollmpc generate``: render the C controller for a YAML config
(:func:`rollmpc_codegen.pipeline.generate`).

Before the dense maths the design's predicted flash, RAM and cycles are checked against
its ``target:`` section (qp/footprint.py); ``--force-size`` generates it anyway.  It is a
flag of its own, not ``--force``: that one lets rollmpc write into a directory it did not
write, a data-safety rule, and a user who asks for a large design must not waive it by
the same word (nor waive the size check by forcing a directory).  The prediction is
printed on stdout, before the maths when the maths is slow; design warnings (hard output
bounds no input can meet from rest, qp/feasibility.py) go to stderr and leave exit 0.
"""
from __future__ import annotations

import sys
from pathlib import Path

from .options import add_force, add_precision


def add_parser(sub) -> None:
    g = sub.add_parser("generate", help="render the C controller for a YAML config")
    g.add_argument("config")
    g.add_argument("-o", "--output", help="output directory (default generated/<config "
                   "name>, with _f32 for float)")
    add_force(g)
    g.add_argument("--force-size", action="store_true",
                   help="generate a design beyond its target's flash, RAM or cycle budget "
                   "(target: section, or the documented defaults)")
    add_precision(g)
    g.set_defaults(func=run)


def default_out_dir(config: str, precision: str | None) -> Path:
    stem = Path(config).stem
    return Path("generated") / (f"{stem}_f32" if precision == "float" else stem)


def _print_footprint(footprint) -> None:
    for line in footprint.summary():
        print(f"rollmpc: {line}", flush=True)


def run(args) -> int:
    from ..pipeline import generate
    from ..qp.feasibility import rest_warnings

    predicted = []

    def announce(footprint) -> None:  # before the dense maths
        predicted.append(footprint)
        if footprint.slow:
            _print_footprint(footprint)

    # `-o ''` reaches the writer, which refuses it (it is not the default directory)
    out = args.output if args.output is not None else default_out_dir(args.config, args.precision)
    model, ctx = generate(args.config, out, args.precision, args.force, args.force_size,
                          announce)
    if not predicted[0].slow:
        _print_footprint(predicted[0])
    sizes = ", ".join(f"{m['name']}: n={m['n']} m={m['m']}" for m in ctx["modes"])
    print(f"rollmpc: wrote {out}/ ({ctx['precision']}; {sizes})")
    for warning in rest_warnings(model):
        print(f"rollmpc: warning: {warning}", file=sys.stderr)
    return 0
