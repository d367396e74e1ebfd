"""Stage 7b: put rendered files into an output directory without losing anyone's file.

rollmpc replaces only what it wrote.  Each output directory carries a manifest
(:data:`MANIFEST`) naming the files of the last generation.  Regenerating replaces those
files, removes the listed ones that are no longer generated, and keeps every other file.
The rules (docs/reliability.md, "Data safety"):

* A non-empty directory without a manifest is refused (one line, exit 2).  So is an existing
  file that would be overwritten but is not listed.  ``force`` allows both: our files are
  written over same-named ones, and nothing else is deleted.
* An output path that is a symbolic link is refused, with or without ``force``.  So is
  anything but a regular file where a generated file goes.  No symlink is followed, and
  nothing beside the directory is touched.
* Atomic per file set.  Everything is rendered and staged in a fresh temporary directory
  before the first file moves, so a failure up to then leaves the old tree intact.  A new
  directory appears with one rename.  An existing one gets one rename per file, between two
  manifest updates: the first lists old and new files, so an interruption leaves no file of
  ours unlisted.
"""
from __future__ import annotations

import os
import shutil
import stat
import tempfile
from pathlib import Path

from ..config import ConfigError

MANIFEST = ".rollmpc-manifest"
MANIFEST_HEADER = "# rollmpc replaces exactly these files when it regenerates; others are kept\n"
STAGING_PREFIX = ".rollmpc-staging-"


class OutputRefused(ConfigError):
    """Writing there could lose a file rollmpc did not write: one line, exit 2, nothing written."""


def manifest_text(names) -> str:
    """The manifest's content: sorted names and no timestamp, so it regenerates byte for byte."""
    return MANIFEST_HEADER + "".join(f"{name}\n" for name in sorted(names))


def _is_plain_name(name: str) -> bool:
    """A file directly inside the directory (a manifest line can name nothing else)."""
    return (name not in ("", ".", "..", MANIFEST) and not name.startswith("#")
            and not any(ch in name for ch in ("/", os.sep, "\n", "\r", "\0")))


def _listed(out: Path) -> set[str] | None:
    """The names in ``out``'s manifest, or None when it has none."""
    path = out / MANIFEST
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return None
    if not stat.S_ISREG(mode):
        raise OutputRefused(str(path), "is not a regular file; remove it or choose another "
                            "output directory")
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError:
        raise OutputRefused(str(path), "is not a rollmpc manifest (not UTF-8)") from None
    names = {line for line in lines if line and not line.startswith("#")}
    foreign = sorted(name for name in names if not _is_plain_name(name))
    if foreign:
        raise OutputRefused(str(path), f"lists {foreign[0][:80]!r}, which is not a file of "
                            "this directory; remove the manifest or choose another directory")
    return names


def check_output_dir(out_dir: str | os.PathLike, force: bool = False) -> set[str] | None:
    """Refuse an output path rollmpc must not write into (before any work is done).

    Returns the names listed in the directory's manifest, or None (no directory or no
    manifest).
    """
    if str(out_dir) == "":
        raise OutputRefused("output directory", "empty path; name the directory to write")
    out = Path(out_dir)
    if out.is_symlink():
        raise OutputRefused(str(out), f"is a symbolic link (to {os.readlink(out)}); rollmpc "
                            "follows no link: name the directory itself")
    if not out.exists():
        return None
    if not out.is_dir():
        raise OutputRefused(str(out), "exists and is not a directory")
    listed = _listed(out)
    if listed is None and not force and any(os.scandir(out)):
        raise OutputRefused(str(out), f"is not empty and has no {MANIFEST}, so rollmpc did "
                            "not write it; choose a new or empty directory, or pass --force "
                            "to add the generated files (other files are kept)")
    return listed


def _check_destinations(out: Path, names: set[str], listed: set[str] | None,
                        force: bool) -> None:
    """Every generated file may replace what is in its place (nothing moved yet)."""
    for name in sorted(names):
        try:
            mode = os.lstat(out / name).st_mode
        except FileNotFoundError:
            continue
        if not stat.S_ISREG(mode):
            raise OutputRefused(str(out / name), "is not a regular file; rollmpc writes a "
                                "generated file there and replaces only regular files")
        if listed is not None and name not in listed and not force:
            raise OutputRefused(str(out / name), f"exists and is not listed in {MANIFEST}; "
                                "rollmpc replaces only the files it wrote (--force to "
                                "overwrite it)")


def _stage(files: dict[str, str], where: Path, prefix: str) -> Path:
    """A fresh temporary directory in ``where`` holding ``files``."""
    stage = Path(tempfile.mkdtemp(prefix=prefix, dir=where))
    try:
        for name, text in files.items():
            (stage / name).write_text(text)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    return stage


def _write_manifest(out: Path, stage: Path, names) -> None:
    (stage / MANIFEST).write_text(manifest_text(names))
    os.replace(stage / MANIFEST, out / MANIFEST)


def _create(files: dict[str, str], out: Path) -> None:
    """A new directory: staged beside it under a fresh name, then one rename."""
    out.parent.mkdir(parents=True, exist_ok=True)
    stage = _stage({**files, MANIFEST: manifest_text(files)}, out.parent,
                   f".{out.name}{STAGING_PREFIX}")
    try:
        stage.chmod(0o755)  # mkdtemp's 0700 would hide the sources from the user's group
        os.rename(stage, out)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise


def _replace(files: dict[str, str], out: Path, listed: set[str]) -> None:
    """An existing directory: staged inside it, then one rename per file."""
    names = set(files)
    stage = _stage(files, out, STAGING_PREFIX)
    try:
        _write_manifest(out, stage, listed | names)
        for name in sorted(names):
            os.replace(stage / name, out / name)
        for name in sorted(listed - names):  # listed by us, no longer generated
            path = out / name
            if path.is_file() and not path.is_symlink():
                path.unlink()
        _write_manifest(out, stage, names)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def write_output(files: dict[str, str], out_dir: str | os.PathLike,
                 force: bool = False) -> Path:
    """Write ``files`` (name -> text) into ``out_dir`` under the rules of this module."""
    bad = [name for name in files if not _is_plain_name(name)]
    if bad:
        raise ValueError(f"generated file name {bad[0]!r} is not a plain file name")
    listed = check_output_dir(out_dir, force)
    out = Path(out_dir)
    if out.is_dir():
        _check_destinations(out, set(files), listed, force)
        _replace(files, out, listed or set())
    else:
        _create(files, out)
    return out
