"""Formation templates: a reference shape and a formation graph for ``N`` UAVs by a fixed rule.

Offsets are in the formation's own frame (``u`` forward, ``v`` to the left, metres), centred on
their mean, then turned to the team's heading. Graph rule (docs/scenario-format.md, ``[fleet]``):

- ``line`` (abreast, perpendicular to the heading): a chain ``i - (i+1)``;
- ``wedge`` (leader 0 ahead, members alternate right/left, each rank one ``spacing`` further back
  and out): each member linked to the one ahead of it on its wing (members 1 and 2 to the leader);
- ``grid`` (rows of ``columns``, row 0 ahead): links to the right-hand and the rear neighbour;
- ``circle`` (neighbours ``spacing`` apart): a ring ``i - (i+1 mod N)``.

Every edge ``(a, b)``, ``a < b``, has head ``a`` and tail ``b``; both end UAVs weigh it 1
(``mu[a, e] = mu[b, e] = 1``), the others 0.
"""

from __future__ import annotations

import math

import numpy as np

TEMPLATES = ("line", "wedge", "grid", "circle")


def template_offsets(template: str, count: int, spacing: float, columns: int | None = None) -> np.ndarray:
    """``(count, 2)`` offsets ``(u, v)`` (forward, left) centred on their mean."""
    n = count
    i = np.arange(n)
    if template == "line":
        uv = np.column_stack([np.zeros(n), -(i - (n - 1) / 2.0) * spacing])
    elif template == "wedge":
        rank = (i + 1) // 2
        side = np.where(i % 2 == 1, -1.0, 1.0)  # odd: right, even: left
        uv = np.column_stack([-rank * spacing, side * rank * spacing])
        uv[0] = 0.0
    elif template == "grid":
        c = columns or int(math.ceil(math.sqrt(n)))
        row, col = i // c, i % c
        uv = np.column_stack([-row * spacing, -(col - (c - 1) / 2.0) * spacing]).astype(float)
    elif template == "circle":
        if n == 1:
            uv = np.zeros((1, 2))
        else:
            radius = spacing / (2.0 * math.sin(math.pi / n))
            a = 2.0 * math.pi * i / n
            uv = np.column_stack([radius * np.cos(a), radius * np.sin(a)])
    else:
        raise ValueError(f"unknown formation template {template!r}; use one of {', '.join(TEMPLATES)}")
    return uv - uv.mean(axis=0)


def template_edges(template: str, count: int, columns: int | None = None) -> list[tuple[int, int]]:
    """Edges ``(head, tail)`` of the template's formation graph (see the module docstring)."""
    n = count
    if template == "line":
        return [(i, i + 1) for i in range(n - 1)]
    if template == "wedge":
        return [(0 if i <= 2 else i - 2, i) for i in range(1, n)]
    if template == "grid":
        c = columns or int(math.ceil(math.sqrt(n)))
        out = []
        for i in range(n):
            if i % c + 1 < c and i + 1 < n:
                out.append((i, i + 1))
            if i + c < n:
                out.append((i, i + c))
        return out
    if template == "circle":
        if n == 2:
            return [(0, 1)]
        return [(min(i, (i + 1) % n), max(i, (i + 1) % n)) for i in range(n)] if n > 2 else []
    raise ValueError(f"unknown formation template {template!r}")


def graph_matrices(count: int, edges: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
    """Incidence ``(N, M)`` (+1 head, -1 tail) and edge weights ``(N, M)`` (1 for both ends)."""
    inc = np.zeros((count, len(edges)))
    for e, (a, b) in enumerate(edges):
        inc[a, e] = 1.0
        inc[b, e] = -1.0
    return inc, np.abs(inc)


def place(offsets: np.ndarray, centre: np.ndarray, heading_rad: float) -> np.ndarray:
    """``(N, 3)`` points ``(x, y, h)``: formation offsets ``(N, 2)`` turned to ``heading_rad``
    (counter-clockwise from east) around ``centre`` ``(x, y, h)``."""
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    u, v = offsets[:, 0], offsets[:, 1]
    out = np.empty((len(offsets), 3))
    out[:, 0] = centre[0] + u * c - v * s
    out[:, 1] = centre[1] + u * s + v * c
    out[:, 2] = centre[2]
    return out
