"""One JSBSim aircraft: trim, turbulence, what its sensors read, what its surfaces get.

Every JSBSim property the flight code reads or writes is named in this module. The names
and their meaning were checked in JSBSim's own sources (docs/flight.md, "JSBSim"):
``atmosphere/turb-type`` and the MIL-F-8785C Dryden parameters in
``src/models/atmosphere/FGWinds.{h,cpp}``, the aileron's ``aerosurface_scale`` in
``src/models/flight_control/FGGain.cpp``, the trim in ``FGFDMExec``/``FGTrim``.

The aileron command of our controllers is the deflection of the left aileron in degrees
of surface: the c172p's roll and yaw moments are linear in ``fcs/left-aileron-pos-rad``
(ClDa, Cnda), while its normalised command maps to the surface piecewise (+1 -> +15 deg,
-1 -> -20 deg, FGGain's zero-centred scale). In degrees the plant is linear over the whole
real travel, which :func:`measure_travel` measures through the aircraft's own FCS:

**Travel at steady state.** A full command (-1, then +1) is held on the ground until
the left aileron stops moving (its actuator may lag or be rate-limited: the f15's and
f16's kinematic actuators take 0.3 s end to end, and one step moved them 1 deg of 20).
The largest rate seen on those steps is the actuator's rate limit; an aileron that
reaches its end within one step has none.

``settings`` are JSBSim properties (gear, flaps, mixture, ...) set once the engines run,
before the trim, and held through the flight: an aircraft's configuration (docs/flight.md,
"Trim settings").
"""
from __future__ import annotations

import math
import os
import re
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from ..config.errors import ConfigError
from ..extras import require_module

DEFAULT_AIRCRAFT = "c172p"
DEFAULT_ALTITUDE_FT = 4000.0
DEFAULT_AIRSPEED_KTS = 90.0
FDM_STEPS_PER_SAMPLE = 2  # JSBSim steps per controller sample: 200 Hz at Ts = 10 ms
SETTLE_MAX_S = 5.0  # the longest an aileron may take to reach its end
SETTLED_DEG = 1e-6  # a step that moves the surface less than this: it has arrived

# atmosphere/turb-type takes FGWinds::tType {ttNone, ttStandard, ttCulp, ttMilspec, ttTustin}
# (the class comment's "4 resp. 5" is off by one; the enum is what SetTurbType receives)
TURB_NONE, TURB_MILSPEC = 0, 3
# JSBSim's reference values (FGWinds.h, from MIL-F-8785C figs. 7 and 9): wind at 20 ft AGL
# in ft/s (sets the intensity below 1000 ft) and the severity, the probability-of-
# exceedance curve of the intensity above 2000 ft (interpolated in between)
TURBULENCE = {"none": (0.0, 0), "light": (25.0, 3), "moderate": (50.0, 4), "severe": (75.0, 6)}

# what FGTrim names when an axis cannot be trimmed ("Sorry, udot doesn't appear to be
# trimmable", printed on stdout), and what it means for the user
TRIM_AXES = {
    "udot": "no throttle holds the airspeed (thrust cannot match drag: a speed beyond "
            "the engines, or an engine or propeller left unset; see --set)",
    "wdot": "no angle of attack holds level flight (below the stall speed, or past the "
            "elevator's authority)",
    "qdot": "the elevator and pitch trim cannot balance the pitching moment",
    "pdot": "the ailerons cannot balance the rolling moment",
    "rdot": "the rudder cannot balance the yawing moment",
    "vdot": "no bank angle balances the side force",
}
EVERY_ENGINE = "[*]"  # in a setting's property name: every engine's index (apply_settings)
# the named options of `rollmpc identify` for the usual configuration settings
GEAR_PROPERTY, FLAPS_PROPERTY = "gear/gear-cmd-norm", "fcs/flap-cmd-norm"
MIXTURE_PROPERTY = "fcs/mixture-cmd-norm" + EVERY_ENGINE
TRIM_SORRY = re.compile(r"Sorry, (\w+) doesn't appear to be trimmable")
FT_PER_S_PER_KT = 1.6878098571011957
RAD = 180.0 / math.pi  # degrees per radian


