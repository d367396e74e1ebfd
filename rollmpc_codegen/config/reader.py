"""Typed reading of the YAML tree: every value is checked where it is read, and every
failure names its full key path (``modes[1].weights.P: must be ...``)."""
from __future__ import annotations

import difflib
import math
import re
from typing import Any

import numpy as np

from .errors import ConfigError
from .schema import MAX_LIST_LENGTH

# matched with fullmatch: `$` would also match before a trailing newline
IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
LISTED_KEYS_MAX = 8  # an unknown key without a close match lists a section's keys up to this


class Reader:
    """Typed access to one YAML mapping with the given ``keys``; every failure names its
    full key path.

    Any other key is reported at once, before a value of the section is read: read later,
    a misspelled key surfaces as another problem (``R_detla`` as "R must be positive
    definite", ``horizn`` as "horizon: missing required key").
    """

    def __init__(self, data: Any, path: str, keys: tuple[str, ...]):
        if not isinstance(data, dict):
            raise ConfigError(path or "<top>", "must be a mapping")
        self.data = data
        self.path = path
        self.keys = keys
        for name in data:  # the first unknown key as written
            if name not in keys:
                raise ConfigError(self.key(str(name)), unknown_key(str(name), keys))

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def has(self, name: str) -> bool:
        """Is an optional key given?  ``key:`` with no value counts as absent, as in raw()."""
        assert name in self.keys, f"{self.key(name)} is not declared in the schema"
        return self.data.get(name) is not None

    def raw(self, name: str, default: Any = ...) -> Any:
        assert name in self.keys, f"{self.key(name)} is not declared in the schema"
        if name not in self.data or self.data[name] is None:
            if default is not ...:
                return default
            raise ConfigError(self.key(name), "missing required key")
        return self.data[name]

    def number(self, name: str, default: Any = ..., positive: bool = False,
               nonnegative: bool = False) -> float:
        value = self.raw(name, default)
        return read_number(value, self.key(name), positive=positive, nonnegative=nonnegative)

    def integer(self, name: str, default: Any = ..., minimum: int | None = None,
                maximum: int | None = None) -> int:
        value = self.raw(name, default)
        if isinstance(value, float) or (isinstance(value, str) and "e" in value.lower()):
            # whole numbers written as 1e6 / 1.0e6 (YAML 1.1 reads the latter as a string)
            try:
                as_float = float(value)
            except ValueError:
                as_float = math.nan
            if math.isfinite(as_float) and as_float == int(as_float):
                value = int(as_float)
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(self.key(name), f"must be an integer, got {value!r}")
        if minimum is not None and value < minimum:
            raise ConfigError(self.key(name), f"must be >= {minimum}, got {value}")
        if maximum is not None and value > maximum:
            raise ConfigError(self.key(name), f"must be <= {maximum}, got {value}")
        return value

    def boolean(self, name: str, default: Any = ...) -> bool:
        value = self.raw(name, default)
        if not isinstance(value, bool):
            raise ConfigError(self.key(name), f"must be true or false, got {value!r}")
        return value

    def string(self, name: str, default: Any = ..., choices: tuple[str, ...] | None = None) -> str:
        value = self.raw(name, default)
        if not isinstance(value, str):
            raise ConfigError(self.key(name), f"must be a string, got {value!r}")
        if choices is not None and value not in choices:
            raise ConfigError(self.key(name), f"must be one of {', '.join(choices)}; got {value!r}")
        return value

    def names(self, name: str) -> tuple[str, ...]:
        value = self.raw(name)
        if not isinstance(value, list) or not value:
            raise ConfigError(self.key(name), "must be a non-empty list of names")
        check_length(value, self.key(name))
        for i, item in enumerate(value):
            if not isinstance(item, str) or not IDENTIFIER.fullmatch(item):
                raise ConfigError(f"{self.key(name)}[{i}]",
                                  f"must be a C identifier-like name, got {item!r}")
        if len(set(value)) != len(value):
            raise ConfigError(self.key(name), "names must be unique")
        return tuple(value)

    def psd(self, name: str, shape: tuple[int, int], strict: bool,
            default: Any = ...) -> np.ndarray:
        """A symmetric positive semidefinite matrix (``strict``: definite) of ``shape``."""
        key = self.key(name)
        return check_psd(read_matrix(self.raw(name, default), key, shape), key, strict)

    def sub(self, name: str, keys: tuple[str, ...], default: Any = ...) -> "Reader":
        """The section ``name``, whose own keys are ``keys``."""
        value = self.raw(name, default)
        return Reader(value, self.key(name), keys)


