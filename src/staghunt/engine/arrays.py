"""A :class:`~staghunt.costs.CostModel` and a :class:`~staghunt.solvers.problem.SwarmProblem`
flattened into the plain, writable, C-contiguous arrays the compiled kernels take, and the
kernels' arguments bound by name (:func:`kernel_args`).

Shapes: ``N`` UAVs, ``S`` swarms, ``K`` free waypoints, ``T`` cylinders, ``M`` edges, ``C``
compared objectives. Column layouts are documented in :mod:`staghunt.engine.kernels`, whose
named column constants (``U_*``, ``SW_*``) are used here.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Callable

import numpy as np

from staghunt.costs import CostModel
from staghunt.engine import layout as kn
from staghunt.solvers.problem import SwarmProblem


def _f64(a: np.ndarray) -> np.ndarray:
    return np.array(a, dtype=np.float64, order="C", copy=True)


def _i64(a: np.ndarray) -> np.ndarray:
    return np.array(a, dtype=np.int64, order="C", copy=True)


@dataclass(frozen=True, eq=False)
class ModelArrays:
    """The cost model as kernel arguments: ``uav (N, U_COLUMNS)``, ``weights (N, 5)``, ``cyl (T, 3)``,
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


def model_arrays(model: CostModel, c1: float = 0.0, c2: float = 0.0, team_sum: bool = False) -> ModelArrays:
    """Flatten ``model`` (and the PSO coefficients / objective kind, stored in ``par``)."""
    N = model.n_uavs
    limit = model.safe_distance + 2.0 * model.radius
    uav = np.empty((N, kn.U_COLUMNS))
    uav[:, kn.U_START:kn.U_START + 3] = model.starts
    uav[:, kn.U_GOAL:kn.U_GOAL + 3] = model.goals
    uav[:, kn.U_START_Z] = model.start_abs[:, 2]
    uav[:, kn.U_GOAL_Z] = model.goal_abs[:, 2]
    uav[:, kn.U_RADIUS] = model.radius
    uav[:, kn.U_BETA] = model.beta
    uav[:, kn.U_LIMIT] = limit
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
    """How swarm particles become team paths: ``sw (S, SW_COLUMNS)``, ``member (N,)``, ``offsets (N, 3)``,
    ``fixed (N, K, 3)``, ``players (C,)``."""

    sw: np.ndarray
    member: np.ndarray
    offsets: np.ndarray
    fixed: np.ndarray
    players: np.ndarray


def swarm_arrays(problem: SwarmProblem, waypoints: int) -> SwarmArrays:
    """Flatten the decoding and team-assembly part of ``problem`` for ``K = waypoints``."""
    S = problem.space.n_swarms
    N = problem.model.n_uavs
    sw = np.empty((S, kn.SW_COLUMNS))
    sw[:, kn.SW_START:kn.SW_START + 3] = problem.starts
    sw[:, kn.SW_LOW:kn.SW_LOW + 3] = np.broadcast_to(problem.lower, (S, 3))
    sw[:, kn.SW_HIGH:kn.SW_HIGH + 3] = np.broadcast_to(problem.upper, (S, 3))
    sw[:, kn.SW_RANGE_LOW:kn.SW_RANGE_LOW + 3] = problem.space.lower
    sw[:, kn.SW_RANGE_HIGH:kn.SW_RANGE_HIGH + 3] = problem.space.upper
    sw[:, kn.SW_VMAX:kn.SW_VMAX + 3] = problem.space.vmax
    # The decoder's fast path: psi within pi/4 of 0, phi within pi/4 of its range centre c
    # (always so for the encoding's ranges), sin/cos of phi by angle addition from c.
    centre = 0.5 * (problem.space.lower[:, 2] + problem.space.upper[:, 2])
    quarter = math.pi / 4 * (1.0 + 1e-12)
    small = (
        (np.abs(problem.space.lower[:, 1]) <= quarter) & (np.abs(problem.space.upper[:, 1]) <= quarter)
        & (np.abs(problem.space.lower[:, 2] - centre) <= quarter)
        & (np.abs(problem.space.upper[:, 2] - centre) <= quarter)
    )
    sw[:, kn.SW_SMALL] = small.astype(float)
    sw[:, kn.SW_CENTRE] = centre
    sw[:, kn.SW_SIN] = np.sin(centre)
    sw[:, kn.SW_COS] = np.cos(centre)
    fixed = np.zeros((N, waypoints, 3)) if problem.fixed is None else _f64(problem.fixed)
    players = np.zeros(1, dtype=np.int64) if problem.objective == "sum" else _i64(problem.players)
    return SwarmArrays(
        sw=sw,
        member=_i64(problem.member_of),
        offsets=_f64(np.broadcast_to(problem.offsets, (N, 3))),
        fixed=fixed,
        players=players,
    )


def no_swarm(N: int, K: int, players: np.ndarray | None = None, member: np.ndarray | None = None) -> SwarmArrays:
    """The swarm arrays of a run without a swarm (an evaluation of given waypoints)."""
    return SwarmArrays(sw=np.zeros((0, kn.SW_COLUMNS)),
                       member=np.zeros(N, dtype=np.int64) if member is None else member,
                       offsets=np.zeros((N, 3)), fixed=np.zeros((N, K, 3)),
                       players=np.zeros(1, dtype=np.int64) if players is None else players)


@lru_cache(maxsize=None)
def parameters(kernel: Callable[..., Any]) -> tuple[str, ...]:
    """The parameter names of a compiled kernel, in order (its Python definition's)."""
    return tuple(inspect.signature(getattr(kernel, "py_func", kernel)).parameters)


def kernel_args(kernel: Callable[..., Any], *sources: Any, per_call: tuple[str, ...] = ()) -> tuple[Any, ...]:
    """The arguments of ``kernel`` after its leading ``per_call`` parameters (the scalars that
    change from call to call, given at the call), each found by its parameter name as an
    attribute of the first of ``sources`` that has it (:class:`ModelArrays`,
    :class:`SwarmArrays`, a block :class:`~staghunt.engine.scratch.Scratch`, a run; objects whose
    type fixes their attributes). The kernel's own definition is thus the one place that spells
    the argument order. Which source gives which argument is worked out once per kernel and
    types of the sources (:func:`_binder`); binding then costs what spelling the attributes out
    by hand does, plus a dictionary lookup."""
    key = (kernel, per_call, *map(type, sources))
    bind = _BINDERS.get(key)
    if bind is None:
        bind = _BINDERS[key] = _binder(kernel, sources, per_call)
    return bind(*sources)


_BINDERS: dict[tuple[Any, ...], Callable[..., tuple[Any, ...]]] = {}


def _binder(kernel: Callable[..., Any], sources: tuple[Any, ...], per_call: tuple[str, ...]) -> Callable[..., tuple[Any, ...]]:
    """A function of ``sources`` returning ``kernel``'s arguments after ``per_call``: one tuple
    expression, compiled once, that reads each from its source (``s2.uav``)."""
    names = parameters(kernel)
    if names[:len(per_call)] != per_call:
        raise TypeError(f"{kernel.__name__} does not start with the parameters {per_call}")
    terms = []
    for name in names[len(per_call):]:
        where = next((i for i, source in enumerate(sources) if hasattr(source, name)), None)
        if where is None:
            raise TypeError(f"{kernel.__name__}: no source has its argument {name!r}")
        terms.append(f"s{where}.{name}")
    args = ", ".join(f"s{i}" for i in range(len(sources)))
    return eval(f"lambda {args}: ({', '.join(terms)},)")  # noqa: S307 (the kernel's own parameter names)
