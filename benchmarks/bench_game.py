"""What the default method and its certificate cost, against the paper's Algorithm 1, in one run.

For each scenario and seed, at the scenario's budget (the built-ins: the paper's 2000 particles x
1500 iterations, K = 10), with the compiled engine (warm), in this order:

- ``paper``: Algorithm 1's search time and evaluations;
- ``game``: the default method's search time and evaluations (it may stop early);
- the certificate that ``staghunt plan`` adds (default budget, 400 x 200 per UAV) on the game plan.

Reported per run and as medians: seconds per million path evaluations of each search, their
ratio ``game / paper`` (target: <= 1, "no slower per evaluation"), and the certificate's time as
a share of the game search (target: <= 30 %). Machines differ 3-4x in speed and are shared, so
only ratios of measurements made side by side in this run are compared.

    python benchmarks/bench_game.py                    # scenario1 and scenario2, seeds 1-3
    python benchmarks/bench_game.py --seeds 1-5 --scenarios scenario2
    python benchmarks/bench_game.py --particles 500 --iterations 300   # a quick look

Writes ``benchmarks/results/game.md`` and ``game.json`` (unless ``--no-write``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import staghunt
from staghunt.engine import get_engine
from staghunt.solvers.response import CertifyOptions

RESULTS = Path(__file__).parent / "results"


def _seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def measure(scenario_name: str, seed: int, particles: int | None, iterations: int | None) -> dict:
    scenario = staghunt.load_scenario(scenario_name)
    settings = scenario.solver.with_(particles=particles, iterations=iterations)
    engine = get_engine("numba")
    engine.prepare()
    paper = staghunt.plan(scenario, "paper", seed, settings, engine=engine)
    game = staghunt.plan(scenario, "game", seed, settings, engine=engine, certify=CertifyOptions())
    cert = game.certificate
    assert cert is not None
    per_m_paper = paper.wall_time_s / paper.evaluations * 1e6
    per_m_game = game.wall_time_s / game.evaluations * 1e6
    return {
        "scenario": scenario_name, "seed": seed,
        "particles": settings.particles, "iterations": settings.iterations,
        "paper_s": paper.wall_time_s, "paper_evaluations": paper.evaluations,
        "game_s": game.wall_time_s, "game_evaluations": game.evaluations,
        "s_per_million_paper": per_m_paper, "s_per_million_game": per_m_game,
        "per_evaluation_ratio": per_m_game / per_m_paper,
        "certificate_s": game.certificate_time_s,
        "certificate_evaluations": sum(u.evaluations for u in cert.uavs),
        "certificate_share": game.certificate_time_s / game.wall_time_s,
        "equilibrium": cert.is_equilibrium, "max_relative_gap": cert.max_relative_gap,
        "converged": bool(game.details.get("converged")),
    }


def table(rows: list[dict]) -> str:
    head = ("scenario", "seed", "paper s", "game s", "game evals (M)", "s/M evals paper", "s/M evals game",
            "game/paper per eval", "certificate s", "certificate / search", "gap")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        lines.append("| " + " | ".join([
            r["scenario"], str(r["seed"]), f"{r['paper_s']:.2f}", f"{r['game_s']:.2f}",
            f"{r['game_evaluations'] / 1e6:.2f}", f"{r['s_per_million_paper']:.3f}",
            f"{r['s_per_million_game']:.3f}", f"{r['per_evaluation_ratio']:.2f}",
            f"{r['certificate_s']:.2f}", f"{r['certificate_share']:.1%}", f"{r['max_relative_gap']:.2%}",
        ]) + " |")
    med = lambda k: statistics.median(r[k] for r in rows)  # noqa: E731
    lines.append("")
    lines.append(f"Medians: game / paper seconds per path evaluation = {med('per_evaluation_ratio'):.2f}; "
                 f"certificate / game search time = {med('certificate_share'):.1%}.")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenarios", default="scenario1,scenario2")
    ap.add_argument("--seeds", default="1-3")
    ap.add_argument("--particles", type=int)
    ap.add_argument("--iterations", type=int)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    rows = []
    for name in args.scenarios.split(","):
        for seed in _seeds(args.seeds):
            rows.append(measure(name, seed, args.particles, args.iterations))
            print(json.dumps(rows[-1]), flush=True)
    text = table(rows)
    print(text)
    if not args.no_write:
        RESULTS.mkdir(exist_ok=True)
        meta = {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
                "load_average": os.getloadavg(), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
        (RESULTS / "game.json").write_text(json.dumps({"meta": meta, "runs": rows}, indent=1) + "\n")
        (RESULTS / "game.md").write_text(
            "# Default method and certificate against Algorithm 1 (benchmarks/bench_game.py)\n\n"
            f"{meta['date']}, {meta['cpus']} CPUs, load average {meta['load_average'][0]:.2f} at the end.\n\n"
            + text + "\n")


if __name__ == "__main__":
    main()
