"""Stage 2: each mode's plant -> a discrete, well-scaled state-space realisation (ZOH).

The controller's realisation is ``x = [x_g; y]`` when ``integrator: true``: the states
of G(s) followed by one integrator per output, so that y (the roll angle) is a state
and its rate ``C_g x_g + D_g u`` (the roll rate) is a known linear function of x.
The realisation of G(s) is balanced (diagonal similarity) before sampling, so the
observer and the x-dependent matrices are not needlessly ill-conditioned.  A
transfer-function *matrix* is realised minimally by :mod:`rollmpc_codegen.model.tf_realisation`.
"""
from __future__ import annotations

import cmath
from dataclasses import dataclass

import warnings

import control
import numpy as np
import scipy.linalg
import scipy.signal

from . import tf_realisation
from .pbh import (RANK_TOL, Defect, defect_text, eigenvalue_text, more_text, pbh_defects,
                  state_names)
from ..config import ConfigError, ModeConfig, PlantConfig


@dataclass(frozen=True)
class ContinuousPlant:
    """Continuous realisation ``x' = A x + B u``, outputs ``y = C x`` and ``rate = Cr x + Dr u``.

    ``Cr, Dr`` give dy/dt exactly (the pre-integrator signal) when the plant was built
    with ``integrator: true``; otherwise they are None.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Cr: np.ndarray | None
    Dr: np.ndarray | None


@dataclass(frozen=True)
class DiscretePlant:
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Cr: np.ndarray | None  # rate output at the sampling instants (see ContinuousPlant)
    Dr: np.ndarray | None
    # offset-free tracking (disturbance_model.augment): the last nd states are constant
    # disturbances, and u_s = input_target @ x is the input that cancels them
    nd: int = 0
    input_target: np.ndarray | None = None
    # Δu weighting (input_rate.augment): the last n_prev states are the previous input
    # u_{k-1} (u_prev+ = u), after the disturbance states
    n_prev: int = 0

    @property
    def nx(self) -> int:
        return self.A.shape[0]

    @property
    def disturbance_states(self) -> np.ndarray:
        """Indices of the nd disturbance states: after the plant's, before u_prev's."""
        first = self.nx - self.n_prev - self.nd
        return np.arange(first, first + self.nd)

    @property
    def non_disturbance_states(self) -> np.ndarray:
        """Indices of every state but the disturbance states (constant: nothing feeds them)."""
        return np.setdiff1d(np.arange(self.nx), self.disturbance_states)

    @property
    def nu(self) -> int:
        return self.B.shape[1]

    @property
    def ny(self) -> int:
        return self.C.shape[0]


def _balanced(A: np.ndarray, B: np.ndarray, C: np.ndarray):
    """Diagonal similarity that balances A (scipy/LAPACK gebal), applied to B and C."""
    if A.size == 0:
        return A, B, C
    _, (scale, perm) = scipy.linalg.matrix_balance(A, permute=False, separate=True)
    T = np.diag(scale)
    Ti = np.diag(1.0 / scale)
    return Ti @ A @ T, Ti @ B, C @ T


def g_realisation(plant: PlantConfig, key: str = "plant") -> tuple[np.ndarray, ...]:
    """(A, B, C, D) of the continuous G(s) of a plant config (``key``), before any
    integrator."""
    key_of_num = f"{key}.transfer_function.num"
    if plant.tf_matrix is not None:  # MIMO: minimal realisation (tf_realisation)
        A, B, C, D = tf_realisation.realise(plant.tf_matrix)
        A, B, C = _balanced(A, B, C)
    elif plant.kind == "transfer_function":
        with warnings.catch_warnings():  # scipy drops numerator terms it deems zero
            warnings.simplefilter("error", scipy.signal.BadCoefficients)
            try:
                sys = control.tf2ss(control.tf(list(plant.num), list(plant.den)))
            except scipy.signal.BadCoefficients:
                num = ", ".join(f"{c:g}" for c in plant.num)
                raise ConfigError(key_of_num, f"[{num}] is numerically zero next "
                                  f"to den's leading coefficient {plant.den[0]:g}: scipy's "
                                  "realisation drops every term below 1e-14 of it; write "
                                  "such a term as 0, or rescale the units") from None
        A, B, C, D = (np.atleast_2d(np.asarray(m, dtype=float)) for m in
                      (sys.A, sys.B, sys.C, sys.D))
        if A.size == 0:  # static gain (only legal with an integrator)
            A = np.zeros((0, 0))
            B = np.zeros((0, 1))
            C = np.zeros((1, 0))
        A, B, C = _balanced(A, B, C)
    else:
        A, B, C, D = plant.A, plant.B, plant.C, plant.D
    return A, B, C, D


def with_integrator(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray,
                    integrator: bool) -> ContinuousPlant:
    """G(s) = (A, B, C, D), with one integrator appended per output when ``integrator``."""
    if not integrator:
        return ContinuousPlant(A=A, B=B, C=C, Cr=None, Dr=None)
    ng, ny, nu = A.shape[0], C.shape[0], B.shape[1]
    Aa = np.block([[A, np.zeros((ng, ny))], [C, np.zeros((ny, ny))]])
    Ba = np.vstack([B, D])
    Ca = np.hstack([np.zeros((ny, ng)), np.eye(ny)])
    Cr = np.hstack([C, np.zeros((ny, ny))])
    return ContinuousPlant(A=Aa, B=Ba, C=Ca, Cr=Cr, Dr=np.asarray(D, dtype=float).reshape(ny, nu))


def continuous_realisation(plant: PlantConfig, key: str) -> ContinuousPlant:
    """Realise a continuous plant config (G(s), then its integrators); ``key`` names it."""
    return with_integrator(*g_realisation(plant, f"{key}.plant"), plant.integrator)


def zoh(cont: ContinuousPlant, Ts: float) -> DiscretePlant:
    """Exact zero-order-hold sampling (matrix exponential of the augmented system)."""
    nx, nu = cont.B.shape
    M = np.zeros((nx + nu, nx + nu))
    M[:nx, :nx] = cont.A
    M[:nx, nx:] = cont.B
    expM = scipy.linalg.expm(M * Ts)
    return DiscretePlant(A=expM[:nx, :nx], B=expM[:nx, nx:], C=cont.C.copy(),
                         Cr=cont.Cr, Dr=cont.Dr)


def _has_zero_at(num: tuple[float, ...], s: complex) -> bool:
    """num(s) = 0 up to rounding: G(s) really has that zero (not a number too small)."""
    terms = [c * s ** (len(num) - 1 - i) for i, c in enumerate(num)]
    return abs(sum(terms)) <= RANK_TOL * sum(abs(v) for v in terms)


def _remedy(mode: ModeConfig, defect: Defect, inputs: bool) -> str:
    """What the user can change, in the terms of the plant they wrote."""
    if mode.plant.kind != "state_space":  # the generator's states: a cancelled pole
        if mode.plant.integrator and abs(defect.eigenvalue - 1.0) <= RANK_TOL:
            return ("cancels a zero of G(s) at s = 0: remove the factor s from num, or set "
                    "integrator: false")
        return "cancels a zero of the transfer function: remove the common factor from num and den"
    if inputs:
        return (f"is not moved by any of the mode's actuators ({', '.join(mode.actuators)}); "
                "drop it or actuate it (B)")
    return "does not reach any output; drop it or measure it (C)"


def _numerical_defect(cont: ContinuousPlant | None, mode: ModeConfig, defect: Defect,
                      inputs: bool, sample_time: float | None, key: str) -> ConfigError | None:
    """The error when the defect is the numbers', not the model's (else None): a sampling
    that loses the pole (``sample_time`` too short, or pathological), or a SISO transfer
    function whose coefficients hide a pole that no zero cancels."""
    if cont is None:  # a discrete plant: the model is what the user wrote
        return None
    value, _ = eigenvalue_text(defect.eigenvalue, sample_time)
    prop = "controllable" if inputs else "observable"
    if not pbh_defects(cont.A, cont.B if inputs else cont.C, inputs):
        return ConfigError("sample_time", f"{sample_time:g} s loses the {value} of mode "
                           f"{mode.name!r}: its continuous model is {prop}, sampled it is "
                           "not (too short a sample time for that pole to move, or a "
                           "pathological one); choose another sample time")
    plant = mode.plant
    if plant.kind == "transfer_function" and plant.tf_matrix is None:
        s = 0.0 if plant.integrator and abs(defect.eigenvalue - 1.0) <= RANK_TOL else (
            cmath.log(defect.eigenvalue) / sample_time)
        if not _has_zero_at(plant.num, s):
            return ConfigError(f"{key}.plant.transfer_function", f"mode {mode.name!r} is "
                               f"numerically not {prop} at its {value} although num has no "
                               "zero there: the coefficients of num and den differ too much "
                               "in size; rescale the units")
    return None


def _check_pbh(disc: DiscretePlant, mode: ModeConfig, key: str, sample_time: float | None,
               outputs: tuple[str, ...] | None, cont: ContinuousPlant | None = None) -> None:
    """Controllability, then observability (PBH per eigenvalue, model/pbh.py): the first
    eigenvalue that fails, its direction and the remedy, as one line (``cont``: the
    continuous model sampled, which tells a lost pole from a cancelled one)."""
    names = state_names(mode, disc.nx, 0, 0, outputs)
    for inputs, X, prop in ((True, disc.B, "controllable"), (False, disc.C, "observable")):
        defects = pbh_defects(disc.A, X, inputs)
        if defects:
            numerical = _numerical_defect(cont, mode, defects[0], inputs, sample_time, key)
            if numerical is not None:
                raise numerical
            raise ConfigError(f"{key}.plant", f"the discrete model of mode {mode.name!r} is "
                              f"not {prop}: {defect_text(defects[0], names, sample_time, inputs)} "
                              f"{_remedy(mode, defects[0], inputs)}{more_text(defects)}")


def discretise(mode: ModeConfig, Ts: float, key: str,
               outputs: tuple[str, ...] | None = None) -> DiscretePlant:
    """The mode's discrete model for prediction, checked for controllability/observability
    (``outputs``: the output names its errors use)."""
    plant = mode.plant
    cont = None
    if plant.kind == "state_space" and plant.discrete:
        disc = DiscretePlant(A=plant.A, B=plant.B, C=plant.C, Cr=None, Dr=None)
    else:
        cont = continuous_realisation(plant, key)
        disc = zoh(cont, Ts)
    if not np.all(np.isfinite(disc.A)) or not np.all(np.isfinite(disc.B)):
        raise ConfigError(f"{key}.plant", "sampling produced non-finite matrices")
    _check_pbh(disc, mode, key, None if plant.discrete else Ts, outputs, cont)
    return disc
