"""PBH tests that say *which* part of a mode's model no input moves or no output sees.

"the discrete model is not observable" left a new user guessing (issue 18): the check now
names the eigenvalue that fails the Popov-Belevitch-Hautus test and its direction in the
user's terms.  Per distinct eigenvalue z of A, the null space of ``[A - zI; C]``
(unobservable) or the left null space of ``[A - zI, B]`` (uncontrollable) is the set of
state directions at fault; scipy.linalg.null_space finds it (an SVD, as the rank test
did before).

The direction is shown in the states of the plant the user wrote (``x[i]`` of a
state-space A, then each output's integrator, disturbance and previous-input states).
A transfer function's states are the generator's own realisation, meaningless to the
user, so there the pole itself is named: a state that no input moves or no output sees
is a pole cancelled by a zero.
"""
from __future__ import annotations

import cmath
from dataclasses import dataclass

import numpy as np
import scipy.linalg

# a singular value of [A - zI; X] at most this times max(1, |A|, |X|) counts as zero (the
# rank decision of the checks since the first commit)
RANK_TOL = 1e-9
TERMS_SHOWN = 6  # of a direction; the rest are elided


@dataclass(frozen=True)
class Defect:
    """An eigenvalue of A and the state direction (uncontrollable: the weights w of the
    combination w'x) that fails the PBH test there, scaled so its largest entry is 1."""

    eigenvalue: complex
    direction: np.ndarray


def pbh_defects(A: np.ndarray, X: np.ndarray, inputs: bool,
                only_unstable: bool = False) -> list[Defect]:
    """The uncontrollable (``inputs``: X = B) or unobservable (X = C) eigen-directions of
    A, one per distinct eigenvalue that fails; ``only_unstable`` keeps |z| >= 1 only (the
    detectability of a Kalman filter)."""
    n = A.shape[0]
    scale = max(1.0, float(np.abs(A).max(initial=0.0)), float(np.abs(X).max(initial=0.0)))
    found: list[Defect] = []
    for z in np.linalg.eigvals(A):
        if (only_unstable and abs(z) < 1.0 - RANK_TOL) or any(  # a conjugate is the same pole
                min(abs(z - d.eigenvalue), abs(z - d.eigenvalue.conjugate()))
                <= RANK_TOL * scale for d in found):
            continue
        shifted = A - z * np.eye(n)
        M = np.hstack([shifted, X]).conj().T if inputs else np.vstack([shifted, X])
        smax = np.linalg.norm(M, 2)
        if smax == 0.0:  # A = zI and X = 0: every direction fails
            space = np.eye(n, dtype=complex)[:, :1]
        else:
            space = scipy.linalg.null_space(M, rcond=RANK_TOL * scale / smax)
        if space.shape[1]:
            v = space[:, 0]
            found.append(Defect(complex(z), v / v[np.argmax(np.abs(v))]))
    return found


def _number(v: float) -> str:
    return "0" if abs(v) < 1e-9 else f"{v:.4g}"


def _complex(z: complex, symbol: str) -> str:
    if abs(z.imag) < 1e-9 * max(1.0, abs(z)):
        return f"{symbol} = {_number(z.real)}"
    return f"{symbol} = {_number(z.real)} ± {_number(abs(z.imag))}j"


def eigenvalue_text(z: complex, sample_time: float | None) -> tuple[str, str]:
    """(``pole s = -2`` for a continuous plant, s = ln(z) / Ts, or ``eigenvalue z = 0.9``
    for a discrete one; what it is: an integrator, unstable, ... or "")."""
    text = (_complex(z, "eigenvalue z") if sample_time is None
            else _complex(cmath.log(z) / sample_time if z != 0 else complex(-np.inf),
                          "pole s"))
    if abs(z - 1.0) <= RANK_TOL:
        return text, "an integrator"
    if abs(z) > 1.0 + RANK_TOL:
        return text, "unstable"
    if abs(abs(z) - 1.0) <= RANK_TOL:
        return text, "an undamped oscillation"
    return text, ""


def direction_text(direction: np.ndarray, names: list[str], noun: str) -> str:
    """``x[4]``, ``the <noun> x[1] - 0.5 x[2]``; a complex (oscillating) direction by its
    states."""
    big = [i for i in np.argsort(-np.abs(direction), kind="stable")
           if abs(direction[i]) > 1e-6]
    shown = sorted(big[:TERMS_SHOWN])
    more = f" and {len(big) - len(shown)} more states" if len(big) > len(shown) else ""
    if np.any(np.abs(direction[shown].imag) > 1e-9):
        return "the oscillation of " + ", ".join(names[i] for i in shown) + more
    terms = []
    for i in shown:
        c = direction[i].real
        size = "" if abs(abs(c) - 1.0) < 1e-9 else f"{abs(c):.3g} "
        sign = "-" if c < 0 else "+"
        terms.append(f"{sign} {size}{names[i]}")
    text = " ".join(terms)
    text = (text[2:] if text.startswith("+ ") else "-" + text[2:]) + more
    return text if len(big) == 1 else f"the {noun} {text}"


def state_names(mode, nx: int, nd: int, n_prev: int,
                outputs: tuple[str, ...] | None = None) -> list[str] | None:
    """The model's states in the user's terms: ``x[i]`` of a state-space A, ``∫<output>``
    for each integrator, ``d[<signal>]`` for a disturbance, ``u_prev[<actuator>]``; None
    when the plant's states are the generator's (a transfer function)."""
    plant = mode.plant
    if plant.kind != "state_space":
        return None
    ny = plant.C.shape[0]
    outs = list(outputs) if outputs is not None else [f"output {j}" for j in range(ny)]
    names = [f"x[{i}]" for i in range(plant.A.shape[0])]
    names += [f"∫{o}" for o in outs] if plant.integrator else []
    names += [f"d[{s}]" for s in (mode.actuators if mode.disturbance == "input" else outs)][:nd]
    names += [f"u_prev[{a}]" for a in mode.actuators][:n_prev]
    return names if len(names) == nx else None


def defect_text(defect: Defect, names: list[str] | None, sample_time: float | None,
                inputs: bool) -> str:
    """``x[4] (pole s = 0: an integrator)``, or ``the pole s = 0 (an integrator)`` without
    state names; with several states the combination w'x no input moves (``inputs``) or
    the direction no output sees."""
    value, kind = eigenvalue_text(defect.eigenvalue, sample_time)
    if names is None:
        return f"the {value}" + (f" ({kind})" if kind else "")
    noun = "combination" if inputs else "direction"
    return f"{direction_text(defect.direction, names, noun)} ({value}" + (
        f": {kind})" if kind else ")")


def more_text(defects: list[Defect]) -> str:
    """``; 1 more eigenvalue fails the same way`` when several eigenvalues fail."""
    k = len(defects) - 1
    return "" if k < 1 else (f"; {k} more eigenvalue{'s fail' if k > 1 else ' fails'} "
                             "the same way")
