"""Inspection benchmark: issue 37's targets on the built-in inspections (site_inspection3 and
site_inspection, 3 and 8 UAVs over site_wedge), run on demand, not by the test suite.

    python benchmarks/inspection.py            # everything (about 10-20 min on 2 cores)
    python benchmarks/inspection.py --quick    # one seed, no wind repeat, short OR-Tools reference

For each team size:

1. planning (``plan_inspection``, the scenario's budget, certificate included): wall and CPU
   time, its parts, the makespan of the allocation and of the timed plan against the lower
   bound, the greedy baseline, the photos against QGroundControl's count for the same survey;
2. the flight, no wind and in 5 m/s Dryden wind: coverage measured on the photos the cameras
   took along the flown trajectories (areas: share of cells with 5 or more photos at the target
   GSD, overlaps reached; facades: share of patches at the target GSD within the incidence limit),
   motion blur, trigger intervals, least separation and clearance;
3. losing UAVs mid-mission (1 of 3, 2 of 8) at several times: area coverage, the re-allocation's
   latency (p50, p95, max), safety;
4. the allocation on small instances (sub-problems of the built-in tasks: 6-10 tasks, 2-3 UAVs)
   against OR-Tools minimising the makespan directly with a long time limit.

Results: ``benchmarks/results/inspection.json`` (everything) and ``inspection.md`` (the table).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import sys
import time
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import provenance

from staghunt.flight.inspection import fly_inspection
from staghunt.inspection.allocation import Problem
from staghunt.inspection.routing import solve, solve_ortools
from staghunt.inspection.files import clean
from staghunt.inspection.planner import SLACK, InspectConfig, fleet_of, plan_inspection
from staghunt.scenario import load_scenario
from staghunt.world.dynamic import Event

RESULTS = Path(__file__).parent / "results"


def cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def trigger_intervals(photos) -> float:
    """The least time between two photos of one UAV (s)."""
    least = math.inf
    for u in np.unique(photos.uav):
        t = np.sort(photos.t[photos.uav == u])
        if len(t) > 1:
            least = min(least, float(np.diff(t).min()))
    return least


def coverage_row(coverage: list[dict]) -> dict:
    out = {}
    for c in coverage:
        if c["kind"] == "area":
            out[c["objective"]] = {"cells_5_images_at_gsd": c["min_images_share"], "cells_at_gsd": c["target_share"],
                                   "front_overlap_reached": c["front_overlap"]["reached_share"],
                                   "front_overlap_p5": c["front_overlap"]["p5"],
                                   "side_overlap_reached": c["side_overlap"]["reached_share"],
                                   "side_overlap_p5": c["side_overlap"]["p5"], "blur_px_max": c["blur_px"]["max"],
                                   "photos": c["photos"]}
        elif c["kind"] == "facade":
            out[c["objective"]] = {"patches_at_gsd_within_incidence": c["target_share"], "blur_px_max": c["blur_px"]["max"],
                                   "photos": c["photos"]}
        else:
            out[c["objective"]] = {"visits_done": c["visits_done"], "visits": c["visits"]}
    return out


def flight_row(f) -> dict:
    return {"coverage": coverage_row(list(f.coverage)), "photos": len(f.photos),
            "least_trigger_interval_s": trigger_intervals(f.photos),
            "least_separation_m": float(f.min_separation.min()), "separation_limit_m": float(f.separation_limit.max()),
            "least_clearance_m": float(f.min_clearance.min()), "required_clearance_m": f.required_clearance,
            "problems": list(f.problems), "simulated_s": float(f.times[-1]), "wall_s": f.wall_time_s,
            "decisions": [{"time": d.time, "latency_s": d.latency_s, "cpu_s": d.cpu_s,
                          "tasks": d.tasks_left} for d in f.decisions]}


def way_out(plan) -> dict:
    """The team's way out (the game, to the first captures, arriving together) against the
    farthest UAV's straight line at the cruise speed, and the makespan before and after the work
    is allocated again from the way out's end (``None``: kept the first)."""
    import re

    outs = [(p.t1, p.points[0], p.points[-1]) for pieces in plan.timeline.pieces for p in pieces if p.label == "outbound"]
    if not outs:
        return {"way_out_s": None, "way_out_straight_s": None, "first_makespan_s": None}
    straight = max(float(np.linalg.norm(b - a)) for _, a, b in outs) / plan.scenario.vehicle.cruise_speed
    again = re.search(r"makespan (\d+) s -> (\d+) s", plan.message)
    return {"way_out_s": max(t for t, _, _ in outs), "way_out_straight_s": straight,
            "first_makespan_s": float(again.group(1)) if again else None}


