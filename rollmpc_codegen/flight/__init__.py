"""Software in the loop on a nonlinear 6-DOF aircraft (JSBSim, the optional ``flight`` extra).

``aircraft`` (the JSBSim model: trim, turbulence, sensors, surfaces) -> ``identify`` (the
lateral model at each trim, written as a config) -> the generated C flies it: ``loop``
(one flight at the controller rate), ``outer_loops`` (pitch, altitude, airspeed, yaw
damper), ``pid_roll`` (the PX4-style baseline), ``scenario`` (reference and airspeed
command), ``metrics``, ``plot``, ``run`` (one flight and its baseline, as ``rollmpc fly``
does) and ``matrix`` (the turbulence x seed table of docs/flight.md).
"""
