"""The sizes of each mode's QP and of the generated C, predicted from the configuration alone.

``build_model`` checks them before any maths: a ``horizon: 10000`` without output bounds
once condensed a 10,000-variable QP for minutes before anything was refused.  The
prediction needs no plant maths: n = N nu (or blocks * nu), m counts the finite bounds
(config/checks.py, :func:`qp_rows`), and nx is the plant's order plus its integrators,
disturbance and previous-input states (for a transfer-function matrix an upper bound: the
order before the minimal realisation).

* **stored bytes**: every array of :data:`.arrays.STORED_ARRAYS` (the flash of the data),
  from its declared shape, so it is exact whenever nx is;
* **struct bytes**: the arrays of ``P_ctrl`` (api.h.j2), the RAM of one instance, without
  its scalar members and padding (a lower bound, within about a hundred bytes);
* **condensing bytes**: the dense N x N matrices the offline maths builds, even when move
  blocking keeps n small.

The limits (schema.py) are the safety ones: int16 rows and row quantities (the rows
themselves are checked while parsing, config/checks.py), states whose tests would take
hours, and memory no microcontroller has.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import prod

import numpy as np

from ..config import ConfigError, ControllerConfig, ModeConfig
from ..config.checks import output_rows, qp_rows
from ..config.constraints import signal_row_count
from ..config.schema import (MAX_CONDENSING_BYTES, MAX_ROWS, MAX_STATES, MAX_STORED_BYTES,
                              MAX_STRUCT_BYTES)
from .arrays import REAL, declared_for
from .work import ADD_BATCH

C_TYPE_BYTES = {"int16_t": 2, "int8_t": 1}  # the integer element types of stored arrays


@dataclass(frozen=True)
class ModeSizes:
    """One mode's sizes, named as :class:`.storage.ModeData` names them (so that a
    StoredArray's declared shape can be evaluated on it)."""

    N: int
    nx: int
    nu: int
    ny: int
    n: int  # decision variables
    m: int  # constraint rows
    m_box: int  # rows that are not output rows (input and Δu bounds)
    nt: int  # terminal rows of the E split: ny when P is positive definite
    w_cap: int  # working-set capacity: n + soft (output, stage) pairs
    has_output_rows: bool
    ny_pred: int  # outputs predicted on line: those with constraint rows
    # general constraints (features/signals.py); an LQR-invariant terminal set's facets
    # are known only once it is computed, and left out
    nzq: int = 0
    nsig: int = 0
    nsig_live: int = 0
    z_pred_ops: int = 0
    has_signal_reference: bool = False
    has_soft_signal_rows: bool = False

    @property
    def n_yq(self) -> int:
        return self.N * self.ny

    @property
    def has_signal_rows(self) -> bool:
        return self.nzq > 0

    @property
    def has_output_and_signal_rows(self) -> bool:
        return self.has_output_rows and self.has_signal_rows


def plant_order(mode: ModeConfig, ny: int) -> int:
    """States of the realised plant with its ``ny`` integrators (an upper bound for a
    transfer-function matrix, whose minimal realisation may drop some)."""
    plant = mode.plant
    if plant.kind == "state_space":
        order = plant.A.shape[0]
    elif plant.tf_matrix is not None:
        order = sum(len(den) - 1 for row in plant.tf_matrix for _, den in row)
    else:
        order = len(plant.den) - 1
    return order + (ny if plant.integrator else 0)


def mode_sizes(cfg: ControllerConfig, mode: ModeConfig) -> ModeSizes:
    nu, ny, N = len(mode.actuators), cfg.n_outputs, cfg.horizon
    nd = {"none": 0, "input": nu, "output": ny}[mode.disturbance]
    n_prev = nu if mode.R_delta is not None or mode.has_rate_bounds else 0
    n = (N if mode.blocks is None else len(mode.blocks)) * nu
    bounded = np.isfinite(mode.y_min) | np.isfinite(mode.y_max)
    soft = (0 if mode.soft_l2 is None else
            N * int(np.sum(np.any(mode.soft_l2 > 0.0, axis=1) & bounded)))
    m = qp_rows(N, mode)
    sig = signal_sizes(mode, N, nu, plant_order(mode, ny))
    return ModeSizes(N=N, nx=plant_order(mode, ny) + nd + n_prev, nu=nu, ny=ny, n=n,
                     m=m + sig.pop("terminal_rows"), m_box=m - output_rows(N, mode)
                     - signal_row_count(mode.signals),
                     nt=ny if np.linalg.eigvalsh(mode.P).min() > 0 else 0,
                     w_cap=n + soft + sig.pop("soft_quantities"),
                     has_output_rows=bool(np.any(bounded)),
                     ny_pred=int(np.sum(bounded)), **sig)


