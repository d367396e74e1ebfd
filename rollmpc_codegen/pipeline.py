"""The ``generate`` pipeline, one stage a folder:

config/ (validated dataclasses) -> model/ (plant, observer; features/ augment it) -> qp/
(condensed QP, stored data) -> codegen/ (context dict, rendered sources on disk).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from . import config as config_mod
from .codegen.context import build_context
from .codegen.output import check_output_dir, write_output
from .codegen.render import render_sources
from .config import ConfigError, ControllerConfig, ModeConfig
from .config.target import part_target
from .config.checks import check_representable
from .features import input_rate
from .features.disturbance_model import prediction_model
from .model.controller import ControllerModel, ModeModel
from .model.plant import DiscretePlant
from .model.reach import innovation_limit
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
    limits = _per_mode(cfg, _innovation_limit, plants)
    if before_maths is not None:
        before_maths(cfg)
    return ControllerModel(config=cfg, modes=tuple(_per_mode(cfg, _mode_model, plants, limits)))


def _prediction_plant(cfg: ControllerConfig, mode: ModeConfig, key: str) -> DiscretePlant:
    """One mode's prediction model, with its disturbances, and the previous input with Δu
    weighting (input_rate); its predictions over the horizon checked for overflow."""
    plant = input_rate.augment(prediction_model(mode, cfg.sample_time, key, cfg.outputs), mode)
    predictions(plant, cfg.horizon, key)
    return plant


def _innovation_limit(cfg: ControllerConfig, mode: ModeConfig, key: str,
                      plant: DiscretePlant) -> np.ndarray:
    """The mode's innovation limits, those the config leaves to the model derived from
    its reach (model/reach.py), before the dense maths."""
    return innovation_limit(mode, plant, cfg.horizon, f"{key}.observer.innovation_limit",
                            cfg.outputs)


def _mode_model(cfg: ControllerConfig, mode: ModeConfig, key: str,
                plant: DiscretePlant, limit: np.ndarray) -> ModeModel:
    """One mode's QP, observer and stored data."""
    qp = condense(plant, mode, cfg.horizon, key)
    L, poles = input_rate.observer_gain(plant, mode, key)
    act_index = [cfg.actuators.index(a) for a in mode.actuators]
    data = mode_data(mode.name, act_index, plant, L, limit, qp, mode.u_min,
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


def load_config(config, precision: str | None = None,
                part: str | None = None) -> ControllerConfig:
    """The validated config of a YAML file, a :class:`ControllerConfig` or a
    :class:`~rollmpc_codegen.api.Design`, with ``precision`` overriding its own as
    ``--precision`` does and ``part`` replacing its target: section as ``--part`` does:
    what every library run (generate, simulate, bench, report) accepts."""
    if isinstance(config, (str, Path)):
        return config_mod.load(config, precision, part)
    config_for = getattr(config, "config_for", None)  # a Design
    cfg = config_for(precision) if callable(config_for) else config
    if precision is not None and precision != cfg.precision:
        cfg = dataclasses.replace(cfg, precision=precision)
        check_representable(precision, cfg.sample_time, cfg.modes, cfg.scheduler, cfg.solver)
    if part is not None:
        cfg = dataclasses.replace(cfg, target=part_target(part, "--part"))
    return cfg


def config_label(config) -> str:
    """How a run's JSON names its config: the file, or the design of the Python API."""
    if isinstance(config, (str, Path)):
        return str(config)
    return f"{load_config(config).prefix} (Python API)"


def load_model(config, precision: str | None = None,
               part: str | None = None) -> tuple[ControllerModel, dict]:
    """Validate the config (a file, a ControllerConfig or a Design: :func:`load_config`)
    and compute every static matrix; returns (model, context).  A Design's are built
    once per precision (on its own target)."""
    build = getattr(config, "build", None)
    if callable(build) and part is None:
        return build(precision)
    return load_model_from_config(load_config(config, precision, part))


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


def generate(config, out_dir: str | Path, precision: str | None = None,
             force: bool = False, force_size: bool = False,
             announce: Callable[[Footprint], None] | None = None,
             part: str | None = None) -> tuple[ControllerModel, dict]:
    """Render the controller for ``config`` (a file, a ControllerConfig or a Design:
    :func:`load_config`) into ``out_dir`` (the keywords of :func:`generate_config`;
    ``part`` replaces the target: section)."""
    check_output_dir(out_dir, force)  # a bad output path costs no maths
    return generate_config(load_config(config, precision, part), out_dir, force, force_size,
                           announce)
