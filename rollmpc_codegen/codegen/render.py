"""Stage 7: render the context through the jinja2 templates into an output directory.

One template per generated file.  Output is written to a temporary sibling directory
and renamed into place only when every file rendered, so a failure never leaves a
half-written output directory behind.
"""
from __future__ import annotations

import math
import os
import shutil
import tempfile
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


def write_atomically(files: dict[str, str], out_dir: Path) -> None:
    """Write ``files`` as the whole content of ``out_dir``, replacing it only on success."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise FileExistsError(f"{out_dir} exists and is not a directory")
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", dir=out_dir.parent))
    tmp.chmod(0o755)
    try:
        for name, text in files.items():
            (tmp / name).write_text(text)
        if out_dir.exists():
            old = out_dir.with_name(f".{out_dir.name}.old")
            if old.exists():
                shutil.rmtree(old)
            os.rename(out_dir, old)
            os.rename(tmp, out_dir)
            shutil.rmtree(old)
        else:
            os.rename(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
