"""``rollmpc generate``: render the C controller for a YAML config
(:func:`rollmpc_codegen.pipeline.generate`); for a float controller, then the float check
of :mod:`rollmpc_codegen.host.float_check` (one line; a warning when float does not serve
the design).  The check runs after every file is written and never fails the command."""
from __future__ import annotations

import sys
from pathlib import Path

from .options import add_build_dir, add_force, add_precision


def add_parser(sub) -> None:
    g = sub.add_parser("generate", help="render the C controller for a YAML config")
    g.add_argument("config")
    g.add_argument("-o", "--output", help="output directory (default generated/<config "
                   "name>, with _f32 for float)")
    add_force(g)
    add_precision(g)
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


def run(args) -> int:
    from ..pipeline import generate

    # `-o ''` reaches the writer, which refuses it (it is not the default directory)
    out = args.output if args.output is not None else default_out_dir(args.config, args.precision)
    model, ctx = generate(args.config, out, args.precision, args.force)
    sizes = ", ".join(f"{m['name']}: n={m['n']} m={m['m']}" for m in ctx["modes"])
    print(f"rollmpc: wrote {out}/ ({ctx['precision']}; {sizes})")
    if ctx["precision"] == "float" and not args.no_float_check:
        sys.stdout.flush()
        float_check(model, ctx, args.build_dir)
    return 0