def require_jsbsim() -> None:
    """One line, exit 1 in the CLI, when the ``flight`` extra is missing."""
    require_module("jsbsim", "flight", "flying an aircraft")


def aircraft_names() -> list[str]:
    """The aircraft shipped with the installed jsbsim wheel."""
    import jsbsim

    root = Path(jsbsim.get_default_root_dir()) / "aircraft"
    return sorted(p.name for p in root.iterdir() if (p / f"{p.name}.xml").is_file())


def check_aircraft(name: str) -> None:
    """ConfigError unless the jsbsim wheel has ``name`` (JSBSim itself would crash on a
    second load_model after a failed one)."""
    require_jsbsim()
    if name not in aircraft_names():
        raise ConfigError("aircraft", f"unknown aircraft {name!r}; the jsbsim wheel has "
                          f"{', '.join(aircraft_names())}")


@dataclass(frozen=True)
class Trim:
    """Straight and level flight at one airspeed and altitude, as JSBSim trimmed it."""

    airspeed_kts: float  # calibrated
    altitude_ft: float
    throttle: float  # normalised commands
    elevator: float
    pitch_trim: float
    aileron: float
    rudder: float
    aileron_deg: float  # the left aileron's deflection at the trim
    pitch_deg: float
    alpha_deg: float
    true_airspeed_kts: float
    roll_deg: float = 0.0  # a full trim may bank the wings a little (the c310: -1.9 deg)


@dataclass(frozen=True)
class Sensors:
    """The true values the IMU and air data would read (noise and delay are the loop's)."""

    roll_deg: float
    roll_rate_dps: float  # body rate p
    pitch_deg: float
    pitch_rate_dps: float
    yaw_rate_dps: float
    airspeed_kts: float  # calibrated
    altitude_ft: float
    climb_fps: float
    sideslip_deg: float
    alpha_deg: float


@dataclass(frozen=True)
class Travel:
    travel_deg: tuple[float, float]  # (at command -1, at +1), steady state
    rate_dps: float | None  # the largest rate on those steps; None: one step reaches the end
    settle_s: float  # the longer of the two steps' times to arrive


def measure_travel(aircraft: Aircraft) -> Travel:
    """The left aileron's steady deflection at commands -1 and +1 (deg) and its rate, on
    the ground (module docstring). ConfigError when it does not move both ways."""
    f = aircraft.fdm
    f.run_ic()
    dt = float(f.get_delta_t())
    ends, rates, settle = [], [], 0.0
    for command in (-1.0, 1.0):
        f["fcs/aileron-cmd-norm"] = command
        before = float(f["fcs/left-aileron-pos-deg"])
        steps, fastest = 0, 0.0
        while steps * dt < SETTLE_MAX_S:
            f.run()
            steps += 1
            now = float(f["fcs/left-aileron-pos-deg"])
            if abs(now - before) < SETTLED_DEG:
                break
            fastest = max(fastest, abs(now - before) / dt)
            before = now
        ends.append(before)
        rates.append(None if steps <= 2 else fastest)
        settle = max(settle, (steps - 1) * dt)
    f["fcs/aileron-cmd-norm"] = 0.0
    if not ends[0] < 0.0 < ends[1]:
        raise ConfigError("aircraft", f"{aircraft.name}: the left aileron moves "
                          f"{ends[0]:g} .. {ends[1]:g} deg for commands -1 .. +1 at steady "
                          "state (fcs/left-aileron-pos-deg); rollmpc flies an aircraft whose "
                          "positive command rolls right through that deflection")
    limited = [r for r in rates if r is not None]
    return Travel(travel_deg=(ends[0], ends[1]), rate_dps=min(limited) if limited else None,
                  settle_s=settle)


