"""Data safety: rollmpc replaces only the files it wrote, and loads only what it built.

Each test reproduces one finding of the audit; the old writer (replace the whole output
directory) and the old cache (``$TMPDIR/rollmpc-build``, loaded when present) fail them.
"""
from __future__ import annotations

import os
import stat
import subprocess
from pathlib import Path

import pytest

from conftest import edited_config, short_uav_config
from rollmpc_codegen.cli.main import main
from rollmpc_codegen.codegen.output import MANIFEST, OutputRefused, manifest_text, write_output
from rollmpc_codegen.codegen.render import render_sources
from rollmpc_codegen.host.build import build_host_controller, compile_shared
from rollmpc_codegen.host.build_cache import UnsafeBuildDirectory, default_build_root
from rollmpc_codegen.pipeline import load_model

THEIRS = {"main.c": b"int main(void) { return 0; }\n", "Makefile": b"all:\n",
          ".git/config": b"[core]\n"}
PLANTED_C = """#include <stdio.h>
__attribute__((constructor)) static void planted(void)
{
    FILE *f = fopen("%s", "w");
    if (f != NULL) {
        (void)fclose(f);
    }
}
"""


@pytest.fixture(scope="module")
def small(tmp_path_factory) -> Path:
    """The UAV config at N = 8 (prefix rollmpc): fast to generate and to compile."""
    return short_uav_config(tmp_path_factory.mktemp("cfg"), horizon=8)


@pytest.fixture(scope="module")
def other_prefix(small) -> Path:
    def edit(data):
        data["prefix"] = "other"
    return edited_config(small.parent, small, "other", edit)


@pytest.fixture(scope="module")
def small_ctx(small) -> dict:
    return load_model(small)[1]


@pytest.fixture(autouse=True)
def no_debug(monkeypatch):
    monkeypatch.delenv("ROLLMPC_DEBUG", raising=False)  # it turns errors into tracebacks


def _generate(config: Path, out, *extra: str) -> int:
    return main(["generate", str(config), "-o", str(out), *extra])


def _tree(directory: Path) -> dict[str, object]:
    """Every entry under ``directory``: file -> bytes, symlink -> its target, dir -> None."""
    out: dict[str, object] = {}
    for path in sorted(directory.rglob("*")):
        key = str(path.relative_to(directory))
        out[key] = (("link", os.readlink(path)) if path.is_symlink() else
                    None if path.is_dir() else path.read_bytes())
    return out


def _plant(directory: Path, files: dict[str, bytes]) -> None:
    for name, data in files.items():
        (directory / name).parent.mkdir(parents=True, exist_ok=True)
        (directory / name).write_bytes(data)


def _assert_refused(capsys, rc: int, *fragments: str) -> None:
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("rollmpc: error: "), err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def _assert_refused_untouched(capsys, watched: Path, config: Path, out, *extra: str,
                              says: tuple[str, ...]) -> None:
    """``generate config -o out`` refuses (one line saying ``says``), nothing under ``watched``
    changes."""
    capsys.readouterr()
    before = _tree(watched)
    _assert_refused(capsys, _generate(config, out, *extra), *says)
    assert _tree(watched) == before


def _ours(prefix: str = "rollmpc") -> set[str]:
    return {f"{prefix}{tail}" for tail in (".h", "_config.h", "_internal.h", "_data.c",
                                           "_linalg.c", "_solver.c", "_controller.c",
                                           "_context.json", "_README.md",
                                           "_target.mk")}


# ----------------------------------------------------------------------- the output directory
def test_foreign_directory_is_refused_and_untouched(tmp_path, small, capsys):
    project = tmp_path / "project"
    _plant(project, THEIRS)
    _assert_refused_untouched(capsys, tmp_path, small, project,
                              says=(str(project), MANIFEST, "--force"))


def test_force_writes_ours_and_keeps_theirs(tmp_path, small, capsys):
    project = tmp_path / "project"
    _plant(project, THEIRS)
    assert _generate(small, project, "--force") == 0
    tree = _tree(project)
    assert all(tree[name] == data for name, data in THEIRS.items())
    assert set(p.name for p in project.iterdir()) == {*_ours(), MANIFEST, "main.c", "Makefile",
                                                      ".git"}
    assert (project / MANIFEST).read_text() == manifest_text(_ours())
    assert _generate(small, project) == 0  # now it carries our manifest: no --force needed
    assert all(_tree(project)[name] == data for name, data in THEIRS.items())


def test_config_inside_the_output_directory_survives(tmp_path, small, capsys):
    out = tmp_path / "out"
    out.mkdir()
    config = out / "controller.yaml"
    config.write_bytes(small.read_bytes())
    _assert_refused_untouched(capsys, tmp_path, config, out, says=("--force",))
    assert _generate(config, out, "--force") == 0
    assert _generate(config, out) == 0  # regenerating from the config inside
    assert config.read_bytes() == small.read_bytes()
    assert set(os.listdir(out)) == {*_ours(), MANIFEST, "controller.yaml"}


def test_siblings_of_the_output_are_untouched(tmp_path, small):
    _plant(tmp_path, {".out.old/keep.txt": b"mine\n", ".out.tmp": b"also mine\n"})
    before = _tree(tmp_path)
    out = tmp_path / "out"
    assert _generate(small, out) == 0
    assert _generate(small, out) == 0  # the old writer renamed and deleted .out.old here
    after = _tree(tmp_path)
    assert {k: after[k] for k in before} == before
    assert sorted(os.listdir(tmp_path)) == [".out.old", ".out.tmp", "out"]


