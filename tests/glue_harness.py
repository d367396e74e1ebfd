"""The autopilot glue core (firmware_stub/integration/common/rollglue.c) in a closed loop.

The glue and a generated controller are compiled into one host library and driven
through cffi. The plant is the simulated UAV (``SimulatedPlant``); "the autopilot's own
controller", which flies whenever the glue hands over, is the saturated LQR baseline
(``LqrController``), run every sample like fw_rate_control or ArduPlane's roll
controller. The servo path is modelled as the autopilots do it: the glue's normalised
channel values become deflections through the same channel, sign and throw mapping.
"""
from __future__ import annotations

import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import cffi
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
GLUE = ROOT / "firmware_stub" / "integration" / "common"
MAX_CHANNELS = 32
SAMPLE_US = 10_000
WARNINGS = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wshadow",
            "-Wdouble-promotion", "-Wfloat-equal", "-Wcast-align", "-Wstrict-prototypes",
            "-Wbad-function-cast", "-Wnested-externs", "-fno-common", "-Werror"]

CDEF = """
typedef struct {{
    uint32_t timeout_us; uint16_t frozen_samples; uint16_t warmup_samples;
    uint16_t max_failures; float ref_slew_dps;
    int8_t channel[{n}][2]; int8_t sign[{n}][2]; float throw_deg[{n}];
}} rollglue_params;
typedef struct {{
    float roll_deg; uint64_t roll_us; float roll_rate_dps; uint64_t rate_us;
    float roll_cmd_deg; uint64_t cmd_us; float airspeed_mps; uint64_t airspeed_us;
    float applied[{c}]; int engage;
}} rollglue_input;
typedef struct {{
    int valid; uint32_t channel_mask; float value[{c}]; float u_deg[{n}];
}} rollglue_output;
typedef struct {{
    int state; uint32_t reasons; int status; int mode; uint32_t consecutive_failures;
    uint32_t failures; uint32_t engagements; uint32_t solve_cycles; uint32_t max_solve_cycles;
    uint16_t warm_samples;
}} rollglue_telemetry;
void rollglue_init(void *g);
int rollglue_set_params(void *g, const rollglue_params *p, uint32_t n_channels);
int rollglue_step(void *g, const rollglue_input *in, uint64_t now_us, rollglue_output *out);
const rollglue_telemetry *rollglue_get_telemetry(const void *g);
void rollglue_sizes(uint32_t sizes[5]);
"""
# reason bits and states of rollglue.h
NOT_REQUESTED, STALE_ROLL, STALE_RATE, STALE_CMD, FROZEN, NONFINITE, WARMING, SOLVER, \
    LOCKED_OUT, NO_PARAMS, STALE_SCHED = (1 << i for i in range(11))
TRACKING, ENGAGED, LOCKOUT = 0, 1, 2


