"""The one warning type of every front end: what ``generate``, ``simulate`` and ``report``
print as ``rollmpc: warning: ...`` is a :class:`DesignWarning` first (docs/checks.md).

A bad configuration is a ConfigError (errors.py): one line naming the key, nothing
written.  A design that generates but that a control engineer would question (a sample
time the plant outruns, a bound no input meets, a loop that diverges where no bound is
active, a budget beyond the sample period, ...) is a DesignWarning: the same line, with
a stable ``code`` to filter on and the ``key`` to change.  The library functions return
them as data (``.warnings`` of their results); the CLI prints them; the Python API
(api.py) also hands them to Python's :mod:`warnings` as :class:`RollmpcWarning`.

Like errors.py, this module imports nothing of the package: every stage may raise one.
"""
from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass


class RollmpcWarning(UserWarning):
    """The category the Python API warns with (``warnings.simplefilter("error",
    RollmpcWarning)`` turns every design warning into an exception)."""


@dataclass(frozen=True)
class DesignWarning:
    """One warning: ``code`` (stable, snake_case; docs/checks.md lists them), ``key``
    (the configuration key to change, "" when none is one) and the one-line
    ``message`` the CLI prints after ``rollmpc: warning:``."""

    code: str
    key: str
    message: str

    def __str__(self) -> str:
        return self.message

    def as_dict(self) -> dict:
        return asdict(self)


def messages(found: list[DesignWarning]) -> list[str]:
    """The lines of ``found``, e.g. for a JSON document."""
    return [w.message for w in found]


def emit(found: list[DesignWarning], stacklevel: int = 3) -> None:
    """Hand each warning to Python's :mod:`warnings` (category RollmpcWarning); by default
    attributed to the caller of the API method that calls this."""
    for w in found:
        warnings.warn(f"{w.message} [{w.code}]", RollmpcWarning, stacklevel=stacklevel)
