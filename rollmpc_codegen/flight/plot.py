"""``rollmpc fly --plot``: a flight in the style of the paper's Fig. 2, the baseline
dashed (the line styles of :mod:`rollmpc_codegen.sim.figures`).

(a) true roll and reference; (b) aileron (deg of left-aileron deflection, dash-dot: the
travel); (c) the scheduling signal, measured airspeed, with its command, the band
thresholds (dotted: +/- epsilon) and the MPC's mode on a second axis; (d) what the outer
loops hold: the altitude excursion and the sideslip.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..config import ControllerConfig
from ..sim.figures import BASELINE_STYLE, MPC_STYLE, _pyplot, _save
from .loop import FlightLog


def plot_flight(path: str | Path, cfg: ControllerConfig, log: FlightLog,
                baseline: FlightLog | None = None, title: str = "",
                baseline_label: str = "PID") -> Path:
    plt = _pyplot()
    runs = [("MPC", log, MPC_STYLE)]
    if baseline is not None:
        runs.append((baseline_label, baseline, BASELINE_STYLE))
    fig, (ax_y, ax_u, ax_s, ax_h) = plt.subplots(
        4, 1, figsize=(10, 10.5), sharex=True,
        gridspec_kw={"height_ratios": [2.2, 1.3, 1.6, 1.2]})
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    t = log.controller.t

    ax_y.plot(t, log.controller.r[:, 0], color="0.35", linestyle=":", linewidth=1.4,
              label="reference")
    for label, run, style in runs:
        ax_y.plot(t, run.aircraft["roll"], color=colors[0], **style, label=f"roll, {label}")
    ax_y.set_ylabel("roll [deg]")
    ax_y.set_title("(a) roll angle (true) and reference", loc="left", fontsize=10)
    ax_y.legend(loc="upper left", fontsize=8, ncol=3)
    ax_y.grid(alpha=0.3)

    for label, run, style in runs:
        ax_u.plot(t, run.controller.u[:, 0], color=colors[2], **style, label=f"aileron, {label}")
    for v in sorted({float(b) for m in cfg.modes for b in (*m.u_min, *m.u_max)}):
        ax_u.axhline(v, color="0.6", linewidth=0.8, linestyle="-.")
    ax_u.set_ylabel("aileron [deg]")
    ax_u.set_title("(b) left-aileron command (dash-dot: travel bounds)", loc="left", fontsize=10)
    ax_u.legend(loc="upper left", fontsize=8, ncol=2)
    ax_u.grid(alpha=0.3)

    ax_s.plot(t, log.aircraft["airspeed_cmd"], color="0.35", linestyle=":", linewidth=1.4,
              label="airspeed command")
    for label, run, style in runs:
        ax_s.plot(t, run.controller.sched[:, 0], color=colors[4], **style,
                  label=f"measured airspeed, {label}")
    sc = cfg.scheduler
    if sc is not None:
        for v, eps in zip(sc.thresholds, sc.epsilons):
            ax_s.axhline(v, color="0.5", linewidth=0.8)
            for e in (-eps, eps):
                ax_s.axhline(v + e, color="0.7", linewidth=0.6, linestyle=":")
        ax_m = ax_s.twinx()
        names = [m.name for m in cfg.modes]
        ax_m.step(t, log.controller.mode + 1, where="post", color="k", linewidth=0.9,
                  label="MPC mode")
        ax_m.set_yticks(np.arange(1, len(names) + 1), names)
        ax_m.set_ylim(0.5, len(names) + 0.5 + 0.6 * len(names))
        ax_m.legend(loc="upper right", fontsize=8)
    ax_s.set_ylabel("airspeed [kts]")
    ax_s.set_title("(c) scheduling signal: calibrated airspeed (solid: band thresholds, "
                   "dotted: +/- epsilon) and the active mode", loc="left", fontsize=10)
    ax_s.legend(loc="upper left", fontsize=8, ncol=3)
    ax_s.grid(alpha=0.3)

    altitude0 = log.aircraft["altitude"][0]
    for label, run, style in runs:
        ax_h.plot(t, run.aircraft["altitude"] - altitude0, color=colors[1], **style,
                  label=f"altitude - {altitude0:.0f} ft, {label}")
        ax_h.plot(t, run.aircraft["sideslip"], color=colors[3], **style,
                  label=f"sideslip [deg], {label}")
    ax_h.set_ylabel("ft / deg")
    ax_h.set_xlabel("time t [s]")
    ax_h.set_title("(d) outer loops: altitude excursion and sideslip", loc="left", fontsize=10)
    ax_h.legend(loc="upper left", fontsize=8, ncol=2)
    ax_h.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=11)
    return _save(plt, fig, path)