def build_glue(generated: Path, out: Path, extra: tuple[Path, ...] = (),
               defines: tuple[str, ...] = ()) -> Path:
    """lib of the glue core + the generated controller in ``generated`` (strict flags),
    plus ``extra`` sources (an autopilot's C glue; their directories are on the path) and
    ``defines`` (-D flags: the prefix of a tree that is not rollmpc)."""
    lib = out / "librollglue.so"
    cmd = ["gcc", "-O2", "-fPIC", "-shared", "-ffp-contract=off", *WARNINGS, *defines,
           f"-I{generated}",
           f"-I{GLUE}", *dict.fromkeys(f"-I{src.parent}" for src in extra), "-o", str(lib),
           str(GLUE / "rollglue.c"), *map(str, extra),
           *map(str, sorted(generated.glob("*.c"))), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    return lib


DEFAULTS = dict(timeout_us=25_000, frozen_samples=25, warmup_samples=20, max_failures=5,
                ref_slew_dps=30.0, channel=((0, -1), (1, -1)), sign=((1, 1), (1, 1)),
                throw_deg=(15.0, 15.0))


class Glue:
    """One rollglue instance in a host library."""

    def __init__(self, lib_path: Path, n_actuators: int):
        self.ffi = cffi.FFI()
        self.ffi.cdef(CDEF.format(n=n_actuators, c=MAX_CHANNELS))
        self.lib = self.ffi.dlopen(str(lib_path))
        sizes = self.ffi.new("uint32_t[5]")
        self.lib.rollglue_sizes(sizes)
        declared = [self.ffi.sizeof(t) for t in ("rollglue_params", "rollglue_input",
                                                 "rollglue_output", "rollglue_telemetry")]
        assert list(sizes)[1:] == declared, "CDEF is out of step with rollglue.h"
        self.state = self.ffi.new("char[]", sizes[0])
        self.lib.rollglue_init(self.state)
        self.input = self.ffi.new("rollglue_input *")
        self.output = self.ffi.new("rollglue_output *")

    def set_params(self, n_channels: int = 8, **changes) -> int:
        p = self.ffi.new("rollglue_params *")
        for key, value in {**DEFAULTS, **changes}.items():
            setattr(p, key, [list(v) if isinstance(v, tuple) else v for v in value]
                    if isinstance(value, tuple) else value)
        return self.lib.rollglue_set_params(self.state, p, n_channels)

    def step(self, now_us: int, engage: bool, roll, rate, cmd, roll_us, rate_us, cmd_us,
             applied: dict[int, float]):
        i = self.input
        i.roll_deg, i.roll_rate_dps, i.roll_cmd_deg = roll, rate, cmd
        i.roll_us, i.rate_us, i.cmd_us = roll_us, rate_us, cmd_us
        for c in range(MAX_CHANNELS):
            i.applied[c] = applied.get(c, float("nan"))
        i.engage = int(engage)
        valid = self.lib.rollglue_step(self.state, i, now_us, self.output)
        return valid, self.output

    def telemetry(self):
        return self.lib.rollglue_get_telemetry(self.state)


@dataclass
class Faults:
    """Sensor faults of a run, by sample index k -> what the autopilot hands the glue."""
    stale: dict = field(default_factory=dict)     # k -> set of "roll" / "rate" / "cmd"
    frozen: range = range(0)                      # attitude re-published unchanged
    nan: range = range(0)                         # NaN roll and rate


@dataclass
class Log:
    y: list = field(default_factory=list)
    rate: list = field(default_factory=list)
    valid: list = field(default_factory=list)
    u: list = field(default_factory=list)
    reasons: list = field(default_factory=list)
    values: list = field(default_factory=list)

    def arrays(self):
        return {k: np.array(v) for k, v in self.__dict__.items()}


def closed_loop(glue: Glue, model, ctx, steps: int, engage, cmd, faults: Faults | None = None,
                params: dict | None = None) -> Log:
    """Run ``steps`` samples: ``engage(k)``, ``cmd(k)`` in deg; returns the log."""
    from rollmpc_codegen.sim.lqr_baseline import LqrController
    from rollmpc_codegen.sim.scenario import SimulatedPlant

    faults = faults or Faults()
    p = {**DEFAULTS, **(params or {})}
    plant, autopilot = SimulatedPlant(model.config), LqrController(model, ctx)
    n = ctx["horizon"]
    log, last, frozen = Log(), {}, None
    for k in range(steps):
        now = (k + 1) * SAMPLE_US
        y, rate = float(plant.outputs()[0]), float(plant.schedule_signal()[0])
        _, u_ap = autopilot.step([y], [rate], np.full(n, cmd(k)))
        for name, value in (("roll", y), ("rate", rate), ("cmd", cmd(k))):
            if name not in faults.stale.get(k, ()):  # a stopped topic keeps value and stamp
                last[name] = (now, value)
        (roll_us, y_in), (rate_us, rate_in), (cmd_us, cmd_in) = (
            last.get(name, (0, 0.0)) for name in ("roll", "rate", "cmd"))
        if k in faults.frozen:  # re-published unchanged at fresh stamps
            frozen = frozen or (y_in, rate_in)
            y_in, rate_in = frozen
        if k in faults.nan:
            y_in = rate_in = float("nan")
        first_servo = [(ch[0], sg[0], t) for ch, sg, t in zip(p["channel"], p["sign"],
                                                             p["throw_deg"])]
        applied = {ch: s * u / t for (ch, s, t), u in zip(first_servo, u_ap)}
        valid, out = glue.step(now, engage(k), y_in, rate_in, cmd_in, roll_us, rate_us, cmd_us,
                               applied)
        if valid:  # the servos: normalised value -> deflection through the same mapping
            u = np.array([s * out.value[ch] * t for ch, s, t in first_servo])
        else:
            u = u_ap
        log.y.append(y)
        log.rate.append(rate)
        log.valid.append(valid)
        log.u.append(np.array(u, float))
        log.reasons.append(glue.telemetry().reasons)
        log.values.append([out.value[c] for c in range(MAX_CHANNELS)])
        plant.advance(u)
    return log
