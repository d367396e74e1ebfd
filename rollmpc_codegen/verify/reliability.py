"""Measure the figures of docs/reliability.md (issue 4) and write them as JSON.

    python -m rollmpc_codegen.verify [--out build/reliability] [--only qp,infeasible,...]

(``make reliability``.)  Sections:

* ``qp``: 10,000 random feasible QPs (80 controllers x 125), errors per cond(E) band in
  double and float (:mod:`rollmpc_codegen.verify.qp_campaign`); each failing float QP is
  classed by its stored-data floor (:mod:`rollmpc_codegen.verify.float_floor`);
* ``infeasible``: 1,000 infeasible QPs (50 controllers x 20) and their recovery;
* ``memory``: the paper's test-vector program and a 100,000-step random closed loop
  under ASan+UBSan, and the test-vector program under valgrind, both precisions;
* ``stack``: worst stack path per entry point (GCC -fstack-usage), host and every core;
* ``misra``: cppcheck + MISRA addon findings per rule on generated/, and how many are
  not covered by rollmpc_codegen/codegen/misra_deviations.py;
* ``spikes``: one huge but finite measurement in the closed loop of three examples, and the
  samples to recovery (:mod:`rollmpc_codegen.verify.spike_recovery`);
* ``hostile``: one hostile sample (1e7, 1e8, 1e30, NaN, Inf) of each input, y, the
  schedule signal, r and P_observe's u_applied, on the UAV and a scheduled MIMO design,
  and the samples to recovery (the same module).

Each section writes ``<out>/<section>.json`` (with the commit and template hashes it
measured); failing records go to ``<out>/<section>_failures.json`` with x and r, and
the campaigns' configs stay in ``<out>/<section>/configs/``.  Replay failures with the
current templates:

    python -m rollmpc_codegen.verify.reliability --replay build/reliability/qp_failures.json
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

from . import qp_campaign as qc
from .spike_recovery import measure_hostile, measure_spikes
from ..host.programs import (SANITIZE, SOAK_SUMMARY, VALGRIND_BUILD, VECTORS_SUMMARY,
                            compile_program, run_program, write_soak_program)
from ..parts import CORES
from ..sim.simulate import progress_printer
from ..status import STATUS_NAMES

ROOT = Path(__file__).resolve().parents[2]
UAV = ROOT / "examples" / "uav_roll.yaml"
SECTIONS = ("qp", "infeasible", "memory", "stack", "misra", "spikes", "hostile")
FREESTANDING = ("-ffreestanding", "-fno-math-errno")  # beside each core's flags (parts.py)


def measure_qp(work: Path, configs: int = 80, per_config: int = 125) -> tuple[dict, list]:
    records = qc.feasible_campaign(configs, per_config, work,
                                   progress=progress_printer(configs, "random QPs"))
    return qc.summarise_feasible(records), qc.failures_json(records)


def measure_infeasible(work: Path, configs: int = 50, per_config: int = 20) -> tuple[dict, list]:
    records = qc.infeasible_campaign(configs, per_config, work,
                                     progress=progress_printer(configs, "infeasible QPs"))
    return qc.summarise_infeasible(records), qc.failures_json(records)


def measure_memory(work: Path, soak_steps: int = 100_000) -> dict:
    from ..host.testvectors import write_test_vectors

    out: dict = {}
    valgrind = shutil.which("valgrind")
    for prec in ("double", "float"):
        src = write_test_vectors(UAV, work / f"tv_{prec}", prec, 6000)
        run = run_program(compile_program(src, work / f"tv_{prec}_asan", SANITIZE))
        passed, failed = run.counts(VECTORS_SUMMARY) or (0, -1)
        out[f"vectors_asan_ubsan_{prec}"] = {"passed": passed, "failed": failed,
                                             "sanitizer_reports": run.sanitizer_reports}
        if valgrind:
            run = run_program(compile_program(src, work / f"tv_{prec}_vg", VALGRIND_BUILD),
                              valgrind=valgrind)
            passed, failed = run.counts(VECTORS_SUMMARY) or (0, -1)
            out[f"vectors_valgrind_{prec}"] = {"passed": passed, "failed": failed,
                                               "valgrind_errors": run.valgrind_errors}
        src = write_soak_program(UAV, work / f"soak_{prec}", prec)
        t0 = time.time()
        run = run_program(compile_program(src, work / f"soak_{prec}_asan", SANITIZE),
                          (str(soak_steps), "1"))
        counts = run.counts(SOAK_SUMMARY)
        out[f"soak_asan_ubsan_{prec}"] = {
            "steps": counts[0] if counts else 0, "faults": counts[1] if counts else 0,
            "statuses": dict(zip(STATUS_NAMES.values(), counts[2:-1])) if counts else {},
            "violations": counts[-1] if counts else -1,
            "sanitizer_reports": run.sanitizer_reports, "seconds": round(time.time() - t0, 1)}
    return out


def measure_stack(work: Path) -> dict:
    from ..pipeline import generate
    from ..target.stack_usage import analyse

    out: dict = {}
    targets = [("host-gcc", "gcc", ()), *((core.name, "arm-none-eabi-gcc",
                                           (*core.cflags, *FREESTANDING))
                                          for core in CORES.values())]
    for prec in ("double", "float"):
        src = work / f"src_{prec}"
        generate(UAV, src, prec)
        for name, cc, flags in targets:
            if shutil.which(cc) is None:
                continue
            for opt in ("-O2", "-Os"):
                rep = analyse(src, work / f"su_{prec}_{name}{opt}", cc, (*flags, opt))
                key = f"{prec}/{name}{opt}"
                out[key] = {"max_frame": max(rep.frames.values()), "unbounded": rep.unbounded,
                            "library_calls": sorted(rep.external)}
                for entry in ("rollmpc_step", "rollmpc_solve_qp", "rollmpc_init"):
                    depth, chain = rep.worst_path(entry)
                    out[key][entry] = {"bytes": depth, "path": chain}
    return out


def measure_misra(work: Path) -> dict:
    from ..codegen.misra_deviations import DEVIATIONS
    from .misra import by_rule, run_cppcheck, unjustified

    out: dict = {"deviations": len(DEVIATIONS)}
    for tree in ("uav_roll_f32", "uav_roll"):
        findings = run_cppcheck(ROOT / "generated" / tree)
        bad = unjustified(findings, "rollmpc")
        out[tree] = {"findings": len(findings), "by_rule": by_rule(findings),
                     "unjustified": len(bad),
                     "unjustified_list": [f"{f.file}:{f.line}: {f.rule}" for f in bad]}
    return out


def provenance() -> dict:
    """Which code was measured: git commit, whether the tree was dirty, template hashes."""
    import hashlib
    import subprocess

    def git(*args):
        proc = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
        return proc.stdout.strip() if proc.returncode == 0 else None

    templates = sorted((ROOT / "templates").glob("*.j2"))
    return {"commit": git("rev-parse", "--short", "HEAD"),
            "dirty_files": len((git("status", "--porcelain", "--untracked-files=no") or "")
                               .splitlines()),
            "templates_sha256": hashlib.sha256(b"".join(p.read_bytes() for p in templates))
            .hexdigest()[:16]}


def replay(failures: Path, first: int = 10) -> int:
    """Solve recorded failing QPs again, cold, with the current templates; print each."""
    import json

    import numpy as np

    from ..host.build import build_host_controller
    from ..qp.exact import qp_data, relative_error, solve_exact
    from .float_floor import stored_data_floor
    from ..pipeline import load_model

    failures = Path(failures)
    section = failures.name.removesuffix("_failures.json")
    records = json.loads(failures.read_text())["failures"][:first]
    for rec in records:
        cfg = failures.parent / section / "configs" / rec["config"]
        model, ctx = load_model(cfg, rec["precision"])
        c = build_host_controller(ctx)
        qp = model.modes[0].qp
        x = np.asarray(rec["x"], model.dtype)
        r = np.asarray(rec["r"], model.dtype)
        st, U, its = c.solve_qp(0, x, r)
        data = qp_data(qp, x.astype(float), r.astype(float))
        sol = solve_exact(data)
        line = f"{cfg} {rec['precision']} qp {rec['index']}: status {st}, sweeps {its}"
        if sol.status == "optimal":
            f = data.f.astype(float)
            cost = [float(0.5 * u @ qp.E @ u + f @ u) for u in (U.astype(float), sol.U)]
            err = relative_error(U, sol.U)
            line += f", error {err:.3g}, cost {cost[0]:.10g} vs optimal {cost[1]:.10g}"
            if rec["precision"] == "float":
                _, dctx = load_model(cfg, "double")
                fst, floor = stored_data_floor(model.modes[0].data, dctx["solver"], x, r, sol.U)
                line += f", stored-data floor {floor:.3g} (status {fst})"
        else:
            line += f", reference: {sol.status}"
        print(line)
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rollmpc_codegen.verify",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="build/reliability", help="output directory")
    ap.add_argument("--only", default=",".join(SECTIONS),
                    help=f"comma-separated sections ({', '.join(SECTIONS)})")
    ap.add_argument("--work", default=None, help="scratch directory (default: a temp dir)")
    ap.add_argument("--replay", metavar="FAILURES_JSON",
                    help="instead: re-solve the first --first records of a *_failures.json")
    ap.add_argument("--first", type=int, default=10)
    args = ap.parse_args(argv)
    if args.replay:
        return replay(Path(args.replay), args.first)
    out = Path(args.out)
    only = [s for s in args.only.split(",") if s]
    unknown = set(only) - set(SECTIONS)
    if unknown:
        print(f"rollmpc: error: --only: unknown section(s) {', '.join(sorted(unknown))}",
              file=sys.stderr)
        return 2
    work = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="rollmpc-rel-"))
    for section in only:
        t0 = time.time()
        # the campaigns keep their configs next to the JSON, for --replay
        sub = out / section if section in ("qp", "infeasible") else work / section
        sub.mkdir(parents=True, exist_ok=True)
        if section in ("qp", "infeasible"):
            summary, failures = {"qp": measure_qp, "infeasible": measure_infeasible}[section](sub)
            qc.write_json(out / f"{section}_failures.json", {"failures": failures})
        else:
            summary = {"memory": measure_memory, "stack": measure_stack,
                       "misra": measure_misra,
                       "spikes": lambda _: measure_spikes(ROOT / "examples"),
                       "hostile": lambda _: measure_hostile()}[section](sub)
        summary["seconds"] = round(time.time() - t0, 1)
        summary["provenance"] = provenance()
        qc.write_json(out / f"{section}.json", summary)
        print(f"reliability: {section} done in {summary['seconds']} s -> {out / section}.json")
    return 0

