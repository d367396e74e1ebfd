"""``generate`` as one library call for both front ends: ``rollmpc generate`` prints what
:func:`run_generate` returns, ``Design.generate`` returns it (and warns with it).

The run writes the files (pipeline.generate_config: the footprint before the maths, the
refusals), then collects the design warnings (qp/sanity.py); for a float build
:meth:`GenerateRun.check_float` adds the float check (float_check.py) and its warning.
Every warning is a DesignWarning on ``warnings`` (docs/checks.md): the CLI prints the
same list, so a Python user sees what a CLI user sees.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from ..config.diagnostics import DesignWarning
from ..model.controller import ControllerModel
from ..pipeline import generate_config, load_config
from ..qp.footprint import Footprint
from ..qp.sanity import design_warnings


@dataclass
class GenerateRun:
    """What a generation wrote and found; a path-like of its output directory."""

    path: Path
    model: ControllerModel
    ctx: dict
    footprint: Footprint
    warnings: list[DesignWarning] = field(default_factory=list)
    float_check: object | None = None  # a host.float_check.FloatCheck once checked

    def __fspath__(self) -> str:
        return os.fspath(self.path)

    def check_float(self, build_dir: str | Path | None = None) -> None:
        """The float check of a float build (float_check.py), its warning added to
        ``warnings``; a check that cannot run (no C compiler, ...) is a warning too:
        the files are written already."""
        from .float_check import check_float

        try:
            self.float_check = check_float(self.model, self.ctx, build_dir=build_dir)
        except Exception as exc:  # noqa: BLE001 (informative only, never fails generate)
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            self.warnings.append(DesignWarning(
                "float_check_not_run", "", f"float check not run ({type(exc).__name__}: "
                f"{first})"))
            return
        found = self.float_check.design_warning()
        if found is not None:
            self.warnings.append(found)


def run_generate(config, out_dir: str | Path, *, precision: str | None = None,
                 force: bool = False, force_size: bool = False,
                 announce: Callable[[Footprint], None] | None = None,
                 part: str | None = None) -> GenerateRun:
    """Write the controller of ``config`` (a file, a ControllerConfig or a Design) into
    ``out_dir`` with the rules of ``rollmpc generate`` (``force``, ``force_size``;
    ``announce`` receives the footprint before the dense maths; ``part`` replaces its
    target: section) and collect its design warnings.  The float check is
    :meth:`GenerateRun.check_float`."""
    predicted: list[Footprint] = []

    def before_maths(footprint: Footprint) -> None:
        predicted.append(footprint)
        if announce is not None:
            announce(footprint)

    model, ctx = generate_config(load_config(config, precision, part), out_dir, force,
                                 force_size, before_maths)
    return GenerateRun(path=Path(out_dir), model=model, ctx=ctx, footprint=predicted[0],
                       warnings=design_warnings(model))
