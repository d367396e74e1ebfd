"""The one exception of a bad configuration, importable without the parsers.

Later stages and features (move_blocking.py, model/, qp/) raise it too, and the parsers
import some of them: this module imports nothing, so that raising needs no parser.
"""
from __future__ import annotations


class ConfigError(ValueError):
    """A configuration problem, reported as one line: ``<key>: <problem>``."""

    def __init__(self, key: str, problem: str):
        # the CLI promises exactly one line on stderr, whatever the YAML text contained
        key, problem = (" ".join(str(t).splitlines()) for t in (key, problem))
        super().__init__(f"{key}: {problem}")
        self.key = key
        self.problem = problem
