"""``rollmpc report CONFIG --flight flight.csv``: a flight's controller inputs on the
emulated Cortex-M4F.

The CSV of ``rollmpc fly --csv`` gives, per sample, what the generated C was given: ``y``
(the roll), ``rho`` (the airspeed, with a scheduler) and ``r`` (the reference, from which
the preview r_{k+1..k+N} is rebuilt as the flight built it: held at the end of the
flight). The host build of the report's precision steps through exactly these inputs
(open loop: the aircraft is not flown again) and records every output
(:func:`.replay.record_host_runs`); the target image then replays them bit for bit
(:func:`.measure.measure`). The CSV keeps every number as Python's ``repr``, so a flight
flown in the report's precision is reproduced exactly: its ``u_<actuator>`` and
``status`` columns are compared with the host's too (``flight.commands_match``).
"""
from __future__ import annotations

import csv
import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config.errors import ConfigError
from ..sim.scenario import preview
from .replay import HostRecord, record_host_runs


@dataclass(frozen=True)
class FlightInputs:
    y: np.ndarray  # (K, n_outputs) what the controller was given
    sched: np.ndarray  # (K, n_schedule)
    reference: np.ndarray  # (K,) or (K, n_outputs): r_k, the preview's source
    u: np.ndarray  # (K, n_actuators) what it returned in the flight
    status: np.ndarray  # (K,)


def read_flight_inputs(path: str | Path, ctx: dict, steps: int | None = None) -> FlightInputs:
    """The controller columns of a flight CSV (the first ``steps`` rows), named as
    ``rollmpc simulate --csv`` names them for ``ctx``; ConfigError naming ``--flight``."""
    from ..sim.simulate import csv_header

    key = "--flight"
    # the columns read below (a CSV written before the ``work`` column still reads)
    columns = [c for c in csv_header(ctx) if c not in ("iterations", "solve_us", "work")]
    try:
        with open(path, newline="") as fh:
            reader = csv.DictReader(fh)
            missing = [c for c in columns if c not in (reader.fieldnames or [])]
            if missing:
                raise ConfigError(key, f"{path}: no column {missing[0]!r} (a CSV of `rollmpc "
                                  "fly --csv` flown with this config?)")
            rows = list(itertools.islice(reader, steps))
    except OSError as exc:
        raise ConfigError(key, f"cannot read {path}: {exc.strerror}") from None
    if not rows:
        raise ConfigError(key, f"{path}: no samples")

    def table(names):
        try:
            return np.array([[float(row[c]) for c in names] for row in rows]).reshape(len(rows), -1)
        except ValueError:
            raise ConfigError(key, f"{path}: a value of {', '.join(names)} is not a number") \
                from None

    outputs, actuators = ctx["outputs"], ctx["actuators"]
    single = len(outputs) == 1
    y = table(["y"] if single else [f"y_{o}" for o in outputs])
    r = table(["r"] if single else [f"r_{o}" for o in outputs])
    sched = table(["rho"]) if ctx["n_schedule"] else np.zeros((len(rows), 0))
    u = table([f"u_{a}" for a in actuators])
    status = table(["status"]).astype(int)[:, 0]
    return FlightInputs(y=y, sched=sched, reference=r[:, 0] if single else r, u=u,
                        status=status)


def record_flight(ctx: dict, inputs: FlightInputs, build_root: Path, progress=None,
                  repeats: int = 1, layout=None) -> HostRecord:
    """The host build stepped through the flight's inputs, every output recorded (with
    the kernels and instance ``layout`` of the target: replay.record_host_runs)."""
    N, ny, ns = ctx["horizon"], ctx["n_outputs"], ctx["n_schedule"]

    def drive(controller, progress_cb):
        for k in range(len(inputs.y)):
            controller.step(inputs.y[k], inputs.sched[k] if ns else None,
                            preview(inputs.reference, k, N, ny))
            if progress_cb:
                progress_cb(k)

    return record_host_runs(ctx, build_root, len(inputs.y), drive, progress, repeats,
                            "report: host replay of the flight", layout)


def commands_match(inputs: FlightInputs, record: HostRecord) -> dict:
    """The host replay against the flight's own commands and statuses, bit for bit (in
    float64: a float build's commands are exact doubles)."""
    u = np.array([np.asarray(v, np.float64) for v in record.u])
    status = np.array([info["status"] for info in record.info])
    bad = np.flatnonzero(np.any(u.view(np.uint64) != inputs.u.view(np.uint64), axis=1)
                         | (status != inputs.status))
    return {"commands_match": bool(bad.size == 0), "mismatching_samples": int(bad.size),
            "first_mismatch": int(bad[0]) if bad.size else None}
