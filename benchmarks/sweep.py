"""Throughput of ``staghunt sweep``: the same 40-task sweep with ``--workers 1`` (in this
process) and then ``--workers 2`` (a local Dask cluster of 2 worker processes), in one run;
prints tasks per minute of each and their ratio (target >= 1.7x on 2 cores), with the load
average before and after (the machine may be shared: say so when reporting).

    python benchmarks/sweep.py             # 40 tasks: scenario 1, game, 20 seeds x 2 betas
    python benchmarks/sweep.py --quick     # 8 tasks at a tiny budget (smoke check)
    python benchmarks/sweep.py --rounds 3  # three rounds, each 1 worker then 2; the median ratio

The engine's kernels are loaded (or compiled) once before the first timing; each sweep writes to
a fresh directory, so nothing is skipped. Elapsed times run from the first task submitted to the
last row written (the cluster's start-up is reported apart).

Each round then runs the same 40 tasks once more without Dask: two plain processes, each with
half of the tasks inline, started at the same instant: what two cores of this machine give this
workload at best (the ceiling the Dask ratio is to be read against).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import provenance

SPEC = """
scenarios = ["scenario1"]
methods = ["game"]
seeds = "{seeds}"
particles = {particles}
iterations = {iterations}
waypoints = 8

[certificate]
particles = {cert_particles}
iterations = {cert_iterations}

