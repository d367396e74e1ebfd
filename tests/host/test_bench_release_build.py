"""`rollmpc bench` times the generated C as a release build (host/bench.py's BENCH_OPT), as
DAQP's C is timed with its own -O3. EXACT_MATH holds the sums to the reference's rounding
at any optimisation level, so the timed build replays the tests' -O2 build bit for bit:
the timing changes, not one command."""
from __future__ import annotations

import numpy as np

from conftest import ROOT, Built
from rollmpc_codegen.codegen.render import render_sources
from rollmpc_codegen.host.bench import BENCH_OPT
from rollmpc_codegen.host.bench_record import record_qp_sequence, select_qps
from rollmpc_codegen.host.bench_replay import replay_c
from rollmpc_codegen.host.build import HostController, compile_shared


def test_the_timed_build_replays_the_tested_build_bit_for_bit(build_root, tmp_path):
    built = Built(ROOT / "examples" / "thermal_zones_rate.yaml", "double", build_root)
    src = tmp_path / "src"
    src.mkdir()
    for name, text in render_sources(built.ctx).items():
        (src / name).write_text(text)
    libs = [compile_shared(built.ctx, src, build_root, opt=opt) for opt in ("-O2", BENCH_OPT)]
    # other machine code, or the replay below would compare a build with itself
    assert libs[0].read_bytes() != libs[1].read_bytes()
    tested, timed = (HostController.load(built.ctx, lib) for lib in libs)
    seq = record_qp_sequence(built.model, tested, 400, None)
    idx = select_qps(seq, True, None)
    a, b = replay_c(tested, built.model, seq, idx), replay_c(timed, built.model, seq, idx)
    assert a.status == b.status and a.status.count("optimal") == idx.size
    assert a.u0.tobytes() == b.u0.tobytes()
    assert np.array_equal(a.iterations, b.iterations)
