"""The arrays of a compiled pass and how they are handed to the kernels: :class:`Pass` (one run of a
swarm, or one evaluation of given allocations, with its block buffers), the evaluation passes
kept per thread (:func:`evaluation_pass`) and the compiled twin of :func:`staghunt.costs.evaluate`
on them (:func:`evaluate_pass`). Nothing here compiles: the caller has loaded the kernels
(:func:`staghunt.engine.compilation.prepare`)."""

from __future__ import annotations

import functools
import threading
from contextlib import contextmanager
from typing import Any, Iterable, Iterator

import numpy as np

from staghunt.costs import CostModel, Costs
from staghunt.engine import kernels as kn
from staghunt.engine.arrays import ModelArrays, SwarmArrays, kernel_args, model_arrays, no_swarm
from staghunt.engine.jit import entry_table
from staghunt.engine.scratch import Scratch, borrow, give_back

UAV_PASS_PER_CALL = ("mode", "q0", "nb", "it", "key", "inertia")
TEAM_PASS_PER_CALL = ("mode", "q0", "nb")
POLISH_PER_CALL = ("n", "step", "min_step", "max_evaluations", "J0", "lower", "upper", "path")
TEAM_SEARCH_PER_CALL = ("slide", "fractions", "step", "min_step", "max_evaluations", "spent", "costs", "lower",
                        "upper", "ends", "best")
"""The kernel entries' leading parameters given at each call; the rest are bound by name
(:func:`staghunt.engine.arrays.kernel_args`)."""


class Pass:
    """The arrays of one run of ``P`` particles (or, with ``wp`` ``(Q, N, K, 3)``, one
    evaluation of ``Q`` allocations) and the two kernel calls per block."""

    def __init__(self, ma: ModelArrays, sa: SwarmArrays, N: int, K: int, S: int, C: int, P: int,
                 wp: np.ndarray | None = None, initial: np.ndarray | None = None) -> None:
        self.ma, self.sa = ma, sa
        self.B = kn.block_size(N, K)
        self.X = np.zeros((S, K, 3, P))
        self.V = np.zeros((S, K, 3, P))
        self.PB = np.zeros((S, K, 3, P))
        self.pcost = np.zeros((C, P))
        self.pviol = np.zeros(P)
        self.cost = np.zeros((C, P))
        self.viol = np.zeros(P)
        self.J = np.zeros((N, P))
        self.gbest = np.zeros((S, K, 3))
        self.initial = np.zeros((0, S, K, 3)) if initial is None else initial
        if wp is None:
            self.wp = np.zeros((0, N, K, 3))
            self.terms_out, self.vio_out, self.res_out = np.zeros((0, N, 5)), np.zeros((0, N, 3)), np.zeros((0, 3, N))
        else:
            Q = wp.shape[0]
            self.wp = wp
            self.terms_out, self.vio_out, self.res_out = np.empty((Q, N, 5)), np.empty((Q, N, 3)), np.empty((Q, 3, N))
        self.scratch: list[Scratch] = []
        self.N, self.K, self.S = N, K, S
        self.mode, self.it, self.key, self.inertia = kn.MODE_INIT, 0, np.uint64(0), 0.0
        self._bound: dict[int, tuple[Any, ...]] = {}

    @property
    def uav_entries(self) -> np.ndarray:
        """``uav_pass``'s compiled code, as :func:`kernels.iterate` and :func:`kernels.polish` call it
        (:func:`staghunt.engine.jit.entry_table`)."""
        return entry_table(kn.uav_pass)

    @property
    def team_entries(self) -> np.ndarray:
        """``team_pass``'s compiled code, likewise."""
        return entry_table(kn.team_pass)

    def ensure_scratch(self, threads: int) -> None:
        """Borrow block buffers for ``threads`` threads from the pool (see :meth:`release`)."""
        if len(self.scratch) < threads:
            self.scratch += borrow((self.N, self.K, self.S, self.B), threads - len(self.scratch))

    def release(self) -> None:
        """Give the block buffers back to the pool: the next run of the same shape reuses them
        (every kernel writes a buffer before it reads it, within each block)."""
        give_back((self.N, self.K, self.S, self.B), self.scratch)
        self.scratch = []

    def block(self, q0: int, nb: int, worker: int, entries: Iterable[str] = ("uav_pass", "team_pass")) -> None:
        """Run the kernel entries on particles ``q0 .. q0+nb`` (``nb <= B``) with ``worker``'s scratch."""
        w = self.scratch[worker]
        bound = self._bound.get(worker)
        if bound is None or bound[0] is not w:  # the arrays, bound once by the kernels' parameter names
            bound = self._bound[worker] = (
                w, kernel_args(kn.uav_pass, self, self.ma, self.sa, w, per_call=UAV_PASS_PER_CALL),
                kernel_args(kn.team_pass, self, self.ma, self.sa, w, per_call=TEAM_PASS_PER_CALL))
        for name in entries:
            if name == "uav_pass":
                kn.uav_pass(self.mode, q0, nb, self.it, self.key, self.inertia, *bound[1])
            else:
                kn.team_pass(self.mode, q0, nb, *bound[2])

    def work(self, p0: int, p1: int, worker: int) -> None:
        """All particles ``p0 .. p1`` in blocks of ``B``."""
        for q0 in range(p0, p1, self.B):
            self.block(q0, min(self.B, p1 - q0), worker)


