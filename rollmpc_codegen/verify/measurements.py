"""``make measurements``: the current figures of docs/solver.md and docs/target.md,
measured by the commands a user runs, into docs/measurements.md.

Every row is one command (``rollmpc report``, ``simulate`` or ``bench``) on one example,
run as a user runs it, with the commit it ran at.  The rows are kept in
docs/measurements.json, so ``--only uav_roll,fw_lateral`` re-measures those examples and
keeps every other row with its own commit; the Markdown is rendered from the JSON
(measurements_table.py).  Host timings are ratios within one bench run; cycle counts are
the emulator's and deterministic.  ``python -m rollmpc_codegen.verify.measurements
[--only A,B] [--skip bench,flights,horizons] [--out docs/measurements.md]``.
"""
from __future__ import annotations

import argparse
import csv
import datetime
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from .measurements_table import render

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "measurements.md"
UNBUDGETED = 1_000_000_000  # solver.work_budget of the run that shows what a design needs
FLIGHTS = ("--flights", "20", "--seed", "1", "--steps", "3000", "--noise", "0.1",
           "--disturbance", "0.5", "--mismatch", "0.2")
HORIZONS = "25,50,100"
KINDS = ("report", "simulate", "unbudgeted", "bench", "flights", "horizons")


def examples() -> list[str]:
    return sorted(p.stem for p in (ROOT / "examples").glob("*.yaml"))


def commit() -> str:
    """The short commit, ``+dirty`` when tracked files outside docs/ differ from it."""
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, text=True,
                          capture_output=True, check=True).stdout.strip()
    changed = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                             cwd=ROOT, text=True, capture_output=True, check=True).stdout
    dirty = [line for line in changed.splitlines() if not line[3:].startswith("docs/")]
    return head + ("+dirty" if dirty else "")


def rollmpc_exe() -> str:
    exe = Path(sys.executable).parent / "rollmpc"
    return str(exe) if exe.exists() else (shutil.which("rollmpc") or "rollmpc")


def run(args: list[str], shown: str, log, csv_path: Path | None = None) -> dict:
    """Run ``rollmpc <args> --json F``; the JSON it wrote (and the rows of ``csv_path``,
    when the command wrote one), the command as shown, its time."""
    with tempfile.TemporaryDirectory(prefix="rollmpc-measure-") as tmp:
        out = Path(tmp) / "out.json"
        t0 = time.perf_counter()
        proc = subprocess.run([rollmpc_exe(), *args, "--quiet", "--json", str(out)], cwd=ROOT,
                              text=True, capture_output=True)
        seconds = time.perf_counter() - t0
        log(f"  {seconds:6.1f} s  {shown}")
        if proc.returncode != 0:
            raise RuntimeError(f"{shown} failed ({proc.returncode}): {proc.stderr.strip()}")
        data = json.loads(out.read_text())
        if csv_path is not None:
            with csv_path.open() as f:
                data["_csv"] = list(csv.DictReader(f))
    return {"data": data, "command": f"rollmpc {shown} --quiet --json F",
            "seconds": round(seconds, 1)}


def _report(row: dict) -> dict:
    d = row["data"]
    counts = d["statuses"]
    return {"horizon": d["horizon"], "sample_time": d["sample_time"],
            "flash": d["flash_bytes"], "ram": d["ram_bytes"], "ctrl": d["ctrl_bytes"],
            "stack": d["stack_bytes"], "worst": d["worst_step_cycles"],
            "worst_step": d["worst_step"], "worst_share": d["budget"]["worst_load_percent"],
            "worst_fits": d["budget"]["worst_fits"], "cpu_mhz": d["budget"]["cpu_mhz"],
            "median": d["median_step_cycles"], "cycles_per_unit": d["cycles_per_work_unit"]["max"],
            "work_budget": d["work_budget"], "optimal": counts.get("optimal", 0),
            "steps": sum(counts.values()), "statuses": counts,
            "longest_time_limit_run": d["longest_time_limit_run"],
            "bit_exact": bool(d["bit_exact_vs_host"] and d.get("state_bit_exact", True)),
            "worst_flight": d.get("worst_flight"), "toolchain": d["toolchain"],
            "flights": (d.get("perturbations") or {}).get("flights")}


def _simulate(row: dict) -> dict:
    d = row["data"]
    return {"samples": d["samples"], "statuses": d["status_counts"],
            "optimal": d["status_counts"].get("optimal", 0),
            "longest_time_limit_run": d["longest_time_limit_run"],
            "max_settled_error": d["max_settled_error"],
            "hard_violations": d["constraint_violations"]["total"],
            "y_max_beyond": d["constraint_violations"].get("y_max_beyond", {}),
            "work": d["work"], "units": d["units"]["outputs"]}


def _unbudgeted(row: dict, budget: int) -> dict:
    work = [int(float(r["work"])) for r in row["data"]["_csv"]]
    return {**{k: row["data"]["work"][k] for k in ("median", "p99", "max")},
            "budget": budget, "above_budget": sum(w > budget for w in work),
            "samples": len(work), "optimal": row["data"]["status_counts"].get("optimal", 0)}


