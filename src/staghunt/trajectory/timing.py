"""Time-optimal synchronised timing of a team's paths (TOPP-RA, one path parameter for the team).

The formation cost is defined per waypoint index, so the team must reach its ``k``-th waypoints
together. The timing therefore gives the whole team **one path parameter** ``s`` and times it
with one function ``s(t)``:

1. **Merge** near-duplicate waypoints for the whole team (:func:`merge_waypoints`): a waypoint
   index where no UAV moves more than :data:`MERGE_M` from the previous one is dropped for
   every UAV at once, so synchronisation is kept and no zero-length leg is left.
2. **Geometric path.** ``s`` is the team's cumulative chord length (per leg the longest UAV
   leg, metres), optionally after splitting every leg into equal sub-legs (``spacing``, the
   same split for the whole team). Each UAV's path ``p_n(s)`` is a natural cubic spline
   through its points over these ``s`` (C2, through every waypoint at the waypoint's ``s``).
3. **Time-optimal parameterisation** by reachability analysis (toppra's TOPP-RA) of
   ``x = (ds/dt)^2`` and ``u = d2s/dt2`` under every UAV's limits as *norms*:

   - speed: ``|p_n'(s)| sqrt(x) <= cruise_speed`` is a bound on ``x`` per grid point;
   - acceleration: ``a_n = p_n'(s) u + p_n''(s) x`` must lie in the ball of radius
     ``max_acceleration``; the ball is replaced by the inscribed polyhedron of
     :data:`ACC_DIRECTIONS` Fibonacci-sphere directions ``d_j``: ``d_j . a_n <= a_max / R``,
     where ``R`` is the polyhedron's circumradius for ``d_j . a <= 1`` (about 1.08), so every
     vertex lies inside the ball and the polyhedron gives up at most 8 % of it.

   Both are linear in ``(u, x)``, which is the form TOPP-RA solves exactly on its grid
   (:data:`GRID_M` metres of ``s`` between grid points, every waypoint a grid point), from
   rest to rest.
4. **Trajectories.** The times of the grid points follow from ``x``; every UAV gets a clamped
   cubic spline in ``t`` through its points ``p_n(s_i)`` at those times (zero velocity at
   both ends, C2). The waypoints are grid points, so the ``k``-th waypoints keep one common
   time ``t_k``. Speed and acceleration are then checked on a fine grid; if the interpolation
   between grid points breaks a limit, the whole schedule is stretched by one factor (a stretch
   ``c`` divides velocities by ``c`` and accelerations by ``c^2``).

Why toppra: it is the maintained implementation of time-optimal path parameterisation, it
accepts any constraint linear in ``(u, x)`` through its ``LinearConstraint`` interface, and it
has compiled wheels on PyPI. Giving it the team's stacked ``3N``-dimensional path is what keeps
the timing common (a per-UAV timing would break the formation's shared waypoint times).
"""

from __future__ import annotations

import logging
import math
from functools import lru_cache

import numpy as np
import toppra
import toppra.algorithm
import toppra.constraint
from scipy.interpolate import CubicSpline
from scipy.spatial import HalfspaceIntersection

MERGE_M = 0.5
"""Waypoints of one index closer than this (m) to the previous ones for every UAV are merged."""
GRID_M = 0.5
"""Spacing (m of the path parameter) of TOPP-RA's grid."""
ACC_DIRECTIONS = 48
"""Directions of the polyhedron that stands in for the acceleration ball."""
TOPP_MARGIN = 0.02
"""Relative margin TOPP-RA keeps below the limits (the interpolation between its grid points)."""
HOLD_S = 0.2
"""Duration (s) of a plan in which nobody moves."""


def merge_waypoints(points: np.ndarray, tol: float = MERGE_M) -> np.ndarray:
    """``(M',)`` indices of the waypoints kept from ``points`` ``(N, M, 3)``.

    Walking along the waypoints, an index whose point lies within ``tol`` of the last kept
    point *for every UAV* is dropped for the whole team; the start and the goal are always
    kept (a goal close to the last kept waypoint replaces it)."""
    p = np.asarray(points, dtype=float)
    keep = [0]
    for k in range(1, p.shape[1]):
        near = float(np.linalg.norm(p[:, k] - p[:, keep[-1]], axis=-1).max()) < tol
        if not near:
            keep.append(k)
        elif k == p.shape[1] - 1:
            if len(keep) > 1:
                keep[-1] = k
            else:
                keep.append(k)
    return np.asarray(keep, dtype=int)


