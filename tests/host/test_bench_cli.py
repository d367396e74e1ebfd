"""`rollmpc bench` contract: the markdown table with every row, the JSON schema,
the plot, one-line errors.  Shortened with --steps/--max-qps/--variants; no timings are
asserted, only that they are there and positive.
"""
from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from conftest import UAV, cli, edit_bounds, edited_config
from rollmpc_codegen.cli.bench import parse_variants
from rollmpc_codegen.host.bench_record import QpSequence, select_qps
from rollmpc_codegen.cli.main import main

VARIANTS = ["default", "hildreth_plus_prime", "daqp", "osqp"]
MAX_QPS = 40  # two blocks of 20: samples 33-52 and 1181-1200
ROW_KEYS = {"solver", "avg_s", "max_s", "max_lt_ts", "avg_abs_err", "max_abs_err", "median_s",
            "call_avg_s", "call_max_s", "optimal", "not_optimal", "status_counts",
            "median_s_by_mode", "timer", "key", "qps"}


@pytest.fixture(scope="module")
def bench_run(tmp_path_factory):
    for module in ("quadprog", "daqp", "osqp"):
        pytest.importorskip(module, reason="install with: pip install 'rollmpc-codegen[peers]'")
    pytest.importorskip("matplotlib", reason="install with: pip install 'rollmpc-codegen[plot]'")
    out = tmp_path_factory.mktemp("bench")
    paths = {"json": out / "bench.json", "png": out / "times.png"}
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        rc = main(["bench", str(UAV), "--steps", "1200", "--max-qps", str(MAX_QPS),
                   "--variants", ",".join(VARIANTS), "--repeat", "2",
                   "--json", str(paths["json"]),
                   "--plot", str(paths["png"])])
    return rc, stdout.getvalue(), stderr.getvalue(), paths


def test_table_has_every_requested_row(bench_run):
    rc, out, err, _ = bench_run
    assert rc == 0, err
    table = [line for line in out.splitlines() if line.startswith("|")]
    assert table[0].startswith("| solver | timer | avg [s] |")
    body = table[2:]
    # the selected rows plus quadprog, the reference, which always runs
    assert len(body) == len(VARIANTS) + 1
    firsts = [line.split("|")[1].strip() for line in body]
    assert any(f.startswith("default: hildreth_plus_prime") for f in firsts)
    assert "Hildreth+' W [C]" in firsts and "quadprog" in firsts
    assert "DAQP (Model, warm)" in firsts and "OSQP (default)" in firsts
    assert "Polishing not needed" not in out  # OSQP's C chatter is silenced
    assert "reduced set" in out
    assert "bench daqp (2/2) [####################] 100.0%" in err  # progress on stderr


def test_json_schema(bench_run):
    _, _, _, paths = bench_run
    data = json.loads(paths["json"].read_text())
    assert {"cpu", "cores", "python", "numpy", "daqp", "osqp", "quadprog"} <= set(data["machine"])
    assert data["qps"] == MAX_QPS and data["sampled"] is True
    assert data["skipped_transient_samples"] == 32
    assert data["repeat"] == 2 and data["timing"].startswith("per-QP minimum over 2")
    assert sum(data["qps_by_mode"].values()) == MAX_QPS
    rows = {r["key"]: r for r in data["rows"]}
    assert set(rows) == {*VARIANTS, "quadprog"}
    for r in rows.values():
        assert ROW_KEYS <= set(r), r["key"]
        assert isinstance(r["max_lt_ts"], bool)
        assert 0 < r["avg_s"] <= r["max_s"] and r["call_max_s"] > 0
        assert r["optimal"] + r["not_optimal"] == MAX_QPS == r["qps"]
    assert rows["quadprog"]["max_abs_err"] == 0.0
    # the generated default solver and DAQP agree with quadprog on every sampled QP
    assert rows["default"]["optimal"] == MAX_QPS
    assert rows["default"]["max_abs_err"] < 1e-6
    assert rows["daqp"]["max_abs_err"] < 1e-6
    assert data["replay_max_abs_diff_vs_closed_loop"] < 1e-9
    assert set(data["reduced_set_check"]) >= {"sigma", "constrained_qps", "violating_qps"}


def test_infeasible_qps_do_not_stop_the_bench(tmp_path):
    """A roll floor of 5 deg that the aircraft at rest cannot meet: every QP of the start is
    infeasible. The reduced-set check used to stop the whole bench on quadprog's ValueError
    (found on quad_attitude's scenario, whose TIME_LIMIT commands then left the tilt
    bound); it now counts them apart."""
    pytest.importorskip("quadprog", reason="install with: pip install 'rollmpc-codegen[peers]'")
    out = tmp_path / "q.json"
    floor = edited_config(tmp_path, UAV, "uav_floor", edit_bounds(y_min=5))
    code, text, err = cli(["bench", str(floor), "--variants", "default", "--repeat", "1",
                           "--quiet", "--json", str(out), "--steps", "60",
                           "--include-transient"])
    assert code == 0, err
    rs = json.loads(out.read_text())["reduced_set_check"]
    assert rs["infeasible_qps"] > 0
    assert f"{rs['infeasible_qps']} infeasible QPs left out" in text


