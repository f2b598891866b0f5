"""The compiled engine: :func:`staghunt.solvers.swarm.run_swarm` and
:func:`staghunt.costs.evaluate` with the same semantics, on Numba kernels.

Randomness: one 64-bit key is drawn from the run's ``numpy.random.Generator``; every random
number of the run is a counter-based hash of (key, iteration, swarm, waypoint, component,
particle), so a seed gives the same plan for any thread count or block split. The stream is not
the NumPy engine's, so the two engines give different (statistically equivalent) plans.

Compilation: every kernel is compiled on first use and cached on disk (``cache=True``; Numba's
cache directory rules apply, e.g. ``NUMBA_CACHE_DIR``). :func:`prepare` does that explicitly and,
when it takes longer than a moment (a cold cache), reports once through ``notify`` (default: a
``logging`` warning on ``staghunt.engine``, which reaches stderr even when logging is not
configured).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Callable

import numpy as np

from staghunt.costs import CostModel, Costs
from staghunt.engine import kernels as kn
from staghunt.engine.arrays import model_arrays, swarm_arrays
from staghunt.engine.threads import AdaptiveThreads, BlockRunner, usable_cores
from staghunt.scenario.model import SolverSettings
from staghunt.solvers.problem import SwarmProblem
from staghunt.solvers.swarm import Progress, SwarmOutcome

logger = logging.getLogger("staghunt.engine")

COLD_COMPILE_ESTIMATE_S = 25
"""Measured one-time compile of all kernels on a 2-core laptop-class machine (seconds, rounded up)."""

NOTIFY_AFTER_S = 1.0
"""A warm cache loads in well under this; beyond it we are compiling and say so."""

_ready = threading.Event()
_prepare_lock = threading.Lock()
_compile_seconds: float | None = None


def _warm_up() -> None:
    """Run every kernel once on a tiny problem with the exact argument types of real runs."""
    from staghunt.encoding import search_space
    from staghunt.scenario import load_scenario

    model = CostModel.from_scenario(load_scenario("scenario2"))
    settings = SolverSettings(particles=8, iterations=1, waypoints=2)
    n = model.n_uavs
    problem = SwarmProblem(
        model=model,
        space=search_space(model.starts, model.goals, 2),
        starts=model.starts,
        lower=np.broadcast_to(model.lower, (n, 3)),
        upper=np.broadcast_to(model.upper, (n, 3)),
        member_of=np.arange(n),
        offsets=np.zeros((n, 3)),
        objective="players",
        players=tuple(range(n)),
    )
    _run(problem, settings, np.random.default_rng(0), None, None, AdaptiveThreads(1, 1))
    evaluate(model, np.full((1, n, 2, 3), 20.0))


def prepare(notify: Callable[[str], None] | None = None) -> float:
    """Load (or, the first time, compile) the kernels; returns the seconds it took.

    If that takes longer than :data:`NOTIFY_AFTER_S`, ``notify`` (default: a warning on the
    ``staghunt.engine`` logger) is called once with a message saying what happens.
    """
    global _compile_seconds
    if _ready.is_set():
        return 0.0
    with _prepare_lock:
        if _ready.is_set():
            return 0.0
        say = notify if notify is not None else logger.warning
        t0 = time.perf_counter()
        errors: list[BaseException] = []

        def target() -> None:
            try:
                _warm_up()
            except BaseException as exc:  # re-raised in the caller's thread
                errors.append(exc)

        worker = threading.Thread(target=target, name="staghunt-engine-compile", daemon=True)
        worker.start()
        worker.join(NOTIFY_AFTER_S)
        if worker.is_alive():
            say(
                "staghunt: compiling the fast engine (one time, about "
                f"{COLD_COMPILE_ESTIMATE_S} s; later runs load it from the cache)..."
            )
            worker.join()
        if errors:
            raise errors[0]
        _compile_seconds = time.perf_counter() - t0
        _ready.set()
        return _compile_seconds


def evaluate(model: CostModel, waypoints: np.ndarray) -> Costs:
    """Compiled twin of :func:`staghunt.costs.evaluate`: ``(P, N, K, 3)`` ``(x, y, h)`` -> :class:`Costs`."""
    wp = np.array(waypoints, dtype=np.float64, order="C", copy=True)
    P, N = wp.shape[0], wp.shape[1]
    ma = model_arrays(model)
    terms = np.empty((P, N, 5))
    vio = np.empty((P, N, 3))
    res = np.empty((P, 3, N))
    kn.evaluate_population(wp, *ma.args(), terms, vio, res)
    return Costs(terms=terms, single=res[:, 1].copy(), formation=res[:, 0].copy(),
                 total=res[:, 2].copy(), violation=vio)


def _run(
    problem: SwarmProblem,
    settings: SolverSettings,
    rng: np.random.Generator,
    progress: Progress | None,
    initial: np.ndarray | None,
    control: AdaptiveThreads,
) -> SwarmOutcome:
    P, K, iterations = settings.particles, settings.waypoints, settings.iterations
    S = problem.space.n_swarms
    N = problem.model.n_uavs
    C = problem.n_objectives
    key = np.uint64(int(rng.integers(2**63)))
    ma = model_arrays(problem.model, float(settings.c1), float(settings.c2), problem.objective == "sum")
    sa = swarm_arrays(problem, K)
    X = np.empty((S, K, 3, P))
    V = np.zeros((S, K, 3, P))
    PB = np.empty((S, K, 3, P))
    pcost = np.empty((C, P))
    pviol = np.empty(P)
    cost = np.empty((C, P))
    viol = np.empty(P)
    J = np.empty((N, P))
    gbest = np.zeros((S, K, 3))
    gcost = np.zeros((C, 1))
    kn.sample_positions(key, X, sa.sw)
    if initial is not None:
        X[..., 0] = np.asarray(initial, dtype=float).reshape(S, K, 3)
    extra = (*sa.args(), *ma.args())
    history = np.empty((iterations + 1, C))
    rhistory = np.empty((iterations + 1, N))
    hviol = np.empty(iterations + 1)

    state = {"it": 0, "inertia": float(settings.c0)}

    def work(p0: int, p1: int) -> None:
        kn.swarm_block(p0, p1, state["it"], key, state["inertia"], X, V, PB, pcost, pviol,
                       cost, viol, J, gbest, *extra)

    with BlockRunner(control.max_threads) as runner:
        runner.run(work, P, control.max_threads)
        g = kn.select_global(cost, viol, gcost, 0.0, False)
        gbest[...] = X[..., g]
        gcost[:, 0] = cost[:, g]
        gviol = float(viol[g])
        history[0], rhistory[0], hviol[0] = gcost[:, 0], J[:, g], gviol
        for it in range(1, iterations + 1):
            state["it"] = it
            threads = control.next()
            t0 = time.perf_counter()
            runner.run(work, P, threads)
            control.record(time.perf_counter() - t0)
            g = kn.select_global(cost, viol, gcost, gviol, True)
            if g >= 0:
                gbest[...] = X[..., g]
                gcost[:, 0] = cost[:, g]
                gviol = float(viol[g])
                rhistory[it] = J[:, g]
            else:
                rhistory[it] = rhistory[it - 1]
            history[it], hviol[it] = gcost[:, 0], gviol
            state["inertia"] *= settings.damping
            if progress is not None:
                progress(it, iterations, gcost[:, 0].copy())
    return SwarmOutcome(
        best=gbest.copy(),
        best_cost=gcost[:, 0].copy(),
        best_violation=gviol,
        history=history,
        record_history=rhistory,
        history_violation=hviol,
        particle_evaluations=P * (iterations + 1),
    )


class NumbaEngine:
    """The compiled engine. ``threads``: ``None`` = adaptive (1 or all usable cores, whichever
    is faster, re-measured every :data:`~staghunt.engine.threads.PROBE_EVERY` iterations);
    an integer pins the count."""

    name = "numba"

    def __init__(self, threads: int | None = None, notify: Callable[[str], None] | None = None) -> None:
        if threads is not None and (not isinstance(threads, int) or threads < 1):
            raise ValueError(f"threads must be a positive integer or None, not {threads!r}")
        self.threads = threads
        self.notify = notify
        self.last_threads: dict[int, int] = {}

    def prepare(self) -> float:
        """Compile or load the kernels now (see :func:`prepare`)."""
        return prepare(self.notify)

    def run_swarm(
        self,
        problem: SwarmProblem,
        settings: SolverSettings,
        rng: np.random.Generator,
        progress: Progress | None = None,
        initial: np.ndarray | None = None,
    ) -> SwarmOutcome:
        """Same contract as :func:`staghunt.solvers.swarm.run_swarm`."""
        self.prepare()
        control = AdaptiveThreads(usable_cores(), self.threads)
        out = _run(problem, settings, rng, progress, initial, control)
        self.last_threads = control.summary()
        return out

    def evaluate(self, model: CostModel, waypoints: np.ndarray) -> Costs:
        """Same contract as :func:`staghunt.costs.evaluate`."""
        self.prepare()
        return evaluate(model, waypoints)

    def __repr__(self) -> str:
        return f"NumbaEngine(threads={self.threads!r})"
