"""Every size and array the C stores per mode, each declared once.

A :class:`StoredArray` is at the same time a field of :class:`.storage.ModeData`, a key of the
mode in the context JSON and a member of the C struct ``P_mode_data``.  It gives the member's C
element type, its shape in the mode's sizes, when it exists, and the config key that
:func:`rollmpc_codegen.pipeline.build_model` names when it is not finite.  Its shape also
gives the predicted data size (:mod:`.sizes`) before any maths.  From
these declarations, :func:`.codegen.context.build_context` writes the struct members and
each mode's list of defined arrays into the context.  ``internal.h.j2`` renders the struct
from that list.  ``data.c.j2`` renders the definitions and the designated initializers.

To add a stored array, add one record here, then add the maths that computes it (a
ModeData field) and the C that reads it (``md->name``).
"""
from __future__ import annotations

from dataclasses import dataclass
from math import prod
from typing import Callable

import numpy as np

REAL = "real"  # the storage precision: P_real in the C


@dataclass(frozen=True)
class StoredSize:
    """An ``int`` member of ``P_mode_data``: a size of the mode."""

    name: str  # C member and context key
    doc: str
    field: str = ""  # ModeData attribute, when it is named differently
    feature: str | None = None  # top-level context flag the member needs (None: always)

    def of(self, md) -> int:
        return int(getattr(md, self.field or self.name))


