"""The cost model: a scenario compiled into the arrays the batched cost functions need."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from staghunt.scenario.model import Scenario
from staghunt.world import Terrain, cylinder_array, prism_arrays


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class CostModel:
    """Everything the cost of a team of paths depends on, as arrays.

    Shapes: ``N`` UAVs, ``T`` cylinders, ``M`` formation edges.

    - ``starts``, ``goals``: ``(N, 3)`` as ``(x, y, h)``; ``start_abs``, ``goal_abs``: absolute.
    - ``lower``, ``upper``: ``(3,)`` site box in ``(x, y, h)``.
    - ``radius``, ``beta``: ``(N,)``; ``weights``: ``(N, 5)`` = ``w1..w5``.
    - ``cylinders``: ``(T, 3)`` = ``(cx, cy, R)``.
    - ``prisms``: ``(Q, 8)`` and ``prism_edges``: ``(E, 4)`` (:func:`staghunt.world.prism_arrays`);
      ``ceiling``: absolute altitude ceiling (site ``z``, ``inf`` = none).
    - ``heads``, ``tails``: ``(M,)`` UAV index of each edge's head/tail; ``mu``: ``(N, M)``;
      ``ref_diff``: ``(M, 3)`` = ``P_head,r - P_tail,r``.
    """

    terrain: Terrain
    lower: np.ndarray
    upper: np.ndarray
    starts: np.ndarray
    goals: np.ndarray
    start_abs: np.ndarray
    goal_abs: np.ndarray
    radius: np.ndarray
    beta: np.ndarray
    weights: np.ndarray
    cylinders: np.ndarray
    heads: np.ndarray
    tails: np.ndarray
    mu: np.ndarray
    ref_diff: np.ndarray
    reference: np.ndarray
    danger_margin: float
    safe_distance: float
    turning_threshold_deg: float
    climb_threshold_deg: float
    h_ref: float
    continuous_separation: bool
    min_clearance: float = 0.0
    prisms: np.ndarray = field(default_factory=lambda: _frozen(np.zeros((0, 8))))
    prism_edges: np.ndarray = field(default_factory=lambda: _frozen(np.zeros((0, 4))))
    ceiling: float = float("inf")

    @property
    def n_uavs(self) -> int:
        return int(self.starts.shape[0])

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> "CostModel":
        world, form, c = scenario.world, scenario.formation, scenario.costs
        starts, goals = scenario.starts(), scenario.goals()
        terrain = world.terrain
        heads, tails = form.heads_tails()
        ref = np.asarray(form.reference, dtype=float)
        prm, edges = prism_arrays(world.prisms)
        return cls(
            terrain=terrain,
            lower=_frozen(world.bounds.lower),
            upper=_frozen(world.bounds.upper),
            starts=_frozen(starts),
            goals=_frozen(goals),
            start_abs=_frozen(to_absolute(terrain, starts)),
            goal_abs=_frozen(to_absolute(terrain, goals)),
            radius=_frozen(np.array([u.radius for u in scenario.team], dtype=float)),
            beta=_frozen(np.array([u.weights.beta for u in scenario.team], dtype=float)),
            weights=_frozen(np.array([u.weights.as_array() for u in scenario.team])),
            cylinders=_frozen(cylinder_array(world.cylinders)),
            heads=_frozen(heads.astype(np.intp)),
            tails=_frozen(tails.astype(np.intp)),
            mu=_frozen(np.asarray(form.edge_weights, dtype=float)),
            ref_diff=_frozen(ref[heads] - ref[tails]),
            reference=_frozen(ref),
            danger_margin=float(c.danger_margin),
            safe_distance=float(c.safe_distance),
            turning_threshold_deg=float(c.turning_threshold_deg),
            climb_threshold_deg=float(c.climb_threshold_deg),
            h_ref=scenario.h_ref,
            continuous_separation=bool(c.continuous_separation),
            min_clearance=float(c.min_clearance),
            prisms=_frozen(prm),
            prism_edges=_frozen(edges),
            ceiling=float(world.ceiling),
        )


def to_absolute(terrain: Terrain, xyh: np.ndarray) -> np.ndarray:
    """``(..., 3)`` ``(x, y, h)`` -> ``(..., 3)`` absolute ``(x, y, z = h + g(x, y))``."""
    out = np.array(xyh, dtype=float, copy=True)
    out[..., 2] = terrain.absolute(xyh[..., 0], xyh[..., 1], xyh[..., 2])
    return out


def full_paths(model: CostModel, waypoints: np.ndarray) -> np.ndarray:
    """Free waypoints ``(P, N, K, 3)`` ``(x, y, h)`` -> full paths ``(P, N, K + 2, 3)`` with start and goal."""
    P = waypoints.shape[0]
    s = np.broadcast_to(model.starts[None, :, None, :], (P, model.n_uavs, 1, 3))
    g = np.broadcast_to(model.goals[None, :, None, :], (P, model.n_uavs, 1, 3))
    return np.concatenate([s, waypoints, g], axis=2)
