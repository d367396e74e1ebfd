"""The mutation run's planted bugs (rollmpc_codegen/verify/mutants.py) still apply to this
tree: a mutant whose text has gone would silently test nothing in `make mutation`."""
from __future__ import annotations

import pytest

from conftest import ROOT
from rollmpc_codegen.verify.mutants import MUTANTS


@pytest.mark.parametrize("mutant", MUTANTS, ids=lambda m: m.name)
def test_mutant_text_occurs_once_and_changes_it(mutant):
    text = (ROOT / mutant.file).read_text()
    assert text.count(mutant.old) == 1, f"update the mutant for the current {mutant.file}"
    assert mutant.new != mutant.old
    for selection in mutant.tests:
        assert (ROOT / selection.split("::")[0]).is_file(), selection


def test_the_mutants_reach_every_stage():
    """At least sixteen planted bugs, across templates, the generator, features and
    simulation."""
    assert len(MUTANTS) >= 16
    folders = {m.file.split("/")[0] if m.file.startswith("templates") else m.file.split("/")[1]
               for m in MUTANTS}
    assert {"templates", "qp", "model", "features", "sim"} <= folders, folders
