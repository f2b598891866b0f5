"""Closed-loop re-planning benchmark (run on demand, not part of the test suite).

    python benchmarks/replan.py                         # 100 + 10 wind scenario-2, 20 site_wedge (~85 min)
    python benchmarks/replan.py --episodes 10 --wedge-episodes 2 --wind-episodes 2   # smoke run
    python benchmarks/replan.py --solve-only --episodes 30 --wedge-episodes 10       # latency, 2 cores

Episodes (each seeded; the same command gives the same episodes and flights):

- **scenario 2** (3 UAVs), planned once at the paper's setting (2000 x 1500, K = 10, seed 1):
  a cylinder of radius 2-6 m appears on a random UAV's route 2-5 s ahead of it (the UAV
  would touch it 2-5 s after it appears; at a random time in the first 60 % of the flight), and
  a site vehicle (a cylinder of radius 2.5 m, 2-4 m/s, a known motion) crosses the team's route
  on a straight line across the site, timed to reach the route within +-2 s of the team;
- **site_wedge** (8 UAVs), planned once at its own setting (400 x 300, seed 1): the tower
  crane's jib with its load (a box 3 m wide from 10 to 35 m above ground, 55-70 m long) slews
  into the route (from pointing south to pointing north, 3-8 deg/s, timed to sweep the route
  when the team is near), plus a pop-up load 2-5 s ahead of a random UAV;
- **wind**: the first ``--wind-episodes`` scenario-2 episodes flown again with 5 m/s Dryden wind.

Every episode is flown by :func:`staghunt.fly` (rotorpy multirotors at 100 Hz, the planner at
10 Hz). Reported: safety in the simulated flight (collisions, separation breaches), stops to
hover, re-plan latency measured (p50, p95, max; certificate included), the share of re-plans
certified as 1 %-equilibria, tracking error, extra time. By default one episode flies at a
time and each re-plan has both cores (the issue's target); ``--jobs 2`` flies two episodes side
by side, each solving on one thread, twice as fast, but the latencies are then those of one core
(the load average is recorded: a shared machine disturbs them). Writes ``benchmarks/results/replan.json``
and ``replan.md``. ``--solve-only`` re-solves only each episode's first re-plan on the reference
(no vehicle simulated), one at a time on the engine's adaptive threads: the latency with both
cores (``replan_solve.json``, ``replan_solve.md``).
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent


def _reference(scenario: Any, waypoints: np.ndarray) -> Any:
    from staghunt.costs import to_absolute
    from staghunt.trajectory.quintic import Reference, timed_path

    g = scenario.world.terrain
    pts = np.concatenate([to_absolute(g, scenario.starts()[:, None]), to_absolute(g, waypoints),
                          to_absolute(g, scenario.goals()[:, None])], axis=1)
    return Reference((timed_path(pts, 0.0, scenario.vehicle),))


def _popup(scenario: Any, ref: Any, rng: np.random.Generator, radius: tuple[float, float],
           name: str) -> Any:
    """A cylinder on a random UAV's route that the UAV would touch 2-5 s after it appears (its
    reference enters the cylinder grown by the body radius that long after the appearance),
    appearing at a random time in the first 60 % of the flight, clear of every UAV at that
    time (by 2 m) and of every goal (by 5 m)."""
    from staghunt.world import Cylinder
    from staghunt.world.dynamic import Event

    T = ref.arrival
    r = np.array([u.radius for u in scenario.team])
    goals = np.array([u.goal[:2] for u in scenario.team])
    grid = np.arange(0.0, T, 0.05)
    path = ref.state(grid)[0]  # (N, G, 3)
    for _ in range(1000):
        n = int(rng.integers(scenario.n_uavs))
        t = float(rng.uniform(3.0, 0.6 * T))
        lead = float(rng.uniform(2.0, 5.0))
        R = float(rng.uniform(*radius))
        # the centre: the first point on UAV n's route, after time t, whose disc of radius R + r
        # the UAV enters `lead` seconds after t
        later = np.flatnonzero(grid >= t)
        for k in later:
            p = path[n, k, :2]
            inside = np.hypot(path[n, later, 0] - p[0], path[n, later, 1] - p[1]) < R + r[n]
            first = grid[later[np.argmax(inside)]]
            if first - t >= lead:
                break
        else:
            continue
        now = ref.state(np.array([t]))[0][:, 0]
        gap = np.hypot(now[:, 0] - p[0], now[:, 1] - p[1]) - R - r
        to_goal = np.hypot(goals[:, 0] - p[0], goals[:, 1] - p[1]) - R - r
        if gap.min() > 2.0 and to_goal.min() > 5.0:
            return Event(t, "appear", name, Cylinder(float(p[0]), float(p[1]), R, name)), n, float(first - t)
    raise RuntimeError("no pop-up position found")


def _truck(scenario: Any, ref: Any, rng: np.random.Generator) -> Any:
    """A site vehicle crossing the route on a straight line across the site."""
    from staghunt.world.dynamic import MovingCylinder

    b = scenario.world.bounds
    T = ref.arrival
    for _ in range(1000):
        t_c = float(rng.uniform(0.3, 0.8) * T)
        m = int(rng.integers(scenario.n_uavs))
        s = ref.state(np.array([t_c]))
        p, v = s[0][m, 0, :2], s[1][m, 0, :2]
        if np.linalg.norm(v) < 0.5:
            continue
        d = np.array([-v[1], v[0]]) / np.linalg.norm(v)  # across the route
        speed = float(rng.uniform(2.0, 4.0))
        # the segment of the line p + s d inside the site (margin 3 m)
        lo, hi = -1e9, 1e9
        for k, (a, z) in enumerate(((b.xmin + 3, b.xmax - 3), (b.ymin + 3, b.ymax - 3))):
            if abs(d[k]) > 1e-9:
                s1, s2 = (a - p[k]) / d[k], (z - p[k]) / d[k]
                lo, hi = max(lo, min(s1, s2)), min(hi, max(s1, s2))
        if rng.random() < 0.5:
            d, lo, hi = -d, -hi, -lo
        a, z = p + lo * d, p + hi * d
        arrive = t_c + float(rng.uniform(-2.0, 2.0))
        start = arrive - (-lo) / speed  # it passes p at `arrive`
        if start < 0:
            continue
        return MovingCylinder("truck", 2.5, ((float(a[0]), float(a[1])), (float(z[0]), float(z[1]))),
                              speed, start)
    raise RuntimeError("no crossing found")


def _jib(scenario: Any, ref: Any, rng: np.random.Generator) -> Any:
    """The tower crane's jib with its load slewing from south to north into the route."""
    from staghunt.world.dynamic import SlewingJib

    pivot = (398.0, 153.0)
    length = float(rng.uniform(55.0, 70.0))
    rate = float(rng.uniform(3.0, 8.0))
    # when does the team pass the crane's x?
    t = np.linspace(0.0, ref.arrival, 400)
    x = ref.state(t)[0][..., 0].mean(axis=0)
    t_pass = float(t[np.argmin(np.abs(x - pivot[0]))])
    # sweep the route (about 60 degrees before north) at the team's passing time +- 4 s
    start = max(0.0, t_pass + float(rng.uniform(-4.0, 4.0)) - 120.0 / rate)
    g = float(scenario.world.terrain.height(np.array([pivot[0]]), np.array([pivot[1]]))[0])
    return SlewingJib("crane jib (load)", pivot, length, 3.0, g + 10.0, g + 35.0, -90.0, 90.0, rate,
                      0.0, start, "stop", (10.0, 35.0))


