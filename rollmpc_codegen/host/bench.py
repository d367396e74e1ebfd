"""``rollmpc bench``: the paper's Table 2 on the generated C and on PyPI peers, one run.

:func:`run_bench` takes keywords, returns a :class:`BenchResult` and prints nothing (its
progress goes to an optional callback factory, see ``sim.simulate.start_phase``):

1. **Record** the QP sequence of the scenario and **select** the QPs to replay
   (:mod:`rollmpc_codegen.host.bench_record`; samples 1-32, the paper's start-up
   transient, are skipped unless ``include_transient``).
2. **Replay** the same QPs, in order (:mod:`rollmpc_codegen.host.bench_replay`), through
   * the generated solver variants, each built from a config variant with
     ``build_host_controller``: the default config as shipped and, with ``paper``, plain
     Hildreth (cold), Hildreth+ W and Hildreth+' W exactly as the paper describes them
     (``polish: false``; slow: on the UAV up to 2 s per QP);
   * quadprog (the reference for the error columns), DAQP and OSQP
     (:mod:`rollmpc_codegen.qp.peers`; by default those installed).
   ``repeat`` R replays everything R times, each from a fresh start (the replays are
   deterministic), and keeps each QP's minimum time: on a shared machine this removes the
   OS preemptions that otherwise dominate the maxima of the fast rows.
3. **Summarise** each row and check the paper's reduced set
   (:mod:`rollmpc_codegen.host.bench_summary`).
"""
from __future__ import annotations

import os
import platform
import subprocess
from collections.abc import Iterable
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np

from .bench_record import TRANSIENT_SAMPLES, record_qp_sequence, select_qps
from .bench_replay import Replay, fastest_of, replay_c, replay_peer, variant_context
from .bench_summary import reduced_set_check, row_summary
from .build import EXACT_MATH, build_host_controller
from ..extras import installed, require_module
from ..pipeline import config_label, load_model
from ..qp.peers import DaqpPeer, OsqpPeer, QuadprogPeer, c_stdout_silenced
from ..sim.scenario import scenario_reference
from ..sim.simulate import start_phase

# The optimisation level of the generated C's timed host builds: a release build, as DAQP's
# C is built with its own -O3. EXACT_MATH keeps every sum rounding as the reference's at any
# level, so the replays are bit for bit those of the tests' -O2 builds (build.py).
BENCH_OPT = "-O3"

C_VARIANTS = {  # row key: (label, solver.method or None for the config as given)
    "hildreth": ("Hildreth (cold) [C]", "hildreth"),
    "hildreth_plus": ("Hildreth+ W [C]", "hildreth_plus"),
    "hildreth_plus_prime": ("Hildreth+' W [C]", "hildreth_plus_prime"),
    "default": ("default as configured [C]", None),
}
OSQP_TIGHT = {"eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": True}
PEERS = {
    "quadprog": "quadprog",
    "daqp": "DAQP (Model, warm)",
    # DAQP's C built on the host and timed like ours (host.peer_daqp_c): opt-in, its
    # sdist is downloaded once
    "daqp_c": "DAQP C (sample: data + update + solve)",
    "daqp_c_solve": "DAQP C (update + solve only)",
    "osqp": "OSQP (default)",
    "osqp_tight": "OSQP (eps 1e-9, polish)",
}
# the rows timed by our own clock (host.peer_daqp_c), each with what it times
SAME_CLOCK_PEERS = {"daqp_c": "step", "daqp_c_solve": "solve"}
ROWS = (*C_VARIANTS, *PEERS)
REFERENCE_ROW = "quadprog"  # the error columns' reference: it always runs
OURS_AND_PEERS = ("default", "quadprog", "daqp", "osqp")  # the rows run by default
# the paper's algorithms, run only when asked for: on the UAV up to 2 s per QP
PAPER_VARIANTS = ("hildreth", "hildreth_plus", "hildreth_plus_prime")


def table_rows(keys: Iterable[str]) -> list[str]:
    """``keys`` in the table's order, with the reference row; ValueError on an unknown key."""
    keys = list(keys)
    for k in keys:
        if k not in ROWS:
            raise ValueError(f"unknown row {k!r}; choose from {', '.join(ROWS)}")
    return [k for k in ROWS if k in keys or k == REFERENCE_ROW]


def peer_module(key: str) -> str:
    """The Python module a peer row needs (``osqp_tight`` -> ``osqp``)."""
    return key.split("_")[0]


def default_variants() -> list[str]:
    """Ours and the peers of OURS_AND_PEERS that are installed (the reference is needed
    anyway: without quadprog the run fails, naming it)."""
    return [k for k in OURS_AND_PEERS
            if k not in PEERS or k == REFERENCE_ROW or installed(peer_module(k))]


def machine_info() -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    versions = {}
    for pkg in ("numpy", "scipy", "cffi", "quadprog", "daqp", "osqp"):
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None
    try:
        cc = subprocess.run(["gcc", "--version"], capture_output=True, text=True,
                            timeout=10).stdout.splitlines()[0]
    except (OSError, IndexError, subprocess.SubprocessError):
        cc = None
    return {"cpu": cpu, "cores": os.cpu_count(), "load_average": list(os.getloadavg()),
            "platform": platform.platform(), "python": platform.python_version(),
            "c_compiler": cc, "c_flags": " ".join((BENCH_OPT, *EXACT_MATH)), **versions}


