"""A generated tree stands alone: its README says what each file is, the API, the
statuses, the build flags and the MISRA deviations, all from their declarations, and no
generated file points to the generator's sources or docs, which the firmware engineer
does not have."""
from __future__ import annotations

import re

import pytest

from conftest import ROOT
from rollmpc_codegen.codegen.build_flags import REFUSED_FLAGS
from rollmpc_codegen.codegen.misra_deviations import DEVIATIONS
from rollmpc_codegen.codegen.output import MANIFEST
from rollmpc_codegen.info_struct import context_info_fields
from rollmpc_codegen.status import context_statuses

# (committed tree, prefix, runtime_bounds, soft rows)
TREES = [("uav_roll", "rollmpc", False, False), ("chain_runtime_bounds", "chain_rb", True, False),
         ("fw_lateral_f32", "fwlat", False, True)]
OUTSIDE = re.compile(r"\b(docs/|shared/|rollmpc_codegen|tests/|firmware_stub/|\w+\.py\b)")


@pytest.mark.parametrize("tree,prefix,runtime_bounds,soft", TREES)
def test_readme_lists_the_files_api_statuses_flags_and_deviations(tree, prefix,
                                                                  runtime_bounds, soft):
    src = ROOT / "generated" / tree
    readme = (src / f"{prefix}_README.md").read_text()
    listed = re.findall(r"^\| `([^`]+)` \| ", readme.split("## Files")[1].split("##")[0], re.M)
    assert sorted(listed) == sorted(p.name for p in src.iterdir())  # every file, no other
    manifest = (src / MANIFEST).read_text().splitlines()
    assert f"{prefix}_README.md" in manifest  # replaced like the others on regeneration
    for s in context_statuses(prefix, runtime_bounds):
        assert f"| {s['code']} | `{prefix.upper()}_{s['name']}` | {s['message']} |" in readme
    for f in context_info_fields(prefix, soft):
        assert f"| `{f['name']}` | `{f['ctype']}` |" in readme
    assert (f"`{prefix}_set_bounds(" in readme) == runtime_bounds
    for f in REFUSED_FLAGS:
        assert f"| `{f.flag}` | `{f.macro}` | {f.why} |" in readme
    for d in DEVIATIONS:
        assert f"| {d.rule} | `{d.files}` | {d.kind} |" in readme
    assert "-ffp-contract=off" in readme


@pytest.mark.parametrize("tree,prefix,runtime_bounds,soft", TREES)
def test_no_generated_file_points_outside_the_tree(tree, prefix, runtime_bounds, soft):
    src = ROOT / "generated" / tree
    for path in src.iterdir():
        if path.suffix in (".c", ".h", ".md"):
            found = OUTSIDE.findall(path.read_text())
            assert found == [], (path.name, sorted(set(found)))
