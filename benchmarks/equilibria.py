"""Equilibrium selection (issue 18) at the paper's budget: the equilibria the multi-start ``game``
finds, whether a payoff-dominant one exists, and what the selection costs, in one run.

For each budget (``--budget``, default both: ``paper``, the scenario's own particles x
iterations, and ``500x300``), scenario (default: scenario1, scenario2) and seed (default 1-20),
with the compiled engine (``--threads``, default 2) and the default certificate (400 x 200 per
UAV, epsilon 1 %):

- ``game`` with one start (the single-start method of staghunt 0.2, the baseline) and with
  ``--starts`` starts (default: the scenario's); the two runs of a seed alternate, so both see the
  same machine load. Time = search + certificates (every start's), the time to the selected
  certified equilibrium.
- The cross-seed check of the issue: the selected plan of every seed is a certified
  1 %-equilibrium, and no equilibrium found on *any* seed of that scenario (by either
  configuration) Pareto-dominates it (eq. 9a), reported both strictly and "beyond the tolerance"
  (better for no UAV by less than epsilon, i.e. the certificate can tell the two apart).
- The distinct equilibria of each scenario over all seeds (merged within epsilon,
  :func:`staghunt.solvers.selection.select`), which of them are dominated, and whether one
  dominates all the others.

    python benchmarks/equilibria.py                 # both budgets; ~15 min on a quiet 2-core machine
    python benchmarks/equilibria.py --budget 500x300 --seeds 1-2 --no-write

Writes ``benchmarks/results/equilibria.md``, ``.json`` and ``.png`` (the paper's budget) and
``equilibria_500x300.*`` (or ``equilibria_PxI.*``), one set per budget.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np
import provenance

import staghunt
from staghunt.inputs import parse_seeds
from staghunt.engine import get_engine
from staghunt.plots.equilibria import EquilibriaPanel, equilibria_figure
from staghunt.solvers.dominance import dominates
from staghunt.solvers.response import CertifyOptions
from staghunt.solvers.selection import Candidate, select

RESULTS = Path(__file__).parent / "results"
EPSILON = CertifyOptions().epsilon


def parse_budget(text: str) -> tuple[int, int] | None:
    """``"paper"`` -> ``None`` (the scenario's own particles x iterations), ``"500x300"`` -> ``(500, 300)``."""
    if text == "paper":
        return None
    try:
        p, i = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: a budget is 'paper' or PARTICLESxITERATIONS, e.g. 500x300") from None
    if p < 1 or i < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: particles and iterations must be at least 1")
    return p, i


def budget_name(budget: tuple[int, int] | None) -> str:
    return "paper" if budget is None else f"{budget[0]}x{budget[1]}"


def results_stem(budget: tuple[int, int] | None) -> str:
    """``equilibria`` (the paper's budget) or ``equilibria_500x300``."""
    return "equilibria" if budget is None else f"equilibria_{budget_name(budget)}"


def one_run(scenario, seed: int, starts: int, engine, budget: tuple[int, int] | None = None) -> dict:
    settings = scenario.solver.with_(starts=starts)
    if budget is not None:
        settings = settings.with_(particles=budget[0], iterations=budget[1])
    t0 = time.perf_counter()
    r = staghunt.plan(scenario, "game", seed, settings, engine=engine, certify=CertifyOptions())
    total = time.perf_counter() - t0 - r.compile_time_s
    found = r.details.get("candidates") or [{
        "start": "rigid", "J": r.costs.total[0].tolist(), "feasible": r.feasible,
        "certificate": {"status": r.certificate.status, "max_relative_gap": r.certificate.max_relative_gap}}]
    return {
        "seed": seed, "starts": starts, "time_s": total, "search_s": r.wall_time_s,
        "certificate_s": r.certificate_time_s, "evaluations": r.evaluations,
        "J": r.costs.total[0].tolist(), "status": r.certificate.status,
        "max_relative_gap": r.certificate.max_relative_gap,
        "selection": r.details.get("selection"),
        "candidates": [{"start": c["start"], "J": c["J"],
                        "certified": bool(c["certificate"] and c["certificate"]["status"] == "equilibrium")}
                       for c in found],
    }


def _dominates(a, b, tol: float = 0.0) -> bool:
    """``a`` Pareto-dominates ``b`` (9a); with ``tol``: and is better somewhere by more than ``tol``."""
    a, b = np.asarray(a), np.asarray(b)
    if not bool(dominates(a, np.zeros(()), b, np.zeros(()))):
        return False
    return bool(np.any(a < b * (1 - tol)))


def scenario_summary(runs: list[dict], starts: int) -> dict:
    everything = [(r["seed"], r["starts"], c) for r in runs for c in r["candidates"] if c["certified"]]

    class _Certified:  # what select() asks of a certificate: every pooled plan was certified
        is_equilibrium = True

    pool = [Candidate(c["start"], np.zeros(0), np.asarray(c["J"]), 0.0, _Certified(), 0)  # type: ignore[arg-type]
            for _, _, c in everything]
    sel = select(pool, EPSILON) if pool else None
    distinct = [] if sel is None else [
        {"J": [round(x, 1) for x in pool[i].J], "start": pool[i].start, "seed": everything[i][0],
         "from_starts": everything[i][1], "dominated": d,
         "found": sum(1 for h in sel.same_as if h == i)}
        for i, d in zip(sel.equilibria, sel.dominated)]
    checks = {}
    for cfg in sorted({r["starts"] for r in runs}):
        sel_runs = [r for r in runs if r["starts"] == cfg]
        strict = [r["seed"] for r in sel_runs
                  if any(_dominates(c["J"], r["J"]) for _, _, c in everything)]
        beyond = [r["seed"] for r in sel_runs
                  if any(_dominates(c["J"], r["J"], EPSILON) for _, _, c in everything)]
        checks[cfg] = {
            "certified": sum(r["status"] == "equilibrium" for r in sel_runs), "runs": len(sel_runs),
            "dominated_strict": strict, "dominated_beyond_epsilon": beyond,
            "median_time_s": statistics.median(r["time_s"] for r in sel_runs),
        }
    times = {r["seed"]: {} for r in runs}
    for r in runs:
        times[r["seed"]][r["starts"]] = r["time_s"]
    ratios = [t[starts] / t[1] for t in times.values() if 1 in t and starts in t]
    return {"distinct": distinct, "payoff_dominant": bool(sel and sel.payoff_dominant),
            "checks": checks, "time_ratio_median": statistics.median(ratios) if ratios else None,
            "time_ratio_max": max(ratios) if ratios else None}


def markdown(report: dict) -> str:
    s = report["starts"]
    b = report["budget"]
    at = "at the paper's budget" if b["name"] == "paper" else f"at {b['particles']} x {b['iterations']}"
    lines = [f"# Equilibrium selection {at} (`game`, 1 start vs {s} starts)", "",
             f"Machine: {report['machine']}; load before/after: {report['load_before']} / {report['load_after']}. "
             f"Compiled engine, {report.get('threads', 2)} thread(s), certificate 400 x 200 per UAV, epsilon 1 %.", ""]
    for name, summ in report["scenarios"].items():
        lines += [f"## {name}", "", "| starts | certified | selected dominated (strict) | "
                  "dominated beyond 1 % | median time (s) |", "|---|---|---|---|---|"]
        for cfg, c in summ["checks"].items():
            lines.append(f"| {cfg} | {c['certified']}/{c['runs']} | seeds {c['dominated_strict'] or 'none'} | "
                         f"seeds {c['dominated_beyond_epsilon'] or 'none'} | {c['median_time_s']:.2f} |")
        lines += ["", f"Time of {s} starts / 1 start, per seed: median {summ['time_ratio_median']:.2f}, "
                  f"max {summ['time_ratio_max']:.2f}.", "",
                  f"Distinct equilibria found over all seeds (merged within 1 %): {len(summ['distinct'])}; "
                  f"payoff-dominant one: **{'yes' if summ['payoff_dominant'] else 'no'}**.", "",
                  "| J (per UAV) | start | first seed | found | dominated |", "|---|---|---|---|---|"]
        for d in summ["distinct"]:
            lines.append(f"| {', '.join(f'{x:.0f}' for x in d['J'])} | {d['start']} | {d['seed']} | "
                         f"{d['found']} | {'yes' if d['dominated'] else 'no'} |")
        lines.append("")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenarios", default="scenario1,scenario2")
    ap.add_argument("--seeds", default="1-20")
    ap.add_argument("--starts", type=int, default=None, help="default: the scenario's")
    ap.add_argument("--budget", type=parse_budget, action="append", default=None,
                    help="'paper' (the scenario's own particles x iterations) or PxI, e.g. 500x300; "
                    "repeat for several (default: paper and 500x300)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    engine = get_engine("numba", threads=args.threads)
    engine.prepare()
    for budget in args.budget or [None, (500, 300)]:
        run_budget(args, budget, engine)


def run_budget(args, budget: tuple[int, int] | None, engine) -> None:
    """Every scenario and seed at one budget; writes ``results_stem(budget)``.json/.md/.png."""
    started = provenance.start()
    report: dict = {"machine": f"{platform.machine()}, {os.cpu_count()} cores", "load_before": os.getloadavg()[0],
                    "threads": args.threads, "budget": {"name": budget_name(budget)}, "scenarios": {}, "runs": {}}
    for name in args.scenarios.split(","):
        scenario = staghunt.load_scenario(name)
        starts = args.starts or scenario.solver.starts
        report["starts"] = starts
        p, i = budget or (scenario.solver.particles, scenario.solver.iterations)
        report["budget"].update(particles=p, iterations=i)
        runs = []
        for seed in parse_seeds(args.seeds):
            for cfg in ((1, starts) if seed % 2 else (starts, 1)):
                r = one_run(scenario, seed, cfg, engine, budget)
                runs.append(r)
                print(f"[{budget_name(budget)}] {name} seed {seed} starts {cfg}: {r['time_s']:.2f} s, "
                      f"J {np.round(r['J'])}, {r['status']}, {r['selection'] and r['selection']['selected_start']}",
                      flush=True)
        report["runs"][name] = runs
        report["scenarios"][name] = scenario_summary(runs, starts)
    report["load_after"] = os.getloadavg()[0]
    text = markdown(report)
    print(text)
    if not args.no_write:
        RESULTS.mkdir(exist_ok=True)
        stem = results_stem(budget)
        (RESULTS / f"{stem}.json").write_text(json.dumps(provenance.stamped(started, report), indent=1))
        (RESULTS / f"{stem}.md").write_text(text)
        panels = [EquilibriaPanel(name, np.array([d["J"] for d in summ["distinct"]]),
                                  np.array([d["dominated"] for d in summ["distinct"]]),
                                  np.array([r["J"] for r in report["runs"][name] if r["starts"] == report["starts"]]),
                                  tuple(f"UAV{n + 1}" for n in range(len(report["runs"][name][0]["J"]))))
                  for name, summ in report["scenarios"].items()]
        equilibria_figure(panels).savefig(RESULTS / f"{stem}.png", dpi=110)

if __name__ == "__main__":
    main()