def make_episodes(kind: str, count: int, scenario: Any, waypoints: np.ndarray) -> list[dict[str, Any]]:
    """The known motion of each episode, timed against the plan made without it (so that it
    crosses that plan); the pop-up is placed in the worker, on the plan actually flown."""
    from staghunt.world.dynamic import Dynamics

    ref = _reference(scenario, waypoints)
    out = []
    for e in range(count):
        rng = np.random.default_rng([0 if kind == "scenario2" else 1, e])
        if kind == "scenario2":
            dyn = Dynamics(moving=(_truck(scenario, ref, rng),))
        else:
            dyn = Dynamics(jibs=(_jib(scenario, ref, rng),))
        out.append({"kind": kind, "episode": e, "known": dyn})
    return out


def _with_popup(job: dict[str, Any], engine: Any) -> tuple[np.ndarray, Any, int, float]:
    """The plan made sound against the episode's known motion, and the episode's changing world
    with a pop-up 2-5 s ahead of a random UAV on *that* plan."""
    from dataclasses import replace

    from staghunt.flight import FlyConfig
    from staghunt.api import check_plan
    from staghunt.flight.loop import _source, plan_around
    from staghunt.world.dynamic import Dynamics

    scenario, wp, settings = _source(job["result"])
    known = job["known"]
    request = check_plan(replace(scenario, dynamics=known), "game", 1, settings, engine)
    wp2, ref, _ = plan_around(request, known, wp, FlyConfig())
    rng = np.random.default_rng([2 if job["kind"].startswith("scenario2") else 3, job["episode"]])
    radius, name = ((2.0, 6.0), "pop-up") if job["kind"].startswith("scenario2") else ((3.0, 6.0), "pop-up load")
    popup, n, lead = _popup(scenario, ref, rng, radius, name)
    return wp2, Dynamics(known.moving, known.jibs, (popup,), known.sensing), n, lead


