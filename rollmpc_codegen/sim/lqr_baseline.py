"""The LQR-with-saturation baseline of the paper's Fig. 2 (``rollmpc simulate --baseline lqr``).

Design, per mode j, on the controller's own discrete realisation (A_j, B_j, C_j from the
context, the same one the MPC and its observer use):

* **Gain**: infinite-horizon discrete LQR, ``K_j = dlqr(A_j, B_j, C_j' Q_j C_j, R_j)``,
  with the config's stage weights Q (on the output) and R (on the input).  The terminal
  weight P has no role in an infinite-horizon design.
* **Reference tracking**: LQR on the error state.  The steady state (x_ss, u_ss) for a
  constant reference r solves ``(A - I) x_ss + B u_ss = 0, C x_ss = r`` (least squares
  when the system is not square); for the UAV's integrating plant this is the roll angle
  at r with zero roll rate and u_ss = 0.  The command is
  ``u = sat(u_ss - K_j (xhat_j - x_ss))``, clipped to the mode's actuator limits.
* **Disturbance models** (``observer.disturbance``): the disturbance states are not
  controllable, so the gain is designed on the other states; the steady state then also
  cancels the observer's disturbance estimate d, solving
  ``(A - I) x_ss + B u_ss + A_d d = 0, C x_ss + C_d d = r`` (offset-free, as the MPC).
* **No preview**: the LQR uses r_{k+1|k}, the first sample of the preview the MPC gets,
  and nothing beyond it.
* **Same scheduler and observers as the MPC**: eq. (3) with the config's hysteresis on
  the measured scheduling signal, and every mode's predictor observer updated every
  sample (:class:`rollmpc_codegen.sim.switched_observer.SwitchedObserver`).  Inactive
  actuators get 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.controller import ControllerModel
from ..model.terminal_law import TrackingLaw, tracking_law
from .switched_observer import SwitchedObserver


@dataclass(frozen=True)
class LqrMode:
    law: TrackingLaw  # gain and steady state (model/terminal_law.py)
    u_min: np.ndarray
    u_max: np.ndarray
    actuator_index: np.ndarray


def design_lqr(model: ControllerModel, ctx: dict) -> list[LqrMode]:
    """One saturated LQR tracking law per mode (see the module docstring)."""
    modes = []
    for mode_cfg, m, mode in zip(model.config.modes, ctx["modes"], model.modes):
        A, B, C = (np.array(m[k], float) for k in ("A", "B", "C"))
        law = tracking_law(A, B, C, mode_cfg.Q, mode_cfg.R, mode.plant.disturbance_states)
        modes.append(LqrMode(law=law, u_min=np.array(m["u_min"], float),
                             u_max=np.array(m["u_max"], float),
                             actuator_index=np.array(m["actuator_index"], int)))
    return modes


class LqrController:
    """``step(y, sched, r) -> (status, u)`` like the generated C, for ``run_closed_loop``."""

    def __init__(self, model: ControllerModel, ctx: dict):
        self.ctx = ctx
        self.modes = design_lqr(model, ctx)
        self.observer = SwitchedObserver(ctx)
        self.ny = ctx["n_outputs"]

    def step(self, y, sched, r):
        j = self.observer.schedule(sched) if sched is not None and len(sched) else \
            self.observer.mode
        lq = self.modes[j]
        r1 = np.asarray(r, float)[:self.ny]  # r_{k+1|k}: no preview beyond one sample
        xhat = self.observer.xhat[j]
        law = lq.law
        target = np.concatenate((r1, xhat[law.dist]))
        x_ss, u_ss = law.Mx @ target, law.Mu @ target
        u_mode = np.clip(u_ss - law.K @ (xhat[law.keep] - x_ss), lq.u_min, lq.u_max)
        u = np.zeros(self.ctx["n_actuators"])
        u[lq.actuator_index] = u_mode
        self.observer.observe(y, u)
        return 0, u

    def info(self) -> dict:
        return {"status": 0, "mode": self.observer.mode, "iterations": 0, "solve_ticks": 0}
