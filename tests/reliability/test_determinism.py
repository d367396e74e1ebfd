"""Determinism: of the generated files, and of the C's outputs run to run and build to build.

* Regeneration is byte-identical, also across interpreter processes with different hash
  seeds (no set/dict-order or id() leaks into the output), for the paper's config and a
  random one.  (tests/codegen/test_generated_snapshot.py compares against the committed tree.)
* The same inputs give the same outputs and iteration counts on every run: the whole
  6000-step scenario twice on fresh instances, and on libraries built with other
  optimisation levels and with clang (-ffp-contract=off makes every operation round the
  same way), all bit for bit.
"""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, UAV, require_tool, short_uav_config
from rollmpc_codegen.host.build import build_host_controller
from rollmpc_codegen.pipeline import generate, load_model
from rollmpc_codegen.verify.random_configs import random_config
from rollmpc_codegen.sim.simulate import run_closed_loop


def _files(d):
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


def _generate_in_subprocess(config, out, precision, hash_seed: str) -> None:
    env = dict(os.environ, PYTHONHASHSEED=hash_seed)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-m", "rollmpc_codegen.cli.main", "generate", str(config),
                           "--precision", precision, "-o", str(out)],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("which,precision", [
    ("uav", "double"), pytest.param("random", "float", marks=pytest.mark.slow)])
def test_regeneration_is_byte_identical_across_processes(tmp_path, which, precision):
    if which == "uav":
        config = UAV
    else:
        config = tmp_path / "random.yaml"
        config.write_text(random_config(7, prefix="det", kind="twin_outputs", n_max=30).yaml())
    generate(config, tmp_path / "a", precision)
    _generate_in_subprocess(config, tmp_path / "b", precision, "12345")
    a, b = _files(tmp_path / "a"), _files(tmp_path / "b")
    assert sorted(a) == sorted(b) and len(a) >= 8
    assert [n for n in a if a[n] != b[n]] == []


class Recorder:
    """A controller wrapper that records every output and diagnostic."""

    def __init__(self, c):
        self.c = c
        self.rows = []

    def step(self, y, s, r):
        st, u = self.c.step(y, s, r)
        i = self.c.info()
        self.rows.append((st, u.tobytes(), i["iterations"], i["polish_iterations"],
                          i["active"], i["mode"]))
        return st, u


def _scenario(model, c) -> list:
    rec = Recorder(c)
    run_closed_loop(model.config, rec)
    return rec.rows


@pytest.fixture(scope="module")
def short_uav(tmp_path_factory, build_root):
    cfg = short_uav_config(tmp_path_factory.mktemp("det"), 30)
    model, ctx = load_model(cfg, "double")
    return model, ctx, _scenario(model, build_host_controller(ctx, build_root))


def test_same_inputs_same_outputs_on_every_run(uav):
    first = _scenario(uav.model, uav.fresh_c())
    second = _scenario(uav.model, uav.fresh_c())
    assert len(first) == 6000
    assert first == second
    assert len({row[5] for row in first}) == 2  # both modes ran
    assert sum(row[0] != 0 for row in first) == 0


@pytest.mark.parametrize("compiler,opt", [("gcc", "-O0"), ("gcc", "-Os"), ("clang", "-O2"),
                                          pytest.param("gcc", "-O3", marks=pytest.mark.slow),
                                          pytest.param("clang", "-Os", marks=pytest.mark.slow)])
def test_same_outputs_across_builds(short_uav, build_root, compiler, opt):
    model, ctx, reference_run = short_uav
    if compiler != "gcc":
        compiler = require_tool(compiler, "apt-get install -y --no-install-recommends clang")
    c = build_host_controller(ctx, build_root, compiler=compiler, opt=opt)
    run = _scenario(model, c)
    diff = [k for k, (a, b) in enumerate(zip(run, reference_run)) if a != b]
    assert len(run) == 6000 and diff == [], f"first difference at step {diff[:1]}"
    assert np.any([row[2] + row[3] > 0 for row in run])  # the solver really worked
