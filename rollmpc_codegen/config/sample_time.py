"""The sample time against the plant's own time scales: a value in the wrong unit is a
config error naming ``sample_time`` (docs/checks.md, "Sample time").

A buck converter written with ``sample_time: 50`` (for 50 us) was blamed on
``simulation.reference.segment`` ("must be at least sample_time"), or without a
simulation section on a controllability pole; a drone with ``sample_time: 20`` (for
20 ms) generated.  Here, before anything else reads the sample time, each continuous
plant's fastest pole s is set against it: at |s| Ts above :data:`WRONG_UNIT_RAD` the
plant's fastest mode settles (e^-|s|Ts) or turns |s| Ts / 2 pi times within one sample,
which no controller sampled that slowly can act on, so the sample time is refused with
the scalings (ms, us, ns) that would fit.  Milder mismatches are warnings
(qp/sanity.py).  A discrete plant's poles are those of its own sampling: nothing to check.
"""
from __future__ import annotations

import numpy as np

from .errors import ConfigError
from .schema import ModeConfig, PlantConfig

# |s| Ts beyond which a sample time is taken for a wrong unit: e^-100 within one sample,
# or 16 turns of an oscillation; the examples' largest is 0.74 (quad_attitude)
WRONG_UNIT_RAD = 100.0
# |s| Ts of a fastest pole the sampling resolves (qp/sanity.py warns beyond): pi, the
# Nyquist frequency of an oscillation, or a real mode gone to e^-pi = 4 % within a sample
RESOLVED_RAD = np.pi
UNIT_SCALINGS = ((1e-3, "ms"), (1e-6, "us"), (1e-9, "ns"))


def plant_poles(plant: PlantConfig) -> np.ndarray:
    """The continuous poles of a plant config (its integrators' too); none for a
    discrete state-space plant."""
    if plant.kind == "state_space":
        if plant.discrete:
            return np.zeros(0, complex)
        poles = np.linalg.eigvals(plant.A) if plant.A.size else np.zeros(0, complex)
    elif plant.tf_matrix is not None:
        poles = np.concatenate([np.roots(den) for row in plant.tf_matrix for _, den in row])
    else:
        poles = np.roots(plant.den)
    n_int = (plant.C.shape[0] if plant.kind == "state_space" else 1) if plant.integrator else 0
    return np.concatenate([np.asarray(poles, complex), np.zeros(n_int, complex)])


def fastest_pole(modes: tuple[ModeConfig, ...]) -> tuple[int, complex] | None:
    """(mode index, pole) of the pole of largest magnitude over the modes' continuous
    plants; None when no plant has one off the origin."""
    best = None
    for j, mode in enumerate(modes):
        for p in plant_poles(mode.plant):
            if np.isfinite(p) and abs(p) > 0 and (best is None or abs(p) > abs(best[1])):
                best = (j, complex(p))
    return best


def pole_text(s: complex) -> str:
    """``s = -378.8 ± 6731j`` (a conjugate pair as one) or ``s = -20``."""
    if abs(s.imag) <= 1e-12 * abs(s):
        return f"s = {s.real:.4g}"
    return f"s = {s.real:.4g} ± {abs(s.imag):.4g}j"


def seconds_text(t: float) -> str:
    """``50 us``, ``5 ms``, ``2.5 s``: a duration in the unit that reads."""
    for factor, unit in ((1.0, "s"), (1e-3, "ms"), (1e-6, "us")):
        if t >= factor:
            return f"{t / factor:.3g} {unit}"
    return f"{t * 1e9:.3g} ns"


def check_sample_time(sample_time: float, modes: tuple[ModeConfig, ...]) -> None:
    """Refuse a sample time the plant's fastest mode outruns by far (module docstring)."""
    fastest = fastest_pole(modes)
    if fastest is None:
        return
    j, s = fastest
    rad = abs(s) * sample_time
    if rad <= WRONG_UNIT_RAD:
        return
    fits = [f"{sample_time * f:.3g} ({sample_time:g} {unit})" for f, unit in UNIT_SCALINGS
            if abs(s) * sample_time * f <= RESOLVED_RAD]
    hint = f"; meant {fits[0]}?" if fits else ""
    raise ConfigError("sample_time", f"{sample_time:g} s is {rad:.3g} rad at the fastest "
                      f"pole of modes[{j}] ({modes[j].name}: {pole_text(s)}, |s| Ts should "
                      f"be below about {RESOLVED_RAD:.3g}): the plant settles or turns many "
                      f"times within one sample; sample_time is in seconds{hint}")
