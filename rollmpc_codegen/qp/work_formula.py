"""One declaration per work formula, called by Python with numbers and rendered into C.

A formula of :mod:`.work` is a plain Python function decorated with :func:`formula`.
Called with numbers it computes (the reference and the generator call it).  Called by
:func:`traced` with symbols, the same body records its operations instead: the expression
tree that ``templates/solver/work_formula.c.j2`` prints as the C function of that name.
So the C and the Python count work with one set of formulas, in the same order of
operations (the C on ``uint32_t``: the generator keeps every bound below 2**31).

A body may use ``+ - * //`` on its arguments and on ints, call other formulas, and for
what Python would branch on: :func:`smaller`, :func:`larger`, :func:`either` (a flag),
:func:`summed` (a loop) and :func:`named` (a C local, for the reader of the C).
"""
from __future__ import annotations

import functools
import inspect
from typing import Callable, NamedTuple

# ModeData's names of the sizes the formulas read -> P_mode_data's
_C_SIZE_NAMES = {"n_yq": "nyq"}
_PRECEDENCE = {"*": 3, "//": 3, "+": 2, "-": 2}
_C_OPERATOR = {"//": "/"}
_LOCALS: list[list] = []  # the locals of the formula being traced


class Formula(NamedTuple):
    fn: Callable
    params: tuple  # (name, kind): "md" (the mode data), "int", "uint" or "design"
    design: dict  # design parameter -> its key in the context's solver dict (a C literal)


FORMULAS: dict[str, Formula] = {}


class Sym:
    """An operand while a formula is traced: arithmetic on it builds the tree."""

    __slots__ = ("node",)

    def __init__(self, node: tuple):
        self.node = node

    def __bool__(self):
        raise TypeError("a traced work formula cannot branch in Python: use smaller(), "
                        "larger() or either()")

    def _op(self, op, other, reflected=False):
        # a size the design lacks reads 0 (traced(absent=...)): fold it away, so the C of
        # a design without that feature is the formula's text before the feature
        if isinstance(other, int) and not isinstance(other, bool):
            if other == 0 and (op == "+" or (op == "-" and not reflected)):
                return self
            if other == 0 and op == "*":
                return 0
        a, b = (_node(other), self.node) if reflected else (self.node, _node(other))
        return Sym(("bin", op, a, b))

    def __add__(self, o): return self._op("+", o)
    def __radd__(self, o): return self._op("+", o, True)
    def __sub__(self, o): return self._op("-", o)
    def __rsub__(self, o): return self._op("-", o, True)
    def __mul__(self, o): return self._op("*", o)
    def __rmul__(self, o): return self._op("*", o, True)
    def __floordiv__(self, o): return self._op("//", o)
    def __rfloordiv__(self, o): return self._op("//", o, True)


class _Mode:
    """The mode data while a formula is traced: each size read is md->size, but the sizes
    ``absent`` from the design's P_mode_data (a feature it lacks), which read 0."""

    def __init__(self, absent: frozenset = frozenset()):
        self._absent = absent

    def __getattr__(self, name):
        if name in self._absent:
            return 0
        return Sym(("size", _C_SIZE_NAMES.get(name, name)))


def _node(v) -> tuple:
    return v.node if isinstance(v, Sym) else ("lit", int(v))


def _symbolic(*values) -> bool:
    return any(isinstance(v, (Sym, _Mode)) for v in values)


def formula(uint: tuple = (), design: dict | None = None):
    """Declare a work formula (its C parameters are ints, but those in ``uint``; the mode
    data is ``m``; a ``design`` parameter is the C literal of that context key)."""
    design = design or {}

    def declare(fn):
        sig = inspect.signature(fn)
        params = tuple((p, "md" if p == "m" else "design" if p in design
                        else "uint" if p in uint else "int") for p in sig.parameters)
        FORMULAS[fn.__name__] = Formula(fn, params, design)

        @functools.wraps(fn)
        def call(*args, **kwargs):
            if not _symbolic(*args, *kwargs.values()):
                return fn(*args, **kwargs)
            bound = sig.bind(*args, **kwargs)
            bound.apply_defaults()
            return Sym(("call", fn.__name__, tuple(bound.arguments.values())))
        return call
    return declare


def smaller(a, b):
    """min(a, b); in C ``(a < b) ? a : b``."""
    return Sym(("cond", ("cmp", "<", _node(a), _node(b)), _node(a), _node(b))) \
        if _symbolic(a, b) else min(a, b)


