"""Which mirror functions of the solver's partials a closed loop runs.

Each test under tests/solver/ named for a partial (test_seeds.py for seeds.c.j2 ...) runs
a small design whose closed loop takes that partial's code, the host C and the NumPy
reference in lockstep: every status, command byte, sweep and work unit equal. The counts
of the reference's calls show the partial's functions ran, so a design that no longer
reaches them fails instead of passing untested. Each design runs once a session
(conftest.partial_run).
"""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import yaml


def _uav20(tmp_path: Path, **solver) -> Path:
    from conftest import short_uav_config

    return short_uav_config(tmp_path, 20, name="uav20", **solver)


def _sweeps_only(tmp_path: Path) -> Path:
    """The sweeps alone (no polish), with a cap they reach, on a -20 deg step at sample 30."""
    path = _uav20(tmp_path, polish=False, max_iterations=150)
    data = yaml.safe_load(path.read_text())
    data["simulation"]["reference"] = {"levels": [0, -20], "segment": 0.3}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _soft_roll(tmp_path: Path) -> Path:
    from conftest import ROLL45, ROLL45_SOFT

    data = json.loads(json.dumps(ROLL45))
    data["horizon"] = 20
    data["modes"][0]["bounds"]["soft"] = ROLL45_SOFT
    path = tmp_path / "roll45_soft.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _zones_rate(tmp_path: Path) -> Path:
    from conftest import ROOT

    return ROOT / "examples" / "thermal_zones_rate.yaml"


# name -> (config writer, closed-loop samples): each a few seconds
DESIGNS = {
    "sweeps_only": (_sweeps_only, 60),
    # the default solver on the UAV with a budget that binds (80 TIME_LIMIT samples)
    "uav20_budget": (lambda tmp: _uav20(tmp, work_budget=3000), 1500),
    # its soft rows switch state; 45 deg is passed near sample 600
    "soft_roll": (_soft_roll, 900),
    # Δu rows: dependent working sets, the dual factor and the dual active set
    "zones_rate": (_zones_rate, 400),
}


def counted_lockstep(built, steps: int):
    """(mismatches, statuses, calls by function name) of a lockstep closed loop of
    ``built``, the reference's solver functions counted."""
    from conftest import lockstep_closed_loop
    from rollmpc_codegen.reference.solver import SolverRef

    ref, calls = built.reference(), Counter()
    names = [n for n in dir(SolverRef) if not n.startswith("__")
             and callable(getattr(SolverRef, n))
             and getattr(getattr(SolverRef, n), "__module__", "").startswith(
                 "rollmpc_codegen.reference")]
    for solver in ref.solvers:
        for name in names:
            def counted(*args, _fn=getattr(solver, name), _name=name, **kwargs):
                calls[_name] += 1
                return _fn(*args, **kwargs)
            setattr(solver, name, counted)
    bad, seen = lockstep_closed_loop(built, steps, ref)
    return bad, Counter(status for status, _ in seen), calls


def unreached(calls: Counter, names: str) -> list[str]:
    """The functions of ``names`` (space-separated) that never ran."""
    return [n for n in names.split() if calls[n] == 0]