def test_plot_is_a_png(bench_run):
    _, _, _, paths = bench_run
    assert paths["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("extra, word", [
    (["--variants", "hildreth,cplex"], "--variants"),
    (["--max-qps", "0"], "--max-qps"),
    (["--steps", "10"], "--steps"),  # nothing left after the 32 transient samples
    (["--max-qps", "x"], "--max-qps"),
    (["--repeat", "0"], "--repeat"),
])
def test_bad_arguments_one_line_exit_2(extra, word, capsys, monkeypatch, tmp_path):
    monkeypatch.delenv("ROLLMPC_DEBUG", raising=False)
    try:
        rc = main(["bench", str(UAV), "--quiet", "--build-dir", str(tmp_path), *extra])
    except SystemExit as exc:
        rc = exc.code
    out, err = capsys.readouterr()
    assert rc == 2
    assert err.count("\n") == 1 and err.startswith("rollmpc: error: ") and word in err, err


def test_variant_parsing_keeps_order_and_the_reference():
    assert parse_variants("daqp,default") == ["default", "quadprog", "daqp"]
    assert parse_variants("daqp_c_solve,daqp_c,default") == ["default", "quadprog", "daqp_c",
                                                             "daqp_c_solve"]
    assert len(parse_variants(None)) == 10


@pytest.mark.parametrize("extra, rows", [
    ([], ["default", "quadprog", "daqp", "osqp"]),  # ours and the peers: fast
    (["--paper"], ["hildreth", "hildreth_plus", "hildreth_plus_prime", "default",
                   "quadprog", "daqp", "osqp"]),
    (["--paper", "--variants", "daqp"], ["hildreth", "hildreth_plus",
                                         "hildreth_plus_prime", "quadprog", "daqp"]),
])
def test_default_rows_and_paper_flag(extra, rows, tmp_path):
    """Without --variants the paper's slow variants stay out; --paper adds its three."""
    for module in ("quadprog", "daqp", "osqp"):
        pytest.importorskip(module, reason="install with: pip install 'rollmpc-codegen[peers]'")
    out = tmp_path / "bench.json"
    rc, stdout, err = cli(["bench", str(UAV), "--quiet", "--steps", "40", "--max-qps", "3",
                           "--json", str(out), *extra])
    assert rc == 0, err
    assert [r["key"] for r in json.loads(out.read_text())["rows"]] == rows
    assert "Hildreth (cold)" in stdout if "--paper" in extra else "Hildreth" not in stdout


def test_default_rows_leave_out_missing_peers_but_not_the_reference(monkeypatch):
    from rollmpc_codegen.host import bench

    monkeypatch.setattr(bench, "installed", lambda module: module not in ("daqp", "quadprog"))
    assert bench.default_variants() == ["default", "quadprog", "osqp"]


def test_qp_selection_skips_the_transient_and_samples_evenly():
    K = 6000
    seq = QpSequence(k=np.arange(K), mode=np.zeros(K, int), x=[None] * K,
                     r=np.zeros((K, 1)), u_applied=np.zeros((K, 1)))
    idx = select_qps(seq, include_transient=False, max_qps=None)
    assert idx[0] == 32 and idx[-1] == K - 1 and idx.size == K - 32  # samples 33..6000
    assert select_qps(seq, include_transient=True, max_qps=None).size == K
    sample = select_qps(seq, include_transient=False, max_qps=100)
    assert sample.size == 100 and sample[0] == 32 and sample[-1] == K - 1
    assert np.all(np.diff(sample) > 0)
    # five blocks of 20 consecutive samples, spread over the scenario
    assert np.count_nonzero(np.diff(sample) == 1) == 95
    assert select_qps(seq, include_transient=False, max_qps=7).tolist() == list(range(32, 39))


def test_two_sided_form_is_the_same_constraint_set():
    """DAQP/OSQP see [simple bounds on U; two-sided output rows]: same rows as L U <= b."""
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.qp.peers import TwoSidedForm, qp_vectors

    model, _ = load_model(UAV)
    rng = np.random.default_rng(3)
    for mm in model.modes:
        qp = mm.qp
        form = TwoSidedForm(qp)
        assert form.A.shape == (qp.N, qp.n)  # one two-sided row per predicted roll angle
        assert np.all(form.bound_upper >= 0) and np.all(form.bound_lower >= 0)
        for _ in range(20):
            x = rng.normal(0, 30, qp.nx)
            r = np.full(qp.N, rng.uniform(-300, 300))
            U = rng.uniform(-20, 20, qp.n) * rng.choice([1e-3, 1.0, 40.0])
            f, lower, upper = form.data(x, r)
            f_ref, b = qp_vectors(qp, x, r)
            assert np.array_equal(f, f_ref)
            z = np.concatenate((U, form.A @ U))
            two_sided = max((z - upper).max(), (lower - z).max())
            assert two_sided == pytest.approx((qp.L @ U - b).max(), rel=1e-12, abs=1e-9)
