"""An interrupted regeneration leaves the old tree, the new one, or a tree that refuses to
compile with a one-line #error; never a mixed tree that builds.

The audit: rollmpc replaced the files one by one, and a kill -9 or a full disk between two
moves left 7 files of one design beside 5 of another, which compiled, linked and ran into
a stack-buffer-overflow (the horizon changed from 14 to 10).  Here every move of a
regeneration (os.replace, os.rename, the directory exchange, the staging's removal) is a
kill point: a forked child dies there with os._exit (no cleanup runs, as under kill -9),
and the tree is checked; then the same point raises ENOSPC instead.  Both writers are
covered: the exchange of a directory that holds only our files, and the file-by-file moves
into a directory with a user's file in it.  Also: stale staging directories go on the next
run, and ``-o link/sub`` through a symlinked directory is refused.
"""
from __future__ import annotations

import errno
import fcntl
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import short_uav_config
from rollmpc_codegen.cli.main import main
from rollmpc_codegen.codegen import output
from rollmpc_codegen.codegen.output import MANIFEST, STAGING_PREFIX, write_output
from rollmpc_codegen.codegen.render import render_sources
from rollmpc_codegen.pipeline import load_model

KILLED = 9
MISMATCH = "are of different generations"


@pytest.fixture(scope="module")
def trees(tmp_path_factory) -> tuple[dict, dict]:
    """Two designs of one prefix (the UAV at N = 8 and N = 6): (old files, new files)."""
    cfg = tmp_path_factory.mktemp("cfg")
    return tuple(render_sources(load_model(short_uav_config(cfg, horizon=n, name=f"n{n}"))[1])
                 for n in (8, 6))


def _patched(k: int, fail):
    """Make the k-th move (counting from 0) call ``fail`` instead, once; returns the undo."""
    count = [0]
    saved = [(os, "replace"), (os, "rename"), (output, "_exchange"), (shutil, "rmtree")]
    originals = [getattr(mod, name) for mod, name in saved]

    def point(real):
        def wrapper(*args, **kwargs):
            count[0] += 1
            if count[0] == k + 1:
                fail()
            return real(*args, **kwargs)
        return wrapper

    for (mod, name), real in zip(saved, originals):
        setattr(mod, name, point(real))

    def undo():
        for (mod, name), real in zip(saved, originals):
            setattr(mod, name, real)
    return undo


def _killed_at(k: int, files: dict, out: Path) -> int:
    """Regenerate in a child killed before its k-th move: KILLED, or 0 when it finished."""
    pid = os.fork()
    if pid == 0:  # the child: never returns into pytest
        code = 3
        try:
            _patched(k, lambda: os._exit(KILLED))
            write_output(files, out)
            code = 0
        finally:
            os._exit(code)
    return os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])


def _compile_errors(out: Path) -> list[str]:
    return [proc.stderr for c in sorted(out.glob("*.c"))
            if (proc := subprocess.run(["gcc", "-std=c99", "-fsyntax-only", f"-I{out}", str(c)],
                                       capture_output=True, text=True)).returncode != 0]


def _state(out: Path, old: dict, new: dict) -> str:
    """'old', 'new' or 'refuses' (checked: each file whole, listed, and every failing
    source stopped by the generation check); fails the test on anything else."""
    present = {n: (out / n).read_text() for n in new if (out / n).is_file()}
    if present == old:
        return "old"
    if present == new:
        return "new"
    assert set(present) == set(new), "a generated file is missing"
    assert all(text in (old[n], new[n]) for n, text in present.items()), "a file is partial"
    listed = set((out / MANIFEST).read_text().splitlines())
    assert set(present) <= listed, "a file of ours is not in the manifest"
    errors = _compile_errors(out)
    assert errors, "a mixed tree compiles"
    for err in errors:
        lines = [line for line in err.splitlines() if "error" in line]
        assert MISMATCH in lines[0] and "#error" in lines[0], err
    return "refuses"


def _leftovers(out: Path) -> list[str]:
    inside = [p.name for p in out.glob(f"{STAGING_PREFIX}*")] if out.is_dir() else []
    return inside + [p.name for p in out.parent.glob(f".{out.name}{STAGING_PREFIX}*")]


def _start(tmp_path: Path, old: dict, users_file: bool) -> Path:
    out = tmp_path / "out"
    shutil.rmtree(out, ignore_errors=True)
    write_output(old, out)
    if users_file:
        (out / "Makefile").write_text("all:\n")
    return out


