"""Simulated vehicles: the batched, compiled team against rotorpy stepped one vehicle at a time.

    python benchmarks/vehicles.py                     # 3, 8, 24 UAVs, Hummingbird (~3 min)
    python benchmarks/vehicles.py --sizes 8 --airframe m300 --repeats 1

For each team size, :class:`staghunt.flight.vehicles.SimulatedTeam` (one Numba kernel per step
for the whole team) and :class:`staghunt.flight.vehicles.RotorpyTeam` (rotorpy's ``Multirotor``
and ``SE3Control`` per UAV, scipy's ``solve_ivp`` per UAV and step: what ``fly`` used before)
fly the same reference (each UAV on a loop of 8 m at up to 2.8 m/s, 10 m apart) at 100 Hz in 5
m/s Dryden wind, alternately (batched, rotorpy, batched, ...: the machine is shared, so each
pair sees the same load). Measured per run: simulated seconds per wall second and per CPU second
of this process (user + system; the kernel runs on one thread). Reported: the median of the
runs and the ratio batched / rotorpy of the medians, the agreement of the two teams' positions
over the rotorpy run (max |dx|), and the load average. The batched team flies ``--seconds``
(60 s), rotorpy ``--rotorpy-seconds`` (10 s: rotorpy's speed does not change along a flight).
The one-time compile (or cache load) of the kernel is timed apart, before any run.

Targets (issue 38): 8 UAVs at least 2x faster than real time, 24 UAVs at least real time.
Writes ``benchmarks/results/vehicles.json`` and ``vehicles.md`` (``vehicles_AIRFRAME.*`` for
another airframe than the Hummingbird).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
import provenance

HERE = Path(__file__).resolve().parent
DT = 0.01


def _starts(n: int) -> np.ndarray:
    side = int(np.ceil(np.sqrt(n)))
    return np.array([[10.0 * (i % side), 10.0 * (i // side), 20.0] for i in range(n)])


def _references(starts: np.ndarray, steps: int) -> np.ndarray:
    """``(steps, 4, N, 3)``: from rest, ``x = a (1 - cos wt)``, ``y = a sin^2 wt``, ``a = 8`` m,
    ``w = 0.25`` rad/s, the same for every UAV from its start."""
    t = np.arange(steps) * DT
    a, om, zero = 8.0, 0.25, np.zeros(steps)
    c, s, c2, s2 = np.cos(om * t), np.sin(om * t), np.cos(2 * om * t), np.sin(2 * om * t)
    shape = (steps, len(starts), 3)
    pos = np.stack([a * (1 - c), a * s**2, zero], axis=-1)[:, None, :] + starts[None]
    vel = np.broadcast_to(np.stack([a * om * s, a * om * s2, zero], axis=-1)[:, None, :], shape)
    acc = np.broadcast_to(np.stack([a * om**2 * c, 2 * a * om**2 * c2, zero], axis=-1)[:, None, :], shape)
    return np.stack([pos, vel, acc, np.zeros(shape)], axis=1)


def fly(kind: str, n: int, seconds: float, airframe: str, seed: int) -> tuple[dict[str, float], np.ndarray]:
    """One run; returns its timings and the ``(steps, N, 3)`` positions."""
    from staghunt.flight.vehicles import DrydenGust, RotorpyTeam, SimulatedTeam
    from staghunt.task import VehicleLimits

    steps = int(round(seconds / DT))
    starts = _starts(n)
    refs = _references(starts, steps)
    wind = DrydenGust(np.array([5.0, 0.0, 0.0]), 20.0, DT, np.random.default_rng(seed))
    team_cls = SimulatedTeam if kind == "batched" else RotorpyTeam
    team = team_cls(starts, DT, wind, VehicleLimits(airframe=airframe))
    out = np.empty((steps, n, 3))
    wall, cpu = time.perf_counter(), time.process_time()
    for k in range(steps):
        team.step(k * DT, refs[k])
        out[k] = team.positions()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return {"sim_s": seconds, "wall_s": wall, "cpu_s": cpu, "per_wall": seconds / wall, "per_cpu": seconds / cpu}, out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="3,8,24", help="team sizes, comma-separated")
    ap.add_argument("--airframe", default="hummingbird")
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds per batched run")
    ap.add_argument("--rotorpy-seconds", type=float, default=10.0, help="simulated seconds per rotorpy run")
    ap.add_argument("--repeats", type=int, default=2, help="alternated pairs of runs per size")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args()
    started = provenance.start()

    from staghunt.flight.vehicles import SimulatedTeam

    t0 = time.perf_counter()
    SimulatedTeam(np.zeros((1, 3)), DT, None).step(0.0, np.zeros((4, 1, 3)))  # compile or load the kernel
    compile_s = time.perf_counter() - t0
    rows: list[dict[str, Any]] = []
    load = [os.getloadavg()[0]]
    for n in (int(s) for s in args.sizes.split(",")):
        runs: dict[str, list[dict[str, float]]] = {"batched": [], "rotorpy": []}
        gap = 0.0
        for rep in range(args.repeats):
            got, ours = fly("batched", n, args.seconds, args.airframe, rep)
            runs["batched"].append(got)
            got, theirs = fly("rotorpy", n, args.rotorpy_seconds, args.airframe, rep)
            runs["rotorpy"].append(got)
            gap = max(gap, float(np.abs(ours[: len(theirs)] - theirs).max()))
            load.append(os.getloadavg()[0])
        row: dict[str, Any] = {"uavs": n, "airframe": args.airframe, "max_gap_m": gap, "runs": runs}
        for kind in runs:
            for key in ("per_wall", "per_cpu"):
                row[f"{kind}_{key}"] = statistics.median(r[key] for r in runs[kind])
        for key in ("per_wall", "per_cpu"):
            row[f"ratio_{key}"] = row[f"batched_{key}"] / row[f"rotorpy_{key}"]
        rows.append(row)
        print(f"{n:3d} UAVs: batched {row['batched_per_wall']:7.1f} sim s / wall s ({row['batched_per_cpu']:7.1f} / CPU s), "
              f"rotorpy {row['rotorpy_per_wall']:5.2f} ({row['rotorpy_per_cpu']:5.2f}), ratio "
              f"{row['ratio_per_wall']:6.0f} ({row['ratio_per_cpu']:6.0f}), max |dx| {gap * 1000:.2f} mm", flush=True)
    meta = {"airframe": args.airframe, "seconds": args.seconds, "rotorpy_seconds": args.rotorpy_seconds,
            "repeats": args.repeats, "compile_or_load_s": compile_s, "loadavg": load,
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "cpus": os.cpu_count()}
    args.out.mkdir(parents=True, exist_ok=True)
    stem = "vehicles" if args.airframe == "hummingbird" else f"vehicles_{args.airframe}"
    (args.out / f"{stem}.json").write_text(json.dumps(provenance.stamped(started, {"meta": meta, "rows": rows}), indent=1) + "\n")
    lines = [f"Vehicles, {args.airframe}, 100 Hz, 5 m/s Dryden wind ({meta['date']}; load average "
             f"{min(load):.1f}-{max(load):.1f} on {meta['cpus']} CPUs; kernel compile or cache load "
             f"{compile_s:.1f} s). Simulated seconds per wall second (per CPU second), medians of "
             f"{args.repeats} alternated runs: batched {args.seconds:g} s, rotorpy {args.rotorpy_seconds:g} s.", "",
             "| UAVs | batched | rotorpy one by one | ratio | max \\|dx\\| batched vs rotorpy |",
             "|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['uavs']} | {r['batched_per_wall']:.1f} ({r['batched_per_cpu']:.1f}) | "
                     f"{r['rotorpy_per_wall']:.2f} ({r['rotorpy_per_cpu']:.2f}) | "
                     f"{r['ratio_per_wall']:.0f} ({r['ratio_per_cpu']:.0f}) | {r['max_gap_m'] * 1000:.2f} mm |")
    (args.out / f"{stem}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