def first_allocation(plan) -> dict:
    """The allocation from take-off (as the planner makes it first, before the work is allocated
    again from the game's way out) beside the greedy baseline and the bound, and its routes timed
    as the bound times them (straight legs at the cruise speed, no stop, no slack): the
    allocation's own share of the gap."""
    from staghunt.inspection.allocation import time_routes

    cfg = plan.config
    fleet = fleet_of(plan.scenario, plan.inspection)
    first = solve(Problem(plan.tasks, fleet, slack=SLACK), cfg.allocation, cfg.solutions, cfg.rounds, cfg.time_cap_s)
    pb = Problem(plan.tasks, fleet, stop_s=0.0, slack=1.0)
    routes, _ = time_routes(pb, [first.tasks_of(k) for k in range(fleet.n)])
    bound = first.lower_bound
    return {"allocation_makespan_s": first.makespan, "greedy_makespan_s": plan.baseline.makespan,
            "lower_bound_s": bound, "allocation_over_bound": first.makespan / bound,
            "allocation_over_bound_same_model": max(r.end for r in routes) / bound,
            "final_allocation_makespan_s": plan.allocation.makespan}


def flat_ratio(scenario) -> dict:
    """The same surveys planned over level ground: QGroundControl's count does not see the
    terrain, ours flies lower where the ground in a photo falls away (the GSD guarantee). And
    what QGroundControl's own plan (its transects and triggers, terrain following at the GSD's
    height above the ground under the camera) covers, on the site's ground and on level ground."""
    from shapely.geometry import Polygon

    from staghunt.acquisition.coverage import Photos, area_cells, measure
    from staghunt.acquisition.plan import plan_objective
    from staghunt.acquisition.survey import line_angle, qgc_photo_poses
    from staghunt.task.objectives import AreaObjective
    from staghunt.world import Terrain

    flat = replace(scenario, world=replace(scenario.world, terrain=Terrain()))
    out = {}
    for o in scenario.inspection.objectives:
        if not isinstance(o, AreaObjective):
            continue
        p = plan_objective(flat, flat.inspection, o)
        cam = scenario.inspection.camera_for(o)
        qgc = {}
        for label, sc in (("site", scenario), ("level", flat)):
            pos, yaw, pitch = qgc_photo_poses(Polygon(o.polygon), line_angle(Polygon(o.polygon)),
                                              cam.line_spacing_m(o.gsd_cm, o.side_overlap),
                                              cam.trigger_distance_m(o.gsd_cm, o.front_overlap), cam.distance_m(o.gsd_cm),
                                              sc.world.terrain)
            n = len(pos)
            photos = Photos(np.arange(n, dtype=float), np.zeros(n, int), pos, yaw, pitch, np.zeros(n),
                            np.full(n, o.name), np.zeros(n, int))
            c = measure(area_cells(o, sc, 1.0), photos, cam, sc, o.gsd_cm)
            qgc[label] = {"photos": n, "cells_5_images_at_gsd": c.min_images_share, "cells_at_gsd": c.target_share}
        out[o.name] = {"photos": p.photos, "qgc": p.qgc_photos, "ratio": p.photos / p.qgc_photos,
                       "qgc_plan_covers": qgc}
    return out


