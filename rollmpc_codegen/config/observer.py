"""``modes[].observer``: the observer's design (pole placement or a steady-state Kalman
predictor, and the disturbance model of offset-free tracking) and its innovation limit."""
from __future__ import annotations

import math

import numpy as np

from .errors import ConfigError
from .reader import Reader, check_length, read_number, read_vector
from .schema import (DERIVED_FROM_MODEL, DISTURBANCE_MODELS, OBSERVER_KINDS, ModeConfig,
                     default_innovation_limit)


def _poles(o: Reader) -> tuple[complex, ...]:
    raw = o.raw("poles")
    if not isinstance(raw, list) or not raw:
        raise ConfigError(o.key("poles"), "must be a non-empty list")
    check_length(raw, o.key("poles"))
    parsed = []
    for i, p in enumerate(raw):
        k = f"{o.key('poles')}[{i}]"
        if isinstance(p, list) and len(p) == 2:
            parsed.append(complex(read_number(p[0], k), read_number(p[1], k)))
        else:
            parsed.append(complex(read_number(p, k), 0.0))
        if abs(parsed[-1]) >= 1.0:
            raise ConfigError(k, f"observer pole {p!r} is not inside the unit circle")
    return tuple(parsed)


def parse_observer(o: Reader, nu: int, ny: int) -> dict:
    """``modes[].observer``: pole placement (default) or a steady-state Kalman filter, and
    the optional disturbance model of offset-free tracking (docs/features.md)."""
    kind = o.string("kind", ModeConfig.observer_kind, choices=OBSERVER_KINDS)
    disturbance = o.string("disturbance", ModeConfig.disturbance, choices=DISTURBANCE_MODELS)
    out: dict = {"observer_kind": kind, "disturbance": disturbance}
    kalman_keys = [k for k in ("Qn", "Rn", "Qd") if o.has(k)]
    if kind == "poles":
        if kalman_keys:
            raise ConfigError(o.key(kalman_keys[0]), "only with kind: kalman")
        if o.has("poles"):
            out["poles"] = _poles(o)
    else:
        if o.has("poles"):
            raise ConfigError(o.key("poles"), "only with kind: poles (the Kalman filter "
                              "places its own poles)")
        out["observer_Qn"] = o.psd("Qn", (nu, nu), strict=False)
        out["observer_Rn"] = o.psd("Rn", (ny, ny), strict=True)
        if disturbance != "none":
            nd = nu if disturbance == "input" else ny
            out["observer_Qd"] = o.psd("Qd", (nd, nd), strict=True)
        elif o.has("Qd"):
            raise ConfigError(o.key("Qd"), "only with a disturbance model (disturbance: "
                              "input or output)")
    return out



def parse_innovation_limit(o: Reader | None, key: str, outputs: tuple[str, ...],
                           y_min: np.ndarray, y_max: np.ndarray,
                           levels: np.ndarray) -> np.ndarray:
    """``modes[].observer.innovation_limit`` (``key``; ``o`` None: no observer section): a
    scalar for every output or one entry per output, > 0, ``.inf`` never clips; by default
    schema.default_innovation_limit of the mode's output bounds and the scenario's levels,
    and DERIVED_FROM_MODEL (NaN) for an output they give no range: the pipeline fills it
    from what the inputs can make the output reach (model/reach.py)."""
    if o is not None and o.has("innovation_limit"):
        limit = read_vector(o.raw("innovation_limit"), key, len(outputs), allow_inf=True)
        for a, value in enumerate(limit):
            if not value > 0.0:
                raise ConfigError(key, f"must be > 0 (.inf: never clip), got {value} for "
                                  f"output {outputs[a]!r}")
        return limit
    # where nothing in the config gives a range, the model's reach does (pipeline.py,
    # model/reach.py): NaN until then
    limit = default_innovation_limit(y_min, y_max, levels)
    for a, value in enumerate(limit):
        if not math.isfinite(value):  # the clip would be silently off
            raise ConfigError(key, f"has no finite default for output {outputs[a]!r}: ten "
                              f"spans of its range [{y_min[a]:g}, {y_max[a]:g}] overflow; "
                              "give bounds the output can reach, or the limit (.inf: never "
                              "clip)")
    return np.where(limit > 0.0, limit, DERIVED_FROM_MODEL)
