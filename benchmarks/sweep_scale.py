"""How ``staghunt sweep`` scales with the number of tasks (issue 40): for 10^4, 10^5 and 10^6
tasks, the time to expand and check the spec, the time to find which tasks are already in
``results.parquet`` (an empty store, and one holding half of the tasks), and the time from the
command's start to its first line and to its first finished task on a local Dask cluster of two
workers.

    python benchmarks/sweep_scale.py                      # 10^4, 10^5, 10^6 (about 5 minutes)
    python benchmarks/sweep_scale.py --quick              # 10^4 only
    python benchmarks/sweep_scale.py --baseline 6f97d01   # also the code of a commit (up to 10^5)
    python benchmarks/sweep_scale.py --json benchmarks/results/sweep_scale.json

Two shapes of spec per size, both on scenario 1 with two methods: *seeds* (5 grid combinations,
the seeds make the size: the usual study) and *grid* (one seed, every task its own combination
of ``beta`` and ``uav.2.beta``: the worst case for a per-combination cost). Each measurement
runs in a fresh process (its peak RSS is reported); times are wall clock and CPU (user + sys)
of that process, whose CPU time is the figure to read when the machine is shared. The store of
half the tasks is written in parts of 2,000 rows (what a fast sweep's 2-s flushes write), each
row with its key, labels, costs and a 6 x 3 history.

The time to the first finished task runs the real command (``staghunt sweep SPEC --workers 2
--no-figures``, engine ``numpy`` so that no timing includes a compile of the kernels) in a
subprocess and stops it with Ctrl-C (SIGINT) after its first progress line; the time that stop
takes is reported too. ``--baseline COMMIT`` runs the same measurements on the ``src/`` of that
commit (``git archive``) for the sizes up to 10^5 (10^6 takes the old code many minutes).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import provenance

ROOT = Path(__file__).resolve().parents[1]
SIZES = (10_000, 100_000, 1_000_000)
METHODS = 2
SPEC = """scenarios = ["scenario1"]
methods = ["game", "rigid"]
seeds = "{seeds}"
particles = 20
iterations = 5
waypoints = 4
engine = "{engine}"

[certificate]
particles = 10
iterations = 2