def small_instances(plan, rng: np.random.Generator, count: int, long_s: float) -> list[dict]:
    """The allocation (``solve``, as the planner runs it) against OR-Tools' span model with
    ``long_s`` seconds on random sub-problems of the plan's tasks."""
    tasks = list(plan.tasks)
    full = fleet_of(plan.scenario, plan.inspection)
    out = []
    for _ in range(count):
        n_tasks = int(rng.integers(6, 11))
        n_uavs = int(rng.integers(2, 4))
        pick = sorted(rng.choice(len(tasks), size=min(n_tasks, len(tasks)), replace=False))
        uavs = list(range(n_uavs))
        sub = [replace(tasks[j], index=k, uavs=tuple(u for u in tasks[j].uavs if u in uavs)) for k, j in enumerate(pick)]
        fleet = replace(full, active=np.array([k in uavs for k in range(full.n)]))
        pb = Problem(tuple(sub), fleet, slack=SLACK)
        t0 = time.perf_counter()
        ours = solve(pb, "ortools")
        t_ours = time.perf_counter() - t0
        ref = solve_ortools(pb, solutions=10**7, time_cap_s=long_s, span=True, start=ours)
        out.append({"tasks": len(sub), "uavs": n_uavs, "ours_makespan": ours.makespan, "ours_s": t_ours,
                    "reference_makespan": ref.makespan, "reference_s": long_s,
                    "ratio": ours.makespan / ref.makespan if ref.ok and ref.makespan > 0 else None})
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    started = provenance.start()
    seeds = [1] if args.quick else [1, 2]
    long_s = 5.0 if args.quick else 30.0
    rng = np.random.default_rng(37)
    report: dict = {"date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                    "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "python": sys.version.split()[0],
                                "load_before": os.getloadavg()}, "teams": {}}
    for name, lose in (("site_inspection3", ["UAV2"]), ("site_inspection", ["UAV2", "UAV6"])):
        scenario = load_scenario(name)
        team = {"uavs": scenario.n_uavs, "runs": []}
        for seed in seeds:
            c0, w0 = cpu(), time.perf_counter()
            plan = plan_inspection(scenario, scenario.inspection, InspectConfig(), seed=seed)
            run = {"seed": seed, "planning_wall_s": time.perf_counter() - w0, "planning_cpu_s": cpu() - c0,
                   "parts_s": plan.times, "status": plan.status.value, "message": plan.message,
                   **first_allocation(plan), "planned_makespan_s": plan.makespan,
                   "planned_over_bound": plan.makespan / plan.allocation.lower_bound,
                   "outbound_certified": bool(plan.outbound is not None and plan.outbound.certificate is not None
                                              and plan.outbound.certificate.is_equilibrium),
                   "outbound_max_relative_gap": (None if plan.outbound is None or plan.outbound.certificate is None
                                                 else plan.outbound.certificate.max_relative_gap),
                   "safe_in_time": plan.safety.safe, **way_out(plan),
                   "photos_vs_qgc": {o.name: {"photos": o.photos, "qgc": o.qgc_photos, "ratio": o.photos / o.qgc_photos}
                                     for o in plan.captures.objectives if o.qgc_photos},
                   "photos_vs_qgc_flat_ground": flat_ratio(scenario),
                   "planned_coverage": coverage_row(list(plan.coverage))}
            print(f"{name} seed {seed}: planned in {run['planning_wall_s']:.1f} s wall ({run['planning_cpu_s']:.1f} s CPU), "
                  f"makespan {plan.makespan:.0f} s, allocation {plan.allocation.makespan:.0f} s, bound "
                  f"{plan.allocation.lower_bound:.0f} s, greedy {plan.baseline.makespan:.0f} s; {plan.message[:80]}", flush=True)
            for wind in ([0.0] if args.quick and seed > 1 else [0.0, 5.0]):
                f = fly_inspection(scenario, plan.timeline, wind=wind, seed=seed)
                run[f"flight_wind_{wind:g}"] = flight_row(f)
                cov = run[f"flight_wind_{wind:g}"]["coverage"]
                print(f"  flown, wind {wind:g} m/s: " + "; ".join(
                    f"{k} {v.get('cells_5_images_at_gsd', v.get('patches_at_gsd_within_incidence', v.get('visits_done')))}"
                    for k, v in cov.items()) + f"; problems {len(f.problems)}", flush=True)
            losses = []
            for frac in ((0.3, 0.5) if args.quick else (0.25, 0.4, 0.55, 0.7)):
                t_lost = round(frac * plan.makespan, 1)
                events = tuple(Event(t_lost + 10.0 * i, "uav_lost", u) for i, u in enumerate(lose))
                f = fly_inspection(scenario, plan.timeline, events, seed=seed)
                row = flight_row(f)
                row["lost"] = f.lost
                losses.append(row)
                area = next(v for v in row["coverage"].values() if "cells_5_images_at_gsd" in v)
                print(f"  lost {lose} from {t_lost:.0f} s: area {area['cells_5_images_at_gsd']:.4f}, latencies "
                      f"{[round(d['latency_s'], 3) for d in row['decisions']]}, problems {len(f.problems)}", flush=True)
            run["losses"] = losses
            team["runs"].append(run)
        lat = [d["latency_s"] for r in team["runs"] for row in r["losses"] for d in row["decisions"]]
        cpu_lat = [d["cpu_s"] for r in team["runs"] for row in r["losses"] for d in row["decisions"]]
        team["reallocation_latency_s"] = {"n": len(lat), "p50": float(np.percentile(lat, 50)),
                                          "p95": float(np.percentile(lat, 95)), "max": float(max(lat)),
                                          "cpu_p95": float(np.percentile(cpu_lat, 95)), "cpu_max": float(max(cpu_lat))}
        team["small_instances"] = small_instances(plan, rng, 3 if args.quick else 6, long_s)
        report["teams"][name] = team
    report["machine"]["load_after"] = os.getloadavg()
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "inspection.json").write_text(json.dumps(provenance.stamped(started, clean(report)), indent=1) + "\n")
    (RESULTS / "inspection.md").write_text(table(report))
    print(table(report))
    return 0


