"""Numbers at the edge of double give our message, not a library's: one line naming the
key, exit 2, no warning, nothing written.

The audit's findings: a numerator of 1e-308 printed scipy's BadCoefficients warning first;
a sample time of 1e-320 ended in an OverflowError (exit 1); a sample time of 1e-9, or a
numerator too small for the rank test, was reported as a pole that cancels a zero G(s)
does not have; y_min = -1e308 leaked numpy's overflow warning and left the default
innovation limit infinite, the clip silently off.
"""
from __future__ import annotations

import warnings

import pytest

from conftest import ROOT, UAV, edited_config
from rollmpc_codegen.cli.main import main

DRIVES = ROOT / "examples" / "three_drives.yaml"  # mode 'fine': 3/((0.05 s + 1) s)


def _set(path: list, value):
    def edit(data):
        node = data
        for step in path[:-1]:
            node = node[step]
        node[path[-1]] = value
    return edit


FINE_NUM = ["modes", 0, "plant", "transfer_function", "num"]
CASES = {
    "num_1e-308": (UAV, FINE_NUM, [1e-308], "modes[0].plant.transfer_function.num"),
    "drives_num_1e-308": (DRIVES, FINE_NUM, [1e-308], "modes[0].plant.transfer_function.num"),
    "sample_time_1e-320": (DRIVES, ["sample_time"], 1e-320, "sample_time"),
    "sample_time_1e-9": (DRIVES, ["sample_time"], 1e-9, "sample_time"),
    "uav_sample_time_1e-9": (UAV, ["sample_time"], 1e-9, "sample_time"),
    "drives_num_1e-13": (DRIVES, FINE_NUM, [1e-13], "modes[0].plant.transfer_function"),
    "y_min_-1e308": (UAV, ["modes", 0, "bounds", "y_min"], -1e308,
                     "modes[0].observer.innovation_limit"),
}


def _generate(tmp_path, capsys, base, path, value):
    config = edited_config(tmp_path, base, "edge", _set(path, value))
    out = tmp_path / "out"
    capsys.readouterr()
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        rc = main(["generate", str(config), "-o", str(out)])
    return rc, capsys.readouterr().err.splitlines(), [str(w.message) for w in seen], out


@pytest.mark.parametrize("case", sorted(CASES))
def test_edge_number_gives_one_line_naming_the_key(tmp_path, capsys, monkeypatch, case):
    monkeypatch.delenv("ROLLMPC_DEBUG", raising=False)
    base, path, value, key = CASES[case]
    rc, err, warned, out = _generate(tmp_path, capsys, base, path, value)
    assert (rc, warned) == (2, []), (rc, err, warned)
    assert len(err) == 1 and err[0].startswith(f"rollmpc: error: {key}: "), err
    assert "cancels" not in err[0], err  # no such zero: G(s) has none at that pole
    assert not out.exists()


def test_a_real_cancellation_is_still_named(tmp_path, capsys):
    """num = 3 s on top of the integrator: the pole s = 0 does cancel a zero."""
    rc, err, warned, _ = _generate(tmp_path, capsys, DRIVES, FINE_NUM, [3.0, 0.0])
    assert (rc, warned) == (2, [])
    assert err[0].startswith("rollmpc: error: modes[0].plant: ") and \
        "cancels a zero of G(s) at s = 0" in err[0], err
