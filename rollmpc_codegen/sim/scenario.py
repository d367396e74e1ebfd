"""The closed-loop scenario of section 4.1 and the simulated plant.

Reference: 0, -20, 20, -40, 40, 0 deg, 10 s each (6000 samples at Ts = 10 ms), applied
to every output, unless the config gives ``simulation.reference`` (levels, each a scalar
for every output or one value per output, held ``segment`` seconds each); the
controller receives the preview r_{k+1..k+N} (held at the last value past the end).
A random flight (``rollmpc report --flights``) keeps the scenario's segment length and
draws each level uniformly within the range the scenario spans, inside the output
bounds (:func:`reference_range`).

Plant: when each mode drives its own actuators, every mode is a *channel* (its continuous
model from the config, sampled exactly by ZOH); all channels act together and the
measured outputs are their sum -- for the UAV, the roll angle is the integral of the roll
rates produced by both aileron pairs. When modes share an actuator they are operating
points of one plant, and the plant is the one the scheduler picks at rest
(:func:`plant_modes`). The scheduling signal is the summed pre-integrator output (the
roll rate) or the output.
With a :class:`~rollmpc_codegen.sim.mismatch.PlantMismatch` each channel is the mode's
plant perturbed as that module says; the controller's model stays nominal.

Every random draw of a run comes from its seed through :func:`random_stream`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import ControllerConfig
from ..config.schema import PAPER_LEVELS_DEG, PAPER_SEGMENT_S
from ..model.plant import discretise
from ..reference.scheduler import scheduled_mode
from .mismatch import PlantMismatch

# the independent random streams of one seed; "noise" is numpy's default_rng(seed) itself
# (the measurement noise of `rollmpc simulate --seed` since the beginning)
RANDOM_STREAMS = ("noise", "mismatch", "reference")


def random_stream(seed: int, stream: str) -> np.random.Generator:
    """The generator of one of ``seed``'s :data:`RANDOM_STREAMS`."""
    index = RANDOM_STREAMS.index(stream)
    return np.random.default_rng(seed if index == 0 else [seed, index])


def plant_mismatch(cfg: ControllerConfig, fraction: float, seed: int) -> PlantMismatch | None:
    """The plant mismatch of a run seeded ``seed`` (None when ``fraction`` is 0)."""
    if not fraction:
        return None
    return PlantMismatch.draw(len(cfg.modes), fraction, random_stream(seed, "mismatch"))


def paper_reference(sample_time: float, levels=PAPER_LEVELS_DEG,
                    segment_s: float = PAPER_SEGMENT_S) -> np.ndarray:
    """Piecewise-constant reference, one value (or row of ``levels``) per sample (6000 for
    the paper)."""
    per = int(round(segment_s / sample_time))
    return np.repeat(np.asarray(levels, dtype=float), per, axis=0)


def scenario_reference(cfg: ControllerConfig) -> np.ndarray:
    """The reference of the closed-loop scenario, (samples, n_outputs).

    ``simulation.reference`` of the config when given (each level held ``segment`` s),
    else the paper's scenario applied to every output.
    """
    sim = cfg.simulation
    return paper_reference(cfg.sample_time, sim.levels(cfg.n_outputs), sim.segment_s)


def reference_range(cfg: ControllerConfig) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) per output of a random flight's levels: the range the config's own
    scenario spans (the envelope the design was written for), inside the output bounds
    every mode keeps. The bounds alone would be a safety envelope, not a flight: the
    paper's ±270 deg roll bound would ask for -170 deg bank."""
    levels = scenario_reference(cfg)
    low, high = levels.min(axis=0), levels.max(axis=0)
    flat = high - low <= 0  # one level only: ± its size (or ±1) around zero
    size = np.where(np.abs(high) > 0, np.abs(high), 1.0)
    low, high = np.where(flat, -size, low), np.where(flat, size, high)
    y_min = np.max([m.y_min for m in cfg.modes], axis=0)
    y_max = np.min([m.y_max for m in cfg.modes], axis=0)
    low, high = np.maximum(low, y_min), np.minimum(high, y_max)
    if not np.all(low < high):
        raise ValueError("the modes' output bounds leave no common range for a reference")
    return low, high