EVALUATION_PASSES = 8
"""Evaluation passes kept per thread (:func:`evaluate`): the last shapes and models evaluated."""
EVALUATION_ROWS = 256
"""Batches of at most this many allocations use a kept pass; larger ones (rare, and already
dominated by the kernels) build their own, so that no thread keeps large buffers."""
_evaluation_passes = threading.local()


def evaluation_pass(ma: ModelArrays, N: int, K: int, Q: int) -> Pass:
    """The pass that evaluates ``Q`` allocations of ``N`` UAVs x ``K`` waypoints of the model of
    ``ma``, with its own block buffers and its kernel arguments bound once: made on this
    thread's first such evaluation, then reused (a search such as ``game``'s team polish
    evaluates small batches of the same shape thousands of times, and building the pass cost
    more than the kernels). One cache per thread, so that threads never share buffers."""
    runs = getattr(_evaluation_passes, "runs", None)
    if runs is None:
        runs = _evaluation_passes.runs = {}
    key = (id(ma), N, K, Q)
    entry = runs.pop(key, None)
    if entry is not None and entry[0] is not ma:  # another model at a freed model's address
        entry[1].release()
        entry = None
    if entry is None:
        run = Pass(ma, no_swarm(N, K), N, K, 0, 1, 0, wp=np.empty((Q, N, K, 3)))
        run.mode = kn.MODE_EVALUATE
        run.ensure_scratch(1)  # from the pool, given back when the pass is dropped
        entry = (ma, run)
    runs[key] = entry  # the most recent last
    while len(runs) > EVALUATION_PASSES:
        runs.pop(next(iter(runs)))[1].release()
    return entry[1]


def evaluate_pass(ma: ModelArrays, waypoints: np.ndarray) -> Costs:
    """The compiled twin of :func:`staghunt.costs.evaluate` of ``waypoints`` ``(P, N, K, 3)`` on
    the model arrays ``ma``, on this thread's kept pass (or a pass of its own for a large
    batch); the kernels must be loaded."""
    wp = np.asarray(waypoints, dtype=np.float64)
    P, N, K = wp.shape[0], wp.shape[1], wp.shape[2]
    if P <= EVALUATION_ROWS:
        run = evaluation_pass(ma, N, K, P)
        run.wp[...] = wp
        run.work(0, P, 0)
    else:
        run = Pass(ma, no_swarm(N, K), N, K, 0, 1, 0, wp=np.array(wp, order="C"))
        run.mode = kn.MODE_EVALUATE
        run.ensure_scratch(1)
        with releasing(run):
            run.work(0, P, 0)
    res = run.res_out
    return Costs(terms=run.terms_out.copy(), single=res[:, 1].copy(), formation=res[:, 0].copy(),
                 total=res[:, 2].copy(), violation=run.vio_out.copy())


@functools.lru_cache(maxsize=16)
def model_arrays_cached(model: CostModel) -> ModelArrays:
    """:func:`model_arrays` of a model evaluated again and again (a frozen :class:`CostModel`
    hashes by identity; its arrays are read-only)."""
    return model_arrays(model)


@contextmanager
def releasing(run: Pass) -> Iterator[Pass]:
    """Give ``run``'s block buffers back to the pool when the run ends, however it ends."""
    try:
        yield run
    finally:
        run.release()