def run_episode(job: dict[str, Any]) -> dict[str, Any]:
    """One flight in a worker process; returns its summary."""
    import warnings

    warnings.simplefilter("ignore")
    from staghunt.flight import FlyConfig, fly
    from staghunt.io.flight_files import latency_summary

    from staghunt.engine import get_engine

    t0 = time.perf_counter()
    try:
        wp, dyn, n, lead = _with_popup(job, get_engine("auto", job["threads"]))
        r = fly(job["result"], waypoints=wp, events=dyn, seed=job["episode"],
                config=FlyConfig(wind=job.get("wind", 0.0), **job.get("config", {})), threads=job["threads"])
    except ValueError as exc:
        return {**_meta(job), "error": str(exc)}
    recs = r.replans
    return {
        **_meta(job),
        "status": r.status.value,
        "message": r.message,
        "separation_margin_m": float(np.min(r.min_separation - r.separation_limit)),
        "min_clearance_m": float(r.min_clearance.min()),
        "collision": bool(r.min_clearance.min() < 0),
        "separation_breach": bool(np.any(r.min_separation <= r.separation_limit)),
        "stops": r.stops,
        "popup_uav": n, "popup_lead_s": lead,
        "replans": [{"trigger": x.trigger, "status": x.status, "latency_s": x.latency_s,
                     "certified": x.certified, "max_gap": max(x.nash_gaps, default=None),
                     "evaluations": x.evaluations, "attempts": x.attempts} for x in recs],
        "latency": latency_summary(recs),
        "tracking_rms_m": float(np.sqrt(np.mean(r.tracking_rms ** 2))),
        "tracking_max_m": float(r.tracking_max.max()),
        "extra_time_s": None if not math.isfinite(r.extra_time) else float(r.extra_time),
        "flight_s": float(r.times[-1]),
        "plan_windows": len(r.plan_windows),
        "wall_s": time.perf_counter() - t0,
    }


def _meta(job: dict[str, Any]) -> dict[str, Any]:
    return {"kind": job["kind"], "episode": job["episode"], "wind": job.get("wind", 0.0)}


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    ok = [r for r in rows if "error" not in r]
    lat = [x["latency_s"] for r in ok for x in r["replans"]]
    moving = [x["latency_s"] for r in ok for x in r["replans"] if not x["trigger"].startswith("retry")]
    solved = [x for r in ok for x in r["replans"] if x["status"].endswith("replanned")]
    pct = (lambda q: float(np.percentile(lat, q))) if lat else (lambda q: float("nan"))
    extra = [r["extra_time_s"] for r in ok if r["extra_time_s"] is not None]
    return {
        "episodes": len(rows),
        "refused": len(rows) - len(ok),
        "arrived": sum(r["status"] == "arrived" for r in ok),
        "stopped": sum(r["status"] == "stopped" for r in ok),
        "unsafe": sum(r["status"] == "unsafe" for r in ok),
        "collisions": sum(r["collision"] for r in ok),
        "separation_breaches": sum(r["separation_breach"] for r in ok),
        "episodes_with_stop": sum(r["stops"] > 0 for r in ok),
        "least_clearance_m": min((r["min_clearance_m"] for r in ok), default=None),
        "least_separation_margin_m": min((r["separation_margin_m"] for r in ok), default=None),
        "replans": len(lat),
        "latency_p50_ms": 1000 * pct(50), "latency_p95_ms": 1000 * pct(95),
        "latency_max_ms": 1000 * max(lat, default=float("nan")),
        # in flight: every re-plan but the retries from the hover (which have 4x the budget)
        "in_flight_replans": len(moving),
        "in_flight_latency_p50_ms": 1000 * float(np.percentile(moving, 50)) if moving else None,
        "in_flight_latency_p95_ms": 1000 * float(np.percentile(moving, 95)) if moving else None,
        "in_flight_latency_max_ms": 1000 * max(moving) if moving else None,
        "solved": len(solved),
        "certified": sum(x["certified"] for x in solved),
        "tracking_rms_m": float(np.sqrt(np.mean([r["tracking_rms_m"] ** 2 for r in ok]))) if ok else None,
        "tracking_max_m": max((r["tracking_max_m"] for r in ok), default=None),
        "extra_time_s_median": float(np.median(extra)) if extra else None,
        "extra_time_s_range": [float(min(extra)), float(max(extra))] if extra else None,
    }


