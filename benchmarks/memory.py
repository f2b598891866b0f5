"""Memory estimate vs measured peak RSS (``staghunt.budget``).

Runs ``staghunt plan`` in fresh subprocesses for three budget sizes per engine and compares the
peak resident set size (``resource.getrusage(RUSAGE_SELF).ru_maxrss``, read by the process itself
when the run ends) with what :func:`staghunt.budget.estimate_plan` predicted before the run (the
figure ``staghunt plan --dry-run`` prints). Target: within 25 %.

    python benchmarks/memory.py                 # both engines: table on stdout, results/memory_paper.json
    python benchmarks/memory.py --engine numba --method game --iterations 20 --particles 1e5,2e5,4e5
                                                # the default method: results/memory_game.json

The runs use the ``paper`` method (one swarm per UAV, the largest swarm arrays of any method)
with one iteration, no certificate and no figures, so that the swarm arrays dominate and each
run takes seconds (``--method game --iterations 20`` checks the default method: its rigid
seed must take at least one step, or the zero-filled velocity array is never touched). Needs a
warm Numba cache (run any plan once first).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import provenance

ROOT = Path(__file__).resolve().parents[1]
SIZES = {"numba": (100_000, 400_000, 1_600_000), "numpy": (2_000, 8_000, 32_000)}

CHILD = r"""
import json, resource, sys
from staghunt.cli import main
code = main(sys.argv[1:])
print(json.dumps({"code": code, "maxrss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}))
"""


def measure(engine: str, particles: int, scenario: str, method: str, out: Path, iterations: int = 1) -> dict:
    from staghunt import load_scenario
    from staghunt.budget import estimate_plan

    s = load_scenario(scenario)
    settings = s.solver.with_(particles=particles, iterations=iterations)
    est = estimate_plan(s, settings, method, engine, None, None)
    argv = ["plan", scenario, "--method", method, "--particles", str(particles), "--iterations", str(iterations),
            "--engine", engine, "--no-certify", "--no-plots", "--quiet", "--out", str(out)]
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, "-c", CHILD, *argv], capture_output=True, text=True, env=env)
    last = proc.stdout.strip().splitlines()[-1]
    got = json.loads(last)
    measured = got["maxrss_kb"] * 1024
    return {"engine": engine, "particles": particles, "estimate": est.total, "measured": measured,
            "arrays": est.arrays, "ratio": measured / est.total, "code": got["code"]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--engine", choices=["numba", "numpy", "both"], default="both")
    ap.add_argument("--scenario", default="scenario1")
    ap.add_argument("--method", default="paper")
    ap.add_argument("--iterations", type=int, default=1,
                    help="iterations (game: >= 20, so that its rigid seed runs at least one step)")
    ap.add_argument("--particles", type=lambda t: tuple(int(float(x)) for x in t.split(",")),
                    help="comma-separated particle counts (default: per engine)")
    ap.add_argument("--json", type=Path, help="where to write the rows (default results/memory_METHOD.json)")
    args = ap.parse_args()
    started = provenance.start()
    engines = ["numba", "numpy"] if args.engine == "both" else [args.engine]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for engine in engines:
            for p in args.particles or SIZES[engine]:
                row = measure(engine, p, args.scenario, args.method, Path(tmp) / f"{engine}-{p}",
                              args.iterations)
                rows.append(row)
                print(f"# {engine} {p}: estimate {row['estimate'] / 2**20:.0f} MiB, measured "
                      f"{row['measured'] / 2**20:.0f} MiB", file=sys.stderr)
    mib = 2**20
    print(f"{args.scenario}, method {args.method}, {args.iterations} iteration(s), no certificate:\n")
    print("| engine | particles | estimate (MiB) | of which arrays | measured peak RSS (MiB) | measured / estimate |")
    print("|---|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['engine']} | {r['particles']:,} | {r['estimate'] / mib:.0f} | {r['arrays'] / mib:.0f} | "
              f"{r['measured'] / mib:.0f} | {r['ratio']:.2f} |")
    report = {"scenario": args.scenario, "method": args.method, "iterations": args.iterations, "rows": rows}
    path = args.json or ROOT / "benchmarks" / "results" / f"memory_{args.method}.json"
    path.write_text(json.dumps(provenance.stamped(started, report), indent=1) + "\n")
    bad = [r for r in rows if not 0.75 <= r["ratio"] <= 1.25]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
