"""``rollmpc generate``: render the C controller for a YAML config
(:func:`rollmpc_codegen.pipeline.generate`)."""
from __future__ import annotations

from pathlib import Path

from .options import add_force, add_precision


def add_parser(sub) -> None:
    g = sub.add_parser("generate", help="render the C controller for a YAML config")
    g.add_argument("config")
    g.add_argument("-o", "--output", help="output directory (default generated/<config "
                   "name>, with _f32 for float)")
    add_force(g)
    add_precision(g)
    g.set_defaults(func=run)


def default_out_dir(config: str, precision: str | None) -> Path:
    stem = Path(config).stem
    return Path("generated") / (f"{stem}_f32" if precision == "float" else stem)


def run(args) -> int:
    from ..pipeline import generate

    # `-o ''` reaches the writer, which refuses it (it is not the default directory)
    out = args.output if args.output is not None else default_out_dir(args.config, args.precision)
    model, ctx = generate(args.config, out, args.precision, args.force)
    sizes = ", ".join(f"{m['name']}: n={m['n']} m={m['m']}" for m in ctx["modes"])
    print(f"rollmpc: wrote {out}/ ({ctx['precision']}; {sizes})")
    return 0
