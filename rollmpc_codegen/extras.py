"""The optional dependencies (pyproject's extras: plot, peers, target): tell whether one is
installed, and fail before any work, in one line, when a run needs a missing one."""
from __future__ import annotations

import importlib.util


def installed(module: str) -> bool:
    return importlib.util.find_spec(module) is not None


def require_module(module: str, extra: str, what: str) -> None:
    """Raise RuntimeError (the CLI: one line, exit 1) when ``module`` is missing."""
    if not installed(module):
        raise RuntimeError(f"{what} needs {module}: pip install 'rollmpc-codegen[{extra}]'")