def table(report: dict) -> str:
    lines = [f"# Inspection benchmark ({report['date']}, {report['machine']['cpus']} CPUs, load "
             f"{report['machine']['load_before'][0]:.1f} before, {report['machine']['load_after'][0]:.1f} after)", "",
             "| target | 3 UAVs (site_inspection3) | 8 UAVs (site_inspection) |", "|---|---|---|"]
    t3, t8 = report["teams"]["site_inspection3"], report["teams"]["site_inspection"]

    def runs(t, f):
        return ", ".join(f(r) for r in t["runs"])

    def area(r, key):
        return next(v for v in r[key]["coverage"].values() if "cells_5_images_at_gsd" in v)

    def wind5(r):
        return f"{area(r, 'flight_wind_5')['cells_5_images_at_gsd']:.2%}" if "flight_wind_5" in r else "-"

    def blur(r):
        return max(v["blur_px_max"] for v in r["flight_wind_0"]["coverage"].values() if "blur_px_max" in v)

    def lost(r):
        return min(next(v for v in x["coverage"].values() if "cells_5_images_at_gsd" in v)["cells_5_images_at_gsd"]
                   for x in r["losses"])

    def qgc_cover(r):
        return ", ".join(f"{v['qgc_plan_covers']['site']['cells_5_images_at_gsd']:.1%} / "
                         f"{v['qgc_plan_covers']['level']['cells_5_images_at_gsd']:.1%}"
                         for v in r["photos_vs_qgc_flat_ground"].values())

    def facades(r, key):
        return min(v["patches_at_gsd_within_incidence"] for v in r[key]["coverage"].values()
                   if "patches_at_gsd_within_incidence" in v)

    rows = [
        ("area: cells with >= 5 photos at <= target GSD, flown, no wind (>= 99 %)",
         lambda t: runs(t, lambda r: f"{area(r, 'flight_wind_0')['cells_5_images_at_gsd']:.2%}")),
        ("area: the same in 5 m/s wind (>= 99 %)",
         lambda t: runs(t, wind5)),
        ("area: front / side overlap reached, flown (share of photo pairs)",
         lambda t: runs(t, lambda r: f"{area(r, 'flight_wind_0')['front_overlap_reached']:.0%} / "
                                     f"{area(r, 'flight_wind_0')['side_overlap_reached']:.0%}")),
        ("facades: patches at <= target GSD within the incidence limit, flown, no wind (>= 95 %; least facade)",
         lambda t: runs(t, lambda r: f"{facades(r, 'flight_wind_0'):.2%}")),
        ("facades: the same in 5 m/s wind (>= 95 %)",
         lambda t: runs(t, lambda r: f"{facades(r, 'flight_wind_5'):.2%}" if "flight_wind_5" in r else "-")),
        ("photos / QGroundControl's for the survey (<= 1.10): the hilly site; the same polygon over level ground",
         lambda t: runs(t, lambda r: ", ".join(f"{v['ratio']:.2f} ({v['photos']} / {v['qgc']})"
                                               for v in r["photos_vs_qgc"].values()) + "; " + ", ".join(
             f"{v['ratio']:.2f} ({v['photos']} / {v['qgc']})" for v in r["photos_vs_qgc_flat_ground"].values()))),
        ("QGroundControl's own plan of the survey: cells with >= 5 photos at the GSD, on the site / on level ground",
         lambda t: runs(t, qgc_cover)),
        ("least trigger interval flown (camera: 0.7 s)",
         lambda t: runs(t, lambda r: f"{r['flight_wind_0']['least_trigger_interval_s']:.2f} s")),
        ("motion blur at the flown speed, 1/1000 s (<= 0.5 px; max)",
         lambda t: runs(t, lambda r: f"{blur(r):.2f} px")),
        ("makespan / lower bound (<= 1.15): the allocation from take-off timed as the bound is; the same as "
         "allocated (slack 1.25, stops); the timed plan",
         lambda t: runs(t, lambda r: f"{r['allocation_over_bound_same_model']:.2f}; {r['allocation_over_bound']:.2f}; "
                                     f"{r['planned_over_bound']:.2f}")),
        ("the team's way out (the game, arriving together) / the farthest straight at cruise speed (s); makespan "
         "with the first allocation -> the work allocated again from the way out's end (s)",
         lambda t: runs(t, lambda r: f"{r['way_out_s']:.0f} / {r['way_out_straight_s']:.0f}; "
                                     f"{r['first_makespan_s'] or r['planned_makespan_s']:.0f} -> "
                                     f"{r['planned_makespan_s']:.0f}" if r["way_out_s"] else "-")),
        ("makespan from take-off: OR-Tools / greedy / lower bound (s)",
         lambda t: runs(t, lambda r: f"{r['allocation_makespan_s']:.0f} / {r['greedy_makespan_s']:.0f} / "
                                     f"{r['lower_bound_s']:.0f}")),
        ("small instances: ours / OR-Tools with a long limit (<= 1.05; worst)",
         lambda t: f"{max(x['ratio'] for x in t['small_instances'] if x['ratio']):.3f} over {len(t['small_instances'])}"),
        ("UAVs lost mid-mission: area cells with >= 5 photos (>= 99 %; worst)",
         lambda t: runs(t, lambda r: f"{lost(r):.2%}")),
        ("re-allocation + re-plan latency, wall p50 / p95 / max (p95 <= 1 s); CPU p95",
         lambda t: f"{t['reallocation_latency_s']['p50']:.2f} / {t['reallocation_latency_s']['p95']:.2f} / "
                   f"{t['reallocation_latency_s']['max']:.2f} s over {t['reallocation_latency_s']['n']}; "
                   f"{t['reallocation_latency_s']['cpu_p95']:.2f} s"),
        ("safety: problems in every flight (contact or margin breach)",
         lambda t: str(sum(len(r['flight_wind_0']['problems']) + len(r.get('flight_wind_5', {}).get('problems', []))
                           + sum(len(x['problems']) for x in r['losses']) for r in t['runs']))),
        ("outbound leg certified (the team's game)", lambda t: runs(t, lambda r: str(r["outbound_certified"]))),
        ("planning, certificate included (<= 30 s for 8 UAVs): wall / CPU",
         lambda t: runs(t, lambda r: f"{r['planning_wall_s']:.1f} / {r['planning_cpu_s']:.1f} s")),
    ]
    for label, f in rows:
        lines.append(f"| {label} | {f(t3)} | {f(t8)} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
