"""``rollmpc generate``: render the C controller for a YAML config
(:func:`rollmpc_codegen.pipeline.generate`); for a float controller, then the float check
of :mod:`rollmpc_codegen.host.float_check` (one line; a warning when float does not serve
the design).  The check runs after every file is written and never fails the command.

Before the dense maths the design's predicted flash, RAM and cycles are checked against
its ``target:`` section (qp/footprint.py); ``--force-size`` generates it anyway.  It is a
flag of its own, not ``--force``: that one lets rollmpc write into a directory it did not
write, a data-safety rule, and a user who asks for a large design must not waive it by
the same word (nor waive the size check by forcing a directory).  The prediction is
printed on stdout, before the maths when the maths is slow; the design warnings
(qp/sanity.py, docs/checks.md: the list :func:`~rollmpc_codegen.host.generate_run.run_generate`
returns and the Python API warns with) go to stderr and leave exit 0.

``--certify`` adds the work certificate's line (verify/certify.py, on the host C): opt-in,
because it flies 20 closed loops and builds the host C, seconds that a generate of every
example (``make generate``, the tests) should not pay; it informs, as the float check does.
"""
from __future__ import annotations

import sys
from pathlib import Path

from .options import (add_build_dir, add_command, add_config, add_force, add_part,
                      add_precision)


def add_parser(sub) -> None:
    g = add_command(sub, "generate", "render the C controller for a YAML config",
                    "Writes P.h, P_config.h, P_internal.h and the P_*.c sources into -o, "
                    "replacing only the files rollmpc wrote there.  Before the maths it "
                    "predicts flash, RAM and the cycles and work units of a step on the "
                    "target, refusing a design beyond its target: section; after, it prints "
                    "the design warnings on stderr (docs/checks.md) and, for a float build, "
                    "checks float against double on the design's own QPs.")
    add_config(g)
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
    g.add_argument("--certify", action="store_true",
                   help="after writing, print the work certificate's line: `rollmpc certify`'s "
                   "sampling at its defaults, solved by the host C build (a few seconds; "
                   "informs only, exit 0 still: gate CI on `rollmpc certify`)")
    add_build_dir(g)
    g.set_defaults(func=run)


def default_out_dir(config: str, precision: str | None) -> Path:
    stem = Path(config).stem
    return Path("generated") / (f"{stem}_f32" if precision == "float" else stem)


def _print_footprint(footprint) -> None:
    for line in footprint.summary():
        print(f"rollmpc: {line}", flush=True)


def print_warnings(found) -> None:
    """Design warnings on stderr, one line each (the list the Python API returns)."""
    for w in found:
        print(f"rollmpc: warning: {w.message}", file=sys.stderr)


def run(args) -> int:
    from ..host.generate_run import run_generate

    def announce(footprint) -> None:  # before the dense maths
        if footprint.slow:
            _print_footprint(footprint)

    # `-o ''` reaches the writer, which refuses it (it is not the default directory)
    out = args.output if args.output is not None else default_out_dir(args.config, args.precision)
    result = run_generate(args.config, out, precision=args.precision, force=args.force,
                          force_size=args.force_size, announce=announce,
                          part=args.part)
    if not result.footprint.slow:
        _print_footprint(result.footprint)
    ctx = result.ctx
    sizes = ", ".join(f"{m['name']}: n={m['n']} m={m['m']}" for m in ctx["modes"])
    print(f"rollmpc: wrote {out}/ ({ctx['precision']}; {sizes})")
    print_warnings(result.warnings)
    if ctx["precision"] == "float" and not args.no_float_check:
        sys.stdout.flush()
        known = len(result.warnings)
        result.check_float(args.build_dir)
        if result.float_check is not None:
            print(f"rollmpc: {result.float_check.line()}")
            sys.stdout.flush()
        print_warnings(result.warnings[known:])
    if args.certify:
        from ..verify.certify import certify

        sys.stdout.flush()
        cert = certify(args.config, precision=args.precision, engine="host",
                       build_dir=args.build_dir, loaded=(result.model, ctx))
        print(f"rollmpc: {cert.line()}")
    return 0
