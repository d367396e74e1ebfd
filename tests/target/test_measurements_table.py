"""docs/measurements.md is the rendering of docs/measurements.json (`make measurements`
measures the rows, rollmpc_codegen/verify/measurements_table.py renders them): the two
cannot disagree, and every row names the command and the commit that measured it."""
from __future__ import annotations

import json
import re
from pathlib import Path

from rollmpc_codegen.verify.measurements import examples
from rollmpc_codegen.verify.measurements_table import render

ROOT = Path(__file__).resolve().parents[2]
STORE = ROOT / "docs" / "measurements.json"


def test_committed_table_is_the_rendering_of_its_rows():
    assert (ROOT / "docs" / "measurements.md").read_text() == render(json.loads(
        STORE.read_text())), ("docs/measurements.md differs from docs/measurements.json: "
                              "run `python -m rollmpc_codegen.verify.measurements --render`")


def test_every_example_has_its_rows_with_command_and_commit():
    doc = json.loads(STORE.read_text())
    assert sorted(doc["examples"]) == examples()
    text = render(doc)
    for name in examples():
        rows = [line for line in text.splitlines() if line.startswith(f"| {name} |")]
        assert len(rows) == len(doc["examples"][name]) >= 3, name
        for line in rows:
            assert re.search(r"\| `[0-9a-f]{7,}(\+dirty)?` \| `rollmpc [a-z]+ ", line), line
            assert f"examples/{name}.yaml" in line
