"""The compiled engine: :func:`staghunt.solvers.swarm.run_swarm` and
:func:`staghunt.costs.evaluate` with the same semantics, on Numba kernels
(:mod:`staghunt.engine.kernels`), and ``game``'s local searches in one compiled call each
(:mod:`staghunt.engine.deviations`).

Randomness: one 64-bit key is drawn from the run's ``numpy.random.Generator``; every random
number of the run is a counter-based hash of (key, iteration, swarm, waypoint, component,
particle), so a seed gives the same plan for any thread count or block split. The stream is not
the NumPy engine's, so the two engines give different (statistically equivalent) plans.

Compilation: the kernels are compiled on first use and cached on disk (Numba's cache location
rules apply, e.g. ``NUMBA_CACHE_DIR``); :mod:`staghunt.engine.compilation` says what is compiled
when, and how a first run gets going in seconds.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Callable

import numpy as np

from staghunt.costs import CostModel, Costs
from staghunt.engine.arrays import ModelArrays, SwarmArrays, model_arrays, swarm_arrays
from staghunt.engine.compilation import (  # noqa: F401  (prepare: re-exported)
    EVALUATION,
    RUN,
    parallel_ready,
    prepare,
    team_search_ready,
)
from staghunt.engine.deviations import Deviations, team_search
from staghunt.engine.loop import MIN_SHARED_PARTICLES, chunk_length, iterate_chunk, kernel_threads, parallel_block
from staghunt.engine.passes import Pass, evaluate_pass, model_arrays_cached
from staghunt.engine.scratch import borrow, give_back
from staghunt.engine.threads import AdaptiveThreads, usable_cores
from staghunt.scenario.model import SolverSettings
from staghunt.solvers.problem import SwarmProblem
from staghunt.solvers.swarm import Progress, SwarmOutcome


def evaluate(model: CostModel, waypoints: np.ndarray) -> Costs:
    """Compiled twin of :func:`staghunt.costs.evaluate`: ``(P, N, K, 3)`` ``(x, y, h)`` -> :class:`Costs`
    (compiles, the first time, only the two entries of the pass)."""
    prepare(entries=EVALUATION)
    return evaluate_pass(model_arrays_cached(model), waypoints)


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
    if problem.fixed is not None and problem.objective == "players":
        ma = replace(ma, par=np.concatenate([ma.par, _fixed_constants(problem)]))
    sa = swarm_arrays(problem, K)
    start = None if initial is None else np.array(initial, dtype=float).reshape(-1, S, K, 3)[:P].copy()
    run = Pass(ma, sa, N, K, S, C, P, initial=start)
    state = np.array([float(settings.c0), 0.0, float(settings.damping)])  # inertia, best's violation, damping
    gcost = np.zeros((C, 1))
    history = np.empty((iterations + 1, C))
    rhistory = np.empty((iterations + 1, N))
    hviol = np.empty(iterations + 1)
    lanes = min(control.max_threads, kernel_threads())
    shape = (N, K, S, run.B, lanes)
    stack = borrow(shape, 1)[0]
    try:
        def chunk(it0: int, it1: int, threads: int) -> None:
            threads = max(1, min(threads, lanes))
            iterate_chunk(it0, it1, parallel_block(P, run.B, threads), threads, key, state, run, gcost,
                     history, rhistory, hviol, stack)

        # The parallel loop may still be compiling beside a first run: one thread meanwhile,
        # those stretches kept out of the thread choice.
        t0 = time.perf_counter()
        chunk(0, 1, control.max_threads if lanes > 1 and parallel_ready() else 1)
        longest = chunk_length(time.perf_counter() - t0, 1)
        it = 1
        while it <= iterations:
            waiting = lanes > 1 and not parallel_ready()
            if waiting:
                threads, length = 1, max(1, min(iterations - it + 1, longest))
                control.history.extend([1] * length)
            else:
                threads, length = control.chunk(iterations - it + 1, longest)
            t0 = time.perf_counter()
            chunk(it, it + length, threads)
            seconds = time.perf_counter() - t0
            if not waiting:
                control.record_chunk(seconds, length)
            longest = chunk_length(seconds, length)
            if progress is not None:
                for i in range(it, it + length):
                    progress(i, iterations, history[i].copy())
            it += length
    finally:
        give_back(shape, [stack])
    gviol = float(state[1])
    return SwarmOutcome(
        best=run.gbest.copy(),
        best_waypoints=_decode_one(ma, sa, N, K, S, C, run.gbest),
        best_cost=gcost[:, 0].copy(),
        best_violation=gviol,
        history=history,
        record_history=rhistory,
        history_violation=hviol,
        path_evaluations=problem.path_evaluations(settings),
    )


def _fixed_constants(problem: SwarmProblem) -> np.ndarray:
    """``(N * SOLO_STRIDE,)`` per UAV: the unweighted ``J_s`` terms and obstacle and ground
    violations of its ``fixed`` path, computed by the kernels themselves (so a fixed UAV's
    values are bit-identical to a full evaluation's); see :data:`kernels.SOLO_STRIDE`."""
    c = evaluate(problem.model, np.asarray(problem.fixed)[None])
    return np.concatenate([c.terms[0], c.violation[0][:, :2]], axis=1).ravel()


def _decode_one(ma: ModelArrays, sa: SwarmArrays, N: int, K: int, S: int, C: int,
                particle: np.ndarray) -> np.ndarray:
    """Team waypoints ``(N, K, 3)`` of one spherical particle ``(S, K, 3)``, decoded by the kernel
    itself (its trigonometry rounds differently from NumPy's)."""
    one = Pass(ma, sa, N, K, S, C, 1, initial=np.ascontiguousarray(particle[None]))
    one.ensure_scratch(1)
    try:
        one.block(0, 1, 0, ("uav_pass",))
        w = one.scratch[0]
        return np.stack([w.px[:, 1:K + 1, 0], w.py[:, 1:K + 1, 0], w.ph[:, :, 0]], axis=-1).copy()
    finally:
        one.release()


class NumbaEngine:
    """The compiled engine (the whole contract, :class:`staghunt.engine.Engine`, with the compiled
    shortcuts: ``team_search`` and ``deviations``). ``threads``: ``None`` = adaptive (1 or all usable cores, whichever
    is faster, re-measured every :data:`~staghunt.engine.threads.PROBE_EVERY` iterations);
    an integer pins the count. ``notify`` receives the one-time compile message."""

    name = "numba"

    def __init__(self, threads: int | None = None, notify: Callable[[str], None] | None = None) -> None:
        if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int) or threads < 1):
            raise ValueError(f"threads must be a positive integer or None, not {threads!r}")
        self.threads = threads
        self.notify = notify
        self.last_threads: dict[int, int] = {}

    def prepare(self) -> float:
        """Compile or load the kernels a run needs now (see
        :func:`staghunt.engine.compilation.prepare`); the seconds it took."""
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
        shared = settings.particles >= MIN_SHARED_PARTICLES
        control = AdaptiveThreads(usable_cores() if shared else 1, self.threads if shared or self.threads is None else 1)
        out = _run(problem, settings, rng, progress, initial, control)
        self.last_threads = control.summary()
        return out

    def evaluate(self, model: CostModel, waypoints: np.ndarray) -> Costs:
        """Same contract as :func:`staghunt.costs.evaluate`."""
        return evaluate(model, waypoints)

    def team_search(self, model: CostModel, plan: np.ndarray, costs: np.ndarray, max_evaluations: int, spent: int,
                    fractions: tuple[float, ...] = (), step: float = 0.0,
                    min_step: float = 0.0) -> tuple[np.ndarray, int] | None:
        """The team slide or polish of ``plan`` in one compiled call (see
        :func:`staghunt.engine.deviations.team_search`); ``None`` while the kernel is still being
        compiled beside the first run (:func:`team_search_ready`): the caller's Python loop then
        makes the same decisions."""
        if not team_search_ready():
            return None
        return team_search(model, plan, costs, max_evaluations, spent, fractions, step, min_step)

    def deviations(self, model: CostModel, plan: np.ndarray, n: int, costs: Costs | None = None) -> Deviations:
        """UAV ``n``'s deviation costs from the feasible ``plan`` (see
        :class:`staghunt.engine.deviations.Deviations`); ``costs``: this engine's
        :meth:`evaluate` of ``plan[None]``, if the caller has it."""
        self.prepare()
        return Deviations(model, plan, n, costs if costs is not None else self.evaluate(model, plan[None]))

    def __repr__(self) -> str:
        return f"NumbaEngine(threads={self.threads!r})"
