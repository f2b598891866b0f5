"""Paper-scale benchmark of the swarm engines (run on demand, not part of the test suite).

    python benchmarks/bench.py              # everything but the quality check (~3-5 min)
    python benchmarks/bench.py --quick      # a smoke check of every part (~1 min)
    python benchmarks/bench.py --quality    # also 5 seeds fast vs NumPy at the paper setting (~8 min)

Measures, on scenario 2 with ``game`` (3 UAVs x 2000 particles x 1500 iterations, K = 10):

- the compiled engine, warm (kernels loaded from Numba's cache before timing): solver wall
  time, path evaluations per second (``N * particles * (iterations + 1)`` single-UAV paths),
  peak RSS of the process;
- the NumPy engine on the identical problem for a fixed number of iterations, extrapolated
  linearly to the paper's 1500 (said so in the output), and the ratio;
- the one-time compile in a fresh process with an empty ``NUMBA_CACHE_DIR``, and the first
  end-to-end ``staghunt plan scenario2 --no-plots --quiet`` with that empty cache;
- the warm end-to-end ``staghunt plan scenario2 --no-plots --quiet``;
- 1 vs 2 threads vs adaptive, on an idle machine and with one core kept busy by a busy-loop
  process;
- scaling of the time per iteration in particles (500 .. 8000), waypoints K (10, 20, 40) and
  team size N (3, 6, 12, 24: a formation of N built here, scenario 2's obstacles);
- with ``--quality``: per-UAV ``J_n`` of 5 seeds per engine at the paper setting, compared
  with a two-sided Mann-Whitney U test.

Every measurement runs in its own subprocess (``--worker``), so peak memory is that run's.
Writes ``benchmarks/results/``: ``summary.md``, ``bench.json``, ``scaling.csv``,
``scaling.png`` and (``--quality``) ``quality.csv``. Other processes on the machine disturb
timings: each timing is the best of a few repetitions, and the load average is recorded.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import provenance

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
PAPER = {"particles": 2000, "iterations": 1500, "waypoints": 10}


# --------------------------------------------------------------------------------------------
# Workers (run in a subprocess; print one JSON line)


def formation_scenario(n: int) -> Any:
    """A team of ``n`` UAVs on a 7 m grid (5 columns) flying north-east across scenario 2's
    site and obstacles; ring formation graph (a chain for ``n <= 2``), reference = the goals."""
    from staghunt.scenario import load_scenario, scenario_from_dict, scenario_to_dict

    base = scenario_to_dict(load_scenario("scenario2"))
    cols = 5
    starts = [[8.0 + 7.0 * (i % cols), 8.0 + 7.0 * (i // cols), 20.0] for i in range(n)]
    goals = [[s[0] + 55.0, s[1] + 58.0, 20.0] for s in starts]
    team = [{"name": f"UAV{i + 1}", "start": starts[i], "goal": goals[i], "radius": 1.0,
             "beta": 100.0, "weights": [1.0, 100.0, 1.0, 1.0, 1.0]} for i in range(n)]
    edges = [(i, (i + 1) % n) for i in range(n)] if n > 2 else [(0, 1)]
    incidence = [[0] * len(edges) for _ in range(n)]
    weights = [[0.0] * len(edges) for _ in range(n)]
    for e, (h, t) in enumerate(edges):
        incidence[h][e], incidence[t][e] = 1, -1
        weights[h][e] = weights[t][e] = 1.0
    data = {k: v for k, v in base.items() if k not in ("team", "formation", "name", "description")}
    data.update(name=f"formation{n}", description=f"{n} UAVs on a grid, ring graph, scenario 2 obstacles",
                team=team, formation={"incidence": incidence, "edge_weights": weights})
    return scenario_from_dict(data, name=f"formation{n}")


def first_line(text: str) -> str:
    return text.splitlines()[0] if text else ""


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def worker_solver(spec: dict[str, Any]) -> dict[str, Any]:
    """Time ``run_swarm`` of one engine on the ``game`` problem of ``spec``."""
    import numpy as np

    from staghunt.costs import CostModel
    from staghunt.engine import get_engine
    from staghunt.scenario import load_scenario
    from staghunt.solvers.problem import team_problem

    scenario = load_scenario("scenario2") if spec["n"] == 3 and not spec.get("grid") else formation_scenario(spec["n"])
    settings = scenario.solver.with_(particles=spec["particles"], iterations=spec["iterations"],
                                     waypoints=spec["waypoints"])
    model = CostModel.from_scenario(scenario)
    problem = team_problem(model, settings.waypoints, settings.velocity_fraction, "players")
    engine = get_engine(spec["engine"], spec.get("threads"))
    t0 = time.perf_counter()
    engine.prepare()
    load_s = time.perf_counter() - t0
    times, outs = [], []
    for rep in range(spec.get("repeat", 1)):
        t0 = time.perf_counter()
        out = engine.run_swarm(problem, settings, np.random.default_rng(spec.get("seed", 0) + rep))
        times.append(time.perf_counter() - t0)
        outs.append(out)
    threads_used: dict[int, int] = {}
    if engine.name == "numba":  # the thread counts the compiled engine chose
        from staghunt.engine.numba_engine import NumbaEngine

        assert isinstance(engine, NumbaEngine)
        threads_used = engine.last_threads
    best = min(times)
    evals = model.n_uavs * settings.particles * (settings.iterations + 1)
    return {
        "engine": engine.name,
        "threads": spec.get("threads"),
        "threads_used": threads_used,
        "n": model.n_uavs,
        "particles": settings.particles,
        "iterations": settings.iterations,
        "waypoints": settings.waypoints,
        "load_s": load_s,
        "times_s": times,
        "best_s": best,
        "per_iteration_ms": 1e3 * best / (settings.iterations + 1),
        "path_evals_per_s": evals / best,
        "peak_rss_mb": peak_rss_mb(),
        "best_cost": [float(c) for c in outs[0].best_cost],
        "feasible": bool(outs[0].best_violation == 0),
    }


def worker_compile(spec: dict[str, Any]) -> dict[str, Any]:
    """Cold (or warm) :func:`prepare` in this fresh process."""
    t0 = time.perf_counter()
    from staghunt.engine import numba_engine

    import_s = time.perf_counter() - t0
    messages: list[str] = []
    seconds = numba_engine.prepare(notify=messages.append, parallel=spec.get("parallel", True))
    return {"import_s": import_s, "prepare_s": seconds, "messages": messages, "peak_rss_mb": peak_rss_mb()}


def worker_quality(spec: dict[str, Any]) -> dict[str, Any]:
    """One paper-setting ``game`` plan; each UAV's ``J_n`` (NumPy evaluation of the plan)."""
    from staghunt import plan

    t0 = time.perf_counter()
    result = plan("scenario2", "game", spec["seed"], engine=spec["engine"])
    return {"engine": spec["engine"], "seed": spec["seed"], "J": [float(v) for v in result.costs.total[0]],
            "feasible": result.feasible, "wall_s": time.perf_counter() - t0}


