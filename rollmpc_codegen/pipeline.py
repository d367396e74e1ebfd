"""The ``generate`` pipeline, one stage a folder:

config/ (validated dataclasses) -> model/ (plant, observer; features/ augment it) -> qp/
(condensed QP, stored data) -> codegen/ (context dict, rendered sources on disk).
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from . import config as config_mod
from .codegen.context import build_context
from .codegen.output import check_output_dir, write_output
from .codegen.render import render_sources
from .config import ConfigError, ControllerConfig, ModeConfig
from .features import input_rate
from .features.disturbance_model import prediction_model
from .model.controller import ControllerModel, ModeModel
from .model.plant import DiscretePlant
from .qp.arrays import REAL, STORED_ARRAYS
from .qp import footprint
from .qp.condense import condense, predictions
from .qp.footprint import Footprint
from .qp.sizes import check_sizes
from .qp.storage import mode_data


def build_model(cfg: ControllerConfig,
                before_maths: Callable[[ControllerConfig], None] | None = None) -> ControllerModel:
    """Offline maths for every mode, in double, then cast to the storage precision.

    ``before_maths(cfg)`` runs once the models are known to be sound (realised, checked
    by PBH, their predictions finite: cheap) and before the dense maths (condensing, the
    observers, the stored data): ``generate`` refuses or announces the footprint there
    (qp/footprint.py).

    On one BLAS thread: a threaded BLAS sums in an order that depends on the thread count,
    and the generated files must be byte-identical on every machine."""
    with threadpool_limits(limits=1, user_api="blas"):
        return _build_model(cfg, before_maths)


def _per_mode(cfg: ControllerConfig, step, *args) -> list:
    """``step(cfg, mode, key, *per-mode args)`` for every mode, failures naming the mode."""
    out = []
    for j, mode in enumerate(cfg.modes):
        key = f"modes[{j}]"
        # every result is checked below or where it is made, naming a key; numpy's own
        # warnings (overflow, invalid) would only add vaguer lines on stderr
        with np.errstate(all="ignore"):
            try:
                out.append(step(cfg, mode, key, *(a[j] for a in args)))
            except np.linalg.LinAlgError as exc:  # scipy.linalg raises the same class
                raise ConfigError(key, f"the offline maths failed ({' '.join(str(exc).split())}"
                                  "): the mode's numbers are too badly scaled") from None
    return out


def _build_model(cfg: ControllerConfig, before_maths) -> ControllerModel:
    check_sizes(cfg)  # the size limits (int16 rows, states, memory), before any maths
    plants = _per_mode(cfg, _prediction_plant)
    if before_maths is not None:
        before_maths(cfg)
    return ControllerModel(config=cfg, modes=tuple(_per_mode(cfg, _mode_model, plants)))


def _prediction_plant(cfg: ControllerConfig, mode: ModeConfig, key: str) -> DiscretePlant:
    """One mode's prediction model, with its disturbances, and the previous input with Δu
    weighting (input_rate); its predictions over the horizon checked for overflow."""
    plant = input_rate.augment(prediction_model(mode, cfg.sample_time, key, cfg.outputs), mode)
    predictions(plant, cfg.horizon, key)
    return plant


def _mode_model(cfg: ControllerConfig, mode: ModeConfig, key: str,
                plant: DiscretePlant) -> ModeModel:
    """One mode's QP, observer and stored data."""
    qp = condense(plant, mode, cfg.horizon, key)
    L, poles = input_rate.observer_gain(plant, mode, key)
    act_index = [cfg.actuators.index(a) for a in mode.actuators]
    data = mode_data(mode.name, act_index, plant, L, mode.innovation_limit, qp, mode.u_min,
                     mode.u_max, cfg.precision, mode.soft_l1, mode.soft_l2)
    for array in STORED_ARRAYS:
        value = getattr(data, array.name)
        if array.ctype == REAL and value is not None and not np.all(np.isfinite(value)):
            raise ConfigError(f"{key}.{array.blame}", f"{array.name} is not finite in "
                              f"{cfg.precision} precision (the problem is too badly scaled)")
    return ModeModel(plant=plant, qp=qp, observer_gain=L, observer_poles=poles, data=data)


def load_model_from_config(cfg: ControllerConfig) -> tuple[ControllerModel, dict]:
    """Compute every static matrix of a validated config; returns (model, context)."""
    model = build_model(cfg)
    return model, build_context(model)


def load_model(config_path: str | Path, precision: str | None = None,
               part: str | None = None) -> tuple[ControllerModel, dict]:
    """Validate the config file and compute every static matrix; returns (model, context).
    ``precision`` and ``part`` override the file's (config.load)."""
    return load_model_from_config(config_mod.load(config_path, precision, part))


def generate_config(cfg: ControllerConfig, out_dir: str | Path, force: bool = False,
                    force_size: bool = False,
                    announce: Callable[[Footprint], None] | None = None
                    ) -> tuple[ControllerModel, dict]:
    """Render the controller of a validated config into ``out_dir``.

    Only rollmpc's own files there are replaced (codegen/output.py); ``force`` also writes
    into a non-empty directory rollmpc did not write, keeping its other files.  A design
    beyond its target's flash, RAM or cycle budget is refused before the dense maths
    (qp/footprint.py) unless ``force_size``; ``announce`` receives the prediction there.
    """
    check_output_dir(out_dir, force)  # refuse before the maths, not after

    def before_maths(cfg: ControllerConfig) -> None:
        predicted = footprint.predict(cfg)
        if not force_size:
            footprint.check_fits(cfg, predicted)
        if announce is not None:
            announce(predicted)

    model = build_model(cfg, before_maths)
    ctx = build_context(model)
    write_output(render_sources(ctx), out_dir, force)
    return model, ctx


def generate(config_path: str | Path, out_dir: str | Path, precision: str | None = None,
             force: bool = False, force_size: bool = False,
             announce: Callable[[Footprint], None] | None = None,
             part: str | None = None) -> tuple[ControllerModel, dict]:
    """Render the controller for the config file ``config_path`` into ``out_dir``
    (the keywords of :func:`generate_config`; ``part`` replaces the target: section,
    config.load)."""
    check_output_dir(out_dir, force)  # a bad output path costs no maths
    return generate_config(config_mod.load(config_path, precision, part), out_dir, force,
                           force_size, announce)