[grid]
beta = [0.5, 2]
"""


def concurrency(out: Path, elapsed: float) -> tuple[float, float, float]:
    """(mean task wall time, sum of task wall times / elapsed: how many tasks ran at once, sum of
    the tasks' CPU times / elapsed: how many cores the tasks actually got)."""
    import pyarrow.parquet as pq

    t = pq.read_table(out / "results.parquet", columns=["task_time_s", "cpu_time_s"]).to_pydict()
    wall, cpu = t["task_time_s"], t["cpu_time_s"]
    return sum(wall) / len(wall), sum(wall) / elapsed, sum(cpu) / elapsed


def part(spec_path: Path, index: int, parts: int, out: Path, at: float) -> None:
    """Child of :func:`plain_processes`: tasks ``index::parts`` of the spec inline, starting at
    wall-clock time ``at`` (after this process has loaded the kernels); prints the elapsed time."""
    from staghunt.study.executor import InlineExecutor
    from staghunt.study.spec import expand, load_spec
    from staghunt.study.sweep import run_sweep, warm_engine

    sweep = expand(*load_spec(spec_path))
    warm_engine(sweep)
    time.sleep(max(0.0, at - time.time()))
    s = run_sweep(sweep, out, InlineExecutor(), tasks=sweep.tasks[index::parts])
    print(json.dumps({"done": s.done, "failed": s.failed, "elapsed_s": s.elapsed_s}))


def plain_processes(spec_path: Path, out: Path, parts: int = 2) -> tuple[float, int]:
    """The sweep split into ``parts`` plain processes (no Dask) started together: (elapsed time
    of the slowest, tasks done); each process's elapsed time runs from the common start."""
    at = time.time() + 6.0  # every child has loaded the kernels by then (about 1 s)
    procs = [subprocess.Popen([sys.executable, __file__, "--part", str(i), str(parts), str(spec_path),
                               str(out / f"p{i}"), repr(at)], stdout=subprocess.PIPE, text=True)
             for i in range(parts)]
    outs = [json.loads(p.communicate()[0].strip().splitlines()[-1]) for p in procs]
    if any(p.returncode for p in procs):
        raise SystemExit("a plain process failed")
    return max(o["elapsed_s"] for o in outs), sum(o["done"] + o["failed"] for o in outs)


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--rounds", type=int, default=1, help="repeat (1 worker, then 2) this many times; "
                    "the load of a shared machine drifts (default: 1)")
    ap.add_argument("--json", metavar="FILE", help="also write the figures as JSON")
    ap.add_argument("--part", nargs=5, help=argparse.SUPPRESS)
    args = ap.parse_args()
    started = provenance.start()
    if args.part:
        index, parts, spec_path, out, at = args.part
        part(Path(spec_path), int(index), int(parts), Path(out), float(at))
        return
    from staghunt.study.executor import DaskExecutor, InlineExecutor
    from staghunt.study.spec import expand, load_spec
    from staghunt.study.sweep import run_sweep, warm_engine, warm_workers

    budget = (dict(seeds="1-4", particles=10, iterations=5, cert_particles=6, cert_iterations=2) if args.quick
              else dict(seeds="1-20", particles=600, iterations=300, cert_particles=200, cert_iterations=100))
    rounds: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory() as tmp:
        spec_path = Path(tmp) / "bench.toml"
        spec_path.write_text(SPEC.format(**budget))
        sweep = expand(*load_spec(spec_path))
        print(f"{len(sweep.tasks)} tasks; budget {budget}")
        print(f"engine ready in {warm_engine(sweep):.1f} s")
        for r in range(args.rounds):
            before = load()
            print(f"round {r + 1}: load average before: {before}")
            s1 = run_sweep(sweep, Path(tmp) / f"w1-{r}", InlineExecutor())
            mean1, conc1, cores1 = concurrency(Path(tmp) / f"w1-{r}", s1.elapsed_s)
            print(f"  --workers 1: {s1.done} done, {s1.failed} failed in {s1.elapsed_s:.1f} s "
                  f"({s1.throughput * 60:.1f} tasks/min; {mean1:.2f} s per task, {conc1:.2f} at once, "
                  f"{cores1:.2f} cores used); load {load()}")
            t0 = time.perf_counter()
            with DaskExecutor(workers=2) as ex:
                loaded = warm_workers(sweep, ex)
                startup = time.perf_counter() - t0
                print(f"  cluster up and kernels loaded on every worker in {startup:.1f} s "
                      f"(loading took at most {max(loaded):.2f} s per worker)")
                s2 = run_sweep(sweep, Path(tmp) / f"w2-{r}", ex)
            mean2, conc2, cores2 = concurrency(Path(tmp) / f"w2-{r}", s2.elapsed_s)
            print(f"  --workers 2: {s2.done} done, {s2.failed} failed in {s2.elapsed_s:.1f} s "
                  f"({s2.throughput * 60:.1f} tasks/min; {mean2:.2f} s per task, {conc2:.2f} at once, "
                  f"{cores2:.2f} cores used; cluster start-up {startup:.1f} s apart); load {load()}")
            ratio = s2.throughput / s1.throughput if s1.throughput else float("nan")
            with_startup = s1.elapsed_s / (s2.elapsed_s + startup)
            print(f"  throughput ratio 2 workers / 1 worker: {ratio:.2f}x (target >= 1.7x); "
                  f"{with_startup:.2f}x counting the cluster's start-up")
            plain_s, plain_n = plain_processes(spec_path, Path(tmp) / f"p-{r}")
            ceiling = (plain_n / plain_s) / s1.throughput if s1.throughput else float("nan")
            print(f"  2 plain processes (no Dask), half of the tasks each: {plain_n} done in {plain_s:.1f} s: "
                  f"{ceiling:.2f}x the 1-worker throughput (this machine's ceiling for the workload); "
                  f"Dask reaches {ratio / ceiling:.0%} of it; load {load()}")
            rounds.append(dict(load_before=before, load_after=load(), workers1_s=s1.elapsed_s,
                               workers2_s=s2.elapsed_s, task1_s=mean1, task2_s=mean2, at_once1=conc1,
                               at_once2=conc2, cores1=cores1, cores2=cores2, startup_s=startup, ratio=ratio,
                               ratio_with_startup=with_startup, plain2_s=plain_s, ceiling=ceiling))
    ratios = sorted(float(r["ratio"]) for r in rounds)  # type: ignore[arg-type]
    ceilings = sorted(float(r["ceiling"]) for r in rounds)  # type: ignore[arg-type]
    print(f"ratio per round: {', '.join(f'{x:.2f}x' for x in ratios)}; median {statistics.median(ratios):.2f}x; "
          f"two plain processes: median {statistics.median(ceilings):.2f}x")
    if args.json:
        Path(args.json).write_text(json.dumps(provenance.stamped(started, {"tasks": len(sweep.tasks), "budget": budget,
                                                                      "rounds": rounds}), indent=2))

if __name__ == "__main__":
    main()
