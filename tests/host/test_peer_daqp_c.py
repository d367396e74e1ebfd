"""DAQP's own C built on the host (``rollmpc bench``'s daqp_c rows): it solves the QPs the
Python daqp solves, to rounding, each new peer starts from a fresh workspace, and its two
timers nest (the update and solve inside the whole sample)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import UAV

CHAIN = Path(__file__).resolve().parents[2] / "examples" / "chain_of_masses.yaml"


@pytest.fixture(scope="module")
def sources():
    pytest.importorskip("daqp", reason="pip install 'rollmpc-codegen[peers]'")
    from rollmpc_codegen.host.daqp_harness import (DaqpSourceUnavailable, daqp_sources,
                                                   daqp_version)

    try:  # cached outside build_root: downloaded once per machine, not per session
        return daqp_sources(daqp_version())
    except DaqpSourceUnavailable as exc:
        pytest.skip(f"DAQP's sdist is not available (needs pip and network to PyPI once): "
                    f"{exc}")


@pytest.mark.parametrize("config, samples", [pytest.param(CHAIN, 120, marks=pytest.mark.slow),
                                             pytest.param(UAV, 120, marks=pytest.mark.slow)])
def test_daqp_c_matches_python_daqp(sources, build_root, config, samples):
    from rollmpc_codegen.host.bench_record import record_qp_sequence
    from rollmpc_codegen.host.build import build_host_controller
    from rollmpc_codegen.host.peer_daqp_c import DaqpCPeer
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.qp.peers import DaqpPeer

    model, ctx = load_model(config, "double")
    seq = record_qp_sequence(model, build_host_controller(ctx, build_root), samples)
    python = DaqpPeer([mm.qp for mm in model.modes])
    step, solve = DaqpCPeer(model, "step", build_root), DaqpCPeer(model, "solve", build_root)
    plans, constrained = [], 0
    for i in range(len(seq.mode)):
        mode, x, r = int(seq.mode[i]), seq.x[i], seq.r[i]
        ref, a, b = python.solve(mode, x, r), step.solve(mode, x, r), solve.solve(mode, x, r)
        assert a.status == b.status == ref.status == "optimal"
        scale = max(1.0, float(np.abs(ref.U).max()))
        assert np.abs(a.U - ref.U).max() <= 1e-9 * scale, i
        assert np.array_equal(a.U, b.U)  # the same C, the same warm start
        assert a.solver_s > 0 and b.solver_s > 0
        constrained += a.iterations > 0
        plans.append(a.U)
    assert constrained > 0  # the sequence reaches the bounds, so the warm start matters
    again = DaqpCPeer(model, "step", build_root)  # a fresh workspace: the same plans
    for i, U in enumerate(plans):
        assert np.array_equal(again.solve(int(seq.mode[i]), seq.x[i], seq.r[i]).U, U), i


def test_bench_prints_the_daqp_c_rows(sources, build_root, capsys):
    from rollmpc_codegen.cli.main import main

    assert main(["bench", str(CHAIN), "--variants", "default,daqp_c,daqp_c_solve",
                 "--steps", "60", "--quiet", "--build-dir", str(build_root)]) == 0
    out = capsys.readouterr().out
    rows = {line.split("|")[1].strip(): line for line in out.splitlines()
            if line.startswith("| DAQP C")}
    assert set(rows) == {"DAQP C (sample: data + update + solve)",
                         "DAQP C (update + solve only)"}
    for line in rows.values():
        assert "C (same clock as solve_ticks)" in line and "| 28 / 28 |" in line


def test_daqp_is_built_with_its_own_optimisation_flags(sources):
    """HOST_FLAGS are those of DAQP's own Python build (its sdist's setup.py), without its
    in-solve clock: a DAQP release that changes them fails here."""
    import re
    import tarfile

    from rollmpc_codegen.host.daqp_harness import daqp_version
    from rollmpc_codegen.host.peer_daqp_c import HOST_FLAGS

    top = f"daqp-{daqp_version()}"
    with tarfile.open(sources.parents[1] / f"{top}.tar.gz") as tar:
        setup = tar.extractfile(f"{top}/setup.py").read().decode()
    theirs = re.findall(r'"(-[^"]+)"', re.search(r"extra_compile_args=\[([^\]]*)\]", setup)[1])
    assert sorted(f for f in theirs if f != "-DPROFILING") == sorted(
        f for f in HOST_FLAGS if f != "-fPIC")


def test_a_missing_sdist_is_one_line_naming_the_download(tmp_path, capsys, monkeypatch):
    """Without network the daqp_c rows stop the bench with one line that says where DAQP's
    C comes from and why it is missing (exit 1), not a traceback."""
    pytest.importorskip("daqp", reason="pip install 'rollmpc-codegen[peers]'")
    import subprocess

    from rollmpc_codegen.cli.main import main
    from rollmpc_codegen.host import daqp_harness, peer_daqp_c

    run = subprocess.run

    def no_network(cmd, **kwargs):  # pip fails as offline; the compilers still run
        if "pip" not in cmd:
            return run(cmd, **kwargs)
        return subprocess.CompletedProcess(cmd, 1, "", "ERROR: Could not find a version "
                                           "that satisfies the requirement daqp")

    real = daqp_harness.daqp_sources
    monkeypatch.setattr(subprocess, "run", no_network)
    monkeypatch.setattr(peer_daqp_c, "daqp_sources",
                        lambda version, cache_dir=None: real(version, tmp_path / "sdist"))
    monkeypatch.delenv("ROLLMPC_DEBUG", raising=False)
    code = main(["bench", str(CHAIN), "--variants", "default,daqp_c", "--steps", "40",
                 "--quiet"])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1, err
    assert "DAQP's C comes from its sdist" in err and "Could not find a version" in err
