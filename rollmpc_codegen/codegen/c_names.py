"""Generated identifiers against the names of the C, POSIX and newlib libraries.

A firmware build may see any system header (a unity build, a forced include, NuttX or
PX4 headers), so no identifier of the generated C may be one of theirs: ``static int
accept(...)`` stopped every tree that saw <sys/socket.h>, and a prefix ``aio`` defined
``aio_init``, glibc's.  The names are a data file (:data:`LIBRARY_NAMES_FILE`, written by
``python -m rollmpc_codegen.verify.c_library_names`` from this host's glibc and newlib).

* :func:`prefix_collisions`: the library names a prefix would define, read from the
  templates' ``{{ prefix }}_...`` and ``{{ PREFIX }}_...`` identifiers (the config refuses
  such a prefix, naming the key);
* :func:`source_collisions`: the library names a rendered source uses other than
  :data:`USED_LIBRARY_NAMES` (the tests hold every tree to none).
"""
from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

from ..status import Status
from .templates import templates_dir

LIBRARY_NAMES_FILE = Path(__file__).with_name("c_library_names.txt")
# what the generated C takes from the library on purpose: <stddef.h>, <stdint.h>, <math.h>
USED_LIBRARY_NAMES = frozenset((
    "NULL", "size_t", "int8_t", "int16_t", "int64_t", "uint8_t", "uint32_t", "sqrt", "sqrtf",
    "fabs", "fabsf", "isfinite", "isnan", "HUGE_VAL", "HUGE_VALF"))
# the C89/C99 keywords (the generated C's own words); C23's new ones are library names
C99_KEYWORDS = frozenset((
    "auto", "break", "case", "char", "const", "continue", "default", "do", "double", "else",
    "enum", "extern", "float", "for", "goto", "if", "inline", "int", "long", "register",
    "restrict", "return", "short", "signed", "sizeof", "static", "struct", "switch",
    "typedef", "union", "unsigned", "void", "volatile", "while"))
C23_KEYWORDS = ("alignas", "alignof", "bool", "constexpr", "false", "nullptr", "static_assert",
                "thread_local", "true", "typeof", "typeof_unqual")
# {{ prefix }}_tail or {{ PREFIX }}_TAIL, a tail of word characters and {{ expressions }}
# (not a file name: P_data.c names no identifier)
_PREFIXED = re.compile(r"\{\{ (prefix|PREFIX) \}\}_((?:\w|\{\{.*?\}\})+)(?!\w|\{\{|\.(?:[ch]|json)\b)")
# what an expression inside a prefixed identifier renders (else its string literals, else
# any word): a status name, a mode's number
_RENDERS = {"status.name": "(?:" + "|".join(s.name for s in Status) + ")", "j": r"\d+"}


@lru_cache(maxsize=1)
def library_names() -> frozenset[str]:
    lines = LIBRARY_NAMES_FILE.read_text(encoding="ascii").splitlines()
    return frozenset(line for line in lines if line and not line.startswith("#"))


def _tail_pattern(tail: str) -> str:
    """A regex for what a template's identifier tail renders to."""
    out = []
    for part in re.split(r"(\{\{.*?\}\})", tail):
        if not part.startswith("{{"):
            out.append(re.escape(part))
            continue
        expr = part[2:-2].strip()
        literals = re.findall(r'"(\w+)"', expr)
        out.append(_RENDERS.get(expr) or ("(?:" + "|".join(literals) + ")" if literals
                                          else r"\w+"))
    return "".join(out)


@lru_cache(maxsize=1)
def _generated_tails() -> dict[str, re.Pattern]:
    """{"prefix": the lower-case tails, "PREFIX": the upper-case ones}, from every template."""
    tails: dict[str, set[str]] = {"prefix": set(), "PREFIX": set()}
    for path in sorted(templates_dir().rglob("*.j2")):
        for case, tail in _PREFIXED.findall(path.read_text(encoding="utf-8")):
            tails[case].add(_tail_pattern(tail))
    return {case: re.compile("|".join(sorted(found))) for case, found in tails.items()}


def prefix_collisions(prefix: str) -> list[str]:
    """The library names, sorted, that the generated C of ``prefix`` would define."""
    tails = _generated_tails()
    hits = []
    for name in library_names():
        for case, start in (("prefix", prefix + "_"), ("PREFIX", prefix.upper() + "_")):
            if name.startswith(start) and tails[case].fullmatch(name[len(start):]):
                hits.append(name)
    return sorted(hits)


def c_identifiers(source: str) -> set[str]:
    """The identifiers of a C text outside comments, strings, #include lines and the
    directives' own names (#error, #define ...)."""
    text = re.sub(r"/\*.*?\*/|//[^\n]*", " ", source, flags=re.S)
    text = re.sub(r'"(?:\\.|[^"\\\n])*"|\'(?:\\.|[^\'\\\n])*\'', " ", text)
    text = re.sub(r"^\s*#\s*include[^\n]*", " ", text, flags=re.M)
    text = re.sub(r"^\s*#\s*\w+", " ", text, flags=re.M)
    return set(re.findall(r"\b[A-Za-z_]\w*", text))


def source_collisions(source: str) -> list[str]:
    """The library names a generated source uses, beyond :data:`USED_LIBRARY_NAMES`."""
    return sorted((c_identifiers(source) & library_names()) - USED_LIBRARY_NAMES)
