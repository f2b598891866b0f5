"""What the figures share: one colour per UAV (:func:`uav_colour`), the colours of obstacles,
leader and formation links, font sizes, and small helpers over a :class:`PlanResult`."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from staghunt.result import PlanResult

# Colour-blind-friendly, none of them close to the amber of the obstacles or the black leader.
_UAV_COLOURS = (
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#17becf", "#e377c2", "#8c564b", "#7f7f7f",
)
_OBSTACLE_FACE = "#f2b705"
_OBSTACLE_EDGE = "#8a6a00"
_LEADER = "black"
_LINK = "0.35"

_TITLE = 13
_LABEL = 11
_TICK = 10
_LEGEND = 9.5


def uav_colour(n: int) -> str:
    """Colour of UAV ``n`` (0-based), the same in every figure."""
    return _UAV_COLOURS[n % len(_UAV_COLOURS)]


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------


def _status_text(result: PlanResult) -> str:
    return str(getattr(result.status, "value", result.status))


def _title(result: PlanResult, what: str) -> str:
    return (
        f"{what}: {result.scenario.name}, method {result.method}, seed {result.seed}, "
        f"{_status_text(result)}"
    )


def _names(result: PlanResult) -> list[str]:
    return [u.name for u in result.scenario.team]


def _edges(result: PlanResult) -> list[tuple[int, int]]:
    """``(head, tail)`` UAV indices of the formation graph's edges."""
    formation = result.scenario.formation
    if formation.incidence.size == 0:
        return []
    heads, tails = formation.heads_tails()
    return [(int(h), int(t)) for h, t in zip(heads, tails) if h != t]


def _style_axes(ax: Axes) -> None:
    ax.tick_params(labelsize=_TICK)
    ax.grid(True, alpha=0.3)


def _start_goal_handles() -> list[Line2D]:
    return [
        Line2D([], [], ls="none", marker="o", ms=9, mfc="white", mec="0.2", mew=1.5, label="start"),
        Line2D([], [], ls="none", marker="*", ms=13, mfc="white", mec="0.2", mew=1.2, label="goal"),
    ]


def _link_handle() -> Line2D:
    return Line2D([], [], color=_LINK, ls=":", lw=1.0, label="formation at waypoints")


def _ground_grid(
    result: PlanResult, max_cells: int = 60
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(X, Y, G)`` grids over the site for drawing the ground (flat: a 2 x 2 plane)."""
    b = result.scenario.world.bounds
    terrain = result.scenario.world.terrain
    if terrain.elevation is None:
        X, Y = np.meshgrid([b.xmin, b.xmax], [b.ymin, b.ymax])
        return X, Y, np.zeros_like(X)
    rows, cols = terrain.elevation.shape
    nx = int(min(max_cells, max(2, cols)))
    ny = int(min(max_cells, max(2, rows)))
    X, Y = np.meshgrid(np.linspace(b.xmin, b.xmax, nx), np.linspace(b.ymin, b.ymax, ny))
    return X, Y, np.asarray(terrain.height(X, Y), dtype=float)


def _ground_range(result: PlanResult) -> tuple[float, float]:
    _, _, G = _ground_grid(result)
    return float(G.min()), float(G.max())


def _leader_heights(result: PlanResult) -> np.ndarray | None:
    if result.leader_path is None:
        return None
    lp = np.asarray(result.leader_path, dtype=float)
    g = np.asarray(result.scenario.world.terrain.height(lp[:, 0], lp[:, 1]), dtype=float)
    return lp[:, 2] - g


def _legend_handles(result: PlanResult, obstacle_label: str, alpha: float) -> list[Line2D | Patch]:
    """Legend entries every path figure shares: start and goal, formation link (if there are
    edges), obstacle (if there are any)."""
    handles: list[Line2D | Patch] = list(_start_goal_handles())
    if _edges(result):
        handles.append(_link_handle())
    if result.scenario.world.cylinders:
        handles.append(Patch(facecolor=_OBSTACLE_FACE, edgecolor=_OBSTACLE_EDGE, alpha=alpha,
                             label=obstacle_label))
    return handles
