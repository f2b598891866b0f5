"""Statistics and dominance over the finished runs: per method and UAV summaries, whether the
game allocation Pareto-dominates each other method's (per seed), the best seed of a method."""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from staghunt.analysis.compare.model import REFERENCE_METHOD, RunRecord
from staghunt.solvers.dominance import dominates, preference


def _finite(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v[np.isfinite(v)]


def _stat(v: np.ndarray, how: str) -> float:
    f = _finite(v)
    if f.size == 0:
        return math.inf if np.asarray(v).size else math.nan
    return float({"mean": np.mean, "std": np.std, "min": np.min, "max": np.max}[how](f))


def summarize(records: Sequence[RunRecord], methods: Sequence[str], epsilon: float | None) -> dict[str, Any]:
    """Per method: run counts, rates and times; per method and UAV: ``J_n`` statistics (over the
    seeds where it is finite; ``J_n finite`` counts them), mean ``ln J_n``, path length,
    formation RMS error, worst separations and clearance over the seeds, collision-free rate and
    Nash gaps. Standard deviations are population (``ddof = 0``)."""
    out: dict[str, Any] = {}
    for m in methods:
        rs = [r for r in records if r.method == m]
        if not rs:
            continue
        names = rs[0].names
        J = np.array([r.J for r in rs])  # (R, N)
        cf = np.array([r.uav_collision_free() for r in rs])
        gaps = [r.nash_gaps() for r in rs]
        have_gaps = all(g is not None for g in gaps)
        entry: dict[str, Any] = {
            "runs": len(rs),
            "seeds": [r.seed for r in rs],
            "feasible_rate": float(np.mean([r.feasible for r in rs])),
            "collision_free_rate": float(np.mean(cf.all(axis=1))),
            "wall_time_mean": _stat(np.array([r.wall_time_s for r in rs]), "mean"),
            "wall_time_std": _stat(np.array([r.wall_time_s for r in rs]), "std"),
            "evaluations": sorted({r.evaluations for r in rs}),
            "objective_final_mean": _stat(np.array([r.objective_final[0] for r in rs]), "mean")
            if all(r.objective_final.size == 1 for r in rs) else None,
            "ln_objective_final_mean": _stat(np.log(np.array([r.objective_final[0] for r in rs])), "mean")
            if all(r.objective_final.size == 1 and r.objective_final[0] > 0 for r in rs) else None,
        }
        if have_gaps and epsilon is not None:
            rel = np.array([g[1] for g in gaps])  # type: ignore[index]
            entry["equilibrium_rate"] = float(np.mean([r.feasible and bool(np.all(x <= epsilon))
                                                       for r, x in zip(rs, rel)]))
        uavs = []
        for n, name in enumerate(names):
            with np.errstate(divide="ignore"):
                lnJ = np.log(J[:, n])
            u: dict[str, Any] = {
                "name": name,
                "J_mean": _stat(J[:, n], "mean"),
                "J_std": _stat(J[:, n], "std"),
                "J_finite": int(np.isfinite(J[:, n]).sum()),
                "lnJ_mean": _stat(lnJ, "mean"),
                "lnJ_std": _stat(lnJ, "std"),
                "path_length_mean": _stat(np.array([r.metrics.path_length[n] for r in rs]), "mean"),
                "formation_rms_mean": _stat(np.array([r.metrics.formation_rms[n] for r in rs]), "mean"),
                "min_separation_segments": float(np.min([r.metrics.min_separation_segments[n] for r in rs])),
                "min_separation_waypoints": float(np.min([r.metrics.min_separation_waypoints[n] for r in rs])),
                "separation_limit": float(rs[0].metrics.separation_limit[n]),
                "min_clearance": float(np.min([r.metrics.min_clearance[n] for r in rs])),
                "collision_free_rate": float(np.mean(cf[:, n])),
            }
            if have_gaps:
                ab = np.array([g[0][n] for g in gaps])  # type: ignore[index]
                rl = np.array([g[1][n] for g in gaps])  # type: ignore[index]
                u.update({
                    "nash_gap_mean": float(np.mean(ab)) if np.all(np.isfinite(ab)) else math.inf,
                    "nash_gap_max": float(np.max(ab)),
                    "nash_gap_relative_mean": float(np.mean(rl)) if np.all(np.isfinite(rl)) else math.inf,
                    "nash_gap_relative_max": float(np.max(rl)),
                })
            uavs.append(u)
        entry["uavs"] = uavs
        out[m] = entry
    return out


def dominance_table(records: Sequence[RunRecord], methods: Sequence[str],
                    reference: str = REFERENCE_METHOD) -> dict[str, Any]:
    """For each seed and each other method: does the ``reference`` (game) allocation
    Pareto-dominate it (same ``J_n``, feasibility first), is it dominated, or neither; and counts.
    Empty if the reference method is not compared."""
    if reference not in methods:
        return {}
    ref = {r.seed: r for r in records if r.method == reference}
    out: dict[str, Any] = {}
    for m in methods:
        if m == reference:
            continue
        per_seed: dict[str, str] = {}
        counts = {"game_dominates": 0, "dominates_game": 0, "neither": 0}
        for r in records:
            if r.method != m or r.seed not in ref:
                continue
            g = ref[r.seed]
            a = bool(dominates(g.J, np.float64(g.violation), r.J, np.float64(r.violation)))
            b = bool(dominates(r.J, np.float64(r.violation), g.J, np.float64(g.violation)))
            verdict = "game_dominates" if a else ("dominates_game" if b else "neither")
            counts[verdict] += 1
            per_seed[str(r.seed)] = verdict
        out[m] = {"seeds": per_seed, **counts, "compared": sum(counts.values())}
    return out


def dominance_matrix(records: Sequence[RunRecord], methods: Sequence[str]) -> dict[str, Any]:
    """Method x method: ``counts[i][j]`` = seeds where method ``i``'s allocation Pareto-dominates
    method ``j``'s (same ``J_n``, feasibility first, eq. (9b)); ``compared[i][j]`` = seeds both
    ran. The diagonal is 0."""
    by = {(r.method, r.seed): r for r in records}
    M = len(methods)
    counts = [[0] * M for _ in range(M)]
    compared = [[0] * M for _ in range(M)]
    seeds = sorted({r.seed for r in records})
    for i, a in enumerate(methods):
        for j, b in enumerate(methods):
            if i == j:
                continue
            for s in seeds:
                ra, rb = by.get((a, s)), by.get((b, s))
                if ra is None or rb is None:
                    continue
                compared[i][j] += 1
                counts[i][j] += bool(dominates(ra.J, np.float64(ra.violation), rb.J, np.float64(rb.violation)))
    return {"methods": list(methods), "counts": counts, "compared": compared}


def best_seed(records: Sequence[RunRecord], method: str) -> RunRecord | None:
    """The method's best run: least violation, then least ``sum_n ln J_n`` (the dominance
    tie-break of :func:`staghunt.solvers.dominance.preference`), then the lowest seed."""
    rs = sorted((r for r in records if r.method == method), key=lambda r: r.seed)
    if not rs:
        return None
    cost = np.array([r.J for r in rs])
    viol = np.array([r.violation for r in rs])
    key, v = preference(cost, viol)
    order = np.lexsort((np.arange(len(rs)), key, v))
    return rs[int(order[0])]
