"""Checking, running and resuming a comparison: every (method, seed) run checked once before any
work (:func:`check_compare`), then planned and certified, each stored on disk as soon as it ends;
a run already on disk is read back instead (after checking that it was made with the same
scenario, settings and certificate budget)."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from staghunt.analysis.certify import plan_from_result_data
from staghunt.analysis.compare.formats import aggregate, csv_text
from staghunt.analysis.compare.model import (
    DEFAULT_METHODS,
    CertifyOptions,
    CompareListener,
    CompareReport,
    CompareRequest,
    RunRecord,
    _decode,
    _json_normal,
    certificate_file,
    run_file,
)
from staghunt.api import PlanRequest, check_plan
from staghunt.checks import plan_metrics
from staghunt.costs import CostModel, evaluate
from staghunt.engine import Engine
from staghunt.errors import FieldError
from staghunt.io.atomic import write_text_atomic
from staghunt.io.certificate import certificate_to_dict
from staghunt.io.result_json import load_json_strict, read_result, settings_to_dict, write_json_atomic, write_result
from staghunt.scenario import scenario_to_dict
from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.study.executor import InlineExecutor, TaskFailure, run_tasks
from staghunt.study.tasks import PlanTask, TaskOutcome, run_plan_task

DEFAULT_CERTIFY = CertifyOptions()
"""The certificate of every run unless told otherwise (frozen: one shared default is safe)."""


def record_from_files(
    scenario: Scenario, model: CostModel, result_path: Path, cert_path: Path | None
) -> RunRecord:
    """Rebuild a :class:`RunRecord` from a run's ``result.json`` (and certificate file)."""
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
            raise FieldError(
                f"{path} was made with a different {what} from the one this comparison asks for; "
                "use another output directory (or delete that file to plan it again)", "out"
            )


def _check_stored_certificate(data: Any, path: Path, opts: CertifyOptions, seed: int) -> None:
    ok = isinstance(data, dict) and (data.get("particles"), data.get("iterations"), data.get("seed")) == (
        opts.particles, opts.iterations, seed)
    if not ok:
        raise FieldError(
            f"{path} was made with a different certificate budget from the one this comparison asks for; "
            "use another output directory (or delete that file to certify again)", "out"
        )


# ------------------------------------------------------------------------------------------------
# Running
# ------------------------------------------------------------------------------------------------


def check_compare(
    scenario: Scenario,
    methods: Sequence[str] = DEFAULT_METHODS,
    seeds: Sequence[int] = tuple(range(1, 11)),
    settings: SolverSettings | None = None,
    certify: CertifyOptions | None = DEFAULT_CERTIFY,
    *,
    engine: "str | Engine" = "auto",
    threads: int | None = None,
    warn: Callable[[str], None] | None = None,
) -> CompareRequest:
    """Every check a comparison needs, made once, before any run: at least one method and one
    seed, none repeated, and every run (:func:`staghunt.api.check_plan` per method: the method,
    the settings, the certificate's options, the engine and the memory; then each seed with
    :meth:`~staghunt.api.PlanRequest.with_seed`).

    ``settings``: the budget of every method (default: the scenario's). ``certify``: the
    certificate's budget and tolerance, ``None`` to skip certificates. ``engine`` and
    ``threads``: those of :func:`staghunt.plan`, which also run the certificates' searches (runs
    sent to a cluster: ``threads=1``, the workers are the parallelism). ``warn`` receives the
    memory warning. Returns the :class:`CompareRequest`; raises a
    :class:`~staghunt.errors.FieldError` (``methods``, ``seeds``, or a field of
    :func:`~staghunt.api.check_plan`) or a :class:`~staghunt.budget.MemoryBudgetError`."""
    methods, seeds = tuple(methods), tuple(seeds)
    if not methods:
        raise FieldError("no methods to compare", "methods")
    if not seeds:
        raise FieldError("no seeds to run", "seeds")
    if len(set(methods)) != len(methods):
        raise FieldError("methods must not repeat", "methods")
    if len(set(seeds)) != len(seeds):
        raise FieldError("seeds must not repeat", "seeds")
    settings = settings if settings is not None else scenario.solver
    runs: dict[tuple[str, int], PlanRequest] = {}
    for m in methods:
        first = check_plan(scenario, m, seeds[0], settings, engine, threads, certify, warn=warn)
        per_seed = (first, *(first.with_seed(s) for s in seeds[1:]))
        runs.update({(m, r.seed): r for r in per_seed})
    return CompareRequest(scenario, methods, tuple(r.seed for r in per_seed), settings, certify, runs)


