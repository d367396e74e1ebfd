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
real travel, which this module measures through the aircraft's own FCS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from ..config.errors import ConfigError
from ..extras import require_module

DEFAULT_AIRCRAFT = "c172p"
DEFAULT_ALTITUDE_FT = 4000.0
DEFAULT_AIRSPEED_KTS = 90.0
FDM_STEPS_PER_SAMPLE = 2  # JSBSim steps per controller sample: 200 Hz at Ts = 10 ms

# atmosphere/turb-type takes FGWinds::tType {ttNone, ttStandard, ttCulp, ttMilspec, ttTustin}
# (the class comment's "4 resp. 5" is off by one; the enum is what SetTurbType receives)
TURB_NONE, TURB_MILSPEC = 0, 3
# JSBSim's reference values (FGWinds.h, from MIL-F-8785C figs. 7 and 9): wind at 20 ft AGL
# in ft/s (sets the intensity below 1000 ft) and the severity, the probability-of-
# exceedance curve of the intensity above 2000 ft (interpolated in between)
TURBULENCE = {"none": (0.0, 0), "light": (25.0, 3), "moderate": (50.0, 4), "severe": (75.0, 6)}

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


class Aircraft:
    """A JSBSim FDM of ``name`` at ``dt`` seconds per step (Ts / FDM_STEPS_PER_SAMPLE)."""

    def __init__(self, name: str, dt: float):
        check_aircraft(name)
        import jsbsim

        jsbsim.FGJSBBase().debug_lvl = 0  # no banner, no echo of the XML on stdout
        self.name = name
        self.fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
        self.fdm.load_model(name)
        self.fdm.set_dt(dt)
        self.travel_deg = self._aileron_travel()

    def __getitem__(self, prop: str) -> float:
        return self.fdm[prop]

    def _aileron_travel(self) -> tuple[float, float]:
        """(deflection at command -1, at +1) in degrees, read through the aircraft's FCS."""
        f = self.fdm
        f.run_ic()
        ends = []
        for command in (-1.0, 1.0):
            f["fcs/aileron-cmd-norm"] = command
            f.run()
            ends.append(float(f["fcs/left-aileron-pos-deg"]))
        f["fcs/aileron-cmd-norm"] = 0.0
        if not ends[0] < 0.0 < ends[1]:
            raise ValueError(f"{self.name}: the left aileron moves {ends[0]:g} .. {ends[1]:g} "
                             "deg for commands -1 .. +1; a positive command must roll right")
        return ends[0], ends[1]

    def aileron_command(self, deg: float) -> float:
        """The normalised command that deflects the left aileron by ``deg`` (FGGain's
        zero-centred aerosurface_scale, inverted on each side of 0)."""
        lo, hi = self.travel_deg
        return deg / hi if deg >= 0.0 else -deg / lo

    def aileron_slope_deg(self, command: float) -> float:
        """Degrees of surface per unit command on the side of 0 that ``command`` is on."""
        lo, hi = self.travel_deg
        return hi if command > 0.0 else -lo

    def trim(self, airspeed_kts: float, altitude_ft: float) -> Trim:
        """Trim straight and level flight (JSBSim's simple trim, engine running); the FDM is
        left at the trim. ConfigError when JSBSim cannot trim."""
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
        f["propulsion/set-running"] = -1
        try:
            f["simulation/do_simple_trim"] = 1
        except jsbsim.TrimFailureError:
            raise ConfigError("airspeed", f"JSBSim cannot trim {self.name} at "
                              f"{airspeed_kts:g} kts, {altitude_ft:g} ft") from None
        return Trim(airspeed_kts=float(f["velocities/vc-kts"]),
                    altitude_ft=float(f["position/h-sl-ft"]),
                    throttle=float(f["fcs/throttle-cmd-norm"]),
                    elevator=float(f["fcs/elevator-cmd-norm"]),
                    pitch_trim=float(f["fcs/pitch-trim-cmd-norm"]),
                    aileron=float(f["fcs/aileron-cmd-norm"]),
                    rudder=float(f["fcs/rudder-cmd-norm"]),
                    aileron_deg=float(f["fcs/left-aileron-pos-deg"]),
                    pitch_deg=float(f["attitude/theta-deg"]), alpha_deg=float(f["aero/alpha-deg"]),
                    true_airspeed_kts=float(f["velocities/vtrue-kts"]))

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

    def stalled(self) -> bool:
        """The c172p's stall hysteresis is engaged (its lift has broken down)."""
        return float(self.fdm["aero/stall-hyst-norm"]) > 0.0

    def command(self, aileron_deg: float, elevator: float, throttle: float,
                rudder: float) -> None:
        """Set the surfaces: the aileron in degrees of left-aileron deflection, the others
        as JSBSim's normalised commands."""
        f = self.fdm
        f["fcs/aileron-cmd-norm"] = self.aileron_command(aileron_deg)
        f["fcs/elevator-cmd-norm"] = elevator
        f["fcs/throttle-cmd-norm"] = throttle
        f["fcs/rudder-cmd-norm"] = rudder

    def advance(self, steps: int) -> None:
        for _ in range(steps):
            if not self.fdm.run():
                t = self.fdm["simulation/sim-time-sec"]
                raise RuntimeError(f"JSBSim stopped at t = {t:g} s")
