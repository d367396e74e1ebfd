"""The host build cache: a private per-user directory whose artefacts are checked before use.

A cached library is loaded into the Python process, and cffi's dlopen runs its
constructors, so nobody else may be able to write there.  The default root is
``$XDG_CACHE_HOME/rollmpc/build`` (``~/.cache/rollmpc/build``), never the shared temporary
directory.  Every root, the default or ``--build-dir``, is created with mode 0700.  It is
refused when it is a symbolic link, belongs to another user, or is writable by group or
others.  Each cached artefact has a record (:data:`RECORD`) with the key it was built for
(the hash of its sources and flags) and its own sha256.  When the record does not match,
the artefact is rebuilt and never loaded.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path

RECORD = "rollmpc-build.sha256"


class UnsafeBuildDirectory(RuntimeError):
    """The build root could hold files written by someone else."""


def default_build_root() -> Path:
    """``$XDG_CACHE_HOME/rollmpc/build``, else ``~/.cache/rollmpc/build``."""
    xdg = os.environ.get("XDG_CACHE_HOME", "")
    # the XDG specification says to ignore a relative path
    base = Path(xdg) if os.path.isabs(xdg) else Path.home() / ".cache"
    return base / "rollmpc" / "build"


def private_root(build_root: str | os.PathLike | None = None) -> Path:
    """The build root (default when None), created 0700; refused unless only we can write it."""
    root = Path(build_root) if build_root is not None else default_build_root()
    root.mkdir(mode=0o700, parents=True, exist_ok=True)
    st = os.lstat(root)
    problem = ("is a symbolic link" if stat.S_ISLNK(st.st_mode) else
               "is not a directory" if not stat.S_ISDIR(st.st_mode) else
               f"belongs to uid {st.st_uid}, not to you" if st.st_uid != os.getuid() else
               "is writable by group or others" if st.st_mode & 0o022 else None)
    if problem:
        raise UnsafeBuildDirectory(
            f"build directory {root} {problem}; rollmpc loads compiled code from it, so it "
            "must be a directory of yours that nobody else can write (chmod 700, or choose "
            "another --build-dir)")
    return root


def _record(key: str, artefact: Path) -> str:
    """The record's text: the sources' key, then the artefact's sha256 (sha256sum style)."""
    digest = hashlib.sha256(artefact.read_bytes()).hexdigest()
    return f"sources {key}\n{digest}  {artefact.name}\n"


def verified(out_dir: Path, name: str, key: str) -> Path | None:
    """``out_dir/name`` if its record says it was built for ``key`` and it is unchanged since."""
    artefact = out_dir / name
    try:
        matches = (out_dir / RECORD).read_text() == _record(key, artefact)
    except (OSError, UnicodeDecodeError):
        return None
    return artefact if matches else None


@contextmanager
def staging(root: Path, name: str):
    """A fresh directory in ``root`` to build ``name`` in; removed if the build fails."""
    stage = Path(tempfile.mkdtemp(prefix=f"{name}.tmp-", dir=root))
    try:
        yield stage
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise


def _move_into_place(stage: Path, out_dir: Path) -> None:
    if out_dir.is_symlink() or out_dir.is_file():
        out_dir.unlink()
    else:
        shutil.rmtree(out_dir, ignore_errors=True)  # stale or tampered
    stage.rename(out_dir)


def publish(stage: Path, out_dir: Path, name: str, key: str) -> Path:
    """Record ``stage/name`` as built for ``key`` and move the stage to ``out_dir``."""
    (stage / RECORD).write_text(_record(key, stage / name))
    try:
        _move_into_place(stage, out_dir)
    except OSError:  # a concurrent build of the same key got there first
        shutil.rmtree(stage, ignore_errors=True)
        found = verified(out_dir, name, key)
        if found is None:
            raise
        return found
    return out_dir / name


def _holds_exactly(directory: Path, files: dict[str, str]) -> bool:
    try:
        return (sorted(os.listdir(directory)) == sorted(files)
                and all((directory / n).read_text() == text for n, text in files.items()))
    except (OSError, UnicodeDecodeError):
        return False


def source_dir(root: Path, name: str, files: dict[str, str]) -> Path:
    """``root/name`` holding exactly ``files``: reused when it does, rewritten otherwise.

    Every file of the directory is compiled or reachable by ``-I``, so an extra or
    changed file is never kept.
    """
    src = root / name
    if not _holds_exactly(src, files):
        with staging(root, name) as stage:
            for file_name, text in files.items():
                (stage / file_name).write_text(text)
            _move_into_place(stage, src)
    return src
