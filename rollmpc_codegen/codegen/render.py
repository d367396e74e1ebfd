"""Stage 7: render the context through the jinja2 templates (file name -> text).

One template per generated file.  Nothing is written here: :mod:`.output` puts the
rendered files on disk.
"""
from __future__ import annotations

import functools
import math

import jinja2
import numpy as np

from ..qp.arrays import MODE_SIZES
from ..qp.work import (ADD_BATCH, CHOL_UNITS_PER_OP, GUESS_SAMPLE_MIN,
                       PREDICT_UNITS_PER_OP, PRIMAL_CALL_OPS, PRIMAL_CALL_UNITS,
                       PRIMAL_SIXTHS_PER_OP, STEP_FIXED_UNITS, TRI_UNITS_PER_OP, UNIT_CALL_WORK)
from ..qp.work_formula import FORMULAS, traced
from .build_flags import context_build_flags
from .context import context_json, rendering_context
from .misra_deviations import DEVIATIONS
from .output import MANIFEST
from .templates import templates_dir

CONFIG_HEADER = "{p}_config.h"
# generated file name ({p}: the prefix) -> template
GENERATED_FILES = {
    CONFIG_HEADER: "config.h.j2",
    "{p}.h": "api.h.j2",
    "{p}_internal.h": "internal.h.j2",
    "{p}_data.c": "data.c.j2",
    "{p}_linalg.c": "linalg.c.j2",
    "{p}_solver.c": "solver.c.j2",
    "{p}_controller.c": "controller.c.j2",
    "{p}_README.md": "readme.md.j2",
    "{p}_target.mk": "target.mk.j2",
}
CONTEXT_FILE = "{p}_context.json"
# what each file of a generated tree is, in the order its README lists them
FILE_ROLES = {
    "{p}.h": "the public API: the controller instance, its functions, the status codes, "
             "P_info; the only header to include",
    "{p}_config.h": "the precision switch, the sizes, the solver's constants, the sample "
                    "period and the build guards",
    "{p}_internal.h": "the solver's internal declarations: the stored data of a mode, the "
                      "linear algebra",
    "{p}_data.c": "the stored matrices of every mode (const), computed offline in double",
    "{p}_linalg.c": "packed Cholesky factorisation and triangular solves",
    "{p}_solver.c": "the QP solver: the unconstrained step, the dual sweeps, the polish "
                    "and the dual active set, and its work count",
    "{p}_controller.c": "P_init(), P_step(), P_observe(), P_solve_qp(): the scheduler, the "
                        "observers, the QP of the active mode",
    "{p}_README.md": "this file",
    "{p}_target.mk": "the target part's compiler flags and memory map, for a make build "
                     "(the firmware stub includes it)",
    CONTEXT_FILE: "every number the C is compiled with, as JSON (for tools; not compiled)",
    MANIFEST: "the files rollmpc replaces when it regenerates this directory (others stay)",
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


@functools.cache
def work_formulas(absent: frozenset = frozenset()) -> dict:
    """Every work formula of qp/work.py as the C function work_formula.c.j2 prints: its
    design constants are the context's, and the mode sizes ``absent`` from the design's
    P_mode_data (a feature it lacks) read 0."""
    return {name: traced(name, absent) for name in FORMULAS}


def template_vars(ctx: dict) -> dict:
    """What a template renders: the context (rendering_context()) and the work formulas
    of the sizes its P_mode_data has."""
    full = rendering_context(ctx)
    absent = frozenset(s.name for s in MODE_SIZES if s.feature and not full.get(s.feature))
    return full | {"work_formulas": work_formulas(absent)}


def package_facts() -> dict:
    """What the templates see besides the context: the package's declarations, the same
    for every design (the work formulas, the compiler flags, the MISRA deviations, the
    work units' constants, the files of a tree)."""
    return {"work_formulas": work_formulas(), "build_flags": context_build_flags(),
            "misra_deviations": [d._asdict() for d in DEVIATIONS],
            "file_roles": FILE_ROLES,
            "work_constants": {
                "PREDICT_UNITS_PER_OP": PREDICT_UNITS_PER_OP,
                "CHOL_UNITS_PER_OP": CHOL_UNITS_PER_OP, "TRI_UNITS_PER_OP": TRI_UNITS_PER_OP,
                "PRIMAL_SIXTHS_PER_OP": PRIMAL_SIXTHS_PER_OP,
                "PRIMAL_CALL_UNITS": PRIMAL_CALL_UNITS, "PRIMAL_CALL_OPS": PRIMAL_CALL_OPS,
                "GUESS_SAMPLE_MIN": GUESS_SAMPLE_MIN, "ADD_BATCH": ADD_BATCH,
                "UNIT_CALL_WORK": UNIT_CALL_WORK, "STEP_FIXED_UNITS": STEP_FIXED_UNITS}}


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
    env.globals.update(package_facts())
    return env


def render_sources(ctx: dict) -> dict[str, str]:
    """File name -> text for every generated file (nothing written), the config header
    last: codegen/output.py moves the files in this order, and every other file refuses
    to compile beside a config header of another generation (generation_check.j2), so a
    move interrupted once any C file has moved leaves a tree that does not build."""
    env = environment(ctx["precision"])
    out = {name.format(p=ctx["prefix"]): env.get_template(template).render(template_vars(ctx))
           for name, template in GENERATED_FILES.items()}
    out[CONTEXT_FILE.format(p=ctx["prefix"])] = context_json(ctx)  # after a C file: see above
    config_header = CONFIG_HEADER.format(p=ctx["prefix"])
    out[config_header] = out.pop(config_header)
    return out


def render_template(ctx: dict, template: str, **extra) -> str:
    """Render one auxiliary template (host timer, C test harness) with the context."""
    return environment(ctx["precision"]).get_template(template).render(
        template_vars(ctx), **extra)

