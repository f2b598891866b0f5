"""Method comparison: every method on every seed, scored with the same ``J_n``.

:func:`run_compare` plans ``scenario`` with each method and seed (seed-major: all methods of
seed 1, then seed 2, ...), certifies every plan (:mod:`staghunt.analysis.certify`) and keeps
everything on disk as it goes, so a long run can be interrupted and resumed:

- ``DIR/runs/<method>-s<seed>.json``: the plan's ``result.json`` (written atomically as soon as
  the run ends); ``DIR/runs/<method>-s<seed>.certify.json``: its certificate.
- ``DIR/compare.json`` and ``DIR/compare.csv``: the aggregate of every finished run, rewritten
  atomically after each run. A run whose files already exist is not planned again (resume); if
  they were made with other settings the comparison stops with a ``ValueError`` instead of
  mixing budgets.

Fairness: every method gets the same ``SolverSettings`` (particles, iterations, K), hence the
same budget of single-UAV path evaluations, ``particles x (iterations + 1) x N`` (a joint
evaluation of ``N`` paths counts ``N``; ``independent``'s ``N`` one-UAV runs count one each).
Every allocation is re-scored with the scenario's ``J_n`` (the game's cost model), whatever its
method optimised, and compared with :func:`staghunt.solvers.dominance.dominates` (Pareto
dominance with the feasibility-first rule).

``compare.csv`` has one row per method, seed and UAV (see :data:`CSV_COLUMNS`);
``compare.json`` holds the same runs plus the summary per method and UAV, the dominance verdict
of each seed, the Nash gaps and the paper's Fig. 8 block (:mod:`staghunt.analysis.paper`).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from staghunt.checks import Metrics, plan_metrics
from staghunt.costs import CostModel, evaluate
from staghunt.io.atomic import write_text_atomic
from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.dominance import dominates, preference

COMPARE_FORMAT = "staghunt-compare/1"
DEFAULT_METHODS = ("game", "paper", "rigid", "independent", "weighted")
REFERENCE_METHOD = "game"
_SEED_PART = re.compile(r"(\d+)(?:\s*-\s*(\d+))?")

CSV_COLUMNS = (
    "method", "seed", "uav", "status", "J_n", "ln_J_n", "J_s", "J_f", "path_length",
    "formation_rms", "min_separation_waypoints", "min_separation_segments", "separation_limit",
    "min_clearance", "min_height", "collision_free", "wall_time_s", "evaluations",
    "nash_gap", "nash_gap_relative", "game_dominates",
)


@dataclass(frozen=True)
class CertifyOptions:
    """Budget of the equilibrium certificate of every run (per UAV) and its tolerance."""

    particles: int = 200
    iterations: int = 100
    epsilon: float = 0.01


@dataclass(frozen=True, eq=False)
class RunRecord:
    """One finished (method, seed) run, re-scored with the scenario's ``J_n``.

    ``waypoints``: ``(N, K, 3)``; ``paths``: ``(N, K + 2, 3)`` absolute; ``J``, ``J_s``,
    ``J_f``: ``(N,)``; ``violation``: total constraint violation (0 = feasible);
    ``objective_final``: what the method compared at the end (``(C,)``; for ``rigid`` the
    virtual leader's cost, the team sum); ``certificate``: the certificate as plain data
    (:func:`staghunt.analysis.certify.certificate_to_dict`) or ``None``.
    """

    method: str
    seed: int
    status: str
    names: tuple[str, ...]
    waypoints: np.ndarray
    paths: np.ndarray
    J: np.ndarray
    J_s: np.ndarray
    J_f: np.ndarray
    violation: float
    metrics: Metrics
    wall_time_s: float
    evaluations: int
    objective_final: np.ndarray
    certificate: dict[str, Any] | None = None

    @property
    def feasible(self) -> bool:
        return self.violation == 0 and bool(np.all(np.isfinite(self.J)))

    def uav_collision_free(self) -> np.ndarray:
        """``(N,)`` obstacles cleared, above ground, and separation kept along the segments."""
        m = self.metrics
        return (m.min_clearance >= 0) & (m.min_height >= 0) & (m.min_separation_segments > m.separation_limit)

    def nash_gaps(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(N,)`` absolute and relative Nash gaps (``inf`` for an infeasible plan), if certified."""
        if self.certificate is None:
            return None
        u = self.certificate["uavs"]
        return (np.array([_decode(x["gap"]) for x in u], dtype=float),
                np.array([_decode(x["relative_gap"]) for x in u], dtype=float))


@dataclass(frozen=True, eq=False)
class CompareReport:
    """Everything :func:`run_compare` found: the finished runs (seed-major order) and the
    aggregate written to ``compare.json`` (:attr:`data`)."""

    scenario: Scenario
    methods: tuple[str, ...]
    seeds: tuple[int, ...]
    settings: SolverSettings
    certify: CertifyOptions | None
    records: tuple[RunRecord, ...]
    data: dict[str, Any] = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        return len(self.records) == len(self.methods) * len(self.seeds)


class CompareListener:
    """Hooks for progress reports (the default does nothing); the CLI subclasses it."""

    def run_started(self, index: int, total: int, method: str, seed: int) -> None:
        """Run ``index`` (1-based) of ``total`` is about to be planned."""

    def plan_progress(self, iteration: int, total: int, best_cost: np.ndarray) -> None:
        """The ``progress`` callback handed to :func:`staghunt.plan`."""

    def certify_started(self, index: int, total: int, method: str, seed: int) -> None:
        """The plan of run ``index`` is being certified."""

    def certify_progress(self, uav: int, n_uavs: int, iteration: int, total: int) -> None:
        """Progress of the certificate's best-response searches."""

    def run_finished(self, index: int, total: int, record: RunRecord, resumed: bool) -> None:
        """Run ``index`` is on disk (``resumed``: it was found there, not planned now)."""


# ------------------------------------------------------------------------------------------------
# Small helpers
# ------------------------------------------------------------------------------------------------


def _decode(v: Any) -> float:
    if v == "inf":
        return math.inf
    if v == "-inf":
        return -math.inf
    if v is None:
        return math.nan
    return float(v)


def _enc(v: float) -> float | str | None:
    v = float(v)
    if math.isnan(v):
        return None
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return v


def _enc_list(a: Iterable[float]) -> list[float | str | None]:
    return [_enc(v) for v in a]


def _json_normal(obj: Any) -> Any:
    """``obj`` as it reads back from JSON (tuples become lists...), for comparisons."""
    return json.loads(json.dumps(obj, allow_nan=False))


def parse_seeds(text: str) -> tuple[int, ...]:
    """``"1-10"``, ``"3"``, ``"1,4,7"`` or ``"1-3,8"`` -> seeds in order, duplicates dropped.

    Raises ``ValueError`` with one line for anything else (negative, empty, reversed range).
    """
    out: list[int] = []
    seen: set[int] = set()
    for part in text.split(","):
        match = _SEED_PART.fullmatch(part.strip())
        if match is None:
            raise ValueError(
                f"--seeds: expected seeds >= 0 like 1-10, 7 or 1,4,7, got {text!r}"
            )
        lo = int(match.group(1))
        hi = int(match.group(2)) if match.group(2) is not None else lo
        if lo > hi:
            raise ValueError(f"--seeds: the range {part.strip()!r} runs backwards")
        if hi - lo > 100_000:
            raise ValueError(f"--seeds: the range {part.strip()!r} is too long")
        for v in range(lo, hi + 1):
            if v not in seen:
                seen.add(v)
                out.append(v)
    return tuple(out)


def parse_methods(text: str) -> tuple[str, ...]:
    """``"game,rigid"`` -> methods in order; each must be registered (``ValueError`` otherwise)."""
    from staghunt.solvers import METHODS

    names = [m.strip() for m in text.split(",") if m.strip()]
    if not names:
        raise ValueError("--methods: expected a comma-separated list of methods, got an empty value")
    out: list[str] = []
    for m in names:
        if m not in METHODS:
            raise ValueError(f"--methods: unknown method {m!r}; choose from {', '.join(METHODS)}")
        if m not in out:
            out.append(m)
    return tuple(out)


def run_file(out_dir: Path, method: str, seed: int) -> Path:
    return Path(out_dir) / "runs" / f"{method}-s{seed}.json"


def certificate_file(out_dir: Path, method: str, seed: int) -> Path:
    return Path(out_dir) / "runs" / f"{method}-s{seed}.certify.json"


# ------------------------------------------------------------------------------------------------
# Records
# ------------------------------------------------------------------------------------------------


def record_from_files(
    scenario: Scenario, model: CostModel, result_path: Path, cert_path: Path | None
) -> RunRecord:
    """Rebuild a :class:`RunRecord` from a run's ``result.json`` (and certificate file)."""
    from staghunt.analysis.certify import plan_from_result_data
    from staghunt.io.result_json import load_json_strict, read_result

    data = read_result(result_path)
    _, wp, _ = plan_from_result_data(data, str(result_path))
    costs = evaluate(model, wp[None])
    cert = None
    if cert_path is not None and cert_path.exists():
        cert = load_json_strict(cert_path)
    obj = np.asarray(data.get("objective_history") or [[math.nan]], dtype=float)
    return RunRecord(
        method=str(data["method"]),
        seed=int(data["seed"]),
        status=str(data["status"]),
        names=tuple(u.name for u in scenario.team),
        waypoints=wp,
        paths=np.asarray([u["path"] for u in data["uavs"]], dtype=float),
        J=costs.total[0],
        J_s=costs.single[0],
        J_f=costs.formation[0],
        violation=float(costs.total_violation[0]),
        metrics=plan_metrics(model, wp),
        wall_time_s=float(_decode(data.get("wall_time_s", math.nan))),
        evaluations=int(data.get("evaluations", 0)),
        objective_final=obj[-1],
        certificate=cert,
    )


def _check_stored_run(data: dict[str, Any], path: Path, expect: dict[str, Any]) -> None:
    """A stored run must have been made with the requested scenario, method, seed and settings."""
    for key in ("method", "seed", "settings", "scenario"):
        if _json_normal(data.get(key)) != expect[key]:
            what = {"settings": "solver settings", "scenario": "scenario"}.get(key, key)
            raise ValueError(
                f"{path} was made with a different {what} from the one this comparison asks for; "
                "use another --out directory (or delete that file to plan it again)"
            )


def _check_stored_certificate(data: Any, path: Path, opts: CertifyOptions, seed: int) -> None:
    ok = isinstance(data, dict) and (data.get("particles"), data.get("iterations"), data.get("seed")) == (
        opts.particles, opts.iterations, seed)
    if not ok:
        raise ValueError(
            f"{path} was made with a different certificate budget from the one this comparison asks for; "
            "use another --out directory (or delete that file to certify again)"
        )


# ------------------------------------------------------------------------------------------------
# The comparison
# ------------------------------------------------------------------------------------------------


def run_compare(
    scenario: Scenario,
    out_dir: str | os.PathLike[str],
    *,
    methods: Sequence[str] = DEFAULT_METHODS,
    seeds: Sequence[int] = tuple(range(1, 11)),
    settings: SolverSettings | None = None,
    certify: CertifyOptions | None = CertifyOptions(),
    listener: CompareListener | None = None,
    plan_options: dict[str, Any] | None = None,
) -> CompareReport:
    """Plan ``scenario`` with every method and seed, certify each plan, and aggregate.

    ``settings``: the budget of every method (default: the scenario's). ``certify``: the
    certificate's budget and tolerance, ``None`` to skip certificates. ``plan_options``: extra
    keyword arguments for :func:`staghunt.plan`; its ``engine`` and ``threads``, if any, also run
    the certificates' searches. Files go to ``out_dir`` (see
    the module docstring); a ``KeyboardInterrupt`` leaves every finished run on disk and the
    aggregate files consistent with them. Raises ``ValueError`` for bad input.
    """
    from staghunt.analysis.certify import certificate_to_dict, certify_plan
    from staghunt.api import plan, validate_settings
    from staghunt.io.result_json import read_result, settings_to_dict, write_json_atomic, write_result
    from staghunt.scenario import scenario_to_dict
    from staghunt.solvers import METHODS

    methods = tuple(methods)
    seeds = tuple(int(s) for s in seeds)
    if not methods:
        raise ValueError("no methods to compare")
    if not seeds:
        raise ValueError("no seeds to run")
    for m in methods:
        if m not in METHODS:
            raise ValueError(f"unknown method {m!r}; choose from {', '.join(METHODS)}")
    if len(set(methods)) != len(methods) or len(set(seeds)) != len(seeds):
        raise ValueError("methods and seeds must not repeat")
    if any(s < 0 for s in seeds):
        raise ValueError("seeds must be integers >= 0")
    settings = settings if settings is not None else scenario.solver
    validate_settings(settings)
    if certify is not None:
        if certify.particles < 1 or certify.iterations < 0:
            raise ValueError("certificate budget: particles must be >= 1 and iterations >= 0")
        if not (math.isfinite(certify.epsilon) and certify.epsilon >= 0):
            raise ValueError(f"epsilon must be a finite number >= 0, got {certify.epsilon!r}")
    listener = listener or CompareListener()
    out = Path(out_dir)
    runs_dir = out / "runs"
    try:
        runs_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot create output directory {str(runs_dir)!r}: {exc.strerror or exc}") from None

    model = CostModel.from_scenario(scenario)
    expect_common = {
        "settings": _json_normal(settings_to_dict(settings)),
        "scenario": _json_normal(scenario_to_dict(scenario)),
    }
    engine_options = {k: v for k, v in (plan_options or {}).items() if k in ("engine", "threads")}
    jobs = [(m, s) for s in seeds for m in methods]
    # Check every stored run first, so a mismatch stops the comparison before any work.
    for m, s in jobs:
        rf, cf = run_file(out, m, s), certificate_file(out, m, s)
        if rf.exists():
            _check_stored_run(read_result(rf), rf, {**expect_common, "method": m, "seed": s})
        if certify is not None and cf.exists():
            from staghunt.io.result_json import load_json_strict

            _check_stored_certificate(load_json_strict(cf), cf, certify, s)

    records: list[RunRecord] = []
    report = CompareReport(scenario, methods, seeds, settings, certify, ())
    for index, (m, s) in enumerate(jobs, start=1):
        rf, cf = run_file(out, m, s), certificate_file(out, m, s)
        resumed = rf.exists() and (certify is None or cf.exists())
        if not rf.exists():
            listener.run_started(index, len(jobs), m, s)
            result = plan(scenario, m, s, settings, listener.plan_progress, **(plan_options or {}))
            write_result(result, rf)
        if certify is not None and not cf.exists():
            listener.certify_started(index, len(jobs), m, s)
            data = read_result(rf)
            from staghunt.analysis.certify import plan_from_result_data

            _, wp, _ = plan_from_result_data(data, str(rf))
            cert = certify_plan(scenario, wp, particles=certify.particles,
                                iterations=certify.iterations, seed=s, epsilon=certify.epsilon,
                                settings=settings, progress=listener.certify_progress,
                                **engine_options)
            write_json_atomic(certificate_to_dict(cert), cf)
        record = record_from_files(scenario, model, rf, cf if certify is not None else None)
        records.append(record)
        report = _aggregate(scenario, methods, seeds, settings, certify, records)
        write_json_atomic(report.data, out / "compare.json")
        write_text_atomic(csv_text(report), out / "compare.csv")
        listener.run_finished(index, len(jobs), record, resumed)
    return report


# ------------------------------------------------------------------------------------------------
# Aggregation
# ------------------------------------------------------------------------------------------------


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


def _aggregate(
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
        "paper_fig8": fig8_block(records, scenario, settings),
        "runs": [_record_dict(r, dom) for r in records],
    }
    return CompareReport(scenario, methods, seeds, settings, certify, tuple(records), _encode_tree(data))


def csv_text(report: CompareReport) -> str:
    """``compare.csv``: one row per method, seed and UAV (columns :data:`CSV_COLUMNS`)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    dom = report.data.get("dominance", {})

    def num(v: float) -> str:
        v = float(v)
        if math.isnan(v):
            return ""
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)

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


# ------------------------------------------------------------------------------------------------
# Text report
# ------------------------------------------------------------------------------------------------


def _g(v: Any, fmt: str = ".4g") -> str:
    v = _decode(v) if isinstance(v, str) or v is None else float(v)
    if math.isnan(v):
        return "-"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return format(v, fmt)


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
    fig8 = d.get("paper_fig8")
    if fig8:
        lines += ["", format_fig8(fig8)]
    return "\n".join(lines)
