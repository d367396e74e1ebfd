"""Stage 7: render the context through the jinja2 templates (file name -> text).

One template per generated file.  Nothing is written here: :mod:`.output` puts the
rendered files on disk.
"""
from __future__ import annotations

import functools
import math
from pathlib import Path

import jinja2
import numpy as np

from .context import context_json

# generated file name (without prefix) -> template
GENERATED_FILES = {
    "{p}_config.h": "config.h.j2",
    "{p}.h": "api.h.j2",
    "{p}_internal.h": "internal.h.j2",
    "{p}_data.c": "data.c.j2",
    "{p}_linalg.c": "linalg.c.j2",
    "{p}_solver.c": "solver.c.j2",
    "{p}_controller.c": "controller.c.j2",
}


def templates_dir() -> Path:
    """templates/ of the source tree, or the copy shipped inside the wheel."""
    import sys

    here = Path(__file__).resolve().parents[1]  # the rollmpc_codegen package
    shared = Path(sys.prefix) / "share" / "rollmpc" / "templates"
    for cand in (here / "templates", here.parent / "templates", shared):
        if cand.is_dir():
            return cand
    raise FileNotFoundError("rollmpc templates directory not found")


def format_real(value: float, precision: str) -> str:
    """A C literal that round-trips exactly: repr() for double, 9 digits + f for float."""
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"non-finite number {value!r} in generated data")
    if precision == "double":
        text = repr(value)
        return text if any(ch in text for ch in ".en") else text + ".0"
    text = "%.9g" % float(np.float32(value))
    if not any(ch in text for ch in ".en"):
        text += ".0"
    return text + "f"


def _c_array(values, precision: str, per_line: int = 6) -> str:
    flat = np.asarray(values, dtype=np.float64).ravel()
    if flat.size == 0:
        return "0"
    items = [format_real(v, precision) for v in flat]
    lines = [", ".join(items[i:i + per_line]) for i in range(0, len(items), per_line)]
    return ",\n    ".join(lines)


def _c_int_array(values, per_line: int = 16) -> str:
    flat = np.asarray(values, dtype=np.int64).ravel()
    if flat.size == 0:
        return "0"
    items = [str(int(v)) for v in flat]
    lines = [", ".join(items[i:i + per_line]) for i in range(0, len(items), per_line)]
    return ",\n    ".join(lines)


# one per precision: jinja compiles each template once per environment (about half of a
# render's time); the loader still reloads a template whose file changed
@functools.lru_cache(maxsize=None)
def environment(precision: str) -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(templates_dir())),
        undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True,
        keep_trailing_newline=True, autoescape=False)
    env.filters["c_array"] = lambda v: _c_array(v, precision)
    env.filters["c_int_array"] = _c_int_array
    env.filters["c_real"] = lambda v: format_real(v, precision)
    env.filters["size"] = lambda v: max(1, int(np.asarray(v).size))
    return env


def render_sources(ctx: dict) -> dict[str, str]:
    """File name -> text for every generated file (nothing written)."""
    env = environment(ctx["precision"])
    out = {}
    for name, template in GENERATED_FILES.items():
        out[name.format(p=ctx["prefix"])] = env.get_template(template).render(ctx)
    out[f"{ctx['prefix']}_context.json"] = context_json(ctx)
    return out


def render_template(ctx: dict, template: str, **extra) -> str:
    """Render one auxiliary template (host timer, C test harness) with the context."""
    return environment(ctx["precision"]).get_template(template).render(ctx, **extra)

