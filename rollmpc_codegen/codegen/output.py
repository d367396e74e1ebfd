"""Stage 7b: put rendered files into an output directory without losing anyone's file,
and without leaving a mixed tree that builds.

rollmpc replaces only what it wrote.  Each output directory carries a manifest
(:data:`MANIFEST`) naming the files of the last generation.  Regenerating replaces those
files, removes the listed ones that are no longer generated, and keeps every other file.
The rules (docs/reliability.md, "Data safety"):

* A non-empty directory without a manifest is refused (one line, exit 2).  So is an existing
  file that would be overwritten but is not listed.  ``force`` allows both: our files are
  written over same-named ones, and nothing else is deleted.
* An output path that is a symbolic link, or runs through one (``-o link/sub``), is
  refused, with or without ``force``.  So is anything but a regular file where a
  generated file goes.  No symlink is followed, and nothing beside the directory is
  touched but rollmpc's own staging directories.
* Atomic.  Everything is rendered and staged in a fresh directory before the first file
  moves, so a failure up to then leaves the old tree intact.  A new directory appears with
  one rename.  An existing directory that holds only rollmpc's files is exchanged for the
  staged one in one step (renameat2 RENAME_EXCHANGE; Linux).  Otherwise (other files in
  it, or no exchange on this system) each file is renamed into place, the config header
  last, between two manifest updates (the first lists old and new files, so an
  interruption leaves no file of ours unlisted); a failure on the way puts the old files
  back.  A kill between two of those moves leaves files of two generations, and those
  refuse to compile: every generated file checks its generation against the config
  header's (templates/generation_check.j2).
* The staging directories an interrupted run leaves (in the directory or beside it) are
  removed by the next run; one that a running generate holds (a lock) is left alone.
"""
from __future__ import annotations

import ctypes
import errno
import fcntl
import os
import shutil
import stat
import tempfile
from pathlib import Path

from ..config import ConfigError

MANIFEST = ".rollmpc-manifest"
MANIFEST_HEADER = "# rollmpc replaces exactly these files when it regenerates; others are kept\n"
STAGING_PREFIX = ".rollmpc-staging-"
BACKUP = ".rollmpc-old"  # inside a staging directory: the old files, to undo a failed move
# renameat2(2), to exchange two directories in one step (Linux 3.15, glibc 2.28)
_LIBC = ctypes.CDLL(None, use_errno=True)
_AT_FDCWD, _RENAME_EXCHANGE = -100, 2


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


def _refuse_links(out: Path) -> None:
    """No directory on the way to ``out`` (as written: ``-o link/sub``), nor ``out``
    itself, may be a symbolic link: the files would land in the link's target."""
    path = Path(out.anchor) if out.is_absolute() else Path()
    for part in out.parts[1 if out.is_absolute() else 0:]:
        path = path / part
        if path.is_symlink():
            where = "" if path == out else f" on the way to {out}"
            raise OutputRefused(str(path), f"is a symbolic link (to {os.readlink(path)}){where}; "
                                "rollmpc follows no link: name the directory itself")


def check_output_dir(out_dir: str | os.PathLike, force: bool = False) -> set[str] | None:
    """Refuse an output path rollmpc must not write into (before any work is done).

    Returns the names listed in the directory's manifest, or None (no directory or no
    manifest).
    """
    if str(out_dir) == "":
        raise OutputRefused("output directory", "empty path; name the directory to write")
    out = Path(out_dir)
    _refuse_links(out)
    if not out.exists():
        return None
    if not out.is_dir():
        raise OutputRefused(str(out), "exists and is not a directory")
    listed = _listed(out)
    leftovers = {p.name for p in _leftovers(out)}
    if listed is None and not force and any(e.name not in leftovers for e in os.scandir(out)):
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


def _leftovers(out: Path) -> list[Path]:
    """Staging directories of ours in ``out`` and beside it (an interrupted run's, or one
    in use by a concurrent run: :func:`_remove_leftovers` tells them apart)."""
    found = []
    for where, start in ((out, STAGING_PREFIX), (out.parent, f".{out.name}{STAGING_PREFIX}")):
        try:
            entries = list(os.scandir(where))
        except (FileNotFoundError, NotADirectoryError):
            continue
        found += [Path(e.path) for e in entries if e.name.startswith(start)
                  and e.is_dir(follow_symlinks=False)
                  and e.stat(follow_symlinks=False).st_uid == os.geteuid()]
    return found


