"""What the default method and its certificate cost, against the paper's Algorithm 1, in one run.

Everything with the compiled engine (warm), side by side in one process, at the scenario's
budget (the built-ins: the paper's 2000 particles x 1500 iterations, K = 10). Machines differ
3-4x in speed and are shared, so only ratios of measurements made side by side are compared.

1. **Per evaluation** (issue 17, targets 1-2), per scenario and seed (``--seeds``): Algorithm 1
   (``paper``) and the default method (``game``, full budget) on 1 thread and on 2 threads
   (pinned); seconds per million path evaluations, ``game / paper`` per evaluation on each
   thread count (target: <= 1.2 on one thread), and each method's 2-thread speed-up
   (target: ``game`` >= 1.5x); the certificate (400 x 200 per UAV) of the 2-thread ``game``
   plan as a share of its search. The 1-thread ``game`` run has no certificate, so its starts
   run their rounds to their own stopping rule; the certified default run (each start stopped
   at its first certified plan) is also timed on 1 thread, checked to give the same plan, and
   its 2-thread speed-up reported (search, and search + certificates).
2. **Small budget** (target 2): ``game`` at 500 x 300 on 1 and 2 threads (never slower).
3. **Time to a certified equilibrium** (target 4), scenario 2, ``--certified-seeds`` (default
   1-10), 2 threads: ``game`` with ``stop="certified"`` (search + certificate, until the
   certificate accepts a plan; with several starts the later ones are not searched) against
   Algorithm 1's search time (target: median <= 0.5). A build without ``stop`` runs the full
   ``game`` search and then the certificate. For comparison, the default run (every start
   searched and certified, the selected equilibrium) in the same loop.

    python benchmarks/bench_game.py                          # ~4-8 min on a 2-core machine
    python benchmarks/bench_game.py --seeds 1 --certified-seeds 1-3 --no-write   # a quick look

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

import numpy as np

import staghunt
from staghunt.inputs import parse_seeds
from staghunt.engine import get_engine
from staghunt.solvers.response import CertifyOptions

RESULTS = Path(__file__).parent / "results"


def _engines() -> dict[int, object]:
    engines = {t: get_engine("numba", threads=t) for t in (1, 2)}
    engines[1].prepare()
    return engines


def per_evaluation(scenario_name: str, seed: int, particles: int | None, iterations: int | None) -> dict:
    scenario = staghunt.load_scenario(scenario_name)
    settings = scenario.solver.with_(particles=particles, iterations=iterations)
    eng = _engines()
    row: dict = {"scenario": scenario_name, "seed": seed, "particles": settings.particles,
                 "iterations": settings.iterations}
    for t in (1, 2):
        c0 = time.process_time()
        paper = staghunt.plan(scenario, "paper", seed, settings, engine=eng[t])
        c1 = time.process_time()
        cert = CertifyOptions() if t == 2 else None  # timed apart from the search
        game = staghunt.plan(scenario, "game", seed, settings, engine=eng[t], certify=cert)
        c2 = time.process_time()
        if t == 1:  # CPU time: on a shared machine a single thread's wall time includes waiting for a core
            row["cpu_ns_paper_1t"] = (c1 - c0) / paper.evaluations * 1e9
            row["cpu_ns_game_1t"] = (c2 - c1) / game.evaluations * 1e9
            row["cpu_ratio_1t"] = row["cpu_ns_game_1t"] / row["cpu_ns_paper_1t"]
        row[f"paper_s_{t}t"] = paper.wall_time_s
        row[f"game_s_{t}t"] = game.wall_time_s
        row[f"ns_paper_{t}t"] = paper.wall_time_s / paper.evaluations * 1e9
        row[f"ns_game_{t}t"] = game.wall_time_s / game.evaluations * 1e9
        row[f"ratio_{t}t"] = row[f"ns_game_{t}t"] / row[f"ns_paper_{t}t"]
        if cert is not None:
            row["certificate_s"] = game.certificate_time_s
            row["certificate_share"] = game.certificate_time_s / game.wall_time_s
            row["max_relative_gap"] = game.certificate.max_relative_gap
        row["game_evaluations"] = game.evaluations
        if t == 2:
            # The whole default run (search + every certificate), the same run on 1 thread: the
            # thread count changes no decision, so the two do the same work.
            whole = staghunt.plan(scenario, "game", seed, settings, engine=eng[1], certify=cert)
            assert np.array_equal(whole.waypoints, game.waypoints), "the plan depends on the thread count"
            row["whole_s_1t"] = whole.wall_time_s + whole.certificate_time_s
            row["whole_s_2t"] = game.wall_time_s + game.certificate_time_s
            row["whole_search_speedup"] = whole.wall_time_s / game.wall_time_s
            row["whole_speedup"] = row["whole_s_1t"] / row["whole_s_2t"]
    row["paper_speedup"] = row["paper_s_1t"] / row["paper_s_2t"]
    row["game_speedup"] = row["ns_game_1t"] / row["ns_game_2t"]
    return row


def small_budget(seed: int) -> dict:
    scenario = staghunt.load_scenario("scenario2")
    settings = scenario.solver.with_(particles=500, iterations=300)
    eng = _engines()
    g = {t: staghunt.plan(scenario, "game", seed, settings, engine=eng[t]) for t in (1, 2)}
    return {"seed": seed, "game_s_1t": g[1].wall_time_s, "game_s_2t": g[2].wall_time_s,
            "speedup": (g[1].wall_time_s / g[1].evaluations) / (g[2].wall_time_s / g[2].evaluations)}


def certified(seed: int) -> dict:
    scenario = staghunt.load_scenario("scenario2")
    eng = _engines()[2]
    paper = staghunt.plan(scenario, "paper", seed, scenario.solver, engine=eng)
    try:
        game = staghunt.plan(scenario, "game", seed, scenario.solver, engine=eng, certify=CertifyOptions(),
                             stop="certified")
        mode = "stop at certificate"
    except TypeError:  # a build without stop=
        game = staghunt.plan(scenario, "game", seed, scenario.solver, engine=eng, certify=CertifyOptions())
        mode = "full search, then certificate"
    total = game.wall_time_s + game.certificate_time_s
    # The default run (every start searched, the selected equilibrium), for comparison.
    full = staghunt.plan(scenario, "game", seed, scenario.solver, engine=eng, certify=CertifyOptions())
    selected = full.wall_time_s + full.certificate_time_s
    sel = game.details.get("selection") or {}
    return {"seed": seed, "mode": mode, "paper_s": paper.wall_time_s, "game_search_s": game.wall_time_s,
            "certificate_s": game.certificate_time_s, "to_certified_s": total,
            "ratio": total / paper.wall_time_s, "equilibrium": game.certificate.is_equilibrium,
            "max_relative_gap": game.certificate.max_relative_gap, "game_evaluations": game.evaluations,
            "starts_searched": sel.get("starts_searched", 1), "starts": sel.get("starts", 1),
            "J": game.costs.total[0].tolist(), "to_selected_s": selected,
            "selected_ratio": selected / paper.wall_time_s, "selected_J": full.costs.total[0].tolist(),
            "selected_equilibrium": full.certificate.is_equilibrium}


def report(per: list[dict], small: list[dict], cert: list[dict], meta: dict) -> str:
    med = lambda rows, k: statistics.median(r[k] for r in rows)  # noqa: E731
    out = [(f"{meta['date']}, {meta['cpus']} CPUs, load average {meta['load_start'][0]:.2f} at the start, "
            f"{meta['load_end'][0]:.2f} at the end; source {meta['source']}."), ""]
    out += ["## 1. Per path evaluation, 1 and 2 threads (pinned)", "",
            ("| scenario | seed | paper ns/eval 1t | game ns/eval 1t | game/paper 1t | game/paper 1t, CPU time | "
             "paper ns/eval 2t | game ns/eval 2t | game/paper 2t | paper 2t speed-up | game 2t speed-up | "
             "certificate / search | gap | certified run 1t s | certified run 2t s | its search 2t speed-up | "
             "its 2t speed-up |"),
            "|" + "---|" * 17]
    for r in per:
        out.append(f"| {r['scenario']} | {r['seed']} | {r['ns_paper_1t']:.0f} | {r['ns_game_1t']:.0f} | "
                   f"{r['ratio_1t']:.2f} | {r['cpu_ratio_1t']:.2f} | {r['ns_paper_2t']:.0f} | {r['ns_game_2t']:.0f} | "
                   f"{r['ratio_2t']:.2f} | "
                   f"{r['paper_speedup']:.2f} | {r['game_speedup']:.2f} | {r['certificate_share']:.1%} | "
                   f"{r['max_relative_gap']:.2%} | {r['whole_s_1t']:.2f} | {r['whole_s_2t']:.2f} | "
                   f"{r['whole_search_speedup']:.2f} | {r['whole_speedup']:.2f} |")
    if per:
        out += ["", (f"Medians: game/paper per evaluation {med(per, 'ratio_1t'):.2f} (1 thread; "
                     f"{med(per, 'cpu_ratio_1t'):.2f} in CPU time), "
                     f"{med(per, 'ratio_2t'):.2f} (2 threads); 2-thread speed-up paper "
                     f"{med(per, 'paper_speedup'):.2f}, game {med(per, 'game_speedup'):.2f}; "
                     f"certificate / search {med(per, 'certificate_share'):.1%}. The certified default run "
                     f"(identical on 1 and 2 threads) on 2 threads: search {med(per, 'whole_search_speedup'):.2f}x, "
                     f"search + certificates {med(per, 'whole_speedup'):.2f}x faster."), ""]
    if small:
        out += ["## 2. game at 500 x 300, scenario 2", "", "| seed | 1 thread s | 2 threads s | speed-up |", "|---|---|---|---|"]
        out += [f"| {r['seed']} | {r['game_s_1t']:.2f} | {r['game_s_2t']:.2f} | {r['speedup']:.2f} |" for r in small]
        out += ["", f"Median speed-up {med(small, 'speedup'):.2f}.", ""]
    if cert:
        out += ["## 3. Time to a certified equilibrium, scenario 2, paper budget, 2 threads", "",
                ("| seed | paper s | game search s | certificate s | to certified s | / paper | equilibrium | gap | "
                 "starts searched | J | default run (selected) s | / paper | J selected |"),
                "|" + "---|" * 13]
        js = lambda J: "[" + ", ".join(f"{x:.0f}" for x in J) + "]"  # noqa: E731
        out += [f"| {r['seed']} | {r['paper_s']:.2f} | {r['game_search_s']:.2f} | {r['certificate_s']:.2f} | "
                f"{r['to_certified_s']:.2f} | {r['ratio']:.2f} | {r['equilibrium']} | {r['max_relative_gap']:.2%} | "
                f"{r['starts_searched']} of {r['starts']} | {js(r['J'])} | {r['to_selected_s']:.2f} | "
                f"{r['selected_ratio']:.2f} | {js(r['selected_J'])} |" for r in cert]
        out += ["", (f"Median time to a certified equilibrium (`stop=\"certified\"`, {cert[0]['mode']}) / Algorithm 1's "
                     f"time: {med(cert, 'ratio'):.2f}. The default run to its selected equilibrium (every start "
                     f"searched and certified): {med(cert, 'selected_ratio'):.2f}."), ""]
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenarios", default="scenario2")
    ap.add_argument("--seeds", default="1-3")
    ap.add_argument("--small-seeds", default="1-3")
    ap.add_argument("--certified-seeds", default="1-10")
    ap.add_argument("--particles", type=int)
    ap.add_argument("--iterations", type=int)
    ap.add_argument("--tag", default="", help="suffix of the result files (game<tag>.md)")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    meta = {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
            "load_start": os.getloadavg(), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "source": str(Path(staghunt.__file__).parent)}
    per, small, cert = [], [], []
    for name in args.scenarios.split(","):
        for seed in parse_seeds(args.seeds) if args.seeds else []:
            per.append(per_evaluation(name, seed, args.particles, args.iterations))
            print(json.dumps(per[-1]), flush=True)
    for seed in parse_seeds(args.small_seeds) if args.small_seeds else []:
        small.append(small_budget(seed))
        print(json.dumps(small[-1]), flush=True)
    for seed in parse_seeds(args.certified_seeds) if args.certified_seeds else []:
        cert.append(certified(seed))
        print(json.dumps(cert[-1]), flush=True)
    meta["load_end"] = os.getloadavg()
    text = report(per, small, cert, meta)
    print(text)
    if not args.no_write:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / f"game{args.tag}.json").write_text(
            json.dumps({"meta": meta, "per_evaluation": per, "small_budget": small, "certified": cert}, indent=1) + "\n")
        (RESULTS / f"game{args.tag}.md").write_text(
            "# Default method, certificate and Algorithm 1 (benchmarks/bench_game.py)\n\n" + text + "\n")


if __name__ == "__main__":
    main()