@pytest.mark.parametrize("force", [(), ("--force",)], ids=["plain", "force"])
def test_symlink_output_is_refused(tmp_path, small, capsys, force):
    real = tmp_path / "real"
    assert _generate(small, real) == 0
    (tmp_path / "link").symlink_to("real")
    _assert_refused_untouched(capsys, tmp_path, small, tmp_path / "link", *force,
                              says=("symbolic link",))
    assert (tmp_path / "link").is_symlink()


def test_empty_output_path_is_refused(tmp_path, small, capsys, monkeypatch):
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)
    _assert_refused(capsys, main(["generate", str(small), "-o", ""]), "empty")
    assert os.listdir(work) == []  # the old CLI wrote generated/<config name>/ here


def test_regeneration_removes_stale_files_and_keeps_the_users(tmp_path, small, other_prefix):
    out = tmp_path / "out"
    assert _generate(small, out) == 0
    (out / "notes.txt").write_text("added by the user after generating\n")
    assert _generate(other_prefix, out) == 0
    assert set(os.listdir(out)) == {*_ours("other"), MANIFEST, "notes.txt"}
    assert (out / MANIFEST).read_text() == manifest_text(_ours("other"))
    assert (out / "notes.txt").read_text() == "added by the user after generating\n"


def test_unlisted_file_in_the_place_of_a_generated_one(tmp_path, small, other_prefix, capsys):
    out = tmp_path / "out"
    assert _generate(small, out) == 0
    (out / "other_data.c").write_text("/* the user's */\n")
    _assert_refused_untouched(capsys, tmp_path, other_prefix, out,
                              says=("other_data.c", "--force"))
    assert _generate(other_prefix, out, "--force") == 0
    assert "the user's" not in (out / "other_data.c").read_text()


def test_failure_before_the_move_keeps_the_old_tree(tmp_path):
    out = tmp_path / "out"
    write_output({"a.c": "old\n"}, out)
    before = _tree(tmp_path)
    with pytest.raises(TypeError):  # the second file cannot be staged
        write_output({"a.c": "new\n", "b.c": object()}, out)
    assert _tree(tmp_path) == before


def test_a_manifest_naming_outside_files_is_refused(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / MANIFEST).write_text(manifest_text(["a.c"]) + "../victim.txt\n")
    with pytest.raises(OutputRefused, match="victim"):
        write_output({"a.c": "x\n"}, out)
    assert victim.read_text() == "precious\n"
    assert sorted(os.listdir(out)) == [MANIFEST]


# -------------------------------------------------------------------------- the build cache
def test_default_cache_is_per_user_and_private(tmp_path, monkeypatch, small_ctx):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_build_root() == tmp_path / "xdg" / "rollmpc" / "build"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/ignored")  # as the XDG spec says
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    root = tmp_path / "home" / ".cache" / "rollmpc" / "build"
    assert default_build_root() == root
    build_host_controller(small_ctx)
    assert stat.S_IMODE(os.stat(root).st_mode) == 0o700
    assert list(root.glob("*/librollmpc.so"))


def test_new_build_dir_is_created_private(tmp_path, small_ctx):
    build_host_controller(small_ctx, tmp_path / "new" / "cache")
    assert stat.S_IMODE(os.stat(tmp_path / "new" / "cache").st_mode) == 0o700


def _planted_library(tmp_path: Path, marker: Path) -> Path:
    (tmp_path / "planted.c").write_text(PLANTED_C % marker)
    lib = tmp_path / "planted.so"
    subprocess.run(["gcc", "-shared", "-fPIC", "-o", str(lib), str(tmp_path / "planted.c")],
                   check=True)
    return lib


def test_planted_library_is_rebuilt_not_loaded(tmp_path, small_ctx):
    root, src, marker = tmp_path / "cache", tmp_path / "src", tmp_path / "constructor-ran"
    src.mkdir()
    for name, text in render_sources(small_ctx).items():
        (src / name).write_text(text)
    cached = compile_shared(small_ctx, src, root)  # where build_host_controller will look
    cached.write_bytes(_planted_library(tmp_path, marker).read_bytes())
    try:
        c = build_host_controller(small_ctx, root)
    finally:
        assert not marker.exists(), "the planted library was loaded"
    assert c.status_message(0) != "unknown status"
    assert b"constructor-ran" not in cached.read_bytes()  # rebuilt in place


def test_planted_source_in_the_cache_is_not_compiled(tmp_path, small_ctx):
    root, marker = tmp_path / "cache", tmp_path / "constructor-ran"
    build_host_controller(small_ctx, root)
    (src,) = root.glob("src-rollmpc-*")
    (src / "rollmpc_planted.c").write_text(PLANTED_C % marker)
    build_host_controller(small_ctx, root)
    assert not marker.exists()
    assert not (src / "rollmpc_planted.c").exists()


def test_shared_or_linked_build_dir_is_refused(tmp_path, small_ctx):
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o1777)  # like /tmp
    with pytest.raises(UnsafeBuildDirectory, match="writable by group or others"):
        build_host_controller(small_ctx, shared)
    (tmp_path / "private").mkdir(mode=0o700)
    (tmp_path / "link").symlink_to("private")
    with pytest.raises(UnsafeBuildDirectory, match="symbolic link"):
        build_host_controller(small_ctx, tmp_path / "link")
    assert os.listdir(shared) == [] and os.listdir(tmp_path / "private") == []


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to give a directory to another user")
def test_build_dir_of_another_user_is_refused(tmp_path, small_ctx):
    theirs = tmp_path / "theirs"
    theirs.mkdir(mode=0o700)
    os.chown(theirs, 65534, 65534)  # nobody
    with pytest.raises(UnsafeBuildDirectory, match="not to you"):
        build_host_controller(small_ctx, theirs)
