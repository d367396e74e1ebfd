"""Where the templates are (the source tree's templates/, or the copy the wheel installs),
and the generation stamp of a tree rendered from them.

Apart from :mod:`.render` so that the prefix check of the config (:mod:`.c_names`) can
read the templates' identifiers without loading jinja2 and the maths.
"""
from __future__ import annotations

import hashlib
import sys
from functools import lru_cache
from pathlib import Path

from .. import __version__


def templates_dir() -> Path:
    """templates/ of the source tree, or the copy shipped inside the wheel."""
    here = Path(__file__).resolve().parents[1]  # the rollmpc_codegen package
    shared = Path(sys.prefix) / "share" / "rollmpc" / "templates"
    for cand in (here / "templates", here.parent / "templates", shared):
        if cand.is_dir():
            return cand
    raise FileNotFoundError("rollmpc templates directory not found")


# the templates of the test programs and the target harness: not part of a tree
NOT_IN_A_TREE = ("host", "target")


@lru_cache(maxsize=1)
def tree_templates_digest() -> str:
    """sha256 of the templates a generated tree is rendered from (their text, newlines
    normalised, so a CRLF checkout stamps the same trees)."""
    root = templates_dir()
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.j2")):
        rel = path.relative_to(root)
        if rel.parts[0] not in NOT_IN_A_TREE:
            digest.update(rel.as_posix().encode() + b"\0")
            digest.update(path.read_bytes().replace(b"\r\n", b"\n") + b"\0")
    return digest.hexdigest()


def generation_stamp(config_hash: str) -> str:
    """The tree's generation as a C literal for ``#if``: 60 bits of the hash of the config,
    the generator's version and its templates, so that a file of another config or another
    rollmpc refuses to compile beside the config header (templates/generation_check.j2)."""
    text = f"{config_hash}\n{__version__}\n{tree_templates_digest()}"
    return "0x" + hashlib.sha256(text.encode()).hexdigest()[:15]
