"""The local searches of ``game`` on the compiled kernels, each in one call: UAV ``n``'s
deviation costs with the others' paths fixed (``MODE_DEVIATE``; its polish), and the team's
slide and polish (:func:`team_search`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from staghunt.costs import CostModel, Costs
from staghunt.engine import kernels as kn
from staghunt.engine.arrays import kernel_args, no_swarm
from staghunt.engine.passes import (
    POLISH_PER_CALL,
    TEAM_SEARCH_PER_CALL,
    Pass,
    evaluation_pass,
    model_arrays_cached,
    releasing,
)


class Deviations:
    """``J_n`` of UAV ``n``'s candidate paths with the others' paths of ``plan`` ``(N, K, 3)``
    fixed: the compiled twin of :func:`staghunt.solvers.local._own_costs` for a plan whose
    other UAVs are clear of each other and of every obstacle (a feasible plan), evaluating only
    UAV ``n``'s path and its pairs (``MODE_DEVIATE``). Bit-identical to the full evaluation's
    ``J_n``, and ``inf`` exactly where the full evaluation's total violation is not zero."""

    def __init__(self, model: CostModel, plan: np.ndarray, n: int, costs: Costs) -> None:
        """``costs``: the compiled evaluation of ``plan[None]``
        (:func:`~staghunt.engine.numba_engine.evaluate`); the kernels are loaded."""
        plan = np.array(plan, dtype=np.float64, order="C", copy=True)
        N, K = plan.shape[0], plan.shape[1]
        ma = model_arrays_cached(model)
        constants = np.concatenate([costs.terms[0], costs.violation[0][:, :2]], axis=1).ravel()
        self.ma = replace(ma, par=np.concatenate([ma.par, constants]))
        member = np.full(N, -1, dtype=np.int64)
        member[n] = 0
        self.sa = no_swarm(N, K, players=np.array([n], dtype=np.int64), member=member)
        self.plan, self.n = plan, n
        self.lower = np.array(model.lower, dtype=np.float64)
        self.upper = np.array(model.upper, dtype=np.float64)
        self._runs: dict[int, Pass] = {}

    def _run(self, Q: int) -> Pass:
        """The pass over ``Q`` allocations (the plan with UAV ``n``'s rows to fill), made once per
        batch size (a polish sweep, its combined move) and reused; its block buffers are borrowed
        from the pool for each call (:meth:`~staghunt.engine.passes.Pass.ensure_scratch`): a fresh set, about 1 MB of
        zeroed pages for 3 UAVs, cost more than a short polish."""
        run = self._runs.get(Q)
        if run is None:
            N, K = self.plan.shape[0], self.plan.shape[1]
            team = np.repeat(self.plan[None], Q, axis=0)
            run = self._runs[Q] = Pass(self.ma, self.sa, N, K, 0, 1, 0, wp=team)
            run.mode = kn.MODE_DEVIATE
        run.ensure_scratch(1)
        return run

    def polish(self, J: float, max_evaluations: int, step: float, min_step: float) -> tuple[np.ndarray, float, int]:
        """:func:`staghunt.solvers.local.polish` of UAV ``n``'s path (cost ``J``) in one compiled
        call (:func:`staghunt.engine.kernels.polish`: the same decisions on the same costs, so
        the same path). Returns the ``(K, 3)`` path, its ``J_n`` and the evaluations spent."""
        K = self.plan.shape[1]
        path = self.plan[self.n].copy()
        with releasing(self._run(6 * K + 1)) as run:  # the 6 K one-coordinate moves and their combination
            Jn, spent = kn.polish(self.n, float(step), float(min_step), int(max_evaluations), float(J), self.lower,
                                  self.upper, path, *kernel_args(kn.polish, run, self.ma, self.sa, run.scratch[0],
                                                                 per_call=POLISH_PER_CALL))
        return path, float(Jn), int(spent)

    def __call__(self, paths: np.ndarray) -> np.ndarray:
        """``(Q,)`` ``J_n`` for ``paths`` ``(Q, K, 3)``; ``inf`` where infeasible."""
        Q = len(paths)
        with releasing(self._run(Q)) as run:
            run.wp[:, self.n] = paths
            run.work(0, Q, 0)
        clear = np.all(run.vio_out.reshape(Q, -1) == 0, axis=1)
        return np.where(clear, run.res_out[:, 2, self.n], np.inf)


def team_search(model: CostModel, plan: np.ndarray, costs: np.ndarray, max_evaluations: int, spent: int,
                fractions: tuple[float, ...] = (), step: float = 0.0, min_step: float = 0.0) -> tuple[np.ndarray, int]:
    """:func:`staghunt.solvers.game.team_slide` (by ``fractions``, if any) or
    :func:`~staghunt.solvers.game.team_polish` (from ``step`` down to ``min_step``) of the team
    plan ``plan`` ``(N, K, 3)`` with costs ``costs`` ``(N,)`` and ``spent`` evaluations, in one
    compiled call (:func:`staghunt.engine.kernels.team_search`) on this thread's kept evaluation
    pass: the same candidates, costs and decisions as the Python loops (kept as their reference),
    where each of the loop's sweeps paid about three times the kernels' time in array building, a
    Python call and the choice between candidates. Returns the ``(N, K, 3)`` plan reached and the
    evaluations spent in all."""
    best = np.array(plan, dtype=np.float64, order="C", copy=True)
    N, K = best.shape[0], best.shape[1]
    run = evaluation_pass(model_arrays_cached(model), N, K, (2 if fractions else 6) * K)
    ends = np.ascontiguousarray(np.stack([model.starts, model.goals], axis=1), dtype=np.float64)  # (N, 2, 3)
    spent = kn.team_search(len(fractions) > 0, np.array(fractions, dtype=np.float64), float(step), float(min_step),
                           int(max_evaluations), int(spent), np.array(costs, dtype=np.float64),
                           np.array(model.lower, dtype=np.float64), np.array(model.upper, dtype=np.float64), ends,
                           best, *kernel_args(kn.team_search, run, run.ma, run.sa, run.scratch[0],
                                              per_call=TEAM_SEARCH_PER_CALL))
    return best, int(spent)
