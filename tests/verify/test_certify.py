"""rollmpc certify (verify/certify.py): its sampling is reproducible from its seed, the
reference and the host C give the same certificate, a QP solved again from its kept state
spends what it spent in the loop, and the bound it states holds on 20 random flights it
was not made from. Exit codes 0 (fits) and 3 (does not), with what would fit."""
from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import UAV, edited_config
from rollmpc_codegen.verify.certify import certify

STEPS, NOISE, MISMATCH = 200, 0.05, 0.2
# the paper's plant at N = 20 with a budget its flights stop at rarely: the certificate
# (20 loops) sees no stop, 20 other flights 2 in 4,000 samples (measured)
BUDGET = 4500


def _design(tmp_path, budget=BUDGET):
    def edit(data):
        data["horizon"] = 20
        data["solver"] = {**data.get("solver", {}), "work_budget": budget}
        data["simulation"] = dict(data["simulation"], reference={"levels": [0], "segment": 1.0})
    return edited_config(tmp_path, UAV, f"uav_budget_{budget}", edit)


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    return _design(tmp_path_factory.mktemp("certify"))


def _certify(design, build_root, **options):
    kw = dict(loops=3, steps=60, seed=5, noise_std=NOISE, mismatch=MISMATCH,
              precision="float", build_dir=build_root)
    return certify(design, **{**kw, **options}).data


def test_sampling_is_reproducible_from_its_seed(design, build_root):
    first, again = _certify(design, build_root), _certify(design, build_root)
    assert first == again
    other = _certify(design, build_root, seed=6)
    assert other["worst"] != first["worst"] and other["seed"] == 6
    assert first["samples"] == 180 and first["kinds"] == ["inside", "envelope"]
    w = first["work"]
    assert 0 < w["median"] <= w["p99"] <= w["p99_9"] <= w["max"] == first["needed_max"]
    worst = first["worst"][0]
    assert worst["needed"] == w["max"] and len(worst["xhat"]) > 0  # where, and its state


def test_the_host_c_gives_the_reference_certificate(design, build_root):
    ref, host = (_certify(design, build_root, engine=e) for e in ("reference", "host"))
    for d in (ref, host):
        d.pop("engine")
        for e in d["worst"]:
            e.pop("xhat")  # the reference's state estimate; the C keeps its in the instance
    assert ref == host


def test_a_kept_state_solves_again_to_the_same_work(design):
    """The state copy the certificate solves from is the controller's: with the design's
    own budget, the QP spends what it spent in the loop, step after step."""
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.sim.simulate import run_closed_loop
    from rollmpc_codegen.verify.certify_sampling import ReferenceEngine

    model, ctx = load_model(design, "float")
    engine, budget, seen = ReferenceEngine(model, ctx), int(ctx["solver"]["work_budget"]), []

    class Check:
        def step(self, y, s, r):
            state = engine.state()
            out = engine.step(y, s, r)
            seen.append((engine.solve_from(state, y, s, r, budget), (int(out[0]),
                                                                     engine.info()["work"])))
            return out

    run_closed_loop(model.config, Check(), steps=120, reference=np.full((120, 1), 35.0))
    assert all(again == done for again, done in seen)
    assert max(w for _, (_, w) in seen) > 1000  # constrained QPs, not a quiet loop


@pytest.mark.parametrize("engine", ["host", pytest.param("reference", marks=pytest.mark.slow)])
def test_the_bound_holds_on_flights_it_was_not_made_from(design, build_root, engine):
    """20 loops certify the design (seeds 0-19); 20 other flights like them (seeds
    1000-1019) stop no more often than the certificate bounds, per sample and per loop."""
    from rollmpc_codegen.sim.flights_run import run_flights

    options = dict(steps=STEPS, noise_std=NOISE, mismatch=MISMATCH, precision="float",
                   build_dir=build_root)
    cert = certify(design, loops=20, seed=0, engine=engine, **options).data
    fresh = run_flights(design, flights=20, seed=1000, **options).summary
    stops = fresh["totals"]["status_counts"].get("time_limit", 0)
    loops_stopped = sum(f["status_counts"].get("time_limit", 0) > 0 for f in fresh["flights"])
    assert cert["time_limit"]["samples"] == 0 and cert["fits"]
    # measured: bounds 7.5e-4 per sample and 0.139 per loop; fresh 2 of 4,000, 2 of 20 loops
    assert stops / fresh["totals"]["samples"] <= cert["bounds"]["per_sample"]
    assert loops_stopped / 20 <= cert["bounds"]["per_loop"]
    assert cert["bounds"]["per_sample"] == pytest.approx(1 - 0.05 ** (1 / 4000))


def test_exit_codes_and_what_fits(tmp_path, build_root, capsys):
    from rollmpc_codegen.cli.main import main

    tight = _design(tmp_path, budget=2500)
    out = tmp_path / "cert.json"
    args = ["certify", str(tight), "--precision", "float", "--loops", "2", "--steps", "60",
            "--engine", "host", "--quiet", "--build-dir", str(build_root)]
    assert main([*args, "--json", str(out)]) == 3
    cert = json.loads(out.read_text())
    assert not cert["fits"] and cert["time_limit"]["samples"] > 0
    assert cert["needed_max"] > 2500 and "solver.work_budget >= " in cert["what_fits"]
    text = capsys.readouterr().out
    assert "verdict: DOES NOT fit: what fits:" in text and "P(TIME_LIMIT) <=" in text
    assert main(["certify", str(_design(tmp_path, budget=100000)), *args[2:]]) == 0
    assert "verdict: fits" in capsys.readouterr().out
    assert main(["certify", str(tight), "--loops", "0"]) == 2
    assert capsys.readouterr().err.startswith("rollmpc: error: --loops")


def test_generate_prints_the_certificate_line(design, tmp_path, build_root, capsys):
    from rollmpc_codegen.cli.main import main

    assert main(["generate", str(design), "-o", str(tmp_path / "out"), "--precision", "float",
                 "--no-float-check", "--certify", "--build-dir", str(build_root)]) == 0
    line = [x for x in capsys.readouterr().out.splitlines() if "work certificate" in x]
    assert len(line) == 1 and line[0].endswith(": fits")
    assert "(2,000 QPs of 20 closed loops, seed 0)" in line[0]  # 20 x the 100-sample scenario


def test_what_fits_leaves_out_the_qps_no_budget_finishes(design):
    from rollmpc_codegen.pipeline import load_config
    from rollmpc_codegen.verify.certify import _what_fits

    cfg = load_config(design)  # work_budget given: what fits names the budget itself
    text = _what_fits(cfg, 9000, BUDGET, 2)
    assert "solver.work_budget >= 9,000" in text and "horizon <= " in text
    assert text.endswith("2 stopped QPs end at max_iter even without a budget: no budget "
                         "fits them")
    assert _what_fits(cfg, 4000, BUDGET, 0).startswith("what fits: the budget, for every stop")
