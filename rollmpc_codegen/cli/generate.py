"""``rollmpc generate``: render the C controller for a YAML config
(:func:`rollmpc_codegen.pipeline.generate`); for a float controller, then the float check
of :mod:`rollmpc_codegen.host.float_check` (one line; a warning when float does not serve
the design).  The check runs after every file is written and never fails the command.

Before the dense maths the design's predicted flash, RAM and cycles are checked against
its ``target:`` section (qp/footprint.py); ``--force-size`` generates it anyway.  It is a
flag of its own, not ``--force``: that one lets rollmpc write into a directory it did not
write, a data-safety rule, and a user who asks for a large design must not waive it by
the same word (nor waive the size check by forcing a directory).  The prediction is
printed on stdout, before the maths when the maths is slow; design warnings (hard output
bounds no input can meet from rest, qp/feasibility.py; a controller that does not
stabilise its model with no bound active, qp/nominal_loop.py) go to stderr and leave
exit 0.
"""
from __future__ import annotations

import sys
from pathlib import Path

from .options import add_build_dir, add_force, add_part, add_precision


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
    add_part(g)
    g.add_argument("--no-float-check", action="store_true",
                   help="float: skip the check of the design's scenario QPs against double")
    add_build_dir(g)
    g.set_defaults(func=run)


def default_out_dir(config: str, precision: str | None) -> Path:
    stem = Path(config).stem
    return Path("generated") / (f"{stem}_f32" if precision == "float" else stem)


def float_check(model, ctx: dict, build_dir: str | None) -> None:
    """Print the float check's line, and its warning on stderr; a check that cannot run
    (no C compiler, ...) is a warning too: the files are already written."""
    from ..host.float_check import check_float

    try:
        result = check_float(model, ctx, build_dir=build_dir)
    except Exception as exc:  # noqa: BLE001 (informative only, never fails generate)
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        print(f"rollmpc: warning: float check not run ({type(exc).__name__}: {first})",
              file=sys.stderr)
        return
    print(f"rollmpc: {result.line()}")
    if result.warning():
        print(f"rollmpc: {result.warning()}", file=sys.stderr)


def _print_footprint(footprint) -> None:
    for line in footprint.summary():
        print(f"rollmpc: {line}", flush=True)


def run(args) -> int:
    from ..pipeline import generate
    from ..qp.feasibility import rest_warnings
    from ..qp.nominal_loop import unstable_law_warnings

    predicted = []

    def announce(footprint) -> None:  # before the dense maths
        predicted.append(footprint)
        if footprint.slow:
            _print_footprint(footprint)

    # `-o ''` reaches the writer, which refuses it (it is not the default directory)
    out = args.output if args.output is not None else default_out_dir(args.config, args.precision)
    model, ctx = generate(args.config, out, args.precision, args.force, args.force_size,
                          announce, part=args.part)
    if not predicted[0].slow:
        _print_footprint(predicted[0])
    sizes = ", ".join(f"{m['name']}: n={m['n']} m={m['m']}" for m in ctx["modes"])
    print(f"rollmpc: wrote {out}/ ({ctx['precision']}; {sizes})")
    for warning in [*unstable_law_warnings(model), *rest_warnings(model)]:
        print(f"rollmpc: warning: {warning}", file=sys.stderr)
    if ctx["precision"] == "float" and not args.no_float_check:
        sys.stdout.flush()
        float_check(model, ctx, args.build_dir)
    return 0