def larger(a, b):
    """max(a, b); in C ``(a > b) ? a : b``."""
    return Sym(("cond", ("cmp", ">", _node(a), _node(b)), _node(a), _node(b))) \
        if _symbolic(a, b) else max(a, b)


def either(flag, a, b):
    """``a if flag else b``; in C ``flag ? a : b``."""
    return Sym(("cond", _node(flag), _node(a), _node(b))) if _symbolic(flag, a, b) else (
        a if flag else b)


def summed(count, term: Callable):
    """sum(term(k) for k in range(count)); in C a loop over k."""
    if not _symbolic(count):
        return sum(term(k) for k in range(count))
    return Sym(("sum", _node(count), _node(term(Sym(("param", "k", "int"))))))


def named(name: str, value):
    """``value``; in C the local ``const uint32_t name``."""
    if not _symbolic(value):
        return value
    _LOCALS[-1].append((name, _node(value)))
    return Sym(("local", name))


def traced(name: str, absent: frozenset = frozenset()) -> dict:
    """Formula ``name`` as the template prints it: signature, doc, locals and result, each
    expression typed (``uint32_t`` or ``int``, with the casts C needs) and parenthesised;
    the mode sizes ``absent`` from the design's P_mode_data read 0."""
    f = FORMULAS[name]
    args = [_Mode(absent) if kind == "md" else Sym(("design", f.design[p])) if kind == "design"
            else Sym(("param", p, kind)) for p, kind in f.params]
    _LOCALS.append([])
    try:
        result = _node(f.fn(*args))
    finally:
        local_nodes = _LOCALS.pop()
    out = {"name": name, "doc": " ".join(inspect.getdoc(f.fn).split()).replace("``", "`"),
           "params": [{"name": p, "kind": kind} for p, kind in f.params if kind != "design"],
           "locals": [{"name": n, "value": _typed(v, "uint")} for n, v in local_nodes]}
    if result[0] == "sum":
        return out | {"loop": {"count": _typed(result[1], "int"),
                               "term": _typed(result[2], "uint")}}
    return out | {"result": _typed(result, "uint")}


def _typed(node: tuple, ctype: str, paren: bool = False) -> dict:
    """The node as C of type ``ctype`` ("uint", "int", or "flag": a truth value)."""
    kind = node[0]
    if kind == "lit":
        return {"kind": "lit", "value": node[1], "unsigned": ctype == "uint"}
    if kind in ("size", "param", "local"):
        var_type = "uint" if kind == "local" or (kind == "param" and node[2] == "uint") else "int"
        if var_type == "uint" and ctype != "uint":
            raise TypeError(f"{node[1]} is unsigned where C needs an int")
        return {"kind": kind, "name": node[1], "cast": var_type == "int" and ctype == "uint"}
    if kind == "design":
        if ctype != "uint":
            raise TypeError(f"design constant {node[1]} where C needs an int")
        return {"kind": "design", "name": node[1]}
    if kind == "bin":
        op, left, right = node[1:]
        prec = _PRECEDENCE[op]
        return {"kind": "bin", "op": _C_OPERATOR.get(op, op), "paren": paren,
                "left": _typed(left, ctype, _binds_looser(left, prec, False)),
                "right": _typed(right, ctype, _binds_looser(right, prec, True))}
    if kind == "cond":
        test = node[1]
        typed_test = ({"kind": "cmp", "op": test[1], "left": _typed(test[2], ctype),
                       "right": _typed(test[3], ctype)} if test[0] == "cmp"
                      else _typed(test, "flag"))
        return {"kind": "cond", "test": typed_test, "paren": paren,
                "then": _typed(node[2], ctype), "other": _typed(node[3], ctype)}
    if kind == "call":
        if ctype != "uint":
            raise TypeError(f"{node[1]}() returns uint32_t where C needs an int")
        params = FORMULAS[node[1]].params
        return {"kind": "call", "name": node[1],
                "args": [{"kind": "md"} if k == "md" else _typed(_node(a), k)
                         for (_, k), a in zip(params, node[2]) if k != "design"]}
    raise TypeError(f"a {kind} cannot appear inside a work formula's expression")


def _binds_looser(node: tuple, prec: int, right: bool) -> bool:
    """Does the operand need parentheses under an operator of precedence ``prec``?"""
    if node[0] == "cond":
        return True
    if node[0] != "bin":
        return False
    inner = _PRECEDENCE[node[1]]
    return inner < prec or (right and inner == prec)