def run_compare(
    request: CompareRequest,
    out_dir: str | os.PathLike[str],
    *,
    listener: CompareListener | None = None,
    executor: Any = None,
) -> CompareReport:
    """Plan the checked comparison ``request`` (:func:`check_compare`) with every method and
    seed, certify each plan, and aggregate.

    ``executor``: where the runs go (:mod:`staghunt.study.executor`; default: in this process,
    one after the other): every run is one task of :func:`staghunt.study.tasks.run_plan_task`,
    the task function of ``staghunt sweep``. Files go to ``out_dir`` (see the module docstring)
    as each run completes; runs are reported to ``listener`` and aggregated in (seed, method)
    order. A ``KeyboardInterrupt`` leaves every finished run on disk and the aggregate files
    consistent with them. Raises ``ValueError`` when ``out_dir`` cannot be created or holds runs
    made with other settings (before any run).
    """
    scenario, methods, seeds = request.scenario, request.methods, request.seeds
    settings, certify = request.settings, request.certify
    executor = executor if executor is not None else InlineExecutor()
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
    jobs = [(m, s) for s in seeds for m in methods]
    # Check every stored run first, so a mismatch stops the comparison before any work.
    for m, s in jobs:
        rf, cf = run_file(out, m, s), certificate_file(out, m, s)
        if rf.exists():
            _check_stored_run(read_result(rf), rf, {**expect_common, "method": m, "seed": s})
        if certify is not None and cf.exists():
            _check_stored_certificate(load_json_strict(cf), cf, certify, s)

    # One task per run not on disk (plan + certificate), or per plan on disk not yet certified.
    tasks: list[PlanTask] = []
    job_of: dict[str, int] = {}
    resumed: dict[int, bool] = {}
    for index, (m, s) in enumerate(jobs):
        rf, cf = run_file(out, m, s), certificate_file(out, m, s)
        key = f"{m}-s{s}"
        if not rf.exists():
            tasks.append(PlanTask(request.runs[(m, s)], key, keep_result=True))
        elif certify is not None and not cf.exists():
            _, wp, _ = plan_from_result_data(read_result(rf), str(rf))
            tasks.append(PlanTask(request.runs[(m, s)], key, waypoints=wp))
        else:
            resumed[index] = True
            continue
        job_of[key] = index
        resumed[index] = False

    def local_task(task: PlanTask) -> TaskOutcome:
        """The task in this process, with the listener's progress hooks."""
        index = job_of[task.key] + 1
        m, s = task.request.method, task.request.seed
        started = []

        def certify_progress(uav: int, n_uavs: int, iteration: int, total: int) -> None:
            if not started:
                started.append(True)
                listener.certify_started(index, len(jobs), m, s)
            listener.certify_progress(uav, n_uavs, iteration, total)

        if task.waypoints is None:
            listener.run_started(index, len(jobs), m, s)
        return run_plan_task(task, progress=listener.plan_progress, certify_progress=certify_progress)

    def store(task: PlanTask, outcome: "TaskOutcome | TaskFailure") -> None:
        m, s = task.request.method, task.request.seed
        if isinstance(outcome, TaskFailure) or not outcome.ok:
            why = outcome.message if isinstance(outcome, TaskFailure) else outcome.error
            raise RuntimeError(f"run {m} seed {s} failed: {why}")
        rf, cf = run_file(out, m, s), certificate_file(out, m, s)
        cert = outcome.certificate
        if outcome.result is not None:
            write_result(outcome.result, rf)
            cert = outcome.result.certificate
        if certify is not None and cert is not None:
            write_json_atomic(certificate_to_dict(cert), cf)

    records: list[RunRecord] = []
    report = CompareReport(scenario, methods, seeds, settings, certify, ())
    landed = {i for i, r in resumed.items() if r}
    reported = 0

    def report_ready() -> None:
        """Report and aggregate, in job order, every run on disk not reported yet."""
        nonlocal reported, report
        while reported < len(jobs) and reported in landed:
            m, s = jobs[reported]
            rf, cf = run_file(out, m, s), certificate_file(out, m, s)
            record = record_from_files(scenario, model, rf, cf if certify is not None else None)
            records.append(record)
            report = aggregate(scenario, methods, seeds, settings, certify, records)
            write_json_atomic(report.data, out / "compare.json")
            write_text_atomic(csv_text(report), out / "compare.csv")
            reported += 1
            listener.run_finished(reported, len(jobs), record, resumed[reported - 1])

    report_ready()
    fn = local_task if executor.local else run_plan_task
    for i, outcome in run_tasks(fn, tasks, executor):
        store(tasks[i], outcome)
        landed.add(job_of[tasks[i].key])
        report_ready()
    return report
