"""Plant mismatch of the simulated plant (``--mismatch F`` of ``rollmpc simulate`` and
``rollmpc report``): the controller keeps its model, the plant it flies does not.

Each mode's continuous G(s) (before its integrators, which are kinematics, not a model)
becomes (1 + d_g) G(s / (1 + d_p)): its gain scaled by 1 + d_g and every pole (and zero)
by 1 + d_p, so the plant is 1 + d_p times faster at the same DC gain, then 1 + d_g
stronger.  d_g and d_p are drawn uniformly in [-F, F], independently per mode, from the
run's seed (``scenario.random_stream(seed, "mismatch")``).  In state space that is
(A, B, C, D) -> ((1 + d_p) A, (1 + d_p) B, (1 + d_g) C, (1 + d_g) D), sampled by ZOH as
the nominal plant is.  A discrete state-space plant is perturbed through its continuous
equivalent (the matrix logarithm of its ZOH); one with a pole at z <= 0 has none and is
refused.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..config import ConfigError, ModeConfig
from ..model.plant import ContinuousPlant, DiscretePlant, g_realisation, with_integrator, zoh


@dataclass(frozen=True)
class PlantMismatch:
    """Per mode (config order): the factor 1 + d_g of the gain and 1 + d_p of the poles."""

    gain: tuple[float, ...]
    poles: tuple[float, ...]

    @classmethod
    def draw(cls, n_modes: int, fraction: float, rng: np.random.Generator) -> PlantMismatch:
        """d_g, d_p uniform in [-fraction, fraction] for each mode, in that order."""
        if not 0.0 <= fraction < 1.0:
            raise ConfigError("--mismatch", f"must be in [0, 1), got {fraction}")
        d = rng.uniform(-fraction, fraction, size=(n_modes, 2))
        return cls(gain=tuple(float(g) for g in 1.0 + d[:, 0]),
                   poles=tuple(float(p) for p in 1.0 + d[:, 1]))

    def as_dict(self) -> dict:
        return {"gain": [float(g) for g in self.gain], "poles": [float(p) for p in self.poles]}

    def plant(self, j: int, mode: ModeConfig, sample_time: float) -> DiscretePlant:
        """Mode ``j``'s true plant, (1 + d_g) G(s / (1 + d_p)) sampled by ZOH."""
        gain, speed = self.gain[j], self.poles[j]
        plant = mode.plant
        if plant.kind == "state_space" and plant.discrete:
            A, B = _continuous_equivalent(plant.A, plant.B, sample_time, f"modes[{j}].plant")
            cont = ContinuousPlant(A=speed * A, B=speed * B, C=gain * plant.C, Cr=None, Dr=None)
        else:
            A, B, C, D = g_realisation(plant)
            cont = with_integrator(speed * A, speed * B, gain * C, gain * D, plant.integrator)
        return zoh(cont, sample_time)


def _continuous_equivalent(A: np.ndarray, B: np.ndarray, Ts: float,
                           key: str) -> tuple[np.ndarray, np.ndarray]:
    """(Ac, Bc) whose ZOH at Ts is (A, B): the logarithm of [[A, B], [0, I]] over Ts."""
    nx, nu = B.shape
    M = np.block([[A, B], [np.zeros((nu, nx)), np.eye(nu)]])
    z = np.linalg.eigvals(A)
    if np.any((z.real <= 0) & (np.abs(z.imag) <= 1e-12 * np.maximum(1.0, np.abs(z)))):
        raise ConfigError(key, "--mismatch needs a continuous equivalent of this discrete "
                          "plant, and a pole at z <= 0 has none")
    L = scipy.linalg.logm(M) / Ts
    if np.iscomplexobj(L):
        if np.abs(L.imag).max() > 1e-9 * max(1.0, np.abs(L.real).max()):
            raise ConfigError(key, "--mismatch needs a real continuous equivalent of this "
                              "discrete plant")
        L = L.real
    return L[:nx, :nx], L[:nx, nx:]
