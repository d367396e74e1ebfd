"""`rollmpc bench` times the generated C as a release build (host/bench.py, BENCH_OPT =
-O3), as DAQP's C is timed with its own -O3. EXACT_MATH holds the sums to the reference's
rounding at any optimisation level, so the timed build replays the tests' -O2 build bit
for bit: the timing changes, not one command."""
from __future__ import annotations

import numpy as np

from conftest import ROOT, Built
from rollmpc_codegen.host.bench import BENCH_OPT, machine_info
from rollmpc_codegen.host.bench_record import record_qp_sequence, select_qps
from rollmpc_codegen.host.bench_replay import replay_c
from rollmpc_codegen.host.build import build_host_controller


def test_the_timed_build_replays_the_tested_build_bit_for_bit(build_root):
    assert BENCH_OPT == "-O3" and machine_info()["c_flags"].startswith(BENCH_OPT)
    built = Built(ROOT / "examples" / "thermal_zones_rate.yaml", "double", build_root)
    tested = build_host_controller(built.ctx, build_root)  # -O2
    timed = build_host_controller(built.ctx, build_root, opt=BENCH_OPT)
    seq = record_qp_sequence(built.model, tested, 400, None)
    idx = select_qps(seq, True, None)
    a, b = replay_c(tested, built.model, seq, idx), replay_c(timed, built.model, seq, idx)
    assert a.status == b.status and a.status.count("optimal") == idx.size
    assert a.u0.tobytes() == b.u0.tobytes()
    assert np.array_equal(a.iterations, b.iterations)