def solve_only(job: dict[str, Any]) -> dict[str, Any]:
    """The first re-plan of an episode on the reference alone (no vehicle simulated), with the
    engine's adaptive threads: the solve latency on the whole machine, certificate included."""
    from dataclasses import replace

    from staghunt.engine import get_engine
    from staghunt.flight import FlyConfig
    from staghunt.api import check_plan
    from staghunt.flight.loop import _source, plan_around
    from staghunt.flight.aside import rest_worker
    from staghunt.flight.replan import Replanner

    engine = get_engine("auto")
    rest_worker(wait=True)  # the plans from rest's process, started once (as a flight does before its first re-plan)
    wp, dyn, n, lead = _with_popup(job, engine)
    scenario, _, settings = _source(job["result"])
    scenario = replace(scenario, dynamics=dyn)
    _, ref, _ = plan_around(check_plan(scenario, "game", 1, settings, engine), dyn, wp, FlyConfig())
    popup = dyn.events[0]
    config = FlyConfig(**job.get("config", {}))
    planner = Replanner(scenario, dyn, config, engine, np.random.default_rng(job["episode"]))
    planner.known.sensed[popup.name] = popup.shape
    t = math.ceil(popup.time * 10.0) / 10.0  # the first planner tick after it appears
    _, rec = planner.solve(ref, t, "sensed " + popup.name)
    return {**_meta(job), "status": rec.status, "latency_s": rec.latency_s, "certified": rec.certified,
            "max_gap": max(rec.nash_gaps, default=None), "evaluations": rec.evaluations}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--wedge-episodes", type=int, default=20)
    ap.add_argument("--wind-episodes", type=int, default=10)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--solve-only", action="store_true",
                    help="only each episode's first re-plan, on the reference, one at a time with the "
                    "engine's adaptive threads (the latency on the whole machine); writes replan_solve.json")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a FlyConfig setting for every episode, e.g. --set certify_rounds=2 (repeatable)")
    args = ap.parse_args()
    overrides = _overrides(args.set)

    import staghunt
    from staghunt.io.result_json import write_result

    tmp = Path(tempfile.mkdtemp(prefix="staghunt-replan-"))
    jobs: list[dict[str, Any]] = []
    threads = 1 if args.jobs > 1 else None
    plans: dict[str, Any] = {}
    for kind, count in (("scenario2", max(args.episodes, args.wind_episodes)), ("site_wedge", args.wedge_episodes)):
        if count == 0:
            continue
        sc = staghunt.load_scenario(kind)
        t0 = time.perf_counter()
        res = staghunt.plan(sc, seed=1)
        plans[kind] = {"status": res.status.value, "plan_s": time.perf_counter() - t0,
                       "particles": sc.solver.particles, "iterations": sc.solver.iterations}
        path = tmp / f"{kind}.json"
        write_result(res, path)
        for ep in make_episodes(kind, count, sc, np.array(res.waypoints)):
            base = {**ep, "result": str(path), "threads": threads, "config": overrides}
            if kind == "scenario2" and ep["episode"] < args.episodes:
                jobs.append(base)
            if kind == "scenario2" and ep["episode"] < args.wind_episodes:
                jobs.append({**base, "kind": "scenario2-wind", "wind": 5.0})
            if kind == "site_wedge":
                jobs.append(base)
    if args.solve_only:
        return _solve_only([j for j in jobs if j.get("wind", 0.0) == 0.0], args.out)
    print(f"{len(jobs)} episodes, {args.jobs} at a time", file=sys.stderr)
    t0 = time.perf_counter()
    rows: list[dict[str, Any]] = []
    # spawned workers: a forked child of a process that has run OpenMP threads (the plans above)
    # is killed by GNU OpenMP as soon as it starts a parallel loop of its own
    with ProcessPoolExecutor(max_workers=args.jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
        for i, row in enumerate(pool.map(run_episode, jobs)):
            rows.append(row)
            lat = row.get("latency", {})
            print(f"[{i + 1}/{len(jobs)}] {row['kind']} #{row['episode']}: {row.get('status', row.get('error'))} "
                  f"replans {lat.get('replans', 0)} p95 {1000 * lat.get('latency_p95_s', float('nan')):.0f} ms "
                  f"clear {row.get('min_clearance_m', float('nan')):.2f} m", file=sys.stderr)
    wall = time.perf_counter() - t0
    kinds = sorted({r["kind"] for r in rows})
    summary = {k: summarise([r for r in rows if r["kind"] == k]) for k in kinds}
    meta = {"jobs": args.jobs, "threads_per_solve": threads or "adaptive", "wall_s": wall,
            "loadavg": os.getloadavg(), "cpus": os.cpu_count(), "plans": plans}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "replan.json").write_text(json.dumps({"meta": meta, "summary": summary, "episodes": rows},
                                                     indent=1, default=str) + "\n")
    lines = ["| episodes | arrived / stopped / unsafe | collisions | separation breaches | stops | "
             "replans | latency p50 / p95 / max (ms) | in flight (no hover retries) | certified 1 %-equilibria | "
             "tracking RMS / max (m) | extra time median [range] (s) |", "|" + "---|" * 11]
    for k in kinds:
        s = summary[k]
        ex = s["extra_time_s_range"]
        fl = (f"{s['in_flight_replans']}: {s['in_flight_latency_p50_ms']:.0f} / {s['in_flight_latency_p95_ms']:.0f} / "
              f"{s['in_flight_latency_max_ms']:.0f}") if s["in_flight_replans"] else "-"
        lines.append(
            f"| {k}: {s['episodes']} | {s['arrived']} / {s['stopped']} / {s['unsafe']} | {s['collisions']} | "
            f"{s['separation_breaches']} | {s['episodes_with_stop']} | {s['replans']} | "
            f"{s['latency_p50_ms']:.0f} / {s['latency_p95_ms']:.0f} / {s['latency_max_ms']:.0f} | {fl} | "
            f"{s['certified']}/{s['solved']} | {s['tracking_rms_m']:.3f} / {s['tracking_max_m']:.3f} | "
            f"{s['extra_time_s_median']:.1f} [{ex[0]:.1f}, {ex[1]:.1f}] |" if ex else "|")
    md = "\n".join(lines) + f"\n\n{args.jobs} episodes at a time, {threads or 'adaptive'} thread(s) per solve, " \
         f"{wall / 60:.1f} min, load average {os.getloadavg()[0]:.2f} at the end.\n"
    (args.out / "replan.md").write_text(md)
    print(md)
    return 0


