"""Band scheduler (eq. 3 generalised) and the per-mode predictor observers, in double,
from the context.

This is what an integrator of ``P_solve_qp`` runs outside the generated C: the context
JSON carries each mode's ``A, B, C, L`` in the generator's realisation, and the observer
is the paper's predictor form ``xhat(k+1) = A xhat + B u_j + L (y - C xhat)``.  As in
``P_step``, *every* mode's observer is updated every sample with the measurement and
its own actuators' commands (0 while the mode is inactive), so a switch is bumpless.

Used by the LQR baseline of ``rollmpc simulate`` (:mod:`rollmpc_codegen.sim.lqr_baseline`)
and by the QP recording of ``rollmpc bench``.  It is plain NumPy in double, not a
bit-exact mirror of the C (that is :mod:`rollmpc_codegen.reference.controller`).
"""
from __future__ import annotations

import numpy as np

from ..reference.scheduler import scheduled_mode


class SwitchedObserver:
    """Band scheduler with hysteresis (eq. 3 generalised) plus one Luenberger predictor
    per mode."""

    def __init__(self, ctx: dict):
        self.ctx = ctx
        self.A = [np.array(m["A"], float) for m in ctx["modes"]]
        self.B = [np.array(m["B"], float) for m in ctx["modes"]]
        self.C = [np.array(m["C"], float) for m in ctx["modes"]]
        self.L = [np.array(m["L"], float) for m in ctx["modes"]]
        self.actuators = [np.array(m["actuator_index"], int) for m in ctx["modes"]]
        self.reset()

    def reset(self) -> None:
        self.mode = self.ctx["initial_mode"]
        self.xhat = [np.zeros(A.shape[0]) for A in self.A]

    def schedule(self, sched) -> int:
        """The band rule of :mod:`..reference.scheduler` (firmly inside a band -> its mode,
        within a threshold's margin -> keep the current mode), in double.  Returns (and
        keeps) the active mode."""
        sc = self.ctx["scheduler"]
        if sc is None:
            return self.mode
        s = float(np.asarray(sched).ravel()[0])
        self.mode = scheduled_mode(self.mode, s, sc["below"], sc["above"], sc["band_modes"])
        return self.mode

    def observe(self, y, u_phys) -> None:
        """Advance every mode's estimate with the measurement and the applied commands."""
        y = np.asarray(y, float)
        u_phys = np.asarray(u_phys, float)
        for j in range(len(self.A)):
            x = self.xhat[j]
            innovation = y - self.C[j] @ x
            self.xhat[j] = (self.A[j] @ x + self.B[j] @ u_phys[self.actuators[j]]
                            + self.L[j] @ innovation)