def _bench(row: dict) -> dict:
    found = {r["key"]: r for r in row["data"]["rows"]}
    ours, peer = found["default"], found["daqp_c"]
    return {"qps": ours["qps"], "ours_median_us": ours["median_s"] * 1e6,
            "ours_max_us": ours["max_s"] * 1e6, "daqp_median_us": peer["median_s"] * 1e6,
            "daqp_max_us": peer["max_s"] * 1e6,
            "median_ratio": ours["median_s"] / peer["median_s"],
            "max_ratio": ours["max_s"] / peer["max_s"], "statuses": ours["status_counts"]}


def _horizons(row: dict) -> dict:
    d = row["data"]["horizons"]
    return {"rows": d["rows"], "refused": [r["horizon"] for r in d["refused"]],
            "limit": d["fitted_horizon_limit"], "budget": d["budget"]}


def unbudgeted_copy(example: str, directory: Path) -> Path:
    """The example with ``solver.work_budget`` lifted: what its samples need."""
    data = yaml.safe_load((ROOT / "examples" / f"{example}.yaml").read_text())
    data.setdefault("solver", {})["work_budget"] = UNBUDGETED
    path = directory / f"{example}_unbudgeted.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def measure_example(name: str, kinds: set[str], log) -> dict[str, dict]:
    config = f"examples/{name}.yaml"
    rows: dict[str, dict] = {}
    if "report" in kinds:
        r = run(["report", config, "--precision", "float"],
                f"report {config} --precision float", log)
        rows["report"] = {**r, "figures": _report(r)}
    if "simulate" in kinds or "unbudgeted" in kinds:
        r = run(["simulate", config, "--precision", "float"],
                f"simulate {config} --precision float", log)
        rows["simulate"] = {**r, "figures": _simulate(r)}
    if "unbudgeted" in kinds:
        with tempfile.TemporaryDirectory(prefix="rollmpc-measure-") as tmp:
            copy = unbudgeted_copy(name, Path(tmp))
            log_csv = Path(tmp) / "log.csv"
            r = run(["simulate", str(copy), "--precision", "float", "--csv", str(log_csv)],
                    f"simulate <{config} with solver.work_budget: {UNBUDGETED}> "
                    "--precision float --csv L", log, log_csv)
        rows["unbudgeted"] = {**r, "figures": _unbudgeted(
            r, rows["simulate"]["figures"]["work"]["budget"])}
    if "bench" in kinds:
        r = run(["bench", config, "--variants", "default,daqp_c", "--repeat", "3"],
                f"bench {config} --variants default,daqp_c --repeat 3", log)
        rows["bench"] = {**r, "figures": _bench(r)}
    return rows


def measure_paper_config(kinds: set[str], log) -> dict[str, dict]:
    config = "examples/uav_roll.yaml"
    rows: dict[str, dict] = {}
    if "flights" in kinds:
        r = run(["report", config, "--precision", "float", *FLIGHTS],
                f"report {config} --precision float {' '.join(FLIGHTS)}", log)
        rows["flights"] = {**r, "figures": _report(r)}
    if "horizons" in kinds:
        r = run(["report", config, "--precision", "float", "--horizons", HORIZONS],
                f"report {config} --precision float --horizons {HORIZONS}", log)
        rows["horizons"] = {**r, "figures": _horizons(r)}
    return rows


def machine() -> str:
    """The CPU and its core count: the host timings' context."""
    cpu = next((line.split(":", 1)[1].strip() for line in
                Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), "unknown CPU")
    return f"{cpu}, {os.cpu_count()} cores"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rollmpc_codegen.verify.measurements",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--only", help="comma-separated examples to re-measure (default: all)")
    p.add_argument("--skip", default="", help=f"comma-separated kinds of {','.join(KINDS)}")
    p.add_argument("--out", type=Path, default=OUT, help="the Markdown (its .json beside it)")
    p.add_argument("--render", action="store_true",
                   help="only render the Markdown again from the JSON, measuring nothing")
    args = p.parse_args(argv)
    store = args.out.with_suffix(".json")
    if args.render:
        args.out.write_text(render(json.loads(store.read_text())))
        return 0
    kinds = set(KINDS) - set(filter(None, args.skip.split(",")))
    names = args.only.split(",") if args.only else examples()
    doc = json.loads(store.read_text()) if store.exists() else {"examples": {}, "paper": {}}
    stamp = {"commit": commit(), "date": datetime.date.today().isoformat(),
             "machine": machine()}

    def log(text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    def keep(section: dict, rows: dict[str, dict]) -> None:
        """Record the rows and write both files at once: a later failure loses nothing."""
        section.update({k: {**stamp, **{f: v[f] for f in ("command", "seconds", "figures")}}
                        for k, v in rows.items()})
        store.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
        args.out.write_text(render(doc))

    for name in names:
        log(f"{name}:")
        keep(doc["examples"].setdefault(name, {}), measure_example(name, kinds, log))
    if args.only is None or "uav_roll" in names:
        log("uav_roll (paper config):")
        keep(doc["paper"], measure_paper_config(kinds, log))
    log(f"wrote {args.out} and {store}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