def signal_sizes(mode: ModeConfig, N: int, nu: int, nxp: int) -> dict:
    """The signal block's sizes (features/signals.py), from the config: every constrained
    signal's times, and a terminal polytope's or equality's facets (an LQR-invariant
    set's are unknown before it is computed: none counted)."""
    times = [(s.first, s.last, bool(np.any(s.D)), bool(np.any(s.soft_l2 > 0)))
             for s in mode.signals]
    t, terminal_rows = mode.terminal, 0
    if t is not None and t.kind != "lqr_invariant":
        facets = nxp if t.kind == "equality" else t.h.size
        times += [(N, N, False, t.soft_l2 > 0)] * facets
        terminal_rows = facets * (2 if t.kind == "equality" else 1)
    nzq = sum(last - first + 1 for first, last, _, _ in times)
    ops = sum((k + (1 if feed else 0)) * nu for first, last, feed, _ in times
              for k in range(first, last + 1))
    return {"nzq": nzq, "nsig": len(times), "nsig_live": len(mode.signals), "z_pred_ops": ops,
            "has_signal_reference": t is not None,
            "has_soft_signal_rows": any(soft for *_, soft in times),
            "terminal_rows": terminal_rows,
            "soft_quantities": sum(last - first + 1 for first, last, _, soft in times if soft)}


def features_of(cfg: ControllerConfig) -> dict:
    """The top-level context flags that decide which arrays exist (codegen/context.py)."""
    signal_soft = any(np.any(s.soft_l2 > 0) for m in cfg.modes for s in m.signals) or any(
        m.terminal is not None and m.terminal.soft_l2 > 0 for m in cfg.modes)
    return {"move_blocking": any(m.blocks is not None for m in cfg.modes),
            "has_soft_rows": any(m.soft_l2 is not None for m in cfg.modes) or signal_soft,
            "has_signal_rows": any(m.signals or m.terminal is not None for m in cfg.modes),
            "has_signal_reference": any(m.terminal is not None for m in cfg.modes),
            "has_soft_signal_rows": signal_soft}