[grid]
{grid}
"""


def spec_text(size: int, shape: str, engine: str = "numba") -> str:
    """A spec of ``size`` tasks: ``seeds`` (5 betas x seeds x 2 methods) or ``grid`` (one seed,
    ``size / 2`` combinations of beta x uav.2.beta x 2 methods)."""
    if shape == "seeds":
        n = size // (5 * METHODS)
        ranges = ",".join(f"{lo}-{min(lo + 99_999, n)}" for lo in range(1, n + 1, 100_000))
        return SPEC.format(seeds=ranges, engine=engine, grid="beta = [0.5, 1, 2, 4, 8]")
    combos = size // METHODS
    a = 1000 if combos >= 1000 else 100
    b = combos // a
    betas = ", ".join(f"{0.01 * (i + 1):.2f}" for i in range(a))
    uav = ", ".join(f"{0.5 + 0.01 * i:.2f}" for i in range(b))
    return SPEC.format(seeds="1", engine=engine, grid=f"beta = [{betas}]\nuav.2.beta = [{uav}]")


def peak_rss_mb() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def cpu() -> float:
    t = os.times()
    return t.user + t.system


def measure(spec_path: Path, out: Path) -> None:
    """Child: expand the spec, then open the store and find the pending tasks; prints JSON."""
    from staghunt.study.spec import expand, load_spec
    from staghunt.study.sweep import open_stores, pending

    w0, c0 = time.perf_counter(), cpu()
    sweep = expand(*load_spec(spec_path))
    n = len(sweep.tasks)
    w1, c1 = time.perf_counter(), cpu()
    results, _ = open_stores(out, sweep)
    todo = pending(sweep, results)
    w2, c2 = time.perf_counter(), cpu()
    print(json.dumps({"tasks": n, "todo": len(todo), "expand_s": w1 - w0, "expand_cpu_s": c1 - c0,
                      "check_s": w2 - w1, "check_cpu_s": c2 - c1, "peak_rss_mb": peak_rss_mb()}))


def fill(spec_path: Path, out: Path) -> None:
    """Child: write every other task of the spec into ``out/results.parquet`` (parts of 2,000 rows)."""
    from staghunt.study.spec import expand, load_spec
    from staghunt.study.sweep import open_stores

    sweep = expand(*load_spec(spec_path))
    keys = sweep.keys() if hasattr(sweep, "keys") else (t.key for t in sweep.tasks)
    results, _ = open_stores(out, sweep)
    rows: list[dict[str, object]] = []
    for i, key in enumerate(keys):
        if i % 2 == 0:
            rows.append({"key": key, "scenario": "scenario1", "method": "game", "seed": i, "beta": 1.0,
                         "particles": 20, "iterations": 5, "waypoints": 4, "engine": "numba", "status": "feasible",
                         "J": [1.0, 2.0, 3.0], "J_s": [1.0, 2.0, 3.0], "J_f": [0.0, 0.0, 0.0],
                         "max_relative_gap": 0.0, "equilibrium": True, "evaluations": 400,
                         "history": [[1.0, 2.0, 3.0]] * 6, "worker": "bench:0", "version": "bench"})
        if len(rows) == 2000:
            results.append(rows)
            rows = []
    results.append(rows)


def child(args: list[str], src: Path, timeout: float = 1800) -> dict[str, object]:
    env = dict(os.environ, PYTHONPATH=str(src))
    p = subprocess.run([sys.executable, __file__, "--child", *args], env=env, capture_output=True, text=True, timeout=timeout)
    if p.returncode:
        raise SystemExit(f"child {args} failed: {p.stderr.strip().splitlines()[-1:]}")
    lines = p.stdout.strip().splitlines()
    return json.loads(lines[-1]) if lines else {}


def first_task(spec_path: Path, out: Path, src: Path, timeout: float = 600) -> dict[str, float]:
    """The real command on a local cluster of 2 workers, stopped with SIGINT after its first
    progress line: seconds from the start to the first line, to the first finished task, and
    from SIGINT to the exit."""
    env = dict(os.environ, PYTHONPATH=str(src), PYTHONUNBUFFERED="1")
    t0 = time.perf_counter()
    # SIGINT back to its default in the child: a shell ignores it in background jobs, and the
    # child would inherit that (and run to the end).
    p = subprocess.Popen([sys.executable, "-m", "staghunt", "sweep", str(spec_path), "--out", str(out),
                          "--workers", "2", "--no-figures"], env=env, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    got: dict[str, float] = {}
    assert p.stderr is not None
    for line in p.stderr:
        now = time.perf_counter() - t0
        if "first_line_s" not in got:
            got["first_line_s"] = now
        if "Traceback" in line or "ERROR" in line:
            got["errors"] = got.get("errors", 0) + 1
        if "sweep [" in line:
            got["first_task_s"] = now
            p.send_signal(signal.SIGINT)
            t1 = time.perf_counter()
            rest = p.communicate(timeout=timeout)[1]
            got["stop_s"] = time.perf_counter() - t1
            got["errors"] = got.get("errors", 0) + rest.count("Traceback") + rest.count(" ERROR ")
            got["exit"] = p.returncode
            return got
        if now > timeout:
            break
    p.kill()
    p.wait()
    raise SystemExit(f"no finished task within {timeout:.0f} s ({got})")


def baseline_src(commit: str, tmp: Path) -> Path:
    dest = tmp / f"src-{commit}"
    dest.mkdir()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit, "src"], check=True, capture_output=True)
    subprocess.run(["tar", "-x", "-C", str(dest)], input=archive.stdout, check=True)
    return dest / "src"


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="10^4 tasks only")
    ap.add_argument("--baseline", metavar="COMMIT", help="also measure the code of COMMIT (sizes up to 10^5)")
    ap.add_argument("--json", metavar="FILE", help="also write the figures as JSON")
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    started = provenance.start()
    if args.child:
        what, spec_path, out = args.child
        (measure if what == "measure" else fill)(Path(spec_path), Path(out))
        return
    sizes = SIZES[:1] if args.quick else SIZES
    records: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        codes = {"current": ROOT / "src"}
        if args.baseline:
            codes[f"baseline {args.baseline}"] = baseline_src(args.baseline, tmp)
        print(f"load average at the start: {load()}")
        for size in sizes:
            for shape in ("seeds", "grid"):
                spec_path = tmp / f"{shape}-{size}.toml"
                spec_path.write_text(spec_text(size, shape))
                half = tmp / f"half-{shape}-{size}"
                child(["fill", str(spec_path), str(half)], ROOT / "src")
                for code, src in codes.items():
                    if code != "current" and size > 100_000:
                        continue
                    empty = child(["measure", str(spec_path), str(tmp / f"empty-{shape}-{size}-{len(records)}")], src)
                    work = tmp / f"work-{len(records)}"
                    shutil.copytree(half, work)
                    done = child(["measure", str(spec_path), str(work)], src)
                    rec = {"size": size, "shape": shape, "code": code, "empty": empty, "half": done, "load": load()}
                    records.append(rec)
                    print(f"{size:>9,} tasks ({shape:5}), {code}: expand {empty['expand_s']:.2f} s "
                          f"(CPU {empty['expand_cpu_s']:.2f} s), check an empty store {empty['check_s']:.2f} s; "
                          f"half done: check {done['check_s']:.2f} s (CPU {done['check_cpu_s']:.2f} s), "
                          f"{done['todo']:,} to run; expand + check {done['expand_s'] + done['check_s']:.2f} s; "
                          f"peak RSS {done['peak_rss_mb']:.0f} MB; load {rec['load']}", flush=True)
                shutil.rmtree(half)
        for size in sizes:
            spec_path = tmp / f"first-{size}.toml"
            spec_path.write_text(spec_text(size, "seeds", engine="numpy"))
            for code, src in codes.items():
                if code != "current" and size > 100_000:
                    continue
                got = first_task(spec_path, tmp / f"first-{size}-{len(records)}", src)
                records.append({"size": size, "shape": "seeds", "code": code, "cluster": got, "load": load()})
                print(f"{size:>9,} tasks, {code}: first line after {got['first_line_s']:.1f} s, first finished "
                      f"task after {got['first_task_s']:.1f} s (local cluster of 2 workers, its start-up "
                      f"included); Ctrl-C took {got['stop_s']:.1f} s (exit {got['exit']}, "
                      f"{got['errors']} traceback or error lines); load {load()}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(provenance.stamped(started, {"records": records}), indent=2) + "\n")


if __name__ == "__main__":
    main()
