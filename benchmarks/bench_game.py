"""What the default method and its certificate cost, against the paper's Algorithm 1, in one run.

Everything with the compiled engine (warm), side by side in one process, at the scenario's
budget (the built-ins: the paper's 2000 particles x 1500 iterations, K = 10). Machines differ
3-4x in speed and are shared, so only ratios of measurements made side by side are compared.

0. **What two cores give on this host, now** (target 2's ceiling; ``--ceiling-rounds``): swarms
   of the shapes the methods run (a reply-sized deviation of one UAV, 668 x 100; Algorithm 1's
   team swarm, 2000 x 50) and an L1-resident compute loop, alternated round by round: one copy
   on one thread, the swarm on the 2-thread engine, and two copies side by side, each on its own
   thread (no shared work, no barrier). ``2 x one / side by side`` is the throughput two cores
   give that work: a parallel loop cannot beat it, and a shared host moves it from run to run.
1. **Per evaluation** (issue 17, targets 1-2), per scenario and seed (``--seeds``): Algorithm 1
   (``paper``) and the default method (``game``, full budget) on 1 thread and on 2 threads
   (pinned), ``--repeats`` times (default 5), methods and thread counts alternated (a repeat
   makes the same plan: checked). Reported: ns per path evaluation (each run's best time),
   ``game / paper`` per evaluation on each thread count (target: <= 1.2 on one thread) and
   each method's 2-thread speed-up (target: ``game`` >= 1.5x), both from the best times and
   *paired* (the ratio within each repeat, whose runs are seconds apart, then the median over
   the repeats: on a shared host the best times of two methods may come from different
   minutes); the certificate (400 x 200 per UAV) of the 2-thread ``game`` plan as a share of
   its search. The 1-thread ``game`` run has no certificate, so its starts run their rounds to
   their own stopping rule; the certified default run (each start stopped at its first
   certified plan) is also timed on 1 thread, checked to give the same plan, and its 2-thread
   speed-up reported (search, and search + certificates). Also the share of ``game``'s best
   replies that were accepted (each accepted reply changes the plan the next reply answers, so
   replies computed side by side ahead of time would be wasted that often).
2. **Small budget** (target 2): ``game`` at 500 x 300 on 1 and 2 threads (never slower),
   ``--repeats`` times alternated: best times and the paired speed-up.
3. **Time to a certified equilibrium** (target 4), scenario 2, ``--certified-seeds`` (default
   1-10), 2 threads: ``game`` with ``stop="certified"`` (search + certificate, until the
   certificate accepts a plan; with several starts the later ones are not searched) against
   Algorithm 1's search time (target: median <= 0.5). A build without ``stop`` runs the full
   ``game`` search and then the certificate. For comparison, the default run (every start
   searched and certified, the selected equilibrium) in the same loop.

    python benchmarks/bench_game.py                          # ~6-10 min on a 2-core machine
    python benchmarks/bench_game.py --seeds 1 --repeats 1 --ceiling-rounds 0 --certified-seeds 1-3 --no-write  # a look

Writes ``benchmarks/results/game.md`` and ``game.json`` (unless ``--no-write``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import threading
import time
from pathlib import Path

import numpy as np
import provenance

import staghunt
from staghunt.inputs import parse_seeds
from staghunt.costs import CostModel
from staghunt.engine import get_engine
from staghunt.solvers.problem import solo_problem, team_problem
from staghunt.solvers.response import CertifyOptions

RESULTS = Path(__file__).parent / "results"


def _engines() -> dict[int, object]:
    engines = {t: get_engine("numba", threads=t) for t in (1, 2)}
    engines[1].prepare()
    return engines


def per_evaluation(scenario_name: str, seed: int, particles: int | None, iterations: int | None,
                   repeats: int = 1) -> dict:
    scenario = staghunt.load_scenario(scenario_name)
    settings = scenario.solver.with_(particles=particles, iterations=iterations)
    eng = _engines()
    row: dict = {"scenario": scenario_name, "seed": seed, "particles": settings.particles,
                 "iterations": settings.iterations, "repeats": repeats}
    best: dict = {}  # (method, threads) -> least wall time, and least CPU time on one thread
    times: dict = {}  # (method, threads) -> every repeat's ns per path evaluation, in order
    runs: dict = {}
    for _ in range(repeats):  # 1 and 2 threads alternated, each method's best kept
        for t in (1, 2):
            for method in ("paper", "game"):
                cert = CertifyOptions() if (t == 2 and method == "game") else None  # timed apart from the search
                c0 = time.process_time()
                out = staghunt.plan(scenario, method, seed, settings, engine=eng[t], certify=cert)
                cpu = time.process_time() - c0
                if (method, t) in runs:  # the same run: the thread count and the repeat change no decision
                    assert np.array_equal(runs[method, t].waypoints, out.waypoints), "a repeat changed the plan"
                else:
                    runs[method, t] = out
                best[method, t] = min(best.get((method, t), np.inf), out.wall_time_s)
                times.setdefault((method, t), []).append(out.wall_time_s / out.evaluations * 1e9)
                if t == 1:
                    best[method, "cpu"] = min(best.get((method, "cpu"), np.inf), cpu)
    row["replies"], row["accepted_replies"] = _replies(runs["game", 1].details)
    # CPU time: on a shared machine a single thread's wall time includes waiting for a core
    row["cpu_ns_paper_1t"] = best["paper", "cpu"] / runs["paper", 1].evaluations * 1e9
    row["cpu_ns_game_1t"] = best["game", "cpu"] / runs["game", 1].evaluations * 1e9
    row["cpu_ratio_1t"] = row["cpu_ns_game_1t"] / row["cpu_ns_paper_1t"]
    for t in (1, 2):
        paper, game = runs["paper", t], runs["game", t]
        row[f"paper_s_{t}t"] = best["paper", t]
        row[f"game_s_{t}t"] = best["game", t]
        row[f"ns_paper_{t}t"] = best["paper", t] / paper.evaluations * 1e9
        row[f"ns_game_{t}t"] = best["game", t] / game.evaluations * 1e9
        row[f"ratio_{t}t"] = row[f"ns_game_{t}t"] / row[f"ns_paper_{t}t"]
    row["game_evaluations"] = runs["game", 2].evaluations
    game = runs["game", 2]  # certified: its certificate, and the same certified run on 1 thread
    row["certificate_s"] = game.certificate_time_s
    row["certificate_share"] = game.certificate_time_s / game.wall_time_s
    row["max_relative_gap"] = game.certificate.max_relative_gap
    # The whole default run (search + every certificate), the same run on 1 thread: the thread
    # count changes no decision, so the two do the same work (one run each, not repeated).
    whole = staghunt.plan(scenario, "game", seed, settings, engine=eng[1], certify=CertifyOptions())
    assert np.array_equal(whole.waypoints, game.waypoints), "the plan depends on the thread count"
    row["whole_s_1t"] = whole.wall_time_s + whole.certificate_time_s
    row["whole_s_2t"] = game.wall_time_s + game.certificate_time_s
    row["whole_search_speedup"] = whole.wall_time_s / game.wall_time_s
    row["whole_speedup"] = row["whole_s_1t"] / row["whole_s_2t"]
    row["paper_speedup"] = row["paper_s_1t"] / row["paper_s_2t"]
    row["game_speedup"] = row["ns_game_1t"] / row["ns_game_2t"]
    # The same ratios within each repeat (runs a few seconds apart), their median over the
    # repeats: a slow minute then weighs on both sides of a ratio instead of on one best time.
    paired = lambda num, den: statistics.median(a / b for a, b in zip(times[num], times[den]))  # noqa: E731
    row["ns_per_repeat"] = {f"{m}_{t}t": v for (m, t), v in times.items()}
    row["paired_ratio_1t"] = paired(("game", 1), ("paper", 1))
    row["paired_paper_speedup"] = paired(("paper", 1), ("paper", 2))
    row["paired_game_speedup"] = paired(("game", 1), ("game", 2))
    return row


def _replies(details: dict) -> tuple[int, int]:
    """Best replies made and accepted in a ``game`` run (every start's rounds)."""
    rounds = [r for st in details.get("starts", [details]) for r in st.get("rounds", [])]
    gains = [g for r in rounds for g in r["relative_gains"]]
    return len(gains), sum(g > 0 for g in gains)


def two_cores(rounds: int) -> dict:
    """Section 0: ``rounds`` alternations of each work on one thread, on the 2-thread engine
    (swarms) and as two copies side by side on two threads; the per-round ratios."""
    from numba import njit

    @njit(nogil=True)
    def compute(a: np.ndarray, reps: int) -> float:  # 16 KB, independent iterations: core-bound
        for _ in range(reps):
            for i in range(a.shape[0]):
                a[i] = np.sqrt(a[i] * 1.0000001 + 0.5) * 0.999 + 0.01
        return a[0]

    scenario = staghunt.load_scenario("scenario2")
    eng = _engines()
    pair = (eng[1], get_engine("numba", threads=1))
    model = CostModel.from_scenario(scenario)
    vf = scenario.solver.velocity_fraction
    plan = staghunt.plan(scenario, "rigid", 1, scenario.solver.with_(particles=200, iterations=50),
                         engine=eng[1]).waypoints
    works = {
        "deviation swarm 668 x 100 (one UAV, game's replies)":
            (solo_problem(model, plan, 0, vf), scenario.solver.with_(particles=668, iterations=100)),
        "team swarm 2000 x 50 (Algorithm 1)":
            (team_problem(model, scenario.solver.waypoints, vf), scenario.solver.with_(particles=2000, iterations=50)),
        "compute loop (L1-resident)": None,
    }
    arrays = (np.ones(2048), np.ones(2048))
    compute(arrays[0], 1)

    def job(name: str, copy: int) -> None:
        if works[name] is None:
            compute(arrays[copy], 60000)
        else:
            problem, settings = works[name]
            pair[copy].run_swarm(problem, settings, np.random.default_rng(copy))

    def timed(fn, *args) -> float:  # noqa: ANN001
        t = time.perf_counter()
        fn(*args)
        return time.perf_counter() - t

    def side_by_side(name: str) -> None:
        threads = [threading.Thread(target=job, args=(name, c)) for c in (0, 1)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()

    out: dict = {}
    for name, work in works.items():
        job(name, 0)
        job(name, 1)  # warm both engines' buffers
        rows = []
        for _ in range(rounds):
            one = timed(job, name, 0)
            both = timed(side_by_side, name)
            row = {"one_s": one, "side_by_side_s": both, "throughput": 2 * one / both}
            if work is not None:
                row["two_thread_s"] = timed(eng[2].run_swarm, work[0], work[1], np.random.default_rng(0))
                row["speedup"] = one / row["two_thread_s"]
            rows.append(row)
        out[name] = rows
    return out


def small_budget(seed: int, repeats: int = 1) -> dict:
    """Section 2: ``game`` at 500 x 300 on 1 and 2 threads, ``repeats`` times alternated (the
    same plan: checked); the best times and the paired speed-up (median of each repeat's)."""
    scenario = staghunt.load_scenario("scenario2")
    settings = scenario.solver.with_(particles=500, iterations=300)
    eng = _engines()
    times: dict[int, list[float]] = {1: [], 2: []}
    plans = []
    for _ in range(repeats):
        for t in (1, 2):
            g = staghunt.plan(scenario, "game", seed, settings, engine=eng[t])
            plans.append(g.waypoints)
            times[t].append(g.wall_time_s)
    assert all(np.array_equal(p, plans[0]) for p in plans), "the plan depends on the thread count or the repeat"
    return {"seed": seed, "game_s_1t": min(times[1]), "game_s_2t": min(times[2]),
            "speedup": min(times[1]) / min(times[2]),
            "paired_speedup": statistics.median(a / b for a, b in zip(times[1], times[2]))}


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


def report(per: list[dict], small: list[dict], cert: list[dict], meta: dict, cores: dict | None = None) -> str:
    med = lambda rows, k: statistics.median(r[k] for r in rows)  # noqa: E731
    span = lambda rows, k: f"{min(r[k] for r in rows):.2f}-{max(r[k] for r in rows):.2f}"  # noqa: E731
    out = [(f"{meta['date']}, {meta['cpus']} CPUs, load average {meta['load_start'][0]:.2f} at the start, "
            f"{meta['load_end'][0]:.2f} at the end; source {meta['source']}."), ""]
    if cores:
        n = len(next(iter(cores.values())))
        out += ["## 0. What two cores give on this host (target 2's ceiling)", "",
                f"Medians (ranges) of {n} alternated rounds; throughput = 2 x one copy's time / two copies side by side.",
                "", "| work | one copy, 1 thread s | two copies side by side: throughput | the swarm on 2 threads: speed-up |",
                "|---|---|---|---|"]
        for name, rows in cores.items():
            two = (f"{med(rows, 'speedup'):.2f} ({span(rows, 'speedup')})" if "speedup" in rows[0] else "-")
            out.append(f"| {name} | {med(rows, 'one_s'):.3f} | {med(rows, 'throughput'):.2f} "
                       f"({span(rows, 'throughput')}) | {two} |")
        out.append("")
    out += ["## 1. Per path evaluation, 1 and 2 threads (pinned)", "",
            ("| scenario | seed | paper ns/eval 1t | game ns/eval 1t | game/paper 1t | game/paper 1t, CPU time | "
             "paper ns/eval 2t | game ns/eval 2t | game/paper 2t | paper 2t speed-up | game 2t speed-up | "
             "certificate / search | gap | certified run 1t s | certified run 2t s | its search 2t speed-up | "
             "its 2t speed-up | replies accepted (1t run) |"),
            "|" + "---|" * 18]
    for r in per:
        out.append(f"| {r['scenario']} | {r['seed']} | {r['ns_paper_1t']:.0f} | {r['ns_game_1t']:.0f} | "
                   f"{r['ratio_1t']:.2f} | {r['cpu_ratio_1t']:.2f} | {r['ns_paper_2t']:.0f} | {r['ns_game_2t']:.0f} | "
                   f"{r['ratio_2t']:.2f} | "
                   f"{r['paper_speedup']:.2f} | {r['game_speedup']:.2f} | {r['certificate_share']:.1%} | "
                   f"{r['max_relative_gap']:.2%} | {r['whole_s_1t']:.2f} | {r['whole_s_2t']:.2f} | "
                   f"{r['whole_search_speedup']:.2f} | {r['whole_speedup']:.2f} | "
                   f"{r['accepted_replies']} of {r['replies']} |")
    if per:
        out += ["", f"Within each of the {per[0]['repeats']} repeats (paired), median over the repeats:", "",
                "| scenario | seed | game/paper 1t | paper 2t speed-up | game 2t speed-up |", "|---|---|---|---|---|"]
        out += [f"| {r['scenario']} | {r['seed']} | {r['paired_ratio_1t']:.2f} | {r['paired_paper_speedup']:.2f} | "
                f"{r['paired_game_speedup']:.2f} |" for r in per]
        out += ["", (f"Paired medians over the seeds: game/paper per evaluation, 1 thread, "
                     f"{med(per, 'paired_ratio_1t'):.2f}; 2-thread speed-up paper {med(per, 'paired_paper_speedup'):.2f}, "
                     f"game {med(per, 'paired_game_speedup'):.2f}.")]
        out += ["", (f"Medians of the best times: game/paper per evaluation {med(per, 'ratio_1t'):.2f} (1 thread; "
                     f"{med(per, 'cpu_ratio_1t'):.2f} in CPU time), "
                     f"{med(per, 'ratio_2t'):.2f} (2 threads); 2-thread speed-up paper "
                     f"{med(per, 'paper_speedup'):.2f}, game {med(per, 'game_speedup'):.2f}; "
                     f"certificate / search {med(per, 'certificate_share'):.1%}. The certified default run "
                     f"(identical on 1 and 2 threads) on 2 threads: search {med(per, 'whole_search_speedup'):.2f}x, "
                     f"search + certificates {med(per, 'whole_speedup'):.2f}x faster."), ""]
    if small:
        out += ["## 2. game at 500 x 300, scenario 2 (best times; paired speed-up as in section 1)", "",
                "| seed | 1 thread s | 2 threads s | speed-up | paired speed-up |", "|---|---|---|---|---|"]
        out += [f"| {r['seed']} | {r['game_s_1t']:.2f} | {r['game_s_2t']:.2f} | {r['speedup']:.2f} | "
                f"{r['paired_speedup']:.2f} |" for r in small]
        out += ["", f"Median speed-up {med(small, 'speedup'):.2f} (paired {med(small, 'paired_speedup'):.2f}).", ""]
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
    ap.add_argument("--repeats", type=int, default=5,
                    help="section 1: alternated runs per seed, method and thread count; the best kept")
    ap.add_argument("--ceiling-rounds", type=int, default=7, help="rounds of section 0 (0: skip it)")
    ap.add_argument("--particles", type=int)
    ap.add_argument("--iterations", type=int)
    ap.add_argument("--tag", default="", help="suffix of the result files (game<tag>.md)")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    started = provenance.start()
    meta = {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
            "load_start": os.getloadavg(), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "source": str(Path(staghunt.__file__).parent)}
    per, small, cert = [], [], []
    cores = two_cores(args.ceiling_rounds) if args.ceiling_rounds > 0 else {}
    if cores:
        print(json.dumps(cores), flush=True)
    for name in args.scenarios.split(","):
        for seed in parse_seeds(args.seeds) if args.seeds else []:
            per.append(per_evaluation(name, seed, args.particles, args.iterations, args.repeats))
            print(json.dumps(per[-1]), flush=True)
    for seed in parse_seeds(args.small_seeds) if args.small_seeds else []:
        small.append(small_budget(seed, args.repeats))
        print(json.dumps(small[-1]), flush=True)
    for seed in parse_seeds(args.certified_seeds) if args.certified_seeds else []:
        cert.append(certified(seed))
        print(json.dumps(cert[-1]), flush=True)
    meta["load_end"] = os.getloadavg()
    text = report(per, small, cert, meta, cores)
    print(text)
    if not args.no_write:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / f"game{args.tag}.json").write_text(
            json.dumps(provenance.stamped(started, {"meta": meta, "two_cores": cores, "per_evaluation": per,
                                                   "small_budget": small, "certified": cert}), indent=1) + "\n")
        (RESULTS / f"game{args.tag}.md").write_text(
            "# Default method, certificate and Algorithm 1 (benchmarks/bench_game.py)\n\n" + text + "\n")


if __name__ == "__main__":
    main()