def working_set_lengths(w: int) -> dict[str, int]:
    """Lengths of P_work's working-set arrays (api.h.j2) for a capacity of ``w`` rows,
    declared once for the C (codegen/context.py) and the RAM figure (:func:`struct_bytes`).

    * ``tmp``: at least ADD_BATCH, the rows most_violated() ranks in it (a shorter list
      overflowed at run time: fw_lateral at horizon 1, w = 3, crashed the float check).
    * ``wset`` at least 2 rows and ``chol`` (the packed factor of w rows) at least 2
      entries: gcc cannot see that the working set stays within md->w_cap (data), so at
      w = 1 it takes free_multipliers()' read of wset[a + 1] and factor_append()'s loop
      over row nw (both dead code there) for accesses past a 1-element array and refuses
      them (-Warray-bounds at -O2). A second element keeps them inside the array; ``chol``
      takes three, the packed factor of two rows, for factor_working_set()'s column loop
      (gcc 12 reads its chol(1, 1) at w = 1 the same way).
    """
    return {"wset": max(w, 2), "tmp": max(w, ADD_BATCH), "chol": max(w * (w + 1) // 2, 3)}


def real_bytes(precision: str) -> int:
    return 4 if precision == "float" else 8


def stored_bytes(cfg: ControllerConfig, sizes: tuple[ModeSizes, ...],
                 precision: str | None = None) -> int:
    """Bytes of every mode's stored arrays (the generated data, in flash), in ``precision``
    (default: the config's)."""
    real = real_bytes(precision or cfg.precision)
    _, arrays = declared_for(features_of(cfg))
    return sum(prod(a.shape(s)) * (real if a.ctype == REAL else C_TYPE_BYTES[a.ctype])
               for s in sizes for a in arrays if a.exists_in(s))


def struct_bytes(cfg: ControllerConfig, sizes: tuple[ModeSizes, ...],
                 precision: str | None = None) -> int:
    """Bytes of the arrays of one P_ctrl instance (api.h.j2), a lower bound of its size,
    in ``precision`` (default: the config's)."""
    real = real_bytes(precision or cfg.precision)
    top = {name: max(getattr(s, name) for s in sizes)
           for name in ("nx", "nu", "n", "m", "n_yq", "w_cap", "nzq")}
    nx, n, m, nyq, w = top["nx"], top["n"], top["m"], top["n_yq"], top["w_cap"]
    nt = max(1, max(s.nt for s in sizes))
    k, ny = len(cfg.modes), cfg.n_outputs
    lengths = working_set_lengths(w)
    reals = (2 * n + 2 * nyq + 2 * m + 3 * w + lengths["chol"] + max(nt * n, w)
             + nt * (nt + 1) // 2
             + nt + nx + ny  # the work arrays
             + k * (nx + m) + len(cfg.actuators) + n  # xhat, lam, u_last, U
             + 2 * top["nzq"])  # the signals' prediction and free response
    if cfg.runtime_bounds:  # the live bounds of every mode, and the solver's copy
        live = max(s.nsig_live for s in sizes)
        reals += (k + 1) * 2 * (top["nu"] + ny + (max(live, 1) if top["nzq"] else 0))
    # run and set (one union), wset, tmp, the primal factor's rows, plan_mode and plan_age
    int16s = max(cfg.horizon + 1, m) + lengths["wset"] + lengths["tmp"] + n + 2
    bytes_ = m + n + (m if features_of(cfg)["has_soft_rows"] else 0)
    return reals * real + int16s * 2 + bytes_


def condensing_bytes(s: ModeSizes) -> int:
    """Bytes of the dense Omega, Psi and Gamma that condense() builds for a mode."""
    stages_y, stages_u = s.N * s.ny, s.N * s.nu
    return 8 * (stages_y * stages_y + stages_u * stages_u + stages_y * stages_u)


def check_sizes(cfg: ControllerConfig) -> None:
    """Refuse, before any maths, a controller beyond the limits of schema.py."""
    sizes = tuple(mode_sizes(cfg, m) for m in cfg.modes)
    for i, (s, mode) in enumerate(zip(sizes, cfg.modes)):
        if s.nx > MAX_STATES:
            raise ConfigError(f"modes[{i}].plant", f"its prediction model would have up to "
                              f"{s.nx} states; at most {MAX_STATES} supported")
        # the C's int16 row quantities: U, then N ny outputs, then n Δu differences
        # (signals after the Δu quantities' place, whether the mode has Δu rows or not)
        quantities = s.n + s.n_yq + (s.n if mode.has_rate_bounds or s.nzq else 0) + s.nzq
        if quantities > MAX_ROWS:
            raise ConfigError("horizon", f"too long: modes[{i}] would have {quantities} row "
                              f"quantities (n + N ny, plus n with Δu bounds, plus the "
                              f"signals'); at most {MAX_ROWS} supported")
        if condensing_bytes(s) > MAX_CONDENSING_BYTES:
            raise ConfigError("horizon", f"too long: condensing modes[{i}] would need "
                              f"{condensing_bytes(s):,} bytes of dense N x N matrices; at "
                              f"most {MAX_CONDENSING_BYTES:,} supported")
    for what, size, limit in (("stored data", stored_bytes(cfg, sizes), MAX_STORED_BYTES),
                              ("controller instance", struct_bytes(cfg, sizes),
                               MAX_STRUCT_BYTES)):
        if size > limit:
            raise ConfigError("horizon", f"too long: the {what} would take {size:,} bytes "
                              f"({largest_mode(sizes)}); at most {limit:,} supported")


def largest_mode(sizes: tuple[ModeSizes, ...]) -> str:
    """``modes[j]: n = .. variables, m = .. rows`` of the mode with the largest QP."""
    j = max(range(len(sizes)), key=lambda i: sizes[i].n * sizes[i].m)
    return f"modes[{j}]: n = {sizes[j].n} variables, m = {sizes[j].m} rows"