WORKERS = {"solver": worker_solver, "compile": worker_compile, "quality": worker_quality}


# --------------------------------------------------------------------------------------------
# Driver


def run_worker(kind: str, spec: dict[str, Any], env: dict[str, str] | None = None, timeout: float = 3600) -> dict[str, Any]:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", kind, json.dumps(spec)]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"worker {kind} {spec} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def loadavg() -> list[float]:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return []


def cli_plan(cache_dir: str | None, repeat: int) -> dict[str, Any]:
    """Wall time of ``staghunt plan scenario2 --no-plots --quiet`` (best and all of ``repeat``)."""
    exe = shutil.which("staghunt")
    base = [exe] if exe else [sys.executable, "-m", "staghunt"]
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    times, stderr, code = [], "", 0
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeat):
            out = Path(tmp) / f"run{i}"
            t0 = time.perf_counter()
            proc = subprocess.run([*base, "plan", "scenario2", "--no-plots", "--quiet", "--out", str(out)],
                                  capture_output=True, text=True, env=env)
            times.append(time.perf_counter() - t0)
            stderr, code = stderr or proc.stderr.strip(), proc.returncode
    return {"times_s": times, "best_s": min(times), "exit_code": code, "stderr_first_run": stderr[:400]}


class BusyCore:
    """A busy-loop process keeping one core occupied (ended by its own pid on exit)."""

    def __enter__(self) -> "BusyCore":
        self.proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        time.sleep(0.5)
        return self

    def __exit__(self, *exc: object) -> None:
        self.proc.kill()
        self.proc.wait()


