"""Per-evaluation cost of the compiled engine against team size N and waypoints K.

    python benchmarks/scaling_nk.py            # N = 3, 6, 12, 24 x K = 10, 20, 40 (~30 s)
    python benchmarks/scaling_nk.py --quick    # fewer repetitions

Worlds: ``site`` is the built-in ``site_wedge`` site (GeoTIFF terrain, bilinear; 3 buildings, a
cabin, a crane as two boxes, a no-fly zone, a ceiling); ``bare`` is the same box with flat ground
and no obstacle (the worst case for the pair check: nothing else to amortise it). The team is a
``grid`` fleet of N UAVs, spacing 12 m, crossing west to east. A population of P = 512 team
allocations, waypoints scattered around each UAV's straight line with a normal noise of 6 m
(``spread``: an early swarm) or 1 m (``tight``: a converging swarm), seeded, is evaluated with
the compiled engine's ``evaluate`` (every cost term, formation cost, separation at waypoints and
along segments), one thread. Each case is timed in rounds, all cases in every round (a warm-up
call, then several timed calls), and keeps its best: on a shared host a busy minute then slows
every case a little instead of a few cases a lot (a run measuring the cases one after the
other once saw N = 3 at 309 ns per path against 200 in the runs around it).
Reported: ns per team evaluation, ns per path evaluation (per UAV: team time / N), and per K
the ratio of the per-path time at N = 24 to N = 3 (targets: at most 2 on the site; issue 17:
at most 1.6 on the bare box).

Writes ``benchmarks/results/scaling_nk.csv``, ``scaling_nk.md`` and ``scaling_nk.png``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import provenance  # noqa: E402

from staghunt.costs import CostModel  # noqa: E402
from staghunt.engine.numba_engine import evaluate as fast_evaluate  # noqa: E402
from staghunt.scenario import builtin_path, load_scenario  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
NS = (3, 6, 12, 24)
KS = (10, 20, 40)
P = 512


def team_model(n: int) -> CostModel:
    text = builtin_path("site_wedge").read_text()
    head, fleet = text.split("[fleet]")
    rest = fleet[fleet.index("[costs]"):]
    cols = {3: 3, 6: 3, 12: 4, 24: 6}[n]
    new_fleet = (f"[fleet]\ncount = {n}\ntemplate = \"grid\"\ncolumns = {cols}\nspacing = 12.0\n"
                 "start = [80.0, 200.0, 20.0]\ngoal = [520.0, 215.0, 20.0]\nradius = 1.0\nbeta = 10.0\n"
                 "weights = [10.0, 100.0, 1.0, 1.0, 1.0]\n\n")
    path = Path(os.environ.get("TMPDIR", "/tmp")) / f"scaling_nk_{n}.toml"
    base = builtin_path("site_wedge").parent
    body = head.replace('file = "site_hills.tif"', f'file = "{base / "site_hills.tif"}"')
    body = body.replace('file = "site_buildings.geojson"', f'file = "{base / "site_buildings.geojson"}"')
    path.write_text(body + new_fleet + rest)
    return CostModel.from_scenario(load_scenario(path))


def bare(model: CostModel) -> CostModel:
    """The same model on flat ground without any obstacle or ceiling."""
    import dataclasses

    from staghunt.world import Terrain

    return dataclasses.replace(model, terrain=Terrain(), cylinders=np.zeros((0, 3)), prisms=np.zeros((0, 8)),
                               prism_edges=np.zeros((0, 4)), ceiling=np.inf)


def population(model: CostModel, K: int, seed: int, noise: float = 6.0) -> np.ndarray:
    """``(P, N, K, 3)`` waypoints: the straight lines plus noise (metres), heights 10 - 40 m."""
    rng = np.random.default_rng(seed)
    t = (np.arange(1, K + 1) / (K + 1))[None, None, :, None]
    line = model.starts[None, :, None, :] + t * (model.goals - model.starts)[None, :, None, :]
    wp = line + rng.normal(0.0, noise, size=(P, model.n_uavs, K, 3))
    wp[..., 0] = np.clip(wp[..., 0], model.lower[0], model.upper[0])
    wp[..., 1] = np.clip(wp[..., 1], model.lower[1], model.upper[1])
    wp[..., 2] = np.clip(wp[..., 2], 10.0, 40.0)
    return wp


def best_time(model: CostModel, wp: np.ndarray, reps: int) -> float:
    """The best of ``reps`` timed calls after a warm-up call (compile or cache load, buffers)."""
    fast_evaluate(model, wp)
    best = np.inf
    for _ in range(reps):
        t0 = time.perf_counter()
        fast_evaluate(model, wp)
        best = min(best, time.perf_counter() - t0)
    return best


CONDITIONS = (("site", 6.0), ("site", 1.0), ("bare", 6.0), ("bare", 1.0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    started = provenance.start()
    rounds, reps = (2, 3) if a.quick else (8, 5)
    cases = {}  # (world, noise, N, K) -> (model, waypoints)
    for n in NS:
        site = team_model(n)
        for world, noise in CONDITIONS:
            model = site if world == "site" else bare(site)
            for K in KS:
                cases[(world, noise, n, K)] = (model, population(model, K, seed=n * 100 + K, noise=noise))
    best = dict.fromkeys(cases, np.inf)
    for r in range(rounds):
        for key, (model, wp) in cases.items():
            best[key] = min(best[key], best_time(model, wp, reps))
        print(f"round {r + 1} of {rounds} done")
    rows = []  # (world, noise, N, K, ns per team, ns per path)
    for (world, noise, n, K), t in best.items():
        team_ns = t / P * 1e9
        rows.append((world, noise, n, K, team_ns, team_ns / n))
        print(f"{world:4s} noise {noise:g} m  N = {n:2d}  K = {K:2d}: {team_ns:9.0f} ns per team, "
              f"{team_ns / n:7.0f} ns per path")
    RESULTS.mkdir(exist_ok=True)
    with open(RESULTS / "scaling_nk.csv", "w") as fh:
        fh.write("world,noise_m,N,K,ns_per_team_evaluation,ns_per_path\n")
        for r in rows:
            fh.write(f"{r[0]},{r[1]:g},{r[2]},{r[3]},{r[4]:.0f},{r[5]:.0f}\n")
    per = {(w, z, n, K): p for w, z, n, K, _, p in rows}
    team = {(w, z, n, K): t for w, z, n, K, t, _ in rows}
    report = {"team_allocations_per_call": P, "rounds": rounds, "calls_per_round": reps,
              "rows": [{"world": w, "noise_m": z, "N": n, "K": K, "ns_per_team": round(t, 1), "ns_per_path": round(p, 1)}
                       for w, z, n, K, t, p in rows],
              "ratio_24_to_3": [{"world": w, "noise_m": z, "K": K, "ratio": round(per[(w, z, 24, K)] / per[(w, z, 3, K)], 4)}
                                for w, z in CONDITIONS for K in KS]}
    (RESULTS / "scaling_nk.json").write_text(json.dumps(provenance.stamped(started, report), indent=1) + "\n")
    lines = ["# Per-evaluation time against N and K (compiled engine, one thread)", "",
             f"P = {P} team allocations per call, best of {rounds} rounds x {reps} calls (all cases in every round);",
             "ns per path = ns per team evaluation / N.",
             "Worlds and populations: see the docstring of benchmarks/scaling_nk.py. Separation pairs are",
             "pruned past N = 4 by the boxes of their relative positions over a block's lanes (exact).", ""]
    for w, z in CONDITIONS:
        lines += [f"## {w}, waypoint noise {z:g} m", "",
                  "| N | " + " | ".join(f"K = {K}: ns/team | ns/path" for K in KS) + " |",
                  "|---|" + "---|---|" * len(KS)]
        for n in NS:
            lines.append(f"| {n} | " + " | ".join(f"{team[(w, z, n, K)]:,.0f} | {per[(w, z, n, K)]:,.0f}" for K in KS) + " |")
        lines += ["", "| K | " + " | ".join(str(K) for K in KS) + " |", "|---|" + "---|" * len(KS),
                  "| per path N = 24 / N = 3 | " + " | ".join(
                      f"{per[(w, z, 24, K)] / per[(w, z, 3, K)]:.2f}" for K in KS) + " |", ""]
    (RESULTS / "scaling_nk.md").write_text("\n".join(lines))
    print("\n".join(lines))

    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.5), layout="constrained")
    axes = fig.subplots(1, len(CONDITIONS), sharey=False)
    for ax, (w, z) in zip(axes, CONDITIONS):
        for K in KS:
            ax.plot(NS, [per[(w, z, n, K)] / 1000 for n in NS], marker="o", label=f"K = {K}")
        ax.set_xscale("log", base=2)
        ax.set_xticks(NS, [str(n) for n in NS])
        ax.set_ylim(bottom=0)
        ax.set_xlabel("team size N")
        ax.set_title(f"{w}, noise {z:g} m", fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("µs per path evaluation (team time / N)")
    axes[0].legend()
    fig.suptitle("Compiled engine: per-path cost against N and K (one thread)")
    fig.savefig(RESULTS / "scaling_nk.png", dpi=110)
    print(f"wrote {RESULTS / 'scaling_nk.csv'}, scaling_nk.json, scaling_nk.md, scaling_nk.png")


if __name__ == "__main__":
    main()
