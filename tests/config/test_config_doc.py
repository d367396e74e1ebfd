"""docs/config.md is generated from the schema (rollmpc_codegen/config/keys.py and
schema.py) and cannot drift: the committed file is a fresh rendering, every key the
reader accepts has its row, and the defaults it shows are the schema's values."""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from rollmpc_codegen.config import doc, keys, schema

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = ROOT / "docs" / "config.md"


def rows(text: str) -> dict[str, tuple[str, str]]:
    """key path -> (default, meaning) of every table row."""
    found = re.findall(r"^\| `([^`]+)` \| (.*?) \| (.*) \|$", text, re.M)
    return {path: (default, meaning) for path, default, meaning in found}


def test_committed_reference_is_a_fresh_rendering():
    assert REFERENCE.read_text() == doc.render(), (
        "docs/config.md is stale: run `make docs` (python -m rollmpc_codegen.config.doc "
        "> docs/config.md) and commit it")


def test_every_key_the_reader_accepts_has_a_row():
    documented = rows(doc.render())
    accepted = {
        "": schema.TOP_KEYS, "modes[]": schema.MODE_KEYS, "modes[].plant": schema.PLANT_KEYS,
        "modes[].plant.transfer_function": schema.TRANSFER_FUNCTION_KEYS,
        "modes[].plant.state_space": schema.STATE_SPACE_KEYS,
        "modes[].weights": schema.WEIGHT_KEYS, "modes[].bounds": schema.BOUND_KEYS,
        "modes[].bounds.soft": schema.SOFT_KEYS,
        "modes[].bounds.soft.<side>": schema.PENALTY_KEYS,
        "modes[].constraints": schema.CONSTRAINT_KEYS,
        "modes[].constraints.signals.<name>": schema.SIGNAL_KEYS,
        "modes[].constraints.mixed.<name>": schema.MIXED_KEYS,
        "modes[].constraints.terminal": schema.TERMINAL_KEYS,
        "modes[].observer": schema.OBSERVER_KEYS, "scheduler": schema.SCHEDULER_KEYS,
        "scheduler.bands[]": schema.BAND_KEYS, "solver": schema.SOLVER_KEYS,
        "simulation": schema.SIMULATION_KEYS, "simulation.reference": schema.REFERENCE_KEYS,
        "units": schema.UNITS_KEYS, "target": schema.TARGET_KEYS,
        "aircraft": schema.AIRCRAFT_KEYS}
    expected = {f"{path}.{name}" if path else name
                for path, names in accepted.items() for name in names}
    assert set(documented) == expected
    assert all(meaning.strip() for _, meaning in documented.values())


def test_defaults_are_read_from_the_schema(monkeypatch):
    """A default changed in schema.py (or a dataclass field) changes the reference."""
    monkeypatch.setattr(schema, "DEFAULT_EPSILON", 0.75)
    solver = dataclasses.make_dataclass(
        "SolverConfig", [(f.name, f.type, dataclasses.field(default=f.default))
                         for f in dataclasses.fields(schema.SolverConfig)
                         if f.name != "omega"] + [("omega", float, 1.5)])
    monkeypatch.setitem(doc.FIELD_DEFAULTS, "solver", solver)
    with pytest.raises(ValueError, match="solver keys"):  # omega moved to the end
        doc.render()
    monkeypatch.setitem(doc.FIELD_DEFAULTS, "solver", schema.SolverConfig)
    documented = rows(doc.render())
    assert documented["scheduler.epsilon"][0] == "`0.75`"
    assert documented["solver.omega"][0] == "`1.2`"
    assert documented["solver.feasibility_tol"][0] == "`1e-9` double, `0.0001` float"
    assert documented["target.cpu_mhz"][0] == f"`{schema.DEFAULT_CPU_MHZ:g}`"


def test_a_none_default_needs_its_text(monkeypatch):
    """feasibility_tol's field default is None (the precision decides): keys.py must say so."""
    solver = keys.section("solver")
    silent = dataclasses.replace(solver, keys=tuple(
        keys.Key(k.name, None, k.meaning) if k.name == "feasibility_tol" else k
        for k in solver.keys))
    monkeypatch.setattr(doc, "SECTIONS", tuple(silent if s is solver else s
                                               for s in keys.SECTIONS))
    with pytest.raises(ValueError, match="solver.feasibility_tol: keys.py must give"):
        doc.render()
