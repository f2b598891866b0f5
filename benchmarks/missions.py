"""Mission time against its bound, and missions flown in simulation (run on demand).

    python benchmarks/missions.py                      # scenario2, site_wedge; seeds 1-3; both budgets
    python benchmarks/missions.py --no-fly             # timing only (seconds, not minutes)
    python benchmarks/missions.py --scenarios scenario2 --seeds 1 --budgets small
    python benchmarks/missions.py --fly-seeds 1        # fly seed 1 only (8 UAVs fly for minutes)

For every scenario, seed and budget (``small`` = 200 particles x 100 iterations; ``own`` = the
scenario's ``[solver]`` setting: the paper's 2000 x 1500 on scenario 2, 400 x 300 on
site_wedge), the default method plans, then the plan is timed as ``staghunt export`` times it
(:func:`staghunt.trajectory.time_and_check`). Reported: the mission time ``T``, the bound
``B = max_n L_n / cruise_speed + cruise_speed / max_acceleration`` (``L_n`` the planned path
length of UAV ``n``), ``T / B`` (target <= 1.3), the peaks of speed and acceleration on a fine
grid, near-duplicate waypoints merged, the geometric path chosen, the in-time safety, and the
timing's own wall time. Unless ``--no-fly``, the timed ``trajectories.csv`` is flown by the
simulated vehicles (rotorpy, 100 Hz, no wind; :func:`staghunt.flight.mission.fly_mission`):
tracking RMS and maximum, least separation and clearance in flight against the limits.

Writes ``benchmarks/results/missions.json`` and ``missions.md`` (unless ``--no-write``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np
import provenance

import staghunt
from staghunt.inputs import parse_seeds
from staghunt.costs import CostModel
from staghunt.flight.mission import fly_mission, read_trajectories_csv
from staghunt.missions import formats as fm
from staghunt.scenario import load_scenario
from staghunt.trajectory import time_and_check

RESULTS = Path(__file__).parent / "results"
SMALL = (200, 100)


def run(scenario_name: str, seed: int, budget: str, fly: bool) -> dict:
    scenario = load_scenario(scenario_name)
    settings = scenario.solver if budget == "own" else scenario.solver.with_(particles=SMALL[0], iterations=SMALL[1])
    result = staghunt.plan(scenario, "game", seed, settings)
    model = CostModel.from_scenario(scenario)
    names = [u.name for u in scenario.team]
    t0 = time.perf_counter()
    traj, safety = time_and_check(model, result.paths, scenario.vehicle, names)
    timing_s = time.perf_counter() - t0
    fine = np.linspace(0.0, traj.duration, max(2000, int(traj.duration / 0.002)))
    row = {
        "scenario": scenario_name, "seed": seed, "budget": budget,
        "particles": settings.particles, "iterations": settings.iterations,
        "plan_status": result.status.value, "uavs": len(names),
        "duration_s": traj.duration, "bound_s": traj.bound, "ratio": traj.duration / traj.bound,
        "peak_speed": float(np.linalg.norm(traj.spline(fine, 1), axis=-1).max()),
        "peak_acceleration": float(np.linalg.norm(traj.spline(fine, 2), axis=-1).max()),
        "cruise_speed": scenario.vehicle.cruise_speed, "max_acceleration": scenario.vehicle.max_acceleration,
        "merged": traj.merged, "sub_leg_m": None if math.isinf(traj.spacing) else traj.spacing,
        "stretch": traj.stretch, "in_time_safe": safety.safe, "timing_s": timing_s,
    }
    if fly:
        t = traj.grid()
        pos, vel = traj.sample(t)
        flight = fly_mission(scenario, *read_trajectories_csv(fm.trajectories_csv(t, pos, vel)))
        row.update({
            "tracking_rms_m": float(flight.tracking_rms.max()), "tracking_max_m": float(flight.tracking_max.max()),
            "min_separation_m": float(flight.min_separation.min()),
            "separation_limit_m": float(flight.separation_limit.max()),
            "min_clearance_m": float(flight.min_clearance.min()),
            "required_clearance_m": flight.required_clearance,
            "plan_min_separation_m": float(min(safety.min_separation)),
            "plan_min_clearance_m": float(min(safety.min_clearance)),
            "flight_safe": flight.safe, "flight_problems": list(flight.problems[:3]),
            "simulation_s": flight.seconds,
        })
    return row


def table(rows: list[dict]) -> str:
    head = ("| scenario | budget | seed | T (s) | bound (s) | T / bound | peak v | peak a | merged | sub-leg | "
            "in time | tracking RMS / max (m) | flight sep / limit (m) | flight clearance / required (m) |")
    out = [head, "|" + "|".join(["---"] * (head.count("|") - 1)) + "|"]
    for r in rows:
        fly = (f"{r['tracking_rms_m']:.3f} / {r['tracking_max_m']:.3f} | {r['min_separation_m']:.2f} / "
               f"{r['separation_limit_m']:g} | {r['min_clearance_m']:.2f} / {r['required_clearance_m']:g}"
               if "tracking_rms_m" in r else "- | - | -")
        out.append(f"| {r['scenario']} | {r['budget']} ({r['particles']}x{r['iterations']}) | {r['seed']} | "
                   f"{r['duration_s']:.1f} | {r['bound_s']:.1f} | {r['ratio']:.2f} | {r['peak_speed']:.2f} | "
                   f"{r['peak_acceleration']:.2f} | {r['merged']} | {r['sub_leg_m'] or 'none'} | "
                   f"{'safe' if r['in_time_safe'] else 'UNSAFE'} | {fly} |")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default="scenario2,site_wedge")
    ap.add_argument("--seeds", default="1-3")
    ap.add_argument("--budgets", default="small,own")
    ap.add_argument("--no-fly", action="store_true")
    ap.add_argument("--fly-seeds", default=None,
                    help="fly only these seeds (default: every seed; a flight of 8 UAVs takes minutes)")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    started = provenance.start()
    rows = []
    for name in args.scenarios.split(","):
        for budget in args.budgets.split(","):
            for seed in parse_seeds(args.seeds):
                fly = not args.no_fly and (args.fly_seeds is None or seed in parse_seeds(args.fly_seeds))
                row = run(name, seed, budget, fly)
                rows.append(row)
                print(table([row]).splitlines()[-1], flush=True)
    ratios = [r["ratio"] for r in rows]
    summary = {"rows": rows, "max_ratio": max(ratios), "median_ratio": float(np.median(ratios)),
               "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
               "load_average": os.getloadavg()}
    print(f"T / bound: median {summary['median_ratio']:.2f}, max {summary['max_ratio']:.2f}")
    if not args.no_write:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "missions.json").write_text(json.dumps(provenance.stamped(started, summary), indent=1) + "\n")
        (RESULTS / "missions.md").write_text(
            "# Mission time and simulated flight (`benchmarks/missions.py`)\n\n" + table(rows)
            + f"\n\nT / bound: median {summary['median_ratio']:.2f}, max {summary['max_ratio']:.2f}; "
            f"machine {summary['machine']}, load average {summary['load_average'][0]:.2f}\n")


if __name__ == "__main__":
    main()
