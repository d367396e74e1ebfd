"""Run-time bounds of constrained signals (P_set_signal_bounds, P_get_signal_bounds;
features/runtime_bounds.py): statuses as for output bounds, C == reference bit for bit
across a change, and the closed loop holds the tightened bound."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import Built
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.status import BAD_ARGUMENT, BAD_BOUNDS, OPTIMAL

SERVO = Path(__file__).resolve().parents[1] / "data" / "constraints" / "servo_terminal.yaml"
SLOW = 0.3  # the velocity bound set at run time (m/s), from the config's 0.8


@pytest.fixture(scope="module")
def servo(build_root, tmp_path_factory):
    doc = yaml.safe_load(SERVO.read_text())
    doc["runtime_bounds"] = True
    path = tmp_path_factory.mktemp("servo_rb") / "servo_rb.yaml"
    path.write_text(yaml.safe_dump(doc))
    return Built(path, "double", build_root)


@pytest.mark.parametrize("z_min, z_max, status", [
    ([-SLOW], [SLOW], OPTIMAL),
    ([0.2], [0.2], OPTIMAL),  # held at a value
    ([float("nan")], [SLOW], BAD_BOUNDS),
    ([-SLOW], [float("inf")], BAD_BOUNDS),  # a configured bound stays finite
    ([SLOW], [-SLOW], BAD_BOUNDS),
    (None, [SLOW], BAD_ARGUMENT),
])
def test_statuses_are_the_output_bounds_and_the_reference_agrees(servo, z_min, z_max, status):
    c, ref = servo.fresh_c(), servo.reference()
    assert c.set_signal_bounds(0, z_min, z_max) == status
    assert ref.set_signal_bounds(0, z_min, z_max) == status
    got = c.get_signal_bounds(0)[1]
    want = ([-0.8], [0.8]) if status != OPTIMAL else (z_min, z_max)  # unchanged on failure
    assert got["z_min"].tolist() == want[0] and got["z_max"].tolist() == want[1]


def test_a_bad_mode_is_a_bad_argument(servo):
    assert servo.fresh_c().set_signal_bounds(1, [-SLOW], [SLOW]) == BAD_ARGUMENT


def test_a_tightened_signal_bound_holds_and_c_and_reference_agree(servo):
    c, ref = servo.fresh_c(), servo.reference()
    k, mismatches, velocity = [0], [], []

    class Lockstep:
        def step(self, y, s, r):
            if k[0] == 5:
                assert c.set_signal_bounds(0, [-SLOW], [SLOW]) == OPTIMAL
                assert ref.set_signal_bounds(0, [-SLOW], [SLOW]) == OPTIMAL
            st_c, u_c = c.step(y, s, r)
            st_r, u_r = ref.step(y, s, r)
            if (st_c, u_c.tobytes()) != (st_r, u_r.tobytes()):
                mismatches.append(k[0])
            k[0] += 1
            return st_c, u_c

    reference = np.repeat(np.array([[0.0], [0.6]]), [5, 55], axis=0)
    log = run_closed_loop(servo.model.config, Lockstep(), reference=reference, steps=60)
    assert mismatches == [] and np.all(log.status == OPTIMAL)
    # the plant's velocity, from its position samples: within the new bound after a settle
    dt = servo.model.config.sample_time
    velocity = np.diff(log.y[:, 0]) / dt
    assert np.abs(velocity[10:]).max() <= SLOW + 1e-6
    assert np.abs(velocity).max() > 0.25  # the step presses it
