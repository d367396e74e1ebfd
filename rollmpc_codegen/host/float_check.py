"""Is float accurate enough for *this* design?  The check ``rollmpc generate`` runs after
writing a float controller (docs/reliability.md, "Float: checked per design").

Float accuracy depends on the design's stored data, not on cond(E) alone (issue 4,
:mod:`rollmpc_codegen.verify.float_floor`), so the check solves the design's own QPs:

1. **Record** the config's scenario on the double build of the same design
   (:func:`~.bench_record.record_qp_sequence`: mode, state estimate and preview of each
   sample).
2. **Select** up to ``scenario_qps`` of those QPs, half evenly spread over the samples
   whose double solution has an active constraint (where float goes wrong most often),
   the rest evenly over the samples with a nonzero state or reference; and
   ``perturbed_qps`` more, a little off the nominal path: evenly chosen ones of those
   with every state entry scaled by 1 + 0.2 z and the preview of each output offset by
   0.2 z max(1, |r|) (z standard normal, seeded).
3. **Solve** each cold on three host builds: the double build (the reference U_d), the
   float build (U_f, what the target computes) and the *floor build*: the double C on the
   float build's stored numbers widened exactly to double, i.e. the stored-data floor of
   :mod:`~rollmpc_codegen.verify.float_floor` (what rounding the data alone costs; the
   double C agrees with that module's reference solver bit for bit).

Errors are ``max|U - U_d| / max(1, max|U_d|)``, the QP campaigns' measure, over the QPs
the double build solves OPTIMAL.  The design is flagged when the float error exceeds
:data:`FLOAT_ERROR_LIMIT` (the campaigns' float bound) or a QP that double solves is not
OPTIMAL in float.  The check informs only: ``rollmpc generate`` has written every file
before it runs, and prints a failure of the check itself as a warning.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..codegen.context import build_context
from ..config import ControllerConfig
from ..config.diagnostics import DesignWarning
from ..model.controller import ControllerModel
from ..pipeline import load_model_from_config
from ..qp.exact import relative_error
from ..status import OPTIMAL, STATUS_NAMES, TIME_LIMIT
from ..target.build import SOFT_DOUBLE_FACTOR
from ..verify.float_floor import widened
from .bench_record import record_qp_sequence
from .build import build_host_controller

FLOAT_ERROR_LIMIT = 1e-3  # relative; the QP campaigns' float bound (docs/reliability.md)
SCENARIO_QPS = 40
PERTURBED_QPS = 8
PERTURBATION = 0.2  # relative size of the perturbed QPs' state scaling and reference offset


@dataclass(frozen=True)
class FloatCheck:
    """What the float check measured.  The errors are maxima over the QPs OPTIMAL in the
    double build and in the build compared (NaN when there is none)."""

    qps: int  # scenario QPs
    perturbed: int  # perturbed QPs
    error: float  # float build against the double build, the whole plan U
    first_move_error: float  # the same, first move only (what the closed loop applies)
    floor: float  # floor build (float-stored numbers, double arithmetic) against double
    float_statuses: dict  # status name -> QPs, float build, every QP
    lost: dict  # float status name -> QPs OPTIMAL in double but not in float
    seconds: float
    worst: str  # the QP of the largest error, e.g. "sample 591 (perturbed), mode lateral"

    @property
    def float_not_optimal(self) -> int:
        """QPs OPTIMAL in double but not in float."""
        return sum(self.lost.values())

    @property
    def lost_to_precision(self) -> int:
        """QPs double solves that float does not, but for TIME_LIMIT: a QP float stops at
        the work budget is the budget's (the time_limit warnings), and double, soft-float
        on the single-precision cores, would stop sooner."""
        return sum(n for name, n in self.lost.items() if name != STATUS_NAMES[TIME_LIMIT])

    @property
    def unsafe(self) -> bool:
        return self.lost_to_precision > 0 or self.error > FLOAT_ERROR_LIMIT  # NaN: none

    def line(self) -> str:
        """The one-line figure ``rollmpc generate`` prints."""
        total = self.qps + self.perturbed
        if total == 0:
            return ("float check: nothing to check (the scenario's states and references "
                    "are all zero)")
        return (f"float check ({self.qps} scenario + {self.perturbed} perturbed QPs, "
                f"{self.seconds:.1f} s): float plans within {self.error:.2g} of double "
                f"(first moves {self.first_move_error:.2g}), stored-data floor "
                f"{self.floor:.2g}, relative to max(1, |U|), limit {FLOAT_ERROR_LIMIT:g}; "
                f"{self.float_not_optimal} of {total} not OPTIMAL in float")

    def warning(self) -> str | None:
        """The warning line for a design float does not serve, else None."""
        if not self.unsafe:
            return None
        what = []
        if self.error > FLOAT_ERROR_LIMIT:
            cause = ("rounding the stored data alone costs" if self.floor > FLOAT_ERROR_LIMIT
                     else "mostly float arithmetic: the stored-data floor is")
            what.append(f"a plan is {self.error:.2g} off double's ({self.worst}; {cause} "
                        f"{self.floor:.2g})")
        if self.lost_to_precision:
            bad = ", ".join(f"{n} {name.upper()}" for name, n in self.lost.items()
                            if name != STATUS_NAMES[TIME_LIMIT])
            what.append(f"{self.lost_to_precision} QPs that double solves are not OPTIMAL "
                        f"in float ({bad})")
        low, high = SOFT_DOUBLE_FACTOR
        return (f"warning: float is not accurate enough for this design: {'; '.join(what)}; "
                "use --precision double (docs/reliability.md, \"Float\"), at a cost on the "
                f"target: the Cortex-M4F computes in single precision only, so double is "
                f"soft-float, {low}-{high} times the float build's cycles (median to worst "
                "step, docs/checks.md); `rollmpc report --precision double` measures it")

    def design_warning(self) -> DesignWarning | None:
        """:meth:`warning` as the DesignWarning ``generate`` returns (None when float
        serves the design)."""
        text = self.warning()
        return None if text is None else DesignWarning(
            "float_inaccurate", "precision", text.removeprefix("warning: "))


def double_twin(cfg: ControllerConfig) -> ControllerConfig:
    """The same design in double (the precision-dependent solver defaults follow)."""
    return dataclasses.replace(cfg, precision="double")


def floor_context(double_model: ControllerModel, float_model: ControllerModel) -> dict:
    """The double build's context with the float build's stored numbers, widened exactly:
    its C solves as ``float_floor.stored_data_floor`` does."""
    modes = tuple(dataclasses.replace(dm, data=widened(fm.data))
                  for dm, fm in zip(double_model.modes, float_model.modes))
    return build_context(dataclasses.replace(double_model, modes=modes))


def _spread(candidates: np.ndarray, count: int) -> np.ndarray:
    """``count`` evenly spaced entries of ``candidates`` (all of them if fewer)."""
    if candidates.size <= count:
        return candidates
    return candidates[np.linspace(0, candidates.size - 1, count).round().astype(int)]


def _select(seq, active: np.ndarray, count: int) -> np.ndarray:
    """Indices of the scenario QPs to check (module docstring, step 2)."""
    moving = np.array([bool(np.any(x) or np.any(r)) for x, r in zip(seq.x, seq.r)], bool)
    constrained = _spread(np.flatnonzero(moving & (active > 0)), count // 2)
    rest = np.setdiff1d(np.flatnonzero(moving), constrained)
    return np.union1d(constrained, _spread(rest, count - constrained.size))


def _perturbed(seq, picks: np.ndarray, count: int, ny: int, seed: int) -> list:
    """(mode, x, r, label) of ``count`` QPs a little off the scenario's."""
    rng = np.random.default_rng(seed)
    out = []
    for i in _spread(picks, count):
        x, r = np.asarray(seq.x[i], float), np.asarray(seq.r[i], float)
        x = x * (1.0 + PERTURBATION * rng.standard_normal(x.size))
        offset = PERTURBATION * rng.standard_normal(ny) * np.maximum(1.0, np.abs(r[:ny]))
        out.append((int(seq.mode[i]), x, r + np.tile(offset, r.size // ny),
                    f"sample {int(seq.k[i])} (perturbed)"))
    return out


def check_float(float_model: ControllerModel, float_ctx: dict, *,
                scenario_qps: int = SCENARIO_QPS, perturbed_qps: int = PERTURBED_QPS,
                seed: int = 0, build_dir: str | Path | None = None) -> FloatCheck:
    """The float check of a float design, from its model and context as generated."""
    t0 = time.perf_counter()
    root = Path(build_dir) if build_dir else None
    double_model, double_ctx = load_model_from_config(double_twin(float_model.config))
    builds = {name: build_host_controller(ctx, root) for name, ctx in
              (("double", double_ctx), ("float", float_ctx),
               ("floor", floor_context(double_model, float_model)))}
    seq = record_qp_sequence(double_model, builds["double"])

    def solve(build: str, mode: int, x, r) -> tuple[int, np.ndarray, int]:
        controller = builds[build]
        controller.init()  # cold, as after a switch
        status, U, _ = controller.solve_qp(mode, x, r)
        return int(status), U.astype(float), controller.info()["active"]

    active = np.array([solve("double", int(m), x, r)[2]
                       for m, x, r in zip(seq.mode, seq.x, seq.r)])
    picks = _select(seq, active, scenario_qps)
    qps = [(int(seq.mode[i]), seq.x[i], seq.r[i], f"sample {int(seq.k[i])}") for i in picks]
    qps += _perturbed(seq, picks, perturbed_qps, float_ctx["n_outputs"], seed)
    errors, first, floors, statuses, lost, worst = [], [], [], {}, {}, ("", -1.0)
    for mode, x, r, label in qps:
        nu = float_ctx["modes"][mode]["nu"]
        sd, Ud, _ = solve("double", mode, x, r)
        sf, Uf, _ = solve("float", mode, x, r)
        name = STATUS_NAMES.get(sf, str(sf))
        statuses[name] = statuses.get(name, 0) + 1
        if sd != OPTIMAL:
            continue
        sl, Ul, _ = solve("floor", mode, x, r)
        if sl == OPTIMAL:
            floors.append(relative_error(Ul, Ud))
        if sf != OPTIMAL:
            lost[name] = lost.get(name, 0) + 1
        else:
            errors.append(relative_error(Uf, Ud))
            first.append(np.abs(Uf[:nu] - Ud[:nu]).max() / max(1.0, np.abs(Ud).max()))
            if errors[-1] > worst[1]:
                worst = (f"{label}, mode {float_model.config.modes[mode].name}", errors[-1])
    return FloatCheck(qps=len(picks), perturbed=len(qps) - len(picks),
                      error=max(errors, default=float("nan")),
                      first_move_error=float(max(first, default=float("nan"))),
                      floor=max(floors, default=float("nan")),
                      float_statuses=statuses, lost=lost,
                      seconds=time.perf_counter() - t0, worst=worst[0])