def fmt(x: float, digits: int = 3) -> str:
    return f"{x:.{digits}g}" if abs(x) < 1e4 else f"{x:.3e}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="shrink everything for a smoke check")
    ap.add_argument("--quality", action="store_true", help="also 5 seeds per engine at the paper setting")
    ap.add_argument("--skip-cold", action="store_true", help="skip the cold-compile measurements")
    ap.add_argument("--out", default=str(RESULTS), help="results directory (default: benchmarks/results)")
    ap.add_argument("--worker", nargs=2, metavar=("KIND", "SPEC"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(WORKERS[args.worker[0]](json.loads(args.worker[1]))))
        return 0

    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    q = args.quick
    paper = dict(PAPER) if not q else {"particles": 500, "iterations": 100, "waypoints": 10}
    numpy_iters = 10 if q else 50
    started = provenance.start()
    report: dict[str, Any] = {"quick": q, "machine": {
        "python": platform.python_version(), "platform": platform.platform(),
        "cores": os.cpu_count(), "usable_cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "loadavg_start": loadavg(),
    }}
    try:
        import numba
        import numpy

        report["machine"].update(numba=numba.__version__, numpy=numpy.__version__)
    except ImportError:
        pass

    def log(msg: str) -> None:
        print(msg, flush=True)

    # 1. One-time compile and first end-to-end run, each with an empty cache.
    if not args.skip_cold:
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache)
            report["cold_compile"] = run_worker("compile", {}, env=env)
            report["cold_compile_serial"] = None
            if not q:
                with tempfile.TemporaryDirectory() as cache2:
                    env2 = dict(os.environ, NUMBA_CACHE_DIR=cache2)
                    report["cold_compile_serial"] = run_worker("compile", {"parallel": False}, env=env2)
        with tempfile.TemporaryDirectory() as cache:
            report["cli_first_run"] = cli_plan(cache, 1)
        log(f"cold compile {report['cold_compile']['prepare_s']:.1f} s; first CLI run "
            f"{report['cli_first_run']['best_s']:.1f} s")

    # 2. Make sure the default cache is warm, then the paper setting, both engines.
    run_worker("compile", {})
    spec = {"n": 3, **paper, "engine": "numba", "threads": None, "repeat": 1 if q else 3}
    report["paper_numba"] = run_worker("solver", spec)
    log(f"numba paper setting: {report['paper_numba']['best_s']:.2f} s")
    spec_np = {"n": 3, "particles": paper["particles"], "iterations": numpy_iters,
               "waypoints": paper["waypoints"], "engine": "numpy", "repeat": 1}
    report["paper_numpy_measured"] = run_worker("solver", spec_np)
    per_it = report["paper_numpy_measured"]["best_s"] / (numpy_iters + 1)
    report["paper_numpy_extrapolated_s"] = per_it * (paper["iterations"] + 1)
    report["speedup"] = report["paper_numpy_extrapolated_s"] / report["paper_numba"]["best_s"]
    log(f"numpy: {per_it * 1e3:.1f} ms/iteration -> {report['paper_numpy_extrapolated_s']:.0f} s extrapolated; "
        f"ratio {report['speedup']:.0f}x")

    # 3. Warm end-to-end CLI.
    report["cli_warm"] = cli_plan(None, 1 if q else 3)
    log(f"warm CLI: {report['cli_warm']['best_s']:.2f} s")

    # 4. Threads, idle and with one core busy.
    t_iters = 50 if q else 300
    threads = {}
    for busy in (False, True):
        for t in (1, 2, None):
            s = {"n": 3, "particles": paper["particles"], "iterations": t_iters, "waypoints": 10,
                 "engine": "numba", "threads": t, "repeat": 2}
            if busy:
                with BusyCore():
                    r = run_worker("solver", s)
            else:
                r = run_worker("solver", s)
            key = f"{'busy' if busy else 'idle'}-{t if t else 'auto'}"
            threads[key] = {"per_iteration_ms": r["per_iteration_ms"], "threads_used": r["threads_used"]}
            log(f"threads {key}: {r['per_iteration_ms']:.2f} ms/iteration {r['threads_used']}")
    report["threads"] = threads

    # 5. Scaling (one thread, for clean linearity), time per iteration.
    s_iters = 20 if q else 100
    grid = [("particles", p, 3, 10) for p in ((500, 2000) if q else (500, 1000, 2000, 4000, 8000))]
    grid += [("waypoints", 2000, 3, k) for k in ((10, 40) if q else (10, 20, 40))]
    grid += [("uavs", 2000, n, 10) for n in ((3, 12) if q else (3, 6, 12, 24))]
    rows = []
    for axis, p, n, k in grid:
        r = run_worker("solver", {"n": n, "grid": axis == "uavs", "particles": p, "iterations": s_iters,
                                  "waypoints": k, "engine": "numba", "threads": 1, "repeat": 2})
        rows.append({"axis": axis, "uavs": n, "particles": p, "waypoints": k, "iterations": s_iters,
                     "per_iteration_ms": r["per_iteration_ms"],
                     "ns_per_path_eval": 1e9 * r["best_s"] / (n * p * (s_iters + 1)),
                     "peak_rss_mb": r["peak_rss_mb"]})
        log(f"scaling {axis}: N={n} P={p} K={k}: {r['per_iteration_ms']:.2f} ms/iteration")
    report["scaling"] = rows
    with open(out_dir / "scaling.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    plot_scaling(rows, out_dir / "scaling.png")

    # 6. Quality: 5 seeds per engine at the paper setting (NumPy runs two at a time).
    if args.quality:
        report["quality"] = quality(q, out_dir)

    report["machine"]["loadavg_end"] = loadavg()
    report = provenance.stamped(started, report)
    (out_dir / "bench.json").write_text(json.dumps(report, indent=1))
    (out_dir / "summary.md").write_text(summary(report, paper, numpy_iters))
    log(f"wrote {out_dir / 'summary.md'}")
    return 0


def quality(quick: bool, out_dir: Path) -> dict[str, Any]:
    import numpy as np
    from concurrent.futures import ThreadPoolExecutor

    seeds = list(range(1, 3 if quick else 6))
    runs: list[dict[str, Any]] = []
    for seed in seeds:
        runs.append(run_worker("quality", {"engine": "numba", "seed": seed}))
    with ThreadPoolExecutor(2) as pool:  # two single-threaded NumPy processes at a time
        runs += list(pool.map(lambda s: run_worker("quality", {"engine": "numpy", "seed": s}), seeds))
    with open(out_dir / "quality.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["engine", "seed", "feasible", "J1", "J2", "J3", "wall_s"])
        for r in runs:
            w.writerow([r["engine"], r["seed"], r["feasible"], *r["J"], round(r["wall_s"], 2)])
    out: dict[str, Any] = {"seeds": seeds, "runs": runs, "per_uav": []}
    try:
        from scipy.stats import mannwhitneyu
    except ImportError:  # pragma: no cover
        mannwhitneyu = None
    for n in range(3):
        a = np.array([r["J"][n] for r in runs if r["engine"] == "numba"])
        b = np.array([r["J"][n] for r in runs if r["engine"] == "numpy"])
        p = float(mannwhitneyu(a, b, alternative="two-sided").pvalue) if mannwhitneyu else math.nan
        out["per_uav"].append({"uav": n + 1, "numba_mean": a.mean(), "numba_std": a.std(ddof=1) if len(a) > 1 else 0.0,
                               "numpy_mean": b.mean(), "numpy_std": b.std(ddof=1) if len(b) > 1 else 0.0,
                               "numba_log_mean": float(np.log(a).mean()), "numpy_log_mean": float(np.log(b).mean()),
                               "mann_whitney_p": p})
    out["feasible"] = {e: sum(r["feasible"] for r in runs if r["engine"] == e) for e in ("numba", "numpy")}
    return out


def plot_scaling(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    for ax, (axis, key, label) in zip(axes, [("particles", "particles", "particles (N = 3, K = 10)"),
                                             ("waypoints", "waypoints", "waypoints K (N = 3, 2000 particles)"),
                                             ("uavs", "uavs", "UAVs N (2000 particles, K = 10)")]):
        sel = [r for r in rows if r["axis"] == axis]
        x = [r[key] for r in sel]
        y = [r["per_iteration_ms"] for r in sel]
        ax.plot(x, y, "o-", label="measured")
        if axis != "uavs" and len(x) > 1:  # proportional fit through the origin
            c = sum(a * b for a, b in zip(x, y)) / sum(a * a for a in x)
            ax.plot(x, [c * a for a in x], "--", color="grey", label="linear fit")
        ax.set_xlabel(label)
        ax.set_ylabel("ms per iteration (1 thread)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("numba engine, scenario-2 obstacles, game problem")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def summary(r: dict[str, Any], paper: dict[str, int], numpy_iters: int) -> str:
    m = r["machine"]
    pn, pp = r["paper_numba"], r["paper_numpy_measured"]
    lines = [
        "# Engine benchmark" + (" (quick smoke run: reduced sizes)" if r["quick"] else ""),
        "",
        f"Machine: {m.get('platform')}, Python {m.get('python')}, NumPy {m.get('numpy')}, Numba {m.get('numba')}, "
        f"{m.get('usable_cores')} usable cores; load average at start {m.get('loadavg_start')}, end {m.get('loadavg_end')}.",
        "",
        f"Paper setting: scenario 2, `game`, {paper['particles']} particles x {paper['iterations']} iterations, "
        f"K = {paper['waypoints']}, 3 UAVs = {3 * paper['particles'] * (paper['iterations'] + 1):,} path evaluations.",
        "",
        "| measure | value |",
        "|---|---|",
        f"| numba solver, warm (best of {len(pn['times_s'])}) | {pn['best_s']:.2f} s "
        f"(all: {', '.join(f'{t:.2f}' for t in pn['times_s'])}) |",
        f"| numba path evaluations / s | {pn['path_evals_per_s']:.3g} |",
        f"| numba threads used (iterations per count) | {pn['threads_used']} |",
        f"| numba peak RSS (whole process) | {pn['peak_rss_mb']:.0f} MB |",
        f"| numpy, measured over {numpy_iters} iterations | {pp['per_iteration_ms']:.1f} ms / iteration, "
        f"peak RSS {pp['peak_rss_mb']:.0f} MB |",
        f"| numpy, **extrapolated** linearly to {paper['iterations']} iterations | {r['paper_numpy_extrapolated_s']:.0f} s |",
        f"| numpy path evaluations / s | {3 * paper['particles'] / (pp['per_iteration_ms'] / 1e3):.3g} |",
        f"| speed-up numba / numpy | {r['speedup']:.0f}x |",
        f"| `staghunt plan scenario2 --no-plots --quiet`, warm (best of {len(r['cli_warm']['times_s'])}) | "
        f"{r['cli_warm']['best_s']:.2f} s |",
    ]
    if "cold_compile" in r:
        cc = r["cold_compile"]
        lines += [
            f"| one-time compile, empty cache, 2 processes | {cc['prepare_s']:.1f} s (peak RSS {cc['peak_rss_mb']:.0f} MB) |",
        ]
        if r.get("cold_compile_serial"):
            lines.append(f"| one-time compile, empty cache, 1 process | {r['cold_compile_serial']['prepare_s']:.1f} s |")
        lines += [
            f"| first `staghunt plan scenario2 --no-plots --quiet`, empty cache | {r['cli_first_run']['best_s']:.1f} s |",
            f"| its message on stderr | `{first_line(r['cli_first_run']['stderr_first_run'])}` |",
        ]
    lines += ["", "Threads (ms per iteration, same problem; `auto` = adaptive default):", "",
              "| machine | 1 thread | 2 threads | auto (iterations per count) |", "|---|---|---|---|"]
    t = r["threads"]
    for state in ("idle", "busy"):
        lines.append(f"| {state if state == 'idle' else 'one core busy (busy-loop process)'} | "
                     f"{t[state + '-1']['per_iteration_ms']:.2f} | {t[state + '-2']['per_iteration_ms']:.2f} | "
                     f"{t[state + '-auto']['per_iteration_ms']:.2f} {t[state + '-auto']['threads_used']} |")
    lines += ["", "Scaling (1 thread; `scaling.csv`, `scaling.png`):", "",
              "| axis | N | particles | K | ms / iteration | ns / path evaluation | peak RSS MB |",
              "|---|---|---|---|---|---|---|"]
    for row in r["scaling"]:
        lines.append(f"| {row['axis']} | {row['uavs']} | {row['particles']} | {row['waypoints']} | "
                     f"{row['per_iteration_ms']:.2f} | {row['ns_per_path_eval']:.0f} | {row['peak_rss_mb']:.0f} |")
    if "quality" in r:
        qq = r["quality"]
        lines += ["", f"Quality at the paper setting, seeds {qq['seeds']} per engine (`quality.csv`); "
                  f"feasible plans: {qq['feasible']}. Two-sided Mann-Whitney U on each UAV's final J_n:", "",
                  "| UAV | numba mean (std) | numpy mean (std) | numba / numpy mean log J | p |", "|---|---|---|---|---|"]
        for u in qq["per_uav"]:
            lines.append(f"| {u['uav']} | {u['numba_mean']:.0f} ({u['numba_std']:.0f}) | {u['numpy_mean']:.0f} "
                         f"({u['numpy_std']:.0f}) | {u['numba_log_mean']:.2f} / {u['numpy_log_mean']:.2f} | "
                         f"{u['mann_whitney_p']:.2f} |")
    lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