def make_peer(key: str, model, build_root: Path | None):
    """A fresh peer of the row ``key`` (every peer but quadprog, the reference)."""
    qps = [mm.qp for mm in model.modes]
    if key == "daqp":
        return DaqpPeer(qps)
    if key in SAME_CLOCK_PEERS:
        from .peer_daqp_c import DaqpCPeer

        return DaqpCPeer(model, SAME_CLOCK_PEERS[key], build_root)
    return OsqpPeer(qps, **(OSQP_TIGHT if key == "osqp_tight" else {}))


@dataclass
class BenchResult:
    """One bench run: ``summary`` is the JSON document (the table is ``summary["rows"]``),
    ``replays`` the per-QP results of every row and ``samples`` the scenario sample of each
    replayed QP (what Fig. 3 plots them against)."""

    summary: dict
    replays: dict[str, Replay]
    samples: np.ndarray

    @property
    def rows(self) -> list[dict]:
        return self.summary["rows"]


def run_bench(config, *, precision: str | None = None,
              variants: Iterable[str] | None = None, paper: bool = False,
              max_qps: int | None = None, repeat: int = 1, include_transient: bool = False,
              steps: int | None = None, build_dir: str | Path | None = None,
              progress=None) -> BenchResult:
    """Table 2 for ``config`` (a file, a ControllerConfig or a Design; see the module
    docstring) on the rows ``variants`` (default: :func:`default_variants`), with the
    paper's variants too when ``paper``, and quadprog, the reference, always; ``max_qps``
    samples the QPs in blocks, ``steps`` shortens the recorded scenario, ``build_dir``
    holds the host builds (default: a cache in $TMPDIR)."""
    keys = table_rows([*(default_variants() if variants is None else variants),
                       *(PAPER_VARIANTS if paper else ())])
    for key in keys:
        if key in PEERS:
            require_module(peer_module(key), "peers", f"the {key} row")
    model, ctx = load_model(config, precision)
    cfg = model.config
    build_root = Path(build_dir) if build_dir else None
    default_c = build_host_controller(ctx, build_root, opt=BENCH_OPT)
    steps = steps if steps is not None else len(scenario_reference(cfg))
    seq = record_qp_sequence(model, default_c, steps,
                             start_phase(progress, steps, "bench: record scenario"))
    idx = select_qps(seq, include_transient, max_qps)
    qps = [mm.qp for mm in model.modes]

    def repeated(key: str, run_once) -> Replay:
        """``run_once(progress)`` ``repeat`` times from a fresh start; per-QP minimum times."""
        return fastest_of([
            run_once(start_phase(progress, idx.size, f"bench {key}"
                                 + (f" ({n + 1}/{repeat})" if repeat > 1 else "")))
            for n in range(repeat)])

    ref = repeated(REFERENCE_ROW, lambda pr: replay_peer(QuadprogPeer(qps), model, seq, idx, pr))
    replays, rows = {REFERENCE_ROW: ref}, []
    for key in keys:
        if key in C_VARIANTS:
            label, method = C_VARIANTS[key]
            if method is None:
                c = default_c
                s = ctx["solver"]
                label = f"default: {s['method']}{' + polish' if s['polish'] else ''} [C]"
            else:
                c = build_host_controller(variant_context(cfg, method), build_root,
                                          opt=BENCH_OPT)
            rep = repeated(key, lambda pr, c=c: replay_c(c, model, seq, idx, pr))
            timer = "C (solve_ticks)"
        elif key == REFERENCE_ROW:
            label, rep, timer = PEERS[key], ref, "wall (Python call)"
        else:
            def once(pr, key=key):
                with c_stdout_silenced():
                    return replay_peer(make_peer(key, model, build_root), model, seq, idx, pr)

            rep = repeated(key, once)
            label = PEERS[key]
            timer = ("C (same clock as solve_ticks)" if key in SAME_CLOCK_PEERS
                     else f"C ({peer_module(key)} info)")
        replays[key] = rep
        rows.append(row_summary(key, label, timer, rep, ref, seq, idx, model))
    summary = {
        "machine": machine_info(),
        "config": config_label(config),
        "precision": ctx["precision"],
        "sample_time": cfg.sample_time,
        "horizon": cfg.horizon,
        "solver_default": dict(ctx["solver"]),
        "scenario_samples": int(seq.k.size),
        "qps": int(idx.size),
        "skipped_transient_samples": 0 if include_transient else TRANSIENT_SAMPLES,
        "repeat": repeat,
        "timing": "one replay" if repeat == 1 else
                  f"per-QP minimum over {repeat} replays, each from a fresh start",
        "sampled": bool(max_qps is not None and idx.size < seq.k.size - (
            0 if include_transient else TRANSIENT_SAMPLES)),
        "qps_by_mode": {m.name: int((seq.mode[idx] == j).sum())
                        for j, m in enumerate(cfg.modes)},
        "rows": rows,
        "reduced_set_check": reduced_set_check(model, seq, idx, ref),
    }
    if "default" in replays:  # the replay reproduces the recorded closed loop
        applied = np.array([seq.u_applied[i, model.modes[seq.mode[i]].data.actuator_index]
                            for i in idx])
        diff = np.abs(replays["default"].u0[:, :applied.shape[1]] - applied)
        summary["replay_max_abs_diff_vs_closed_loop"] = float(np.nanmax(diff))
    return BenchResult(summary=summary, replays=replays, samples=seq.k[idx])
