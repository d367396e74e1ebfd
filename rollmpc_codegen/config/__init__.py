"""Stage 1 of the pipeline: YAML -> validated, frozen configuration dataclasses.

Every problem is reported as a single :class:`ConfigError` whose text names the
offending key (``modes[1].weights.P: must be a positive number``).  Nothing
downstream re-validates raw YAML; the later stages (plant, mpc, observer) raise
``ConfigError`` too when a *mathematical* property fails (an uncontrollable mode,
an indefinite Hessian, ...), always naming the key that caused it.

Modules: ``errors`` (ConfigError), ``diagnostics`` (DesignWarning, the warnings every
front end prints), ``schema`` (dataclasses, choices, limits, every
default), ``reader`` (typed reading with key paths), ``yaml_loader`` (:func:`load`),
``controller`` (:func:`parse`, the top level), one parser per section (``plant``,
``mode``, ``scheduler``, ``solver``, ``simulation``, ``target``) and ``checks`` (across
sections).

The public names below are imported on first use (PEP 562), not here: a module that
only raises ConfigError (features/move_blocking.py, which ``mode`` itself uses) imports
``config.errors``, and that must not load the parsers -- it would be an import cycle.
"""
from __future__ import annotations

import importlib
from typing import Any

_HOME = {  # public name -> the module that declares it
    "ConfigError": "errors",
    **dict.fromkeys(("DesignWarning", "RollmpcWarning"), "diagnostics"),
    "load": "yaml_loader",
    "parse": "controller",
    **dict.fromkeys(("ControllerConfig", "ModeConfig", "PlantConfig", "SchedulerConfig",
                     "SolverConfig", "SimulationConfig", "UnitsConfig", "TargetConfig",
                     "PRECISIONS", "SOLVER_METHODS", "SCHEDULE_SOURCES", "OBSERVER_KINDS",
                     "DISTURBANCE_MODELS", "MAX_ROWS", "MAX_C_INT", "FLOAT_MAX"), "schema"),
}
__all__ = sorted(_HOME)


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
    globals()[name] = value  # once imported, an ordinary attribute
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
