"""What a report concludes, for CI: its verdicts and its warnings (docs/checks.md, "Exit
codes").  ``rollmpc report`` exits 3 when a verdict fails, and with ``--check`` also when
it warns; a CI job can gate on a design that misses its deadline or its memory.

Verdicts (``verdicts`` of the report, each True when met):

* ``sample_time``: the worst counted step within one sample at ``target.cpu_mhz``;
* ``flash``, ``ram``, ``instance``: the image's flash, its static RAM and the controller
  instance alone within ``target.flash_kib`` / ``ram_kib`` (only those declared);
* ``bit_exact``: every replayed step equal to the host build's, bit for bit.

Warnings (``checks``: DesignWarning dicts): ``time_limit`` (steps stopped at the work
budget), ``soft_float_double`` (a double build on the single-precision M4F, reported
without ``--precision``: what the figures are and what the target runs).
"""
from __future__ import annotations

from ..config import ControllerConfig
from ..config.diagnostics import DesignWarning
from ..sim.run_checks import time_limit_check
from .build import SOFT_DOUBLE_FACTOR

EXIT_VERDICT_FAILED = 3  # beside the CLI's 1 (a tool failed) and 2 (bad input)


def verdicts(rep: dict) -> dict:
    """The report's verdicts (module docstring) from its figures."""
    out = {"sample_time": rep["budget"]["worst_fits"], "bit_exact": rep["bit_exact_vs_host"]}
    for goal, met in rep["goals"].items():
        name = {"flash_bytes": "flash", "ram_bytes": "ram", "ctrl_bytes": "instance"}[
            goal.split("<=")[0]]
        out[name] = met
    return out


def report_warnings(rep: dict, cfg: ControllerConfig,
                    precision: str | None) -> list[DesignWarning]:
    """The report's warnings (module docstring); ``precision`` as asked (None: the
    config's)."""
    counts = rep.get("statuses", {})
    found = time_limit_check(counts, sum(counts.values()), rep.get("longest_time_limit_run", 0),
                             rep["horizon"])
    if precision is None and cfg.precision == "double":
        low, high = SOFT_DOUBLE_FACTOR
        found.append(DesignWarning(
            "soft_float_double", "precision",
            "this report emulates the double build: the Cortex-M4F has single-precision "
            "floating point only, so every double operation is a soft-float call (about "
            f"{low}-{high} times the float build's cycles); the target runs the float "
            "build: --precision float"))
    return found


def conclude(rep: dict, cfg: ControllerConfig, precision: str | None) -> dict:
    """``rep`` with its ``verdicts``, ``passed`` and ``checks`` (in place)."""
    rep["verdicts"] = verdicts(rep)
    rep["passed"] = all(rep["verdicts"].values())
    rep["checks"] = [w.as_dict() for w in report_warnings(rep, cfg, precision)]
    return rep
