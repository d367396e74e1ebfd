"""The scheduling rule of ``P_step`` (k bands with hysteresis, eq. (3) generalised).

One function, shared by the bit-exact mirror of the C (:mod:`.controller`, with the
thresholds rounded to the storage precision) and the double-precision observer bank
(:mod:`..sim.switched_observer`).  It performs the comparisons of ``schedule()`` in
``templates/controller.c.j2`` in the same order.

``below[i] = t_i - eps_i`` and ``above[i] = t_i + eps_i`` for the k-1 increasing
thresholds t_i; ``band_modes[b]`` is the mode of band b (t_{b-1} <= s < t_b).  The
active mode becomes band b's mode only when ``above[b-1] < s < below[b]`` (the bands at
the ends are open); anywhere within a margin of a threshold the current mode is kept.
"""
from __future__ import annotations

from typing import Sequence


def scheduled_mode(current: int, s, below: Sequence, above: Sequence,
                   band_modes: Sequence[int]) -> int:
    """The mode after one sample of scheduling signal ``s`` (finite), from ``current``."""
    band = 0
    while band < len(above) and s > above[band]:
        band += 1  # s is firmly above threshold `band`, hence above all before it
    if band == len(below) or s < below[band]:
        return int(band_modes[band])  # firmly inside the band
    return current  # within the margin of threshold `band`: keep the mode
