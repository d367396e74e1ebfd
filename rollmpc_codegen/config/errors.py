"""The one exception of a bad configuration, importable without the parsers.

Later stages and features (move_blocking.py, model/, qp/) raise it too, and the parsers
import some of them: this module imports nothing, so that raising needs no parser.
"""
from __future__ import annotations

# The most characters of a key and of a problem that are printed: a value echoed in a
# problem can be anything the YAML held (a hostile file once made a 522 MB error line).
ECHO_MAX = 400


def bounded(text: str, limit: int = ECHO_MAX) -> str:
    """``text`` on one line, its middle elided beyond ``limit`` characters (the start
    says what is wrong, the end often says what is allowed)."""
    text = " ".join(str(text).splitlines())
    if len(text) <= limit:
        return text
    cut = f" ... [{len(text) - limit} characters] ... "
    head = (limit - len(cut)) * 2 // 3
    return text[:head] + cut + text[len(text) - (limit - len(cut) - head):]


class ConfigError(ValueError):
    """A configuration problem, reported as one line: ``<key>: <problem>``."""

    def __init__(self, key: str, problem: str):
        # the CLI promises exactly one short line on stderr, whatever the YAML text held
        key, problem = bounded(key), bounded(problem)
        super().__init__(f"{key}: {problem}")
        self.key = key
        self.problem = problem
