"""Malformed YAML files, as users would write them: one line naming the key, exit 2.

tests/config/test_config_errors.py mutates the paper's config in memory (over 100 cases).  The
files in tests/data/bad_configs/ are complete hand-readable YAML files for the cases it
does not cover: NaN/Inf in every kind of number (matrix entries, transfer functions,
bounds, poles, solver settings), a numerically singular Hessian, duplicate keys (PyYAML
silently keeps the last one), and more.  Each file states what it expects on its second
line, ``# expect: <key> | <fragment>``; ``rollmpc generate`` must exit with 2, print
exactly that one line and write nothing.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from rollmpc_codegen.cli import main as cli
from test_config_errors import CASES, _assert_clean_failure, _assert_nothing_written

BAD = Path(__file__).resolve().parents[1] / "data" / "bad_configs"
FILES = sorted(BAD.glob("*.yaml"))


def _expectation(path: Path) -> tuple[str, str]:
    line = path.read_text().splitlines()[1]
    assert line.startswith("# expect: "), path.name
    key, fragment = (p.strip() for p in line[len("# expect: "):].split(" | ", 1))
    return key, fragment


@pytest.mark.filterwarnings("error::RuntimeWarning")
@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_bad_config_file_fails_cleanly(tmp_path, capsys, monkeypatch, path):
    monkeypatch.delenv("ROLLMPC_DEBUG", raising=False)
    key, fragment = _expectation(path)
    (tmp_path / "gen").mkdir()
    out = tmp_path / "gen" / "out"
    rc = cli.main(["generate", str(path), "-o", str(out)])
    captured = capsys.readouterr()
    _assert_clean_failure(rc, captured.err, key, fragment)
    assert captured.out == ""
    _assert_nothing_written(out)


def test_the_files_are_many_distinct_and_new():
    assert len(FILES) >= 30
    texts = [p.read_text().split("\n", 2)[2] for p in FILES]
    assert len(set(texts)) == len(texts)
    assert not ({p.stem for p in FILES} & {c.id for c in CASES})