@dataclass(frozen=True)
class StoredArray:
    """A ``static const`` array of every mode, pointed to by a ``P_mode_data`` member.

    ``dims`` are products of size names (those of :data:`MODE_SIZES`, and N) and integers,
    e.g. ``("n", "nx")`` or ``("2*ny",)``.  With ``packed`` the array holds the packed lower
    triangle of a dims[0] x dims[0] symmetric matrix.
    """

    name: str  # ModeData field, context key and C member
    ctype: str  # REAL or a C integer type
    dims: tuple[str, ...]
    doc: str
    packed: bool = False
    feature: str | None = None  # top-level context flag the member needs (None: always)
    only_if: str | None = None  # ModeData property; a mode without it stores a null pointer
    # the mode's key build_model names when an entry is not finite in the storage
    # precision (REAL arrays): what the array is computed from
    blame: str = "weights"
    # what a mode without the feature (ModeData field None) stores when another mode has it
    neutral: Callable[[tuple[int, ...]], np.ndarray] = np.zeros

    def shape(self, md) -> tuple[int, ...]:
        sizes = {s.name: s.of(md) for s in MODE_SIZES} | {"N": md.N}

        def extent(dim: str) -> int:
            return prod(int(f) if f.isdigit() else sizes[f] for f in dim.split("*"))

        shape = tuple(extent(d) for d in self.dims)
        return (shape[0] * (shape[0] + 1) // 2,) if self.packed else shape

    def exists_in(self, md) -> bool:
        """The mode defines the array (else its member is a null pointer)."""
        return self.only_if is None or bool(getattr(md, self.only_if))

    def stored(self, md) -> np.ndarray:
        """The values the C stores; a mode without the feature stores the neutral ones."""
        value = getattr(md, self.name)
        return self.neutral(self.shape(md)) if value is None else value

    def describe(self) -> str:
        """The struct member's comment: the shape, then the meaning."""
        shape = f"[{self.dims[0]}({self.dims[0]}+1)/2] packed" if self.packed else \
            "".join(f"[{d}]" for d in self.dims)
        return f"{shape} {self.doc}"


MODE_SIZES = (
    StoredSize("nx", "States (with disturbance and u_prev states)."),
    StoredSize("nu", "Inputs of the mode."),
    StoredSize("ny", "Outputs of the mode."),
    StoredSize("n", "Decision variables (N nu, or blocks * nu)."),
    StoredSize("m", "Constraint rows."),
    StoredSize("nyq", "Predicted outputs N ny.", field="n_yq"),
    StoredSize("nt", "Terminal rows of the E split (0: P stays in S)."),
    StoredSize("m_box", "Rows that are not output rows (input and Δu bounds): the first "
               "m_box of scan_rows."),
    StoredSize("ny_pred", "Outputs predict_outputs() computes: the first ny_pred of "
               "pred_out (those with constraint rows, or all of them)."),
    StoredSize("w_cap", "Working-set capacity: n + soft (output, stage) pairs.",
               feature="has_soft_rows"),
    StoredSize("nzq", "Signal quantities: (signal, time) pairs with rows (0: none).",
               feature="has_signal_rows"),
    StoredSize("nsig", "Constrained signals (general constraints).", feature="has_signal_rows"),
    StoredSize("nsig_live", "The first nsig_live of them take run-time bounds (the constrained "
               "signals and mixed rows; a terminal set's facets are baked in).",
               feature="has_signal_rows"),
    StoredSize("z_pred_ops", "Multiply-adds of predict_signals(): the work it is charged.",
               feature="has_signal_rows"),
)

STORED_ARRAYS = (
    StoredArray("actuator_index", "int16_t", ("nu",), "physical actuator of each mode input."),
    StoredArray("A", REAL, ("nx", "nx"), "discrete state matrix.", blame="plant"),
    StoredArray("B", REAL, ("nx", "nu"), "discrete input matrix.", blame="plant"),
    StoredArray("C", REAL, ("ny", "nx"), "output matrix.", blame="plant"),
    StoredArray("L", REAL, ("nx", "ny"), "observer gain.", blame="observer"),
    StoredArray("innovation_limit", REAL, ("ny",), "observer innovation y - C xhat clipped to "
                "+-this (the largest finite number: clip off).", blame="observer"),
    StoredArray("Kx", REAL, ("n", "nx"), "unconstrained state gain."),
    StoredArray("EinvGt", REAL, ("n", "nyq"), "E^-1 Gamma'."),
    StoredArray("Sinv_p", REAL, ("n",), "S^-1.", packed=True),
    StoredArray("Ew", REAL, ("nt", "n"), "E^-1 = S^-1 - Ew' Ew (Woodbury)."),
    StoredArray("Uv", REAL, ("nt", "n"), "V S^-1."),
    StoredArray("T", REAL, ("nt", "nt"), "(2P)^-1 + V S^-1 V'."),
    StoredArray("S_p", REAL, ("n",), "stage Hessian S (E = S + V'(2P)V).", packed=True),
    StoredArray("V", REAL, ("nt", "n"), "terminal rows of Gamma (nt = 0: none).",
                blame="plant"),
    StoredArray("P2inv", REAL, ("nt", "nt"), "(2P)^-1."),
    StoredArray("GEinvGt_p", REAL, ("nyq",), "Gamma E^-1 Gamma' (null: no output rows).",
                packed=True, only_if="has_output_rows"),
    StoredArray("Omega2", REAL, ("N", "ny", "ny"), "2Q per stage, 2P at the last."),
    StoredArray("Phi", REAL, ("nyq", "nx"), "free response of the predicted outputs.",
                blame="plant"),
    StoredArray("markov_by_output", REAL, ("ny", "N*nu"), "Markov parameters C A^i B by "
                "output, the longest lag first: row a holds (C A^(N-1-j) B)[a, :] from j nu, so "
                "output a of stage s is its last (s+1) nu entries times th's first ones.",
                blame="plant"),
    StoredArray("pred_out", "int16_t", ("ny",), "the predicted outputs, ascending, then the "
                "others."),
    StoredArray("row_q", "int16_t", ("m",), "quantity of each row (U index, n + Y index, "
                "or n + nyq + Δu index)."),
    StoredArray("row_sign", "int8_t", ("m",), "-1 lower / +1 upper bound row."),
    StoredArray("row_c", REAL, ("m",), "constant right-hand side c.", blame="bounds"),
    StoredArray("scan_rows", "int16_t", ("m",), "the rows by kind: the m_box rows that are not "
                "output rows, ascending, then the output rows, ascending (violated_kind())."),
    StoredArray("row_next", "int16_t", ("m",), "same constraint one stage later "
                "(shifted warm start)."),
    StoredArray("colsum", REAL, ("ny", "n"), "sum of the E^-1 Gamma' columns of stages 0..N-2."),
    StoredArray("out_bound", REAL, ("nyq",), "|(Gamma th)_k| <= out_bound[k] max|th|.",
                blame="plant"),
    StoredArray("u_min", REAL, ("nu",), "input lower bounds.", blame="bounds"),
    StoredArray("u_max", REAL, ("nu",), "input upper bounds.", blame="bounds"),
    StoredArray("stage_block", "int16_t", ("N",), "move blocking: the block (of U, n = blocks "
                "* nu) holding each stage.", feature="move_blocking",
                neutral=lambda shape: np.arange(shape[0])),  # unblocked: a block per stage
    StoredArray("soft_l1", REAL, ("2*ny",), "soft bound penalty l1 (index 2 j + side, "
                "side 1 = y_max).", feature="has_soft_rows",
                blame="bounds.soft"),  # neutral: every bound hard
    StoredArray("soft_w", REAL, ("2*ny",), "1/(2 l2) of a soft bound, 0 for a hard one.",
                feature="has_soft_rows", blame="bounds.soft"),
    # general constraints (features/signals.py, qp/signal_storage.py): null without
    StoredArray("z_markov", REAL, ("nsig", "N*nu"), "signal Markov parameters, the longest "
                "lag first (as markov_by_output).", feature="has_signal_rows",
                only_if="has_signal_rows", blame="constraints"),
    StoredArray("z_sig", "int16_t", ("nzq",), "the signal of each signal quantity.",
                feature="has_signal_rows", only_if="has_signal_rows"),
    StoredArray("z_stage", "int16_t", ("nzq",), "its Markov stage (inputs 0..stage reach it).",
                feature="has_signal_rows", only_if="has_signal_rows"),
    StoredArray("Zx", REAL, ("nzq", "nx"), "free response of each signal quantity.",
                feature="has_signal_rows", only_if="has_signal_rows", blame="constraints"),
    StoredArray("Zr", REAL, ("nzq", "ny"), "its reference term on r of its time (terminal "
                "sets).", feature="has_signal_reference", only_if="has_signal_reference",
                blame="constraints.terminal"),
    StoredArray("EinvZt", REAL, ("n", "nzq"), "E^-1 Gz'.", feature="has_signal_rows",
                only_if="has_signal_rows", blame="constraints"),
    StoredArray("ZEinvZt_p", REAL, ("nzq",), "Gz E^-1 Gz'.", packed=True,
                feature="has_signal_rows", only_if="has_signal_rows", blame="constraints"),
    StoredArray("GEinvZt", REAL, ("nyq", "nzq"), "Gamma E^-1 Gz' (null: no output rows).",
                feature="has_signal_rows", only_if="has_output_and_signal_rows",
                blame="constraints"),
    StoredArray("z_bound", REAL, ("nzq",), "|(Gz th)_j| <= z_bound[j] max|th|.",
                feature="has_signal_rows", only_if="has_signal_rows", blame="constraints"),
    StoredArray("z_soft_l1", REAL, ("2*nsig",), "soft signal penalty l1 (index 2 j + side).",
                feature="has_soft_signal_rows", only_if="has_soft_signal_rows",
                blame="constraints"),
    StoredArray("z_soft_w", REAL, ("2*nsig",), "1/(2 l2) of a soft signal bound, 0 for a "
                "hard one.", feature="has_soft_signal_rows", only_if="has_soft_signal_rows",
                blame="constraints"),
)


def declared_for(features: dict) -> tuple[tuple[StoredSize, ...], tuple[StoredArray, ...]]:
    """The sizes and arrays of P_mode_data given the top-level context flags ``features``."""
    def exists(item) -> bool:
        # a flag added later is absent where it would be False (codegen.context.LATER_FEATURES)
        return item.feature is None or bool(features.get(item.feature, False))

    return tuple(filter(exists, MODE_SIZES)), tuple(filter(exists, STORED_ARRAYS))
