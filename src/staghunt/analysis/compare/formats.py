"""The comparison's outputs: the aggregate written to ``compare.json`` (:func:`aggregate`),
``compare.csv`` (:func:`csv_text`) and the printed report (:func:`format_report`)."""

from __future__ import annotations

import csv
import io
import math
from typing import Any, Sequence

import numpy as np

from staghunt.analysis.compare.model import (
    COMPARE_FORMAT,
    CertifyOptions,
    CompareReport,
    RunRecord,
    _decode,
    _enc,
    _enc_list,
)
from staghunt.analysis.compare.stats import dominance_matrix, dominance_table, summarize
from staghunt.io.numbers import number_text
from staghunt.scenario.model import Scenario, SolverSettings

CSV_COLUMNS = (
    "method", "seed", "uav", "status", "J_n", "ln_J_n", "J_s", "J_f", "path_length",
    "formation_rms", "min_separation_waypoints", "min_separation_segments", "separation_limit",
    "min_clearance", "min_height", "collision_free", "wall_time_s", "evaluations",
    "nash_gap", "nash_gap_relative", "game_dominates",
)

# ------------------------------------------------------------------------------------------------
# compare.json
# ------------------------------------------------------------------------------------------------


def _record_dict(r: RunRecord, dom: dict[str, Any]) -> dict[str, Any]:
    gaps = r.nash_gaps()
    verdict = dom.get(r.method, {}).get("seeds", {}).get(str(r.seed))
    return {
        "method": r.method,
        "seed": r.seed,
        "status": r.status,
        "feasible": r.feasible,
        "violation": r.violation,
        "file": f"runs/{r.method}-s{r.seed}.json",
        "wall_time_s": _enc(r.wall_time_s),
        "evaluations": r.evaluations,
        "objective_final": _enc_list(r.objective_final),
        "J_n": _enc_list(r.J),
        "J_s": _enc_list(r.J_s),
        "J_f": _enc_list(r.J_f),
        "path_length": _enc_list(r.metrics.path_length),
        "formation_rms": _enc_list(r.metrics.formation_rms),
        "min_separation_waypoints": _enc_list(r.metrics.min_separation_waypoints),
        "min_separation_segments": _enc_list(r.metrics.min_separation_segments),
        "min_clearance": _enc_list(r.metrics.min_clearance),
        "collision_free": [bool(v) for v in r.uav_collision_free()],
        "nash_gap": None if gaps is None else _enc_list(gaps[0]),
        "nash_gap_relative": None if gaps is None else _enc_list(gaps[1]),
        "certificate_status": None if r.certificate is None else r.certificate.get("status"),
        "game_dominates": verdict,
    }


