"""The first `staghunt plan scenario2 --no-plots` on an empty Numba cache, timed as a user meets it.

Each run gets a fresh ``NUMBA_CACHE_DIR``; the wall time is the command's, the CPU time (user +
sys) that of every process of its tree, the compile helper included, also while it goes on
after the plan has ended (it compiles what the run could start without). Several source trees
(``src/`` directories, e.g. this checkout and a ``git worktree`` of an older commit) are run in
turn, A B A B ..., so that a comparison holds while the shared machine's load drifts; the load
average is recorded before and after each run. One JSON object a line on stdout, and all of
them in ``results/first_run.json`` (with the date, the code and the machine), which the README's
first-run figures quote (``python benchmarks/figures.py`` re-quotes them):

    python benchmarks/first_run.py                          # 3 runs of this checkout, labelled "new"
    python benchmarks/first_run.py --runs 3 new=src old=/path/to/old/src   # A B A B A B
    python benchmarks/first_run.py --warm-pairs 3 new=src old=...   # then warm runs, A B alternated

After each first run, the next run on the cache it left (``next_run_compile_time_s``: loading
the kernels). ``--warm-pairs`` adds warm runs of Algorithm 1 and the default method, ns per path
evaluation, the sources alternated (the warm speed a change must keep).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import provenance
import psutil

ROOT = Path(__file__).resolve().parent.parent


def cold_run(src: str) -> dict:
    """One first run of the code in ``src`` on an empty cache."""
    cache = tempfile.mkdtemp(prefix="staghunt-cold-")
    out = tempfile.mkdtemp(prefix="staghunt-out-")
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=os.path.abspath(src))
    load_before = os.getloadavg()[0]
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "staghunt", "plan", "scenario2", "--no-plots", "--out", out],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    cpu: dict[int, float] = {}
    tree: set[int] = set()

    def sample(procs: list[psutil.Process]) -> None:
        for q in procs:
            try:
                c = q.cpu_times()
                cpu[q.pid] = c.user + c.system + c.children_user + c.children_system
            except psutil.Error:
                pass

    root = psutil.Process(proc.pid)
    while proc.poll() is None:
        try:
            kids = root.children(recursive=True)
        except psutil.Error:
            kids = []
        tree |= {k.pid for k in kids}
        sample([root, *kids])
        time.sleep(0.1)
    wall = time.perf_counter() - t0
    stderr = proc.stderr.read().decode() if proc.stderr else ""
    t1 = time.perf_counter()
    helpers = [psutil.Process(p) for p in tree if psutil.pid_exists(p)]
    while helpers:  # the helper may go on compiling after the plan
        sample(helpers)
        helpers = [q for q in helpers if q.is_running() and q.status() != psutil.STATUS_ZOMBIE]
        time.sleep(0.1)
    result = json.load(open(os.path.join(out, "result.json")))
    again = _plan(src, cache, ["--no-plots"])  # the next run, on the cache the first one left
    shutil.rmtree(cache, ignore_errors=True)
    shutil.rmtree(out, ignore_errors=True)
    return {"src": src, "wall_s": round(wall, 2), "cpu_s": round(sum(cpu.values()), 2),
            "next_run_compile_time_s": round(again["compile_time_s"], 2),
            "helper_after_plan_s": round(time.perf_counter() - t1, 2),
            "compile_time_s": round(result["compile_time_s"], 2), "search_s": round(result["wall_time_s"], 2),
            "certificate_s": round(result.get("certificate_time_s") or 0.0, 2),
            "load_before": round(load_before, 2), "load_after": round(os.getloadavg()[0], 2),
            "message": stderr.splitlines()[0] if stderr else "", "date": time.strftime("%Y-%m-%d %H:%M:%S %Z")}


def _plan(src: str, cache: str, extra: list[str]) -> dict:
    """``result.json`` of one ``staghunt plan scenario2`` of the code in ``src`` on ``cache``."""
    out = tempfile.mkdtemp(prefix="staghunt-out-")
    try:
        subprocess.run([sys.executable, "-m", "staghunt", "plan", "scenario2", *extra, "--out", out], check=True,
                       env=dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=src), stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        return json.load(open(os.path.join(out, "result.json")))
    finally:
        shutil.rmtree(out, ignore_errors=True)


def warm_pairs(labelled: list[list[str]], pairs: int) -> list[dict]:
    """Warm runs of each source in turn (its own warm cache), ``pairs`` times per method: ``paper``
    (Algorithm 1) and ``game`` (the default) at 2000 x 1500 on one thread, without plots or the
    certificate; ns per single-UAV path evaluation of the search (``result.json``)."""
    caches = {label: tempfile.mkdtemp(prefix="staghunt-warm-") for label, _ in labelled}
    rows = []
    try:
        for label, src in labelled:  # fill each cache
            _plan(os.path.abspath(src), caches[label], ["--no-plots", "--no-certify", "--threads", "1"])
        for i in range(pairs):
            for method in ("paper", "game"):
                for label, src in labelled:
                    r = _plan(os.path.abspath(src), caches[label],
                              ["--method", method, "--threads", "1", "--no-plots", "--no-certify"])
                    rows.append({"pair": i, "label": label, "method": method, "evaluations": r["evaluations"],
                                 "search_s": round(r["wall_time_s"], 3),
                                 "ns_per_eval": round(r["wall_time_s"] / r["evaluations"] * 1e9, 1),
                                 "load": round(os.getloadavg()[0], 2)})
                    print(json.dumps(rows[-1]), flush=True)
    finally:
        for cache in caches.values():
            shutil.rmtree(cache, ignore_errors=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sources", nargs="*", default=[f"new={ROOT / 'src'}"],
                        help="[LABEL=]SRC: src/ directories to compare, run in turn (default: new=src)")
    parser.add_argument("--runs", type=int, default=3, help="runs of each (default 3)")
    parser.add_argument("--warm-pairs", type=int, default=0,
                        help="then this many alternated warm runs of each source and method (default 0)")
    parser.add_argument("--note", default="", help="a caveat the docs quote after the figures (default: none)")
    parser.add_argument("--json", type=Path, default=ROOT / "benchmarks" / "results" / "first_run.json",
                        help="where to write every run (default results/first_run.json)")
    args = parser.parse_args()
    started = provenance.start()
    labelled = [s.split("=", 1) if "=" in s else [s, s] for s in args.sources]
    runs = []
    for _ in range(args.runs):
        for label, src in labelled:
            runs.append({"label": label, **cold_run(os.path.abspath(src))})
            print(json.dumps(runs[-1]), flush=True)
    report = {"command": "staghunt plan scenario2 --no-plots", "cache": "empty (a fresh NUMBA_CACHE_DIR per run)",
              "note": args.note, "runs": runs}
    if args.warm_pairs:
        report["warm"] = {"command": "staghunt plan scenario2 --method M --threads 1 --no-plots --no-certify",
                          "runs": warm_pairs(labelled, args.warm_pairs)}
    args.json.write_text(json.dumps(provenance.stamped(started, report), indent=1) + "\n")


if __name__ == "__main__":
    main()