def _lock(directory: Path, wait: bool = True) -> int | None:
    """An exclusive lock on a staging directory (released when its holder dies), or None
    when another run holds it."""
    fd = os.open(directory, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
    except BlockingIOError:
        os.close(fd)
        return None
    return fd


def _remove_leftovers(out: Path) -> None:
    """What an interrupted run left: its staging directories, or the old tree a swap left
    under a staging name; never one a running generate holds."""
    for path in _leftovers(out):
        fd = _lock(path, wait=False)
        if fd is not None:
            try:
                shutil.rmtree(path, ignore_errors=True)
            finally:
                os.close(fd)


def _stage(files: dict[str, str], where: Path, prefix: str) -> tuple[Path, int]:
    """A fresh temporary directory in ``where`` holding ``files``, and its lock."""
    stage = Path(tempfile.mkdtemp(prefix=prefix, dir=where))
    lock = _lock(stage)
    try:
        for name, text in files.items():
            (stage / name).write_text(text)
    except BaseException:
        _release(stage, lock)
        raise
    return stage, lock


def _release(stage: Path, lock: int) -> None:
    """Remove a staging directory and drop its lock (whatever the removal does)."""
    try:
        shutil.rmtree(stage, ignore_errors=True)
    finally:
        os.close(lock)


def _exchange(a: Path, b: Path) -> bool:
    """Swap two directories in one step (Linux renameat2 RENAME_EXCHANGE); False where
    the system or the file system cannot."""
    renameat2 = getattr(_LIBC, "renameat2", None)
    if renameat2 is None:
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                          ctypes.c_uint]
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP, errno.EXDEV, errno.EBUSY):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _only_ours(out: Path, listed: set[str] | None) -> bool:
    """``out`` holds nothing but the regular files its manifest lists (and the manifest):
    the whole directory can be swapped."""
    ours = (listed or set()) | {MANIFEST}
    return all(e.name in ours and e.is_file(follow_symlinks=False) for e in os.scandir(out))


def _create(files: dict[str, str], out: Path) -> None:
    """A new directory: staged beside it under a fresh name, then one rename."""
    out.parent.mkdir(parents=True, exist_ok=True)
    stage, lock = _stage({**files, MANIFEST: manifest_text(files)}, out.parent,
                         f".{out.name}{STAGING_PREFIX}")
    try:
        stage.chmod(0o755)  # mkdtemp's 0700 would hide the sources from the user's group
        os.rename(stage, out)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    finally:
        os.close(lock)


def _swap(files: dict[str, str], out: Path) -> bool:
    """A directory of ours only: the new tree staged beside it, then the two exchanged in
    one step; False (nothing changed) where the system cannot exchange them, or the
    parent directory is not ours to write in."""
    try:
        stage, lock = _stage({**files, MANIFEST: manifest_text(files)}, out.parent,
                             f".{out.name}{STAGING_PREFIX}")
    except PermissionError:
        return False
    try:
        stage.chmod(stat.S_IMODE(os.stat(out).st_mode))
        return _exchange(stage, out)
    finally:  # the staged tree, or after the exchange the old one
        _release(stage, lock)


def _write_manifest(out: Path, stage: Path, names) -> None:
    (stage / MANIFEST).write_text(manifest_text(names))
    os.replace(stage / MANIFEST, out / MANIFEST)


def _keep(path: Path, backup: Path) -> None:
    """A hard link to the file at ``path`` (if any) in ``backup``, to undo its move."""
    try:
        os.link(path, backup / path.name, follow_symlinks=False)
    except FileNotFoundError:
        pass


def _undo(out: Path, backup: Path, changed: list[str]) -> None:
    """Put back the old files of ``changed`` (a file that had none goes); best effort."""
    for name in reversed(changed):
        try:
            if (backup / name).exists():
                os.replace(backup / name, out / name)
            else:
                (out / name).unlink(missing_ok=True)
        except OSError:
            pass  # what stays is of two generations: it refuses to compile


def _replace(files: dict[str, str], out: Path, listed: set[str]) -> None:
    """An existing directory with other files in it: staged inside it, then one rename
    per file in the order of ``files`` (the config header last), between two manifest
    updates; a failure on the way puts the old files back."""
    stage, lock = _stage(files, out, STAGING_PREFIX)
    backup = stage / BACKUP
    changed: list[str] = []
    try:
        backup.mkdir()
        for name in [MANIFEST, *files, *sorted(listed - set(files))]:
            _keep(out / name, backup)
        changed.append(MANIFEST)
        _write_manifest(out, stage, listed | set(files))
        for name in files:
            changed.append(name)
            os.replace(stage / name, out / name)
        for name in sorted(listed - set(files)):  # listed by us, no longer generated
            path = out / name
            if path.is_file() and not path.is_symlink():
                changed.append(name)
                path.unlink()
        _write_manifest(out, stage, files)
    except BaseException:
        _undo(out, backup, changed)
        raise
    finally:
        _release(stage, lock)


def write_output(files: dict[str, str], out_dir: str | os.PathLike,
                 force: bool = False) -> Path:
    """Write ``files`` (name -> text) into ``out_dir`` under the rules of this module; the
    last of ``files`` is the one that completes the tree (render_sources: the config
    header), moved last where the files move one by one."""
    bad = [name for name in files if not _is_plain_name(name)]
    if bad:
        raise ValueError(f"generated file name {bad[0]!r} is not a plain file name")
    listed = check_output_dir(out_dir, force)
    out = Path(out_dir)
    _remove_leftovers(out)
    if out.is_dir():
        _check_destinations(out, set(files), listed, force)
        if not (_only_ours(out, listed) and _swap(files, out)):
            _replace(files, out, listed or set())
    else:
        _create(files, out)
    return out
