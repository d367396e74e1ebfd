"""``modes[].plant``: a transfer function (SISO or a matrix) or a state-space model."""
from __future__ import annotations

from typing import Any

import numpy as np

from .errors import ConfigError
from .reader import Reader, check_length, read_matrix, read_vector
from .schema import STATE_SPACE_KEYS, TRANSFER_FUNCTION_KEYS, PlantConfig


def _is_rows(value: Any) -> bool:
    """A non-empty list of lists: the matrix form of a transfer function."""
    return isinstance(value, list) and bool(value) and all(isinstance(v, list) for v in value)


def _tf_element(num_raw: Any, den_raw: Any, knum: str, kden: str, integrator: bool,
                allow_zero: bool) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """One transfer function num/den (coefficients, highest power first), checked."""
    num = np.trim_zeros(read_vector(num_raw, knum), "f")
    den = np.trim_zeros(read_vector(den_raw, kden), "f")
    if den.size == 0:
        raise ConfigError(kden, "must not be all zeros")
    if num.size == 0:
        if allow_zero:  # a zero element of a matrix: no coupling
            return (0.0,), tuple(den)
        raise ConfigError(knum, "must not be all zeros")
    if num.size > den.size:
        raise ConfigError(knum, "improper transfer function (deg num > deg den)")
    if num.size == den.size and not integrator:
        raise ConfigError(knum, "transfer function has feedthrough; MPC needs a "
                          "strictly proper plant (deg num < deg den) or integrator: true")
    if den.size < 2 and not integrator:
        raise ConfigError(kden, "a static gain has no state; use integrator: true")
    return tuple(num), tuple(den)


def _tf_matrix(tf: Reader, integrator: bool):
    """``num``: rows (outputs) of elements (inputs), each a coefficient list or a number;
    ``den``: the same shape, or one coefficient list shared by every element."""
    num_rows, den_raw = tf.raw("num"), tf.raw("den")
    knum, kden = tf.key("num"), tf.key("den")
    check_length(num_rows, knum)
    check_length(num_rows[0], f"{knum}[0]")
    width = len(num_rows[0])
    for i, row in enumerate(num_rows):
        if len(row) != width or not row:
            raise ConfigError(f"{knum}[{i}]", f"has {len(row)} elements where {knum}[0] has "
                              f"{width}: every row needs one per input")
    common = not _is_rows(den_raw)
    if not common and (len(den_raw) != len(num_rows)
                       or any(not isinstance(row, list) or len(row) != width
                              for row in den_raw)):
        raise ConfigError(kden, f"must have the shape of num ({len(num_rows)}x{width}) or be "
                          "one coefficient list (a common denominator)")
    matrix = []
    for i, row in enumerate(num_rows):
        matrix.append(tuple(
            _tf_element(n, den_raw if common else den_raw[i][j], f"{knum}[{i}][{j}]",
                        kden if common else f"{kden}[{i}][{j}]", integrator, allow_zero=True)
            for j, n in enumerate(row)))
    if all(n == (0.0,) for row in matrix for n, _ in row):
        raise ConfigError(knum, "must not be all zeros")
    return tuple(matrix)


def parse_plant(r: Reader) -> PlantConfig:
    """``modes[].plant``: exactly one of ``transfer_function`` and ``state_space``."""
    kinds = [k for k in ("transfer_function", "state_space") if r.has(k)]
    if len(kinds) != 1:
        raise ConfigError(r.path, "give exactly one of transfer_function or state_space")
    integrator = r.boolean("integrator", PlantConfig.integrator)
    if kinds[0] == "transfer_function":
        tf = r.sub("transfer_function", TRANSFER_FUNCTION_KEYS)
        if _is_rows(tf.raw("num")):  # the matrix form: one row per output
            matrix = _tf_matrix(tf, integrator)
            return PlantConfig(kind="transfer_function", tf_matrix=matrix,
                               integrator=integrator)
        num, den = _tf_element(tf.raw("num"), tf.raw("den"), tf.key("num"), tf.key("den"),
                               integrator, allow_zero=False)
        return PlantConfig(kind="transfer_function", num=num, den=den, integrator=integrator)
    ss = r.sub("state_space", STATE_SPACE_KEYS)
    A = read_matrix(ss.raw("A"), ss.key("A"))
    nx = A.shape[0]
    if A.shape != (nx, nx):
        raise ConfigError(ss.key("A"), "must be square")
    B = read_matrix(ss.raw("B"), ss.key("B"))
    if B.shape[0] != nx:
        raise ConfigError(ss.key("B"), f"must have {nx} rows (the size of A)")
    C = read_matrix(ss.raw("C"), ss.key("C"))
    if C.shape[1] != nx:
        raise ConfigError(ss.key("C"), f"must have {nx} columns (the size of A)")
    D = read_matrix(ss.raw("D", [[0.0] * B.shape[1]] * C.shape[0]), ss.key("D"),
                    shape=(C.shape[0], B.shape[1]))
    if np.any(D != 0) and not integrator:
        raise ConfigError(ss.key("D"), "must be zero: MPC needs a strictly proper plant "
                          "(or integrator: true)")
    discrete = ss.boolean("discrete", PlantConfig.discrete)
    if discrete and integrator:
        raise ConfigError(r.key("integrator"), "only for continuous plants")
    return PlantConfig(kind="state_space", A=A, B=B, C=C, D=D, discrete=discrete,
                       integrator=integrator)

