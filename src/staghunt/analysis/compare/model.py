"""The comparison's data: the checked request (:class:`CompareRequest`), one finished run
(:class:`RunRecord`), the report, the progress hooks; parsing seed and method lists; where runs are stored; the JSON encoding of
non-finite numbers (``"inf"``, ``"-inf"``, ``null`` for NaN)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from staghunt.api import PlanRequest
from staghunt.checks import Metrics
from staghunt.errors import FieldError
from staghunt.inputs import parse_seeds  # noqa: F401  (re-exported: compare's seed lists)
from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.response import CertifyOptions

COMPARE_FORMAT = "staghunt-compare/1"
DEFAULT_METHODS = ("game", "paper", "rigid", "independent", "weighted")
REFERENCE_METHOD = "game"


@dataclass(frozen=True, eq=False)
class CompareRequest:
    """A comparison that :func:`~staghunt.analysis.compare.check_compare` has checked: the
    scenario, the methods and seeds (each once, in order), the budget and certificate options
    every run shares, and every run's checked :class:`~staghunt.api.PlanRequest`
    (``runs[(method, seed)]``). :func:`~staghunt.analysis.compare.run_compare` runs it without
    checking anything again."""

    scenario: Scenario
    methods: tuple[str, ...]
    seeds: tuple[int, ...]
    settings: SolverSettings
    certify: CertifyOptions | None
    runs: Mapping[tuple[str, int], PlanRequest]


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


def parse_methods(text: str) -> tuple[str, ...]:
    """``"game,rigid"`` -> method names in order, duplicates dropped (:class:`FieldError` for an
    empty list). Whether each is a method is checked with the rest of its run
    (:func:`~staghunt.analysis.compare.check_compare`)."""
    names = tuple(dict.fromkeys(m.strip() for m in text.split(",") if m.strip()))
    if not names:
        raise FieldError("methods: expected a comma-separated list of methods, got an empty value", "methods")
    return names


def run_file(out_dir: Path, method: str, seed: int) -> Path:
    return Path(out_dir) / "runs" / f"{method}-s{seed}.json"


def certificate_file(out_dir: Path, method: str, seed: int) -> Path:
    return Path(out_dir) / "runs" / f"{method}-s{seed}.certify.json"
