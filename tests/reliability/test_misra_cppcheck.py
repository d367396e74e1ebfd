"""Static analysis of the generated C: cppcheck with the MISRA C 2012 addon.

Every cppcheck finding on the generated C must be covered by a reasoned deviation of
rollmpc_codegen/codegen/misra_deviations.py (rule, files, kind, reason), which every
generated tree's README lists; cppcheck's own warnings
have no deviations.  A finding nobody justified fails the test, so a template change
that introduces a new kind of finding must fix it or add a deviation with its reason.
The deviations are listed in docs/reliability.md.

The default suite checks the paper's controller with N = 8 (the same templates, small
data: cppcheck needs about a minute for the N = 100 data tables); the long run checks
the committed generated/uav_roll_f32 and generated/uav_roll and a single-mode random
controller.  (0 compiler warnings with -Werror on gcc, clang and arm-none-eabi-gcc in
both precisions: tests/codegen/test_compile_flags.py.)
"""
from __future__ import annotations

import re

import pytest

from conftest import ROOT, require_tool, short_uav_config
from rollmpc_codegen.pipeline import generate
from rollmpc_codegen.codegen.misra_deviations import DEVIATIONS
from rollmpc_codegen.verify.misra import by_rule, run_cppcheck, unjustified
from rollmpc_codegen.verify.random_configs import random_config

DOC = ROOT / "docs" / "reliability.md"
HINT = "apt-get install -y --no-install-recommends cppcheck"


def _check(src, prefix="rollmpc"):
    cppcheck = require_tool("cppcheck", HINT)
    findings = run_cppcheck(src, cppcheck)
    bad = unjustified(findings, prefix)
    assert bad == [], "\n".join(f"{f.file}:{f.line}: {f.rule} {f.message}" for f in bad[:20])
    return findings


@pytest.mark.parametrize("precision", ["float", pytest.param("double", marks=pytest.mark.slow)])
def test_misra_findings_are_all_justified(tmp_path, precision):
    src = tmp_path / "src"
    generate(short_uav_config(tmp_path, 8), src, precision)
    findings = _check(src)
    assert findings and all(f.misra for f in findings)  # the addon really ran
    assert len(by_rule(findings)) >= 5


@pytest.mark.slow
@pytest.mark.parametrize("tree", ["uav_roll_f32", "uav_roll"])
def test_misra_on_the_committed_trees(tree):
    _check(ROOT / "generated" / tree)


@pytest.mark.slow
def test_misra_on_a_single_mode_controller(tmp_path):
    config = tmp_path / "c.yaml"
    config.write_text(random_config(11, prefix="solo", n_max=12).yaml())
    src = tmp_path / "src"
    generate(config, src, "float")
    _check(src, "solo")


@pytest.mark.slow
def test_misra_on_rate_rows(tmp_path):
    """The Δu-row code of the solver (has_rate_rows; absent from the UAV build above)."""
    src = tmp_path / "src"
    generate(ROOT / "examples" / "thermal_zones_rate.yaml", src, "float")
    _check(src, "zrate")


def test_deviations_are_complete_and_documented():
    assert len(DEVIATIONS) >= 10
    doc = DOC.read_text()
    readme = (ROOT / "generated" / "uav_roll" / "rollmpc_README.md").read_text()
    for d in DEVIATIONS:
        assert f"| {d.rule} | `{d.files}` | {d.kind} |" in readme, d  # shipped with the C
        assert re.fullmatch(r"\d+\.\d+", d.rule), d
        assert d.kind in ("advisory", "required", "false-positive"), d
        assert len(d.reason) > 40, d
        assert re.search(rf"\b{re.escape(d.rule)}\b", doc), f"rule {d.rule} missing in {DOC.name}"


@pytest.mark.slow
@pytest.mark.parametrize("method", ["hildreth", "hildreth_plus", "hildreth_plus_prime"])
@pytest.mark.parametrize("polish,polish_first", [(True, True), (True, False), (False, False)])
@pytest.mark.parametrize("precision", ["double", "float"])
def test_every_solver_variant_compiles_warning_free(tmp_path, build_root, method, polish,
                                                    polish_first, precision):
    """Every accepted combination of solver switches builds with the strict flags (-Werror)."""
    from conftest import Built

    cfg = short_uav_config(tmp_path, 8, method=method, polish=polish, polish_first=polish_first)
    built = Built(cfg, precision, build_root)  # raises BuildError on any warning
    st, u = built.c.step([0.0], [0.0], [10.0] * 8)
    assert st in (0, 1, 2) and abs(u[0]) <= 15.0
