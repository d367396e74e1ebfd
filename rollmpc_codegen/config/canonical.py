"""The canonical text of a validated configuration, and the config hash stamped from it.

The hash is taken over the *effective* configuration -- the parsed dataclasses, after
every default and the ``--precision`` override -- not over the YAML text. So the same
design gives the same hash (and byte-identical generated files) whether it was written
with comments or without, in the bands form or the eq. (3) shorthand, as YAML or through
the Python API, and whether its precision came from the file or from the command line.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from typing import Any

import numpy as np


def _plain(value: Any) -> Any:
    """JSON-ready data; every float as its repr (exact, and defined for +-inf)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)
                if not _omitted(f, getattr(value, f.name))}
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, complex):
        return [repr(value.real), repr(value.imag)]
    if value is None or isinstance(value, str):
        return value
    raise TypeError(f"no canonical form for {type(value).__name__}")


def _omitted(f: dataclasses.Field, value: Any) -> bool:
    """A field added after designs were generated, at its default: left out, so that those
    designs keep their hash (schema.NEW_FIELD)."""
    return f.metadata.get("canonical") == "omit_default" and value == f.default


def canonical_json(config: Any) -> str:
    """One line of sorted-key JSON naming every field of ``config`` (a config dataclass)."""
    return json.dumps(_plain(config), sort_keys=True, separators=(",", ":"))


def config_digest(config: Any) -> str:
    """The config hash of the generated files: 16 hex digits of SHA-256."""
    return hashlib.sha256(canonical_json(config).encode()).hexdigest()[:16]
