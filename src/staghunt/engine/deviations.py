"""UAV ``n``'s deviation costs with the others' paths fixed, on the compiled kernels
(``MODE_DEVIATE``): what ``game``'s polish evaluates."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from staghunt.costs import CostModel
from staghunt.engine import kernels as kn
from staghunt.engine.arrays import no_swarm
from staghunt.engine.numba_engine import _model_arrays_cached, _Pass, evaluate
from staghunt.engine.scratch import Scratch


class Deviations:
    """``J_n`` of UAV ``n``'s candidate paths with the others' paths of ``plan`` ``(N, K, 3)``
    fixed: the compiled twin of :func:`staghunt.solvers.game._own_costs` for a plan whose
    other UAVs are clear of each other and of every obstacle (a feasible plan), evaluating only
    UAV ``n``'s path and its pairs (``MODE_DEVIATE``). Bit-identical to the full evaluation's
    ``J_n``, and ``inf`` exactly where the full evaluation's total violation is not zero."""

    def __init__(self, model: CostModel, plan: np.ndarray, n: int) -> None:
        plan = np.array(plan, dtype=np.float64, order="C", copy=True)
        N, K = plan.shape[0], plan.shape[1]
        ma = _model_arrays_cached(model)
        c = evaluate(model, plan[None])
        constants = np.concatenate([c.terms[0], c.violation[0][:, :2]], axis=1).ravel()
        self.ma = replace(ma, par=np.concatenate([ma.par, constants]))
        member = np.full(N, -1, dtype=np.int64)
        member[n] = 0
        self.sa = no_swarm(N, K, players=np.array([n], dtype=np.int64), member=member)
        self.plan, self.n = plan, n
        self._runs: dict[int, _Pass] = {}
        self._scratch: Scratch | None = None

    def __call__(self, paths: np.ndarray) -> np.ndarray:
        """``(Q,)`` ``J_n`` for ``paths`` ``(Q, K, 3)``; ``inf`` where infeasible."""
        Q = len(paths)
        run = self._runs.get(Q)
        if run is None:  # one pass per batch size (a polish sweep, its combined move), reused
            N, K = self.plan.shape[0], self.plan.shape[1]
            team = np.repeat(self.plan[None], Q, axis=0)
            run = self._runs[Q] = _Pass(self.ma, self.sa, N, K, 0, 1, 0, wp=team)
            run.mode = kn.MODE_DEVIATE
            if self._scratch is None:
                self._scratch = Scratch(N, K, 0, run.B)
            run.scratch = [self._scratch]
        run.wp[:, self.n] = paths
        run.work(0, Q, 0)
        clear = np.all(run.vio_out.reshape(Q, -1) == 0, axis=1)
        return np.where(clear, run.res_out[:, 2, self.n], np.inf)
