"""Table 3 of docs/flight.md: five aircraft of different classes, each identified by
``rollmpc identify`` as a user would (AIRCRAFT_CASES: the command's airspeeds, altitude
and settings), each flown in LEVEL turbulence over the seeds: the MPC with and without
its preview beside the per-aircraft PID (``run_flight(baseline="pid")``), in float.

Per controller, mean [min, max] over the seeds: RMS roll error, settled error (mean of
the segments), transition time (mean of segments 2-6), and the envelope: the largest
altitude loss, the largest angle of attack against the aircraft's maximum-lift angle,
stalled samples, bounds left and engines lost.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

LEVEL = "moderate"


@dataclass(frozen=True)
class Case:
    label: str  # the class, for the table
    aircraft: str
    airspeeds_kts: tuple[float, ...]  # the first is the design point
    altitude_ft: float
    settings: tuple = ()


AIRCRAFT_CASES = (
    Case("light single", "c172p", (90.0, 70.0, 110.0), 4000.0),
    Case("taildragger", "J3Cub", (55.0, 45.0, 65.0), 2000.0),
    Case("twin turboprop", "DHC6", (115.0, 100.0, 130.0), 4000.0),
    Case("jet trainer", "T37", (175.0, 150.0, 200.0), 10000.0),
    Case("fighter", "f15", (300.0, 250.0, 350.0), 10000.0),
)
WHO = (("mpc", "MPC"), ("no_preview", "MPC without preview"), ("pid", "PID"))


def case_row(s: dict) -> dict:
    """One controller's flight, as the table shows it."""
    segs = s["segments"]
    moves = [x["transition_time_s"] for x in segs[1:]]
    return {"rms": s["rms_roll_error_deg"],
            "settled": float(np.mean([x["settled_error"] for x in segs])),
            "transition": None if None in moves else float(np.mean(moves)),
            "altitude_loss": s["altitude_loss_ft"], "max_alpha": s["max_alpha_deg"],
            "stall_alpha": s["stall_alpha_deg"], "stalled": s["stalled_samples"],
            "violations": s["constraint_violations"]["total"],
            "engines_lost": s["engines"]["count"] - s["engines"]["min_running"]}


def run_cases(seeds, precision: str, work: Path, cases=AIRCRAFT_CASES, build_dir=None,
              progress=None) -> list[dict]:
    """Identify each case into ``work`` and fly it over ``seeds``."""
    from .identify_config import identify_config
    from .run import run_flight

    out = []
    for case in cases:
        config = work / f"{case.aircraft}.yaml"
        identified = identify_config(case.aircraft, case.airspeeds_kts, case.altitude_ft,
                                     settings=case.settings)
        config.write_text(identified.text)
        flights = []
        for seed in seeds:
            run = run_flight(config, turbulence=LEVEL, seed=seed, precision=precision,
                             baseline="pid", build_dir=build_dir, progress=progress)
            s = run.summary
            flights.append({"seed": seed, "mpc": case_row(s),
                            "no_preview": case_row(s["no_preview"]),
                            "pid": case_row(s["baseline"]), "gains": s["baseline"]["gains"]})
        out.append({"label": case.label, "aircraft": case.aircraft,
                    "airspeeds_kts": list(case.airspeeds_kts), "altitude_ft": case.altitude_ft,
                    "settings": dict(case.settings),
                    "delay_margins": identified.delay_margins,
                    "warnings": [w.code for w in identified.warnings], "flights": flights})
    return out


def _range(values, fmt: str = "{:.2f}") -> str:
    if any(v is None for v in values):
        return "-"
    v = np.asarray(values, float)
    return f"{fmt.format(v.mean())} [{fmt.format(v.min())}, {fmt.format(v.max())}]"


def cases_markdown(cases: list[dict]) -> str:
    out = ["| aircraft (class) | controller | RMS roll error (deg) | settled error (deg) | "
           "transition (s) | altitude loss (ft) | max alpha / stall (deg) | stalled "
           "samples | bounds left | engines lost |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for c in cases:
        for key, name in WHO:
            rows = [f[key] for f in c["flights"]]
            stall = rows[0]["stall_alpha"]
            out.append(
                f"| {c['aircraft']} ({c['label']}) | {name} | "
                f"{_range([r['rms'] for r in rows])} | {_range([r['settled'] for r in rows])} | "
                f"{_range([r['transition'] for r in rows])} | "
                f"{max(r['altitude_loss'] for r in rows):.0f} | "
                f"{max(r['max_alpha'] for r in rows):.1f} / "
                f"{'-' if stall is None else f'{stall:g}'} | "
                f"{sum(r['stalled'] for r in rows)} | {sum(r['violations'] for r in rows)} | "
                f"{max(r['engines_lost'] for r in rows)} |")
    out.append("")
    out.append("| aircraft | identify | delay margin (samples, per mode) | PID gains "
               "(tau s, max rate deg/s, FF, P, I, scaling kts) | identify's warnings |")
    out.append("|---|---|---|---|---|")
    for c in cases:
        g = c["flights"][0]["gains"]
        speeds = " ".join(f"--airspeed {v:g}" for v in c["airspeeds_kts"])
        sets = "".join(f" --set {k}={v:g}" for k, v in c["settings"].items())
        warnings = ", ".join(f"{code} x{c['warnings'].count(code)}"
                             for code in dict.fromkeys(c["warnings"])) or "none"
        out.append(f"| {c['aircraft']} | `{speeds} --altitude {c['altitude_ft']:g}{sets}` | "
                   f"{', '.join('>30' if d is None else str(d) for d in c['delay_margins'])} | "
                   f"{g['time_constant_s']:.2f}, {g['max_rate_dps']:.0f}, "
                   f"{g['feed_forward']:.3f}, {g['rate_p']:.3f}, {g['rate_i']:.3f}, "
                   f"{g['trim_airspeed_kts']:g}/{g['min_airspeed_kts']:g} | {warnings} |")
    return "\n".join(out)
