"""Reading a configuration file: bytes -> UTF-8 -> YAML (a key given twice is an error)
-> :func:`parse`; every failure, a YAML syntax error included, is one ConfigError line."""
from __future__ import annotations

from pathlib import Path

import yaml

from .controller import parse
from .errors import ConfigError
from .schema import PRECISIONS, ControllerConfig


def _yaml_problem(exc: yaml.YAMLError) -> tuple[str, str]:
    """(where, what) of a PyYAML error; its str() spans several lines, so not that."""
    if isinstance(exc, yaml.reader.ReaderError):  # a control character; it has no mark
        what = f"{exc.reason} (#x{exc.character:04x})"
        return f"<yaml character {exc.position + 1}>", f"not valid YAML: {what}"
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    where = f"<yaml line {mark.line + 1}>" if mark else "<yaml>"
    what = getattr(exc, "problem", None) or getattr(exc, "context", None) or type(exc).__name__
    return where, f"not valid YAML: {what}"


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that rejects a key given twice in one mapping (PyYAML keeps the last)."""


def _unique_mapping(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False):
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in seen
        except TypeError:  # an unhashable key: construct_mapping reports it
            continue
        if duplicate:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r}", key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _unique_mapping)


def load(path: str | Path, precision: str | None = None) -> ControllerConfig:
    """Read and validate a YAML file; ``precision`` overrides the file's setting."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ConfigError(str(path), f"cannot read: {exc.strerror}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(str(path), f"not UTF-8 text (byte {exc.start})") from None
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 (a SafeLoader)
    except yaml.YAMLError as exc:
        raise ConfigError(*_yaml_problem(exc)) from None
    if data is None:
        raise ConfigError("<top>", "the file is empty")
    if precision is not None:
        if precision not in PRECISIONS:
            raise ConfigError("precision", f"must be one of {', '.join(PRECISIONS)}")
        if isinstance(data, dict):
            data = dict(data, precision=precision)
    return parse(data)
