"""Reading a configuration file: bytes -> UTF-8 -> YAML (a key given twice is an error)
-> :func:`parse`; every failure, a YAML syntax error included, is one ConfigError line.

The file may be hostile (docs/reliability.md, "Hostile input"): at most MAX_CONFIG_BYTES
are read, whatever the path is (/dev/zero, a FIFO without a writer), and the YAML is
bounded while it is composed, before anything is built from it: its nodes, its nesting
and what its aliases repeat (schema.py's limits).
"""
from __future__ import annotations

import os
from pathlib import Path

import yaml

from .controller import parse
from .errors import ConfigError
from .schema import (MAX_ALIAS_NODES, MAX_CONFIG_BYTES, MAX_YAML_DEPTH, MAX_YAML_NODES,
                     PRECISIONS, ControllerConfig)
from .target import part_target


def _yaml_problem(exc: yaml.YAMLError) -> tuple[str, str]:
    """(where, what) of a PyYAML error; its str() spans several lines, so not that."""
    if isinstance(exc, yaml.reader.ReaderError):  # a control character; it has no mark
        what = f"{exc.reason} (#x{exc.character:04x})"
        return f"<yaml character {exc.position + 1}>", f"not valid YAML: {what}"
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    where = f"<yaml line {mark.line + 1}>" if mark else "<yaml>"
    what = getattr(exc, "problem", None) or getattr(exc, "context", None) or type(exc).__name__
    return where, f"not valid YAML: {what}"


class _ConfigLoader(yaml.SafeLoader):
    """SafeLoader that rejects a key given twice in one mapping (PyYAML keeps the last)
    and counts while composing: the nodes the constructor will see (an alias counts as
    every node it repeats), the nodes aliases repeat, and the nesting depth."""

    def __init__(self, stream):
        super().__init__(stream)
        self._size: dict[int, int] = {}  # id(node) -> its nodes, aliases expanded
        self._open: set[str] = set()  # anchors whose node is being composed
        self._nodes = self._repeated = self._depth = 0

    def _refuse(self, event, problem: str):
        raise ConfigError(f"<yaml line {event.start_mark.line + 1}>", problem)

    def compose_node(self, parent, index):
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent):
            if event.anchor in self._open:
                self._refuse(event, f"alias *{event.anchor} inside its own anchor (a "
                             "recursive structure)")
            node = super().compose_node(parent, index)  # an undefined alias fails here
            self._repeated += self._size[id(node)]
            if self._repeated > MAX_ALIAS_NODES:
                self._refuse(event, f"the aliases repeat more than {MAX_ALIAS_NODES} nodes "
                             "(an alias bomb?)")
            self._count(event, self._size[id(node)])
            return node
        self._depth += 1
        if self._depth > MAX_YAML_DEPTH:
            self._refuse(event, f"nested deeper than {MAX_YAML_DEPTH} levels")
        anchor = getattr(event, "anchor", None)
        if anchor is not None:
            self._open.add(anchor)
        node = super().compose_node(parent, index)
        self._open.discard(anchor)
        self._depth -= 1
        children = (node.value if isinstance(node, yaml.SequenceNode) else
                    [n for pair in node.value for n in pair]
                    if isinstance(node, yaml.MappingNode) else [])
        self._size[id(node)] = 1 + sum(self._size[id(c)] for c in children)
        self._count(event, 1)
        return node

    def _count(self, event, nodes: int) -> None:
        self._nodes += nodes
        if self._nodes > MAX_YAML_NODES:
            self._refuse(event, f"more than {MAX_YAML_NODES} YAML nodes")


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


_ConfigLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _unique_mapping)


def load(path: str | Path, precision: str | None = None,
         part: str | None = None) -> ControllerConfig:
    """Read and validate a YAML file; ``precision`` overrides the file's setting, ``part``
    (``--part``) replaces its target: section by that part's own (its figures were for
    another part)."""
    path = Path(path)
    raw = read_bounded(path)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(str(path), f"not UTF-8 text (byte {exc.start})") from None
    try:
        data = yaml.load(text, Loader=_ConfigLoader)  # noqa: S506 (a SafeLoader)
    except yaml.YAMLError as exc:
        raise ConfigError(*_yaml_problem(exc)) from None
    if data is None:
        raise ConfigError("<top>", "the file is empty")
    if precision is not None:
        if precision not in PRECISIONS:
            raise ConfigError("precision", f"must be one of {', '.join(PRECISIONS)}")
        if isinstance(data, dict):
            data = dict(data, precision=precision)
    if part is not None:
        part_target(part, "--part")  # an unknown part names the option, not the file's key
        if isinstance(data, dict):
            data = dict(data, target={"part": part})
    return parse(data)


def read_bounded(path: Path) -> bytes:
    """The file's bytes, refused beyond MAX_CONFIG_BYTES.  Opened without blocking, so a
    FIFO without a writer reads as empty instead of waiting for one; then read with a
    limit, so /dev/zero or a growing file cannot exhaust the memory."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        try:
            os.set_blocking(fd, True)  # a FIFO with a writer: wait for its data
            with os.fdopen(fd, "rb", closefd=False) as stream:
                raw = stream.read(MAX_CONFIG_BYTES + 1)
        finally:
            os.close(fd)
    except OSError as exc:
        raise ConfigError(str(path), f"cannot read: {exc.strerror}") from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError(str(path), f"larger than {MAX_CONFIG_BYTES} bytes (the limit "
                          "of a configuration file)")
    return raw
