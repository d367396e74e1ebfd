"""Stage 7: render the context through the jinja2 templates (file name -> text).

One template per generated file.  Nothing is written here: :mod:`.output` puts the
rendered files on disk.
"""
from __future__ import annotations

import math

import jinja2
import numpy as np

from .context import context_json
from .templates import templates_dir

CONFIG_HEADER = "{p}_config.h"
# generated file name (without prefix) -> template
GENERATED_FILES = {
    CONFIG_HEADER: "config.h.j2",
    "{p}.h": "api.h.j2",
    "{p}_internal.h": "internal.h.j2",
    "{p}_data.c": "data.c.j2",
    "{p}_linalg.c": "linalg.c.j2",
    "{p}_solver.c": "solver.c.j2",
    "{p}_controller.c": "controller.c.j2",
}


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
    """File name -> text for every generated file (nothing written), the config header
    last: codegen/output.py moves the files in this order, and every other file refuses
    to compile beside a config header of another generation (generation_check.j2), so a
    move interrupted once any C file has moved leaves a tree that does not build."""
    env = environment(ctx["precision"])
    out = {name.format(p=ctx["prefix"]): env.get_template(template).render(ctx)
           for name, template in GENERATED_FILES.items()}
    out[f"{ctx['prefix']}_context.json"] = context_json(ctx)  # after a C file: see above
    config_header = CONFIG_HEADER.format(p=ctx["prefix"])
    out[config_header] = out.pop(config_header)
    return out


def render_template(ctx: dict, template: str, **extra) -> str:
    """Render one auxiliary template (host timer, C test harness) with the context."""
    return environment(ctx["precision"]).get_template(template).render(ctx, **extra)