def _encode_tree(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _encode_tree(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_encode_tree(v) for v in obj]
    if isinstance(obj, float):
        return _enc(obj)
    return obj


def aggregate(
    scenario: Scenario,
    methods: tuple[str, ...],
    seeds: tuple[int, ...],
    settings: SolverSettings,
    certify: CertifyOptions | None,
    records: Sequence[RunRecord],
) -> CompareReport:
    from staghunt.analysis.paper import fig8_block
    from staghunt.io.result_json import settings_to_dict

    eps = certify.epsilon if certify is not None else None
    summary = summarize(records, methods, eps)
    dom = dominance_table(records, methods)
    matrix = dominance_matrix(records, methods)
    done = {(r.method, r.seed) for r in records}
    data = {
        "format": COMPARE_FORMAT,
        "scenario": scenario.name,
        "methods": list(methods),
        "seeds": list(seeds),
        "settings": settings_to_dict(settings),
        "budget_note": (
            "every method gets particles x (iterations + 1) joint evaluations of N paths = "
            "particles x (iterations + 1) x N single-UAV path evaluations ('independent': N runs "
            "of particles x (iterations + 1) one-UAV evaluations)"
        ),
        "certify": None if certify is None else {
            "particles": certify.particles, "iterations": certify.iterations,
            "epsilon": certify.epsilon, "epsilon_kind": "relative (gap / J_n of the plan)",
            "seed": "the run's seed",
        },
        "complete": len(done) == len(methods) * len(seeds),
        "missing": [f"{m}-s{s}" for s in seeds for m in methods if (m, s) not in done],
        "summary": summary,
        "dominance": dom,
        "dominance_matrix": matrix,
        "paper_fig8": fig8_block(records, scenario, settings),
        "runs": [_record_dict(r, dom) for r in records],
    }
    return CompareReport(scenario, methods, seeds, settings, certify, tuple(records), _encode_tree(data))


# ------------------------------------------------------------------------------------------------
# compare.csv
# ------------------------------------------------------------------------------------------------


def csv_text(report: CompareReport) -> str:
    """``compare.csv``: one row per method, seed and UAV (columns :data:`CSV_COLUMNS`)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    dom = report.data.get("dominance", {})

    def num(v: float) -> str:
        return number_text(v, nan="")

    for r in report.records:
        gaps = r.nash_gaps()
        cf = r.uav_collision_free()
        m = r.metrics
        verdict = dom.get(r.method, {}).get("seeds", {}).get(str(r.seed), "")
        for n, name in enumerate(r.names):
            with np.errstate(divide="ignore"):
                ln = math.log(r.J[n]) if r.J[n] > 0 else -math.inf
            w.writerow([
                r.method, r.seed, name, r.status, num(r.J[n]), num(ln), num(r.J_s[n]), num(r.J_f[n]),
                num(m.path_length[n]), num(m.formation_rms[n]), num(m.min_separation_waypoints[n]),
                num(m.min_separation_segments[n]), num(m.separation_limit[n]), num(m.min_clearance[n]),
                num(m.min_height[n]), int(bool(cf[n])), num(r.wall_time_s), r.evaluations,
                "" if gaps is None else num(gaps[0][n]), "" if gaps is None else num(gaps[1][n]),
                verdict,
            ])
    return buf.getvalue()


def _g(v: Any, fmt: str = ".4g") -> str:
    return number_text(_decode(v) if isinstance(v, str) or v is None else v, fmt, nan="-")


def _pct(v: Any) -> str:
    v = _decode(v) if isinstance(v, str) or v is None else float(v)
    if math.isnan(v):
        return "-"
    if math.isinf(v):
        return "inf"
    return f"{v:.1%}"


def _table(rows: list[tuple[str, ...]], left: int = 2) -> str:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = []
    for r in rows:
        cells = [c.ljust(w) for c, w in zip(r[:left], widths[:left])]
        cells += [c.rjust(w) for c, w in zip(r[left:], widths[left:])]
        lines.append("  ".join(cells).rstrip())
    return "\n".join(lines)


def format_report(report: CompareReport) -> str:
    """The printed comparison: summary table per method and UAV, dominance per seed, Nash gaps
    and the paper's Fig. 8 block."""
    from staghunt.analysis.paper import format_fig8

    d = report.data
    s = report.settings
    lines = [
        f"Comparison on {report.scenario.name}: {len(report.records)} of "
        f"{len(report.methods) * len(report.seeds)} runs ({', '.join(report.methods)}; seeds "
        f"{', '.join(str(x) for x in report.seeds)}), {s.particles} particles x {s.iterations} "
        f"iterations, K = {s.waypoints}.",
        "",
    ]
    header = ("method", "UAV", "J_n mean", "J_n std", "finite", "ln J_n", "length m", "form RMS m",
              "min sep m", "min clear m", "coll-free", "Nash gap", "time s")
    rows = [header]
    for m in report.methods:
        e = d["summary"].get(m)
        if e is None:
            continue
        for n, u in enumerate(e["uavs"]):
            gap = "-"
            if "nash_gap_relative_mean" in u:
                gap = f"{_pct(u['nash_gap_relative_mean'])}/{_pct(u['nash_gap_relative_max'])}"
            rows.append((
                m if n == 0 else "", u["name"], _g(u["J_mean"]), _g(u["J_std"]),
                f"{u['J_finite']}/{e['runs']}", _g(u["lnJ_mean"], ".3f"), _g(u["path_length_mean"], ".1f"),
                _g(u["formation_rms_mean"], ".2f"), _g(u["min_separation_segments"], ".2f"),
                _g(u["min_clearance"], ".2f"), _pct(u["collision_free_rate"]), gap,
                _g(e["wall_time_mean"], ".2f") if n == 0 else "",
            ))
    lines.append(_table(rows))
    lines.append(
        "J_n and ln J_n: mean over the seeds where J_n is finite ('finite'); min sep: least "
        "separation to a team-mate along the segments (continuous), over all seeds; min clear: "
        "least obstacle clearance (negative = collision); coll-free: share of seeds where that UAV "
        "keeps clear of obstacles, ground and team-mates along its whole path; Nash gap: relative "
        "gap, mean/max over seeds (inf = infeasible plan); time: solver wall time per run."
    )
    if d.get("certify"):
        c = d["certify"]
        lines.append(
            f"Certificates: {c['particles']} particles x {c['iterations']} iterations per UAV, "
            f"epsilon = {_pct(c['epsilon'])} relative; epsilon-equilibria per method: "
            + ", ".join(
                f"{m} {round(e.get('equilibrium_rate', 0) * e['runs'])}/{e['runs']}"
                for m, e in d["summary"].items()
            )
        )
    dom = d.get("dominance") or {}
    if dom:
        lines += ["", "Does the game allocation Pareto-dominate the other method's (same J_n, feasibility first)?"]
        seeds = [str(x) for x in report.seeds]
        short = {"game_dominates": "yes", "dominates_game": "no (dominated)", "neither": "no"}
        rows = [("method", *[f"s{x}" for x in seeds], "game dominates")]
        for m, e in dom.items():
            rows.append((m, *[short.get(e["seeds"].get(x, ""), "-") for x in seeds],
                         f"{e['game_dominates']}/{e['compared']}"
                         + (f" (dominated in {e['dominates_game']})" if e["dominates_game"] else "")))
        lines.append(_table(rows, left=1))
    mat = d.get("dominance_matrix")
    if mat and len(mat["methods"]) > 1:
        lines += ["", "Dominance matrix: seeds where the row method's allocation Pareto-dominates the column's"]
        ms = mat["methods"]
        rows = [("row dominates column", *ms)]
        for i, m in enumerate(ms):
            rows.append((m, *["-" if i == j else f"{mat['counts'][i][j]}/{mat['compared'][i][j]}"
                              for j in range(len(ms))]))
        lines.append(_table(rows, left=1))
    fig8 = d.get("paper_fig8")
    if fig8:
        lines += ["", format_fig8(fig8)]
    return "\n".join(lines)
