"""The comparison that docs/compare.md quotes: ``staghunt compare`` on scenarios 1 and 2, seeds
1-10, at the paper's budget (2000 x 1500) and at 500 x 300, gathered in ``results/compare.json``.

    python benchmarks/compare.py                       # both budgets (~15 min on 2 quiet cores)
    python benchmarks/compare.py --budgets paper --seeds 1-3

Each ``staghunt compare`` runs in its own process with the default engine, threads and
certificate (400 x 200 per UAV, epsilon 1 %). Kept per budget and scenario: its ``compare.json``
(summary, dominance, the paper's Fig. 8 rows) and, per run, the method, seed, status, wall time,
evaluations, ``J_n``, relative Nash gaps and their largest (``max_gap_relative``), the verdict
and whether ``game`` dominates it. The plans are reproducible (same seed and engine, same plan);
the times are this machine's at the time (``date`` and ``machine`` in the file).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import provenance

RESULTS = Path(__file__).resolve().parent / "results"
BUDGETS = {"paper": [], "500x300": ["--particles", "500", "--iterations", "300"]}
KEEP = ("scenario", "methods", "seeds", "settings", "certify", "complete", "summary", "dominance",
        "dominance_matrix", "paper_fig8")
RUN_KEEP = ("method", "seed", "status", "feasible", "wall_time_s", "evaluations", "J_n", "nash_gap_relative",
            "certificate_status", "game_dominates", "collision_free")


def compare(scenario: str, seeds: str, extra: list[str], out: Path) -> dict[str, Any]:
    """One ``staghunt compare`` in a fresh process; the part of its ``compare.json`` kept."""
    cmd = [sys.executable, "-m", "staghunt", "compare", scenario, "--seeds", seeds, "--out", str(out),
           "--no-figure", "--quiet", *extra]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    path = out / "compare.json"
    if not path.exists():
        raise SystemExit(f"compare.py: {' '.join(cmd[2:])} failed ({proc.returncode}): {proc.stderr.strip()[-300:]}")
    data = json.loads(path.read_text(encoding="utf-8"))
    runs = []
    for r in data["runs"]:
        row = {k: r.get(k) for k in RUN_KEEP}
        gaps = [g for g in (r.get("nash_gap_relative") or []) if isinstance(g, (int, float))]
        row["max_gap_relative"] = max(gaps) if gaps and len(gaps) == len(r["nash_gap_relative"]) else None
        runs.append(row)
    return {**{k: data.get(k) for k in KEEP}, "runs": runs}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budgets", default="paper,500x300", help="comma-separated: paper, 500x300")
    ap.add_argument("--scenarios", default="scenario1,scenario2")
    ap.add_argument("--seeds", default="1-10")
    ap.add_argument("--json", type=Path, default=RESULTS / "compare.json")
    args = ap.parse_args()
    started = provenance.start()
    report: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="staghunt-compare-") as tmp:
        for budget in args.budgets.split(","):
            for scenario in args.scenarios.split(","):
                print(f"{budget} {scenario} ...", file=sys.stderr, flush=True)
                report.setdefault(budget, {})[scenario] = compare(scenario, args.seeds, BUDGETS[budget],
                                                                  Path(tmp) / f"{budget}-{scenario}")
    args.json.write_text(json.dumps(provenance.stamped(started, report), indent=1) + "\n")
    print(f"wrote {args.json}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