def turn_backs(points: np.ndarray, at: int, most: int) -> int:
    """How many of the points after ``at`` in ``points`` ``(N, M, 3)`` to drop, at most
    ``most``, so that no UAV turns back (by more than 90 degrees) at point ``at``: dropped one
    after the other while some UAV's next leg still points back, always keeping the last point.
    0: nobody turns back there."""
    p = np.asarray(points, dtype=float)
    into = p[:, at] - p[:, at - 1]  # (N, 3)
    dropped = 0
    while dropped < most and at + dropped + 2 < p.shape[1]:
        out = p[:, at + dropped + 1] - p[:, at]
        if not np.any(np.einsum("nc,nc->n", into, out) < 0.0):
            break
        dropped += 1
    return dropped


def team_chord(points: np.ndarray) -> np.ndarray:
    """``(M,)`` the team's path parameter at each point of ``points`` ``(N, M, 3)``: the
    cumulative sum of the longest UAV leg (m)."""
    legs = np.linalg.norm(np.diff(points, axis=1), axis=-1).max(axis=0)
    return np.concatenate([[0.0], np.cumsum(legs)])


def split_legs(points: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Split every leg of ``points`` ``(N, M, 3)`` into equal sub-legs, the same number for
    the whole team (the longest UAV leg at most ``spacing`` m per sub-leg).

    Returns the dense points ``(N, M', 3)`` and ``(M,)`` the index of each original point."""
    legs = np.linalg.norm(np.diff(points, axis=1), axis=-1).max(axis=0)  # (M - 1,)
    rows = [points[:, :1]]
    index = [0]
    for k, length in enumerate(legs):
        m = max(1, math.ceil(length / spacing))
        f = np.arange(1, m + 1) / m
        rows.append(points[:, k:k + 1] + f[None, :, None] * (points[:, k + 1:k + 2] - points[:, k:k + 1]))
        index.append(index[-1] + m)
    return np.concatenate(rows, axis=1), np.asarray(index, dtype=int)


@lru_cache(maxsize=4)
def acceleration_polyhedron(n: int = ACC_DIRECTIONS) -> tuple[np.ndarray, float]:
    """``(n, 3)`` unit directions ``d_j`` (a Fibonacci sphere) and the circumradius ``R`` of
    ``{a : d_j . a <= 1}``: ``{a : d_j . a <= A / R}`` lies inside the ball of radius ``A``."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1.0 - 2.0 * i / n)
    theta = np.pi * (1.0 + math.sqrt(5.0)) * i
    d = np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1)
    hull = HalfspaceIntersection(np.hstack([d, -np.ones((n, 1))]), np.zeros(3))
    return d, float(np.linalg.norm(hull.intersections, axis=1).max())


class TeamLimits(toppra.constraint.LinearConstraint):
    """Every UAV's speed and acceleration norms along the stacked team path (``3N`` dof).

    In TOPP-RA's canonical form ``a_i u + b_i x + c_i = v``, ``F v <= g``, ``x`` in
    ``xbound_i``: the rows of ``v`` are ``d_j . p_n'`` (``a``) and ``d_j . p_n''`` (``b``) for
    every UAV ``n`` and direction ``j``, ``F`` is the identity, ``g = a_max / R``, and the speed
    bounds ``x <= v_max^2 / max_n |p_n'|^2``, lowered to ``x_cap`` ``(G,)`` where given."""

    def __init__(self, n_uavs: int, max_speed: float, max_acceleration: float,
                 x_cap: np.ndarray | None = None) -> None:
        super().__init__()
        self.x_cap = x_cap
        self.n_uavs = n_uavs
        self.dof = 3 * n_uavs
        self.max_speed = max_speed
        self.directions, radius = acceleration_polyhedron()
        self.bound = max_acceleration / radius
        self.identical = True
        self.set_discretization_type(toppra.constraint.DiscretizationType.Collocation)

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):  # noqa: ANN001 (toppra's API)
        g = len(gridpoints)
        ps = np.asarray(path(gridpoints, 1)).reshape(g, self.n_uavs, 3)
        pss = np.asarray(path(gridpoints, 2)).reshape(g, self.n_uavs, 3)
        a = np.einsum("jk,gnk->gnj", self.directions, ps).reshape(g, -1)
        b = np.einsum("jk,gnk->gnj", self.directions, pss).reshape(g, -1)
        rows = a.shape[1]
        speed2 = np.maximum((ps ** 2).sum(axis=-1).max(axis=1), 1e-12)
        xbound = np.stack([np.zeros(g), self.max_speed ** 2 / speed2], axis=1)
        if self.x_cap is not None:
            xbound[:, 1] = np.minimum(xbound[:, 1], self.x_cap)
        return a, b, np.zeros_like(a), np.eye(rows), np.full(rows, self.bound), None, xbound


def parameterise(points: np.ndarray, max_speed: float, max_acceleration: float,
                 grid_m: float = GRID_M, passes: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time-optimal common timing of the team's paths through ``points`` ``(N, M, 3)``
    (consecutive points distinct for some UAV), from rest to rest.

    TOPP-RA meets the limits at its grid points; the trajectory in time interpolates between
    them and can exceed the acceleration limit where the path bends sharply. Each further pass
    (up to ``passes``) finds the grid points where the interpolated acceleration ``a_i`` exceeds
    the limit ``A`` and caps the path speed there and at both neighbours to
    ``x_i (A / a_i)^2`` (accelerations along a fixed path scale with ``x``): a local
    slowdown instead of a stretch of the whole schedule.

    Returns ``t`` ``(G,)`` the times of the grid points, ``q`` ``(G, N, 3)`` the positions
    there and ``at`` ``(M,)`` the grid index of each point. Raises ``ValueError`` if TOPP-RA
    finds no parameterisation (it should not: rest is always reachable)."""
    n, m, _ = points.shape
    s = team_chord(points)
    path = toppra.SplineInterpolator(s, np.moveaxis(points, 0, 1).reshape(m, -1), bc_type="natural")
    even = np.linspace(0.0, s[-1], max(2, math.ceil(s[-1] / grid_m) + 1))
    near = np.abs(even[:, None] - s[None, :]).min(axis=1) < 0.05 * grid_m  # would duplicate a waypoint
    grid = np.sort(np.concatenate([s, even[~near]]))
    at = np.searchsorted(grid, s)
    q = np.asarray(path(grid)).reshape(len(grid), n, 3)
    logging.getLogger("toppra").setLevel(logging.ERROR)
    a_lim = max_acceleration * (1.0 - TOPP_MARGIN)
    cap = np.full(len(grid), np.inf)
    for _ in range(passes):
        limits = TeamLimits(n, max_speed * (1.0 - TOPP_MARGIN), a_lim, cap)
        solver = toppra.algorithm.TOPPRA([limits], path, gridpoints=grid, solver_wrapper="seidel")
        _, sd, _ = solver.compute_parameterization(0.0, 0.0)
        if sd is None or not np.all(np.isfinite(sd)):
            raise ValueError("TOPP-RA found no timing of the team's paths within the limits")
        x = np.maximum(sd, 0.0) ** 2
        dt = 2.0 * np.diff(grid) / np.maximum(np.sqrt(x[:-1]) + np.sqrt(x[1:]), 1e-9)
        t = np.concatenate([[0.0], np.cumsum(dt)])
        acc = np.linalg.norm(team_spline(t, q)(t, 2), axis=-1).max(axis=1)  # (G,) exact peaks
        over = acc > max_acceleration * (1.0 - 0.5 * TOPP_MARGIN)
        if not over.any():
            break
        factor = np.ones_like(x)
        factor[over] = (a_lim / acc[over]) ** 2
        factor = np.minimum(factor, np.minimum(np.roll(factor, 1), np.roll(factor, -1)))
        cap = np.where(factor < 1.0, np.minimum(cap, x * factor), cap)
    return t, q, at


def team_spline(t: np.ndarray, q: np.ndarray) -> CubicSpline:
    """Clamped cubic spline in time through ``q`` ``(T, N, 3)`` at ``t`` ``(T,)`` (values ``(N, 3)``)."""
    return CubicSpline(t, q, axis=0, bc_type="clamped")


def hold_times() -> np.ndarray:
    """Times of a plan in which nobody moves: start and goal :data:`HOLD_S` apart."""
    return np.array([0.0, HOLD_S])
