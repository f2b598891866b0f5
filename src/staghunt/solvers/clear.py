"""A warm start moved clear of the obstacles: the plan a re-plan starts from, when a new obstacle
cuts it, with its waypoints pushed sideways out of the obstacle's hard clearance, so that the
game's replies start from a feasible plan instead of searching for one.

Without it, a re-plan of the moving team warm-started on a plan through a pop-up sensed 2-4 s
ahead often ended infeasible within its deadline (the detour lies at the edge of the replies'
heading range), and the team stopped to hover where a swerve was possible (benchmarks/JOURNAL.md,
"Closed loop: the warm start pushed clear"). Shapes: ``N`` UAVs, ``K`` free waypoints, ``T``
cylinders.
"""

from __future__ import annotations

import numpy as np

from staghunt.costs import CostModel

CLEAR_PAD = 0.5
"""How far beyond the hard clearance (m) a pushed segment is placed, so that the replies have
room to move without breaking it."""

PUSH_ROUNDS = 40
"""Most rounds of pushes (each moves every offending waypoint part of the way out)."""

PUSH_STEP = 0.6
"""Share of a segment's shortfall its free ends move in one round (below 1: a waypoint shared by
two offending segments is pushed by both)."""


def pushed_clear(model: CostModel, plan: np.ndarray, pad: float = CLEAR_PAD) -> np.ndarray:
    """``plan`` ``(N, K, 3)`` ``(x, y, h)`` with its waypoints moved horizontally until every
    segment of every UAV's full path (its start, the waypoints, its goal) passes at least
    ``R + r_n + c + pad`` from the axis of every cylinder of ``model`` (``R`` the cylinder's
    radius, ``r_n`` the UAV's, ``c`` the model's hard clearance), or :data:`PUSH_ROUNDS` have
    passed. Each round moves the ends of every segment that passes too close directly away
    from the cylinder's axis (from the segment's nearest point), by :data:`PUSH_STEP` of its
    shortfall; the start and goal stay where they are (a start already too close is the
    solver's to leave, not this function's), the waypoints stay inside the site's box and
    keep their heights. Prisms are left as they are. Returns a new ``(N, K, 3)`` array; the
    plan itself when no segment is too close."""
    plan = np.asarray(plan, dtype=float)
    cyl = np.asarray(model.cylinders, dtype=float)
    if len(cyl) == 0:
        return plan
    pts = np.concatenate([model.starts[:, None, :2], plan[..., :2], model.goals[:, None, :2]], axis=1)
    centre = cyl[None, None, :, :2]  # (1, 1, T, 2)
    need = (cyl[None, :, 2] + model.radius[:, None] + model.min_clearance + pad)[:, None, :]  # (N, 1, T)
    moved = False
    for _ in range(PUSH_ROUNDS):
        a, ab = pts[:, :-1], np.diff(pts, axis=1)  # (N, S, 2) with S = K + 1
        length2 = np.maximum((ab**2).sum(axis=-1), 1e-12)[..., None]  # (N, S, 1)
        t = np.clip(((centre - a[:, :, None]) * ab[:, :, None]).sum(axis=-1) / length2, 0.0, 1.0)  # (N, S, T)
        away = a[:, :, None] + t[..., None] * ab[:, :, None] - centre  # (N, S, T, 2) nearest point - axis
        dist = np.linalg.norm(away, axis=-1)
        short = np.maximum(need - dist, 0.0)
        short[:, 0][t[:, 0] <= 0.0] = 0.0  # nearest at the start or the goal: no waypoint can help
        short[:, -1][t[:, -1] >= 1.0] = 0.0
        if not (short > 1e-6).any():
            break
        side = np.stack([-ab[..., 1], ab[..., 0]], axis=-1) / np.sqrt(length2)  # (N, S, 2) a normal
        unit = np.where(dist[..., None] > 1e-9, away / np.maximum(dist, 1e-9)[..., None], side[:, :, None])
        push = PUSH_STEP * (short[..., None] * unit).sum(axis=2)  # (N, S, 2)
        pts[:, 1:-1] += push[:, :-1] + push[:, 1:]  # a waypoint ends one segment and starts the next
        pts[:, 1:-1] = np.clip(pts[:, 1:-1], model.lower[:2], model.upper[:2])
        moved = True
    if not moved:
        return plan
    out = plan.copy()
    out[..., :2] = pts[:, 1:-1]
    return out