class Aircraft:
    """A JSBSim FDM of ``name`` at ``dt`` seconds per step (Ts / FDM_STEPS_PER_SAMPLE),
    with the JSBSim property ``settings`` ((name, value) pairs) applied at each trim;
    ``travel`` (a :class:`Travel`) is measured unless given."""

    def __init__(self, name: str, dt: float, settings=(), travel=None):
        check_aircraft(name)
        import jsbsim

        jsbsim.FGJSBBase().debug_lvl = 0  # no banner, no echo of the XML on stdout
        self.name = name
        self.settings = tuple(settings)
        self.fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
        with quiet_stdout():  # some models print their loading on stdout
            self.fdm.load_model(name)
        self.fdm.set_dt(dt)
        self.engines = int(self.fdm.get_propulsion().get_num_engines())
        if travel is None:  # the steady travel through the FCS
            travel = measure_travel(self)
        self.travel = travel
        self.travel_deg = travel.travel_deg

    def __getitem__(self, prop: str) -> float:
        return self.fdm[prop]

    def engines_running(self) -> int:
        """How many engines run (JSBSim's FGEngine Running flag, ``set-running``)."""
        return sum(float(self.fdm[f"propulsion/engine[{i}]/set-running"]) > 0
                   for i in range(self.engines))

    def thrust_lbs(self) -> float:
        return sum(float(self.fdm[f"propulsion/engine[{i}]/thrust-lbs"])
                   for i in range(self.engines))

    def aileron_command(self, deg: float) -> float:
        """The normalised command that deflects the left aileron by ``deg`` (FGGain's
        zero-centred aerosurface_scale, inverted on each side of 0)."""
        lo, hi = self.travel_deg
        return deg / hi if deg >= 0.0 else -deg / lo

    def aileron_deg(self, command: float) -> float:
        """The steady deflection of the left aileron at normalised ``command``."""
        lo, hi = self.travel_deg
        return command * hi if command >= 0.0 else -command * lo

    def apply_settings(self) -> None:
        """Set every (property, value) of the settings; ``[*]`` in a name stands for each
        engine's index (``fcs/mixture-cmd-norm[*]``: every engine's mixture)."""
        for prop, value in self.settings:
            names = [prop.replace(EVERY_ENGINE, f"[{i}]") for i in range(self.engines)] \
                if EVERY_ENGINE in prop else [prop]
            for name in names:
                # setting an unknown property would create it, silently doing nothing
                if not self.fdm.get_property_manager().hasNode(name):
                    raise ConfigError("--set", f"{self.name} has no JSBSim property {name!r}")
                self.fdm[name] = value

    def trim(self, airspeed_kts: float, altitude_ft: float) -> Trim:
        """Trim straight and level flight (JSBSim's simple trim, engines running, the
        settings applied); the FDM is left at the trim. ConfigError naming the axis that
        JSBSim could not trim."""
        import jsbsim

        f = self.fdm
        f["ic/h-sl-ft"] = altitude_ft
        f["ic/vc-kts"] = airspeed_kts
        f["ic/gamma-deg"] = 0.0
        f["ic/phi-deg"] = 0.0
        f["ic/psi-true-deg"] = 0.0
        for command in ("aileron", "elevator", "rudder"):
            f[f"fcs/{command}-cmd-norm"] = 0.0
        f.run_ic()
        f["propulsion/set-running"] = -1  # every engine (FGPropulsion::InitRunning(-1)) ...
        self.apply_settings()
        with captured_stdout() as printed:
            try:
                f["simulation/do_simple_trim"] = 1
                failed = False
            except jsbsim.TrimFailureError:
                failed = True
        stopped = self.engines - self.engines_running()
        if failed or stopped:
            axes = TRIM_SORRY.findall(printed())
            why = TRIM_AXES.get(axes[0], f"{axes[0]} is not trimmable") if axes else \
                "its trim did not converge (a speed or altitude it cannot fly level at)"
            if stopped:  # FGPiston stops below 80 % of idle RPM: a governor at its minimum
                why = (f"{stopped} of its {self.engines} engines stopped in the trim (a "
                       "piston engine stops below 80 % of its idle RPM, where a constant-"
                       "speed propeller's governor at its lowest RPM takes it)")
            raise ConfigError("airspeed", f"JSBSim cannot trim {self.name} at "
                              f"{airspeed_kts:g} kts, {altitude_ft:g} ft: {why}")
        return Trim(airspeed_kts=float(f["velocities/vc-kts"]),
                    altitude_ft=float(f["position/h-sl-ft"]),
                    throttle=float(f["fcs/throttle-cmd-norm"]),
                    elevator=float(f["fcs/elevator-cmd-norm"]),
                    pitch_trim=float(f["fcs/pitch-trim-cmd-norm"]),
                    aileron=float(f["fcs/aileron-cmd-norm"]),
                    rudder=float(f["fcs/rudder-cmd-norm"]),
                    aileron_deg=self.aileron_deg(float(f["fcs/aileron-cmd-norm"])),
                    pitch_deg=float(f["attitude/theta-deg"]), alpha_deg=float(f["aero/alpha-deg"]),
                    true_airspeed_kts=float(f["velocities/vtrue-kts"]),
                    roll_deg=float(f["attitude/phi-deg"]))

    def set_turbulence(self, level: str, seed: int) -> None:
        """MIL-F-8785C Dryden turbulence (JSBSim's ``ttMilspec``) of ``level`` (a key of
        TURBULENCE), from FGWinds' own random generator seeded with ``seed``."""
        wind_20ft_fps, severity = TURBULENCE[level]
        f = self.fdm
        f["atmosphere/randomseed"] = int(seed)
        f["atmosphere/turb-type"] = TURB_MILSPEC if severity else TURB_NONE
        f["atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps"] = wind_20ft_fps
        f["atmosphere/turbulence/milspec/severity"] = severity

    def sensors(self) -> Sensors:
        f = self.fdm
        return Sensors(roll_deg=float(f["attitude/phi-deg"]),
                       roll_rate_dps=float(f["velocities/p-rad_sec"]) * RAD,
                       pitch_deg=float(f["attitude/theta-deg"]),
                       pitch_rate_dps=float(f["velocities/q-rad_sec"]) * RAD,
                       yaw_rate_dps=float(f["velocities/r-rad_sec"]) * RAD,
                       airspeed_kts=float(f["velocities/vc-kts"]),
                       altitude_ft=float(f["position/h-sl-ft"]),
                       climb_fps=float(f["velocities/h-dot-fps"]),
                       sideslip_deg=float(f["aero/beta-deg"]),
                       alpha_deg=float(f["aero/alpha-deg"]))

    def stall_hysteresis(self) -> bool:
        """The aircraft's stall hysteresis is engaged (only models with
        ``hysteresis_limits`` have one, the c172p among them)."""
        return float(self.fdm["aero/stall-hyst-norm"]) > 0.0

    def command(self, aileron_deg: float, elevator: float, throttle: float,
                rudder: float) -> None:
        """Set the surfaces: the aileron in degrees of left-aileron deflection, the others
        as JSBSim's normalised commands."""
        f = self.fdm
        f["fcs/aileron-cmd-norm"] = self.aileron_command(aileron_deg)
        f["fcs/elevator-cmd-norm"] = elevator
        for i in range(self.engines):  # fcs/throttle-cmd-norm alone is the first engine's
            f[f"fcs/throttle-cmd-norm[{i}]"] = throttle
        f["fcs/rudder-cmd-norm"] = rudder

    def advance(self, steps: int) -> None:
        for _ in range(steps):
            if not self.fdm.run():
                t = self.fdm["simulation/sim-time-sec"]
                raise RuntimeError(f"JSBSim stopped at t = {t:g} s")


@contextmanager
def captured_stdout():
    """JSBSim's C++ prints on file descriptor 1 (FGTrim's reasons among it): redirect it
    to a file for the block; yields a function that returns what was printed."""
    sys.stdout.flush()
    saved = os.dup(1)
    with tempfile.TemporaryFile(mode="w+b") as sink:
        os.dup2(sink.fileno(), 1)
        text: list[str] = []
        try:
            yield lambda: "".join(text)
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            sink.seek(0)
            text.append(sink.read().decode(errors="replace"))


@contextmanager
def quiet_stdout():
    """Drop what JSBSim prints on stdout in the block (a model's loading messages)."""
    with captured_stdout():
        yield