def unknown_key(name: str, keys: tuple[str, ...]) -> str:
    """The problem of an unknown key: the closest known key, else the known keys if few."""
    close = difflib.get_close_matches(name, keys, n=1)
    if close:
        return f"unknown key (did you mean {close[0]}?)"
    if len(keys) <= LISTED_KEYS_MAX:
        return f"unknown key; valid keys are {', '.join(keys)}"
    return "unknown key"


def check_length(items: list, key: str) -> None:
    """Refuse a list longer than MAX_LIST_LENGTH before anything converts its entries."""
    if len(items) > MAX_LIST_LENGTH:
        raise ConfigError(key, f"has {len(items)} entries; at most {MAX_LIST_LENGTH} "
                          "supported")


def read_number(value: Any, key: str, positive: bool = False,
                nonnegative: bool = False) -> float:
    if isinstance(value, str):
        # PyYAML (YAML 1.1) reads 1.0e6 -- no sign in the exponent -- as a string
        try:
            value = float(value.strip())
        except ValueError:
            raise ConfigError(key, f"must be a number, got {value!r}") from None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(key, f"must be a number, got {value!r}")
    try:
        value = float(value)
    except OverflowError:  # an integer literal with hundreds of digits
        raise ConfigError(key, "must be finite, got a number too large for a double") from None
    if not math.isfinite(value):
        raise ConfigError(key, f"must be finite, got {value!r}")
    if positive and value <= 0:
        raise ConfigError(key, f"must be > 0, got {value!r}")
    if nonnegative and value < 0:
        raise ConfigError(key, f"must be >= 0, got {value!r}")
    return value


def read_vector(value: Any, key: str, length: int | None = None,
                allow_inf: bool = False) -> np.ndarray:
    """A scalar (broadcast to ``length``) or a list of numbers."""
    items = value if isinstance(value, list) else [value]
    check_length(items, key)
    if length is not None and not isinstance(value, list):
        items = items * length
    out = []
    for i, item in enumerate(items):
        k = f"{key}[{i}]" if isinstance(value, list) else key
        if allow_inf and isinstance(item, str) and item.strip() in ("inf", "+inf", "-inf"):
            out.append(float(item))
            continue
        if allow_inf and isinstance(item, float) and math.isinf(item):
            out.append(item)
            continue
        out.append(read_number(item, k))
    if length is not None and len(out) != length:
        raise ConfigError(key, f"must have {length} entries, got {len(out)}")
    if not out:
        raise ConfigError(key, "must not be empty")
    return np.array(out, dtype=float)


def read_matrix(value: Any, key: str, shape: tuple[int, int] | None = None) -> np.ndarray:
    """A matrix given as a list of rows; a scalar means scalar * identity (square shapes)."""
    if shape is not None and not isinstance(value, list):
        if shape[0] != shape[1]:
            raise ConfigError(key, f"must be a {shape[0]}x{shape[1]} matrix")
        return read_number(value, key) * np.eye(shape[0])
    if shape is not None and isinstance(value, list) and value and not isinstance(value[0], list):
        # a flat list is a diagonal for square weights
        if shape[0] == shape[1]:
            return np.diag(read_vector(value, key, shape[0]))
    if not isinstance(value, list) or not value or not all(isinstance(r, list) for r in value):
        raise ConfigError(key, "must be a matrix given as a list of rows")
    check_length(value, key)
    rows = [read_vector(r, f"{key}[{i}]") for i, r in enumerate(value)]
    if len({len(r) for r in rows}) != 1:
        raise ConfigError(key, "rows must all have the same length")
    mat = np.array(rows)
    if shape is not None and mat.shape != shape:
        raise ConfigError(key, f"must be {shape[0]}x{shape[1]}, got {mat.shape[0]}x{mat.shape[1]}")
    return mat


def check_psd(mat: np.ndarray, key: str, strict: bool) -> np.ndarray:
    if not np.allclose(mat, mat.T, rtol=0, atol=1e-12 * max(1.0, np.abs(mat).max())):
        raise ConfigError(key, "must be symmetric")
    eig = np.linalg.eigvalsh(mat)
    if strict and eig.min() <= 0:
        raise ConfigError(key, "must be positive definite")
    if not strict and eig.min() < -1e-12 * max(1.0, eig.max()):
        raise ConfigError(key, "must be positive semidefinite")
    return mat