def _overrides(items: list[str]) -> dict[str, Any]:
    """``NAME=VALUE`` strings -> FlyConfig keyword arguments (numbers as int or float)."""
    from dataclasses import fields

    from staghunt.flight import FlyConfig

    known = {f.name: f.type for f in fields(FlyConfig)}
    out: dict[str, Any] = {}
    for item in items:
        name, _, value = item.partition("=")
        if name not in known:
            raise SystemExit(f"--set: unknown FlyConfig setting {name!r}; one of {', '.join(known)}")
        out[name] = int(value) if known[name] in (int, "int") else float(value)
    FlyConfig(**out).check()
    return out


def _solve_only(jobs: list[dict[str, Any]], out: Path) -> int:
    rows = []
    for i, job in enumerate(jobs):
        rows.append(solve_only(job))
        r = rows[-1]
        print(f"[{i + 1}/{len(jobs)}] {r['kind']} #{r['episode']}: {r['status']} {1000 * r['latency_s']:.0f} ms "
              f"certified {r['certified']}", file=sys.stderr)
    lines = ["| episodes | first re-plans solved | latency p50 / p95 / max (ms) | certified |", "|---|---|---|---|"]
    for k in sorted({r["kind"] for r in rows}):
        sel = [r for r in rows if r["kind"] == k]
        lat = np.array([r["latency_s"] for r in sel]) * 1000
        solved = [r for r in sel if r["status"].endswith("replanned")]
        lines.append(f"| {k}: {len(sel)} | {len(solved)} | {np.percentile(lat, 50):.0f} / "
                     f"{np.percentile(lat, 95):.0f} / {lat.max():.0f} | {sum(r['certified'] for r in solved)}/{len(solved)} |")
    settings = ", ".join(f"{k} = {v}" for k, v in jobs[0].get("config", {}).items()) or "default settings"
    md = "\n".join(lines) + (f"\n\none re-plan at a time, adaptive threads, {settings}, load average "
                             f"{os.getloadavg()[0]:.2f} at the end.\n")
    out.mkdir(parents=True, exist_ok=True)
    (out / "replan_solve.json").write_text(json.dumps(rows, indent=1) + "\n")
    (out / "replan_solve.md").write_text(md)
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