def inside_levels(cfg: ControllerConfig, rng: np.random.Generator, count: int) -> np.ndarray:
    """``count`` levels (count, n_outputs) of an inside flight: uniform in
    :func:`reference_range`."""
    low, high = reference_range(cfg)
    return rng.uniform(low, high, size=(count, cfg.n_outputs))


def random_reference(cfg: ControllerConfig, rng: np.random.Generator, samples: int,
                     draw=inside_levels) -> tuple[np.ndarray, np.ndarray]:
    """(levels, reference) of a random flight of at least ``samples`` samples: the
    scenario's segment length and at least its number of levels, drawn by
    ``draw(cfg, rng, count)`` (:func:`inside_levels`, or envelope.envelope_levels)."""
    segment = cfg.simulation.segment_s
    per = int(round(segment / cfg.sample_time))
    count = -(-max(samples, len(scenario_reference(cfg))) // per)
    levels = draw(cfg, rng, count)
    return levels, paper_reference(cfg.sample_time, levels, segment)


def preview(ref: np.ndarray, k: int, N: int, n_outputs: int = 1) -> np.ndarray:
    """r_{k+1|k} .. r_{k+N|k}, output-major per step, held at the end of the record."""
    idx = np.minimum(np.arange(k + 1, k + N + 1), len(ref) - 1)
    return np.repeat(ref[idx], n_outputs) if ref.ndim == 1 else ref[idx].ravel()


@dataclass
class Channel:
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Cr: np.ndarray | None
    Dr: np.ndarray | None
    actuators: np.ndarray  # physical actuator indices


def plant_modes(cfg: ControllerConfig) -> list[int]:
    """The modes whose models make the simulated plant.

    Modes that each drive their own actuators are channels of one vehicle (the paper's
    two aileron pairs, three drives of one axis): the plant is the sum of all of them.
    Modes that share an actuator are operating points of one plant (one aileron at three
    airspeeds): summing them would multiply its gain, so the plant is the one model the
    scheduler picks for the signal at rest (0: the simulated plant starts at rest)."""
    seen: set[str] = set()
    for mode in cfg.modes:
        if seen & set(mode.actuators):
            sc = cfg.scheduler
            return [scheduled_mode(sc.initial, 0.0, sc.below, sc.above, sc.band_modes)]
        seen |= set(mode.actuators)
    return list(range(len(cfg.modes)))


class SimulatedPlant:
    """The modes' channels (:func:`plant_modes`) summed, each sampled exactly (ZOH) at the
    controller rate; ``mismatch`` perturbs each mode's plant (None: the config's model)."""

    def __init__(self, cfg: ControllerConfig, mismatch: PlantMismatch | None = None):
        self.cfg = cfg
        self.channels = []
        for j in plant_modes(cfg):
            mode = cfg.modes[j]
            # the true plant: the config's model, never augmented by a disturbance model
            # (disturbance_model); a discrete state-space plant is used as given
            disc = (discretise(mode, cfg.sample_time, f"modes[{j}]") if mismatch is None
                    else mismatch.plant(j, mode, cfg.sample_time))
            acts = np.array([cfg.actuators.index(a) for a in mode.actuators])
            self.channels.append(Channel(disc.A, disc.B, disc.C, disc.Cr, disc.Dr, acts))
        self.reset()

    def reset(self):
        self.x = [np.zeros(ch.A.shape[0]) for ch in self.channels]
        self.u_prev = np.zeros(len(self.cfg.actuators))

    def outputs(self) -> np.ndarray:
        return sum(ch.C @ x for ch, x in zip(self.channels, self.x))

    def schedule_signal(self) -> np.ndarray:
        if self.cfg.scheduler is None:
            return np.zeros(0)
        if self.cfg.simulation.schedule_source == "output":
            return self.outputs()[:1]
        rate = sum(ch.Cr @ x + ch.Dr @ self.u_prev[ch.actuators]
                   for ch, x in zip(self.channels, self.x))
        return np.atleast_1d(rate)[:1]

    def advance(self, u: np.ndarray, disturbance: np.ndarray | None = None) -> None:
        u_eff = np.asarray(u, float) + (0 if disturbance is None else disturbance)
        for i, ch in enumerate(self.channels):
            self.x[i] = ch.A @ self.x[i] + ch.B @ u_eff[ch.actuators]
        self.u_prev = np.asarray(u, float).copy()
