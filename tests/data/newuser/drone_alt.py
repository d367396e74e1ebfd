"""A design of our own for issue 48 (not among examples/): a quadrotor's altitude loop,
written through the Python API as a new user would from the README.

Linear model about hover (m = 1.5 kg): x = [z (m), vz (m/s), T (N)], T the thrust beyond
hover's 14.7 N behind a first-order motor lag of 50 ms, with linear drag 0.25 N s/m:
    z' = vz,   vz' = (T - 0.25 vz) / m,   T' = (u - T) / 0.05
Outputs: the altitude (tracked) and the vertical speed (bounded hard, not weighted).
Thrust within [-8, 12] N of hover, at most 1 N per 20 ms sample (Δu limits).  The
terminal weight P = 100 Q: with P = Q the 0.4 s horizon settles 0.5 m off.
"""
from __future__ import annotations

import numpy as np

MASS, DRAG, LAG = 1.5, 0.25, 0.05  # kg, N s/m, s
A = np.array([[0.0, 1.0, 0.0], [0.0, -DRAG / MASS, 1.0 / MASS], [0.0, 0.0, -1.0 / LAG]])
B = np.array([[0.0], [0.0], [1.0 / LAG]])
C = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
UNITS = {"outputs": ["m", "m/s"], "actuators": "N"}
SCENARIO = {"reference": {"levels": [0.0, [3.0, 0.0], [1.0, 0.0], [4.0, 0.0]],
                          "segment": 4.0}}


def design(sample_time: float = 0.02, horizon: int = 20, **options):
    """The drone's Design; ``options`` replace or add Design keywords (``mode=`` a dict of
    Mode keywords merged into the mode's)."""
    import control as ct

    import rollmpc_codegen as rm

    mode = {"Q": [10.0, 0.0], "R": 0.1, "P": [1000.0, 0.0], "u_bounds": (-8.0, 12.0),
            "y_bounds": ([-np.inf, -2.0], [np.inf, 3.0]), "du_bounds": (-1.0, 1.0),
            **options.pop("mode", {})}
    plant = options.pop("plant", ct.ss(A, B, C, np.zeros((2, 1))))
    keywords = {"prefix": "drone", "units": UNITS, "simulation": SCENARIO, **options}
    return rm.Design(sample_time=sample_time, horizon=horizon, outputs=["z", "vz"],
                     actuators=["thrust"], modes=[rm.Mode("hover", plant=plant, **mode)],
                     **keywords)
