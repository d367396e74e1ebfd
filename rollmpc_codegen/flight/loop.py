"""One flight: a roll controller closes the loop on the JSBSim aircraft at the controller
rate, JSBSim integrates FDM_STEPS_PER_SAMPLE steps per sample.

Each sample k: read the aircraft; the roll controller gets the IMU's roll and roll rate
and the measured airspeed, with seeded Gaussian noise on roll and roll rate (``noise_std``,
deg and deg/s) and ``delay`` samples of latency (the first reading is held until there is
enough history), the reference r_k and the preview r_{k+1..k+N} (held at the end of the
flight; without ``preview_reference``, r_k held over the horizon: the MPC then knows no
more of the future than the PID does); the outer loops (:mod:`.outer_loops`) set
elevator, throttle and rudder from the true states; the commands are held over the
sample (ZOH, as in the MPC's model).

A command that is not finite or outside the aileron's travel stops the flight with
:class:`CommandError`: it must never happen.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field, replace

import numpy as np

from ..sim.scenario import preview
from ..sim.simulate import ClosedLoopLog
from .aircraft import FDM_STEPS_PER_SAMPLE, Aircraft, Trim
from .outer_loops import OuterLoops
from .scenario import FlightReference

# the true signals logged per sample besides the controller's view (deg, deg/s, kts, ft,
# normalised commands, the stall flag, engines running, total thrust in lbf)
AIRCRAFT_SIGNALS = ("roll", "roll_rate", "airspeed", "airspeed_cmd", "altitude", "pitch",
                    "sideslip", "alpha", "elevator", "throttle", "rudder", "stall_hysteresis",
                    "engines_running", "thrust")


class CommandError(RuntimeError):
    """A roll controller returned a non-finite or out-of-travel aileron command."""


@dataclass
class FlightLog:
    """``controller`` is what the roll controller saw and returned (y: the roll it was
    given, sched: the airspeed, u: the aileron in deg); ``rate_fed`` the roll rate it was
    given; ``aircraft`` the true signals (AIRCRAFT_SIGNALS)."""

    controller: ClosedLoopLog
    rate_fed: np.ndarray
    aircraft: dict = field(default_factory=dict)

    def truth(self) -> ClosedLoopLog:
        """The controller's log with y = the true roll (what the metrics judge)."""
        return replace(self.controller, y=self.aircraft["roll"][:, None])


class MpcRoll:
    """The generated C (a HostController) as a roll controller: y = roll, sched = the
    airspeed when the config has a scheduler, r = the preview."""

    name = "MPC (generated C)"

    def __init__(self, host):
        self.host = host
        self.scheduled = bool(host.ctx["n_schedule"])

    def step(self, roll_deg, roll_rate_dps, airspeed_kts, reference_deg, preview_deg):
        status, u = self.host.step([roll_deg], [airspeed_kts] if self.scheduled else None,
                                   preview_deg)
        info = self.host.info()
        return float(u[0]), int(status), {"mode": info["mode"], "iterations": info["iterations"],
                                          "solve_us": info["solve_ticks"] / 1000.0,
                                          "work": info["work"]}


def fly(aircraft: Aircraft, trim: Trim, controller, reference: FlightReference,
        sample_time: float, horizon: int, *, noise_std: float = 0.0, delay: int = 0,
        seed: int = 0, preview_reference: bool = True, progress=None) -> FlightLog:
    """Fly ``reference`` from ``trim`` (the FDM must be at it, with its turbulence set)."""
    K = len(reference)
    rng = np.random.default_rng(seed)
    loops = OuterLoops(trim, sample_time)
    lo, hi = aircraft.travel_deg
    ref = reference.roll_deg
    log = ClosedLoopLog(t=np.arange(K) * sample_time, r=ref[:, None].copy(),
                        y=np.zeros((K, 1)), sched=np.zeros((K, 1)), u=np.zeros((K, 1)),
                        status=np.zeros(K, int), mode=np.zeros(K, int),
                        iterations=np.zeros(K, int), solve_us=np.zeros(K))
    rate_fed = np.zeros(K)
    truth = {name: np.zeros(K) for name in AIRCRAFT_SIGNALS}
    readings: deque = deque(maxlen=delay + 1)
    for k in range(K):
        s = aircraft.sensors()
        noise = rng.normal(0.0, noise_std, 2) if noise_std > 0 else (0.0, 0.0)
        readings.append((s.roll_deg + noise[0], s.roll_rate_dps + noise[1], s.airspeed_kts))
        roll, rate, speed = readings[0]
        ahead = preview(ref, k, horizon) if preview_reference else np.full(horizon, ref[k])
        u, status, info = controller.step(roll, rate, speed, float(ref[k]), ahead)
        if not (math.isfinite(u) and lo <= u <= hi):
            raise CommandError(f"{controller.name} commanded {u!r} deg at t = "
                               f"{k * sample_time:g} s (travel {lo:g} .. {hi:g} deg)")
        elevator, throttle, rudder = loops.step(s, trim.altitude_ft,
                                                float(reference.airspeed_kts[k]))
        aircraft.command(u, elevator, throttle, rudder)
        log.y[k, 0], log.sched[k, 0], log.u[k, 0], rate_fed[k] = roll, speed, u, rate
        log.u_raw.append(u)
        log.status[k], log.mode[k] = status, info["mode"]
        log.iterations[k], log.solve_us[k] = info["iterations"], info["solve_us"]
        log.record_work(k, info)  # the MPC counts its work; the PID baseline does not
        for name, value in (("roll", s.roll_deg), ("roll_rate", s.roll_rate_dps),
                            ("airspeed", s.airspeed_kts),
                            ("airspeed_cmd", reference.airspeed_kts[k]),
                            ("altitude", s.altitude_ft), ("pitch", s.pitch_deg),
                            ("sideslip", s.sideslip_deg), ("alpha", s.alpha_deg),
                            ("elevator", elevator), ("throttle", throttle), ("rudder", rudder),
                            ("stall_hysteresis", float(aircraft.stall_hysteresis())),
                            ("engines_running", float(aircraft.engines_running())),
                            ("thrust", aircraft.thrust_lbs())):
            truth[name][k] = value
        aircraft.advance(FDM_STEPS_PER_SAMPLE)
        if progress is not None:
            progress(k)
    return FlightLog(controller=log, rate_fed=rate_fed, aircraft=truth)
