"""A :class:`~staghunt.costs.CostModel` and a :class:`~staghunt.solvers.problem.SwarmProblem`
flattened into the plain, writable, C-contiguous arrays the compiled kernels take.

Shapes: ``N`` UAVs, ``S`` swarms, ``K`` free waypoints, ``T`` cylinders, ``M`` edges, ``C``
compared objectives. Column layouts are documented in :mod:`staghunt.engine.kernels`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from staghunt.costs import CostModel
from staghunt.engine import kernels as kn
from staghunt.solvers.problem import SwarmProblem


def _f64(a: np.ndarray) -> np.ndarray:
    return np.array(a, dtype=np.float64, order="C", copy=True)


def _i64(a: np.ndarray) -> np.ndarray:
    return np.array(a, dtype=np.int64, order="C", copy=True)


@dataclass(frozen=True, eq=False)
class ModelArrays:
    """The cost model as kernel arguments: ``uav (N, 11)``, ``weights (N, 5)``, ``cyl (T, 3)``,
    ``prm (Q, 8)``, ``pedge (E, 4)``, ``heads``/``tails (M,)``, ``mu (N, M)``, ``ref_diff (M, 3)``,
    ``grid (R, Cg)``, ``par (13,)``."""

    uav: np.ndarray
    weights: np.ndarray
    cyl: np.ndarray
    prm: np.ndarray
    pedge: np.ndarray
    heads: np.ndarray
    tails: np.ndarray
    mu: np.ndarray
    ref_diff: np.ndarray
    grid: np.ndarray
    par: np.ndarray

    def args(self) -> tuple[np.ndarray, ...]:
        """In the order the kernels take them."""
        return (self.uav, self.weights, self.cyl, self.prm, self.pedge, self.heads, self.tails, self.mu,
                self.ref_diff, self.grid, self.par)


def model_arrays(model: CostModel, c1: float = 0.0, c2: float = 0.0, team_sum: bool = False) -> ModelArrays:
    """Flatten ``model`` (and the PSO coefficients / objective kind, stored in ``par``)."""
    N = model.n_uavs
    limit = model.safe_distance + 2.0 * model.radius
    uav = np.empty((N, 11))
    uav[:, 0:3] = model.starts
    uav[:, 3:6] = model.goals
    uav[:, 6] = model.start_abs[:, 2]
    uav[:, 7] = model.goal_abs[:, 2]
    uav[:, 8] = model.radius
    uav[:, 9] = model.beta
    uav[:, 10] = limit
    terrain = model.terrain
    if terrain.elevation is None:
        mode, grid, origin, cell = 0.0, np.zeros((1, 1)), (0.0, 0.0), 1.0
    else:
        elevation = terrain.elevation
        if terrain.sampling == "bilinear":
            mode = 3.0
        elif elevation.dtype == np.float32:
            mode = 2.0
        else:
            mode = 1.0
        grid, origin, cell = _f64(elevation), terrain.origin, float(terrain.cell_size)
    par = np.zeros(kn.N_PAR)
    par[kn.P_MARGIN] = model.danger_margin
    par[kn.P_CLEAR] = model.min_clearance
    par[kn.P_SAFE] = model.safe_distance
    par[kn.P_THR_TURN] = model.turning_threshold_deg
    par[kn.P_THR_CLIMB] = model.climb_threshold_deg
    par[kn.P_HREF] = model.h_ref
    par[kn.P_CONTINUOUS] = 1.0 if model.continuous_separation else 0.0
    par[kn.P_TERRAIN] = mode
    par[kn.P_OX], par[kn.P_OY] = float(origin[0]), float(origin[1])
    par[kn.P_CELL] = cell
    par[kn.P_C1], par[kn.P_C2] = c1, c2
    par[kn.P_SUM] = 1.0 if team_sum else 0.0
    par[kn.P_CEIL] = model.ceiling
    cyl = _f64(model.cylinders).reshape(-1, 3)
    return ModelArrays(
        uav=uav,
        weights=_f64(model.weights),
        cyl=cyl,
        prm=_f64(model.prisms).reshape(-1, 8),
        pedge=_f64(model.prism_edges).reshape(-1, 4),
        heads=_i64(model.heads),
        tails=_i64(model.tails),
        mu=_f64(model.mu).reshape(N, -1),
        ref_diff=_f64(model.ref_diff).reshape(-1, 3),
        grid=grid,
        par=par,
    )


@dataclass(frozen=True, eq=False)
class SwarmArrays:
    """How swarm particles become team paths: ``sw (S, 22)``, ``member (N,)``, ``offsets (N, 3)``,
    ``fixed (N, K, 3)``, ``players (C,)``."""

    sw: np.ndarray
    member: np.ndarray
    offsets: np.ndarray
    fixed: np.ndarray
    players: np.ndarray

    def args(self) -> tuple[np.ndarray, ...]:
        return (self.sw, self.member, self.offsets, self.fixed, self.players)


def swarm_arrays(problem: SwarmProblem, waypoints: int) -> SwarmArrays:
    """Flatten the decoding and team-assembly part of ``problem`` for ``K = waypoints``."""
    S = problem.space.n_swarms
    N = problem.model.n_uavs
    sw = np.empty((S, 22))
    sw[:, 0:3] = problem.starts
    sw[:, 3:6] = np.broadcast_to(problem.lower, (S, 3))
    sw[:, 6:9] = np.broadcast_to(problem.upper, (S, 3))
    sw[:, 9:12] = problem.space.lower
    sw[:, 12:15] = problem.space.upper
    sw[:, 15:18] = problem.space.vmax
    # The decoder's fast path: psi within pi/4 of 0, phi within pi/4 of its range centre c
    # (always so for the encoding's ranges), sin/cos of phi by angle addition from c.
    centre = 0.5 * (problem.space.lower[:, 2] + problem.space.upper[:, 2])
    quarter = math.pi / 4 * (1.0 + 1e-12)
    small = (
        (np.abs(problem.space.lower[:, 1]) <= quarter) & (np.abs(problem.space.upper[:, 1]) <= quarter)
        & (np.abs(problem.space.lower[:, 2] - centre) <= quarter)
        & (np.abs(problem.space.upper[:, 2] - centre) <= quarter)
    )
    sw[:, 18] = small.astype(float)
    sw[:, 19] = centre
    sw[:, 20] = np.sin(centre)
    sw[:, 21] = np.cos(centre)
    fixed = np.zeros((N, waypoints, 3)) if problem.fixed is None else _f64(problem.fixed)
    players = np.zeros(1, dtype=np.int64) if problem.objective == "sum" else _i64(problem.players)
    return SwarmArrays(
        sw=sw,
        member=_i64(problem.member_of),
        offsets=_f64(np.broadcast_to(problem.offsets, (N, 3))),
        fixed=fixed,
        players=players,
    )