@pytest.mark.parametrize("users_file", [False, True], ids=["exchange", "file_by_file"])
def test_a_kill_at_every_move_leaves_old_new_or_refusing(tmp_path, trees, users_file):
    old, new = trees
    seen = []
    for k in range(40):
        out = _start(tmp_path, old, users_file)
        code = _killed_at(k, new, out)
        assert code in (0, KILLED), code
        seen.append(_state(out, old, new))
        write_output(new, out)  # the next run: the new tree, nothing of the killed one
        assert _state(out, old, new) == "new" and _leftovers(out) == []
        assert (out / "Makefile").is_file() == users_file
        if code == 0:
            break
    assert code == 0, "more moves than kill points tried"
    if users_file:  # 2 manifest writes, 8 files, the staging's removal
        assert seen[:2] == ["old", "old"] and "refuses" in seen and seen[-1] == "new", seen
    else:  # one exchange: before it the old tree, after it the new one
        assert seen == ["old", "new", "new"], seen


@pytest.mark.parametrize("users_file", [False, True], ids=["exchange", "file_by_file"])
def test_a_full_disk_at_every_move_leaves_the_old_tree_or_the_new(tmp_path, trees, users_file):
    old, new = trees

    def full():
        raise OSError(errno.ENOSPC, "No space left on device")

    for k in range(40):
        out = _start(tmp_path, old, users_file)
        undo = _patched(k, full)
        try:
            write_output(new, out)
            finished = True
        except OSError as exc:
            assert exc.errno == errno.ENOSPC
            finished = False
        finally:
            undo()
        state = _state(out, old, new)
        assert state in ("old", "new"), (k, state)  # a failed move is undone
        assert state == "new" or not finished
        if finished:
            break
        write_output(new, out)
        assert _state(out, old, new) == "new" and _leftovers(out) == []
    assert finished


def test_a_full_disk_while_staging_leaves_the_old_tree(tmp_path, trees, monkeypatch):
    old, new = trees
    out = _start(tmp_path, old, users_file=True)
    real, calls = Path.write_text, []

    def write_text(self, *args, **kwargs):
        calls.append(self)
        if len(calls) == 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", write_text)
    with pytest.raises(OSError):
        write_output(new, out)
    monkeypatch.setattr(Path, "write_text", real)
    assert _state(out, old, new) == "old" and _leftovers(out) == []


# --------------------------------------------------------------------------- the stamps
def test_every_file_of_another_generation_refuses_to_compile(tmp_path, trees):
    old, new = trees
    assert _compile_errors(_start(tmp_path, old, False)) == []
    for name in (n for n in old if n.endswith((".c", ".h"))):
        out = _start(tmp_path, old, False)
        (out / name).write_text(new[name])
        assert _state(out, old, new) == "refuses", name


def test_a_config_header_without_a_stamp_stops_every_file(tmp_path, trees):
    """The trees before this change had no stamp: its config header, kept while the other
    files moved (the config header moves last), stops every new file."""
    old, _ = trees
    out = _start(tmp_path, old, False)
    config = next(out.glob("*_config.h"))
    config.write_text("".join(line for line in config.read_text().splitlines(True)
                              if "_GENERATION " not in line))
    errors = _compile_errors(out)
    assert len(errors) == len(list(out.glob("*.c"))) and all(MISMATCH in e for e in errors)


# --------------------------------------------------------------------------- leftovers, links
def test_stale_staging_directories_go_on_the_next_run(tmp_path, trees):
    old, new = trees
    out = _start(tmp_path, old, users_file=True)
    for stale in (out / f"{STAGING_PREFIX}abc", tmp_path / f".out{STAGING_PREFIX}def"):
        stale.mkdir()
        (stale / "rollmpc_solver.c").write_text(old["rollmpc_solver.c"])
    busy = out / f"{STAGING_PREFIX}busy"  # a concurrent generate's: locked, kept
    busy.mkdir()
    fd = os.open(busy, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        write_output(new, out)
    finally:
        os.close(fd)
    assert _leftovers(out) == [busy.name]
    write_output(new, out)
    assert _leftovers(out) == [] and _state(out, old, new) == "new"


def test_output_through_a_symlinked_directory_is_refused(tmp_path, trees, capsys, monkeypatch):
    monkeypatch.delenv("ROLLMPC_DEBUG", raising=False)
    real = tmp_path / "real"
    real.mkdir()
    (tmp_path / "link").symlink_to("real")
    config = short_uav_config(tmp_path, horizon=8)
    capsys.readouterr()
    assert main(["generate", str(config), "-o", str(tmp_path / "link" / "sub")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "symbolic link" in err[0] and str(tmp_path / "link") in err[0], err
    assert list(real.iterdir()) == []
    with pytest.raises(output.OutputRefused):
        write_output(trees[0], tmp_path / "link" / "sub" / "deeper")
    assert list(real.iterdir()) == []
