"""Obstacles ("threats"): vertical cylinders, infinitely tall as in the SPSO reference, and
vertical prisms over polygons (buildings, crane towers, boxes, no-fly zones).

A prism is a polygon footprint in the site's x-y plane extruded between two absolute heights
``base`` and ``top`` (site-frame ``z``, metres). A no-fly zone is a prism with ``base = -inf``
and ``top = +inf``. How a path segment is judged against a prism is in ``docs/model.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np

PrismKind = Literal["prism", "box", "nofly"]


@dataclass(frozen=True)
class Cylinder:
    """A vertical cylinder with axis at ``(x, y)`` and radius ``radius`` (metres)."""

    x: float
    y: float
    radius: float
    name: str = ""


@dataclass(frozen=True)
class Prism:
    """A vertical prism: footprint ``polygon`` (``V`` vertices ``(x, y)``, simple, not closed:
    the last vertex joins the first) between absolute heights ``base < top`` (site ``z``, m;
    ``-inf`` = from the ground, ``+inf`` = forbidden at every height)."""

    polygon: tuple[tuple[float, float], ...]
    base: float
    top: float
    name: str = ""
    kind: PrismKind = "prism"
    agl: tuple[float, float] | None = None
    """``(base, height)`` in metres above the ground as the scenario gave them (``None`` for a
    no-fly zone); written back by :func:`staghunt.scenario.scenario_to_dict`."""

    @property
    def is_nofly(self) -> bool:
        return self.kind == "nofly"


def cylinder_array(cylinders: Sequence[Cylinder]) -> np.ndarray:
    """``(T, 3)`` array of ``(x, y, radius)`` rows."""
    if not cylinders:
        return np.zeros((0, 3))
    return np.array([[c.x, c.y, c.radius] for c in cylinders], dtype=float)


def prism_arrays(prisms: Sequence[Prism]) -> tuple[np.ndarray, np.ndarray]:
    """Prisms as arrays: ``prm (Q, 8)`` = ``base, top, first edge, edge count, bbox xmin, xmax,
    ymin, ymax`` and ``edges (E, 4)`` = ``x0, y0, x1, y1`` of every footprint edge (prism by
    prism, in vertex order, the closing edge last)."""
    prm = np.zeros((len(prisms), 8))
    rows: list[list[float]] = []
    for q, p in enumerate(prisms):
        v = np.asarray(p.polygon, dtype=float)
        w = np.roll(v, -1, axis=0)
        prm[q] = [p.base, p.top, len(rows), len(v), v[:, 0].min(), v[:, 0].max(),
                  v[:, 1].min(), v[:, 1].max()]
        rows.extend(np.column_stack([v, w]).tolist())
    edges = np.array(rows, dtype=float).reshape(-1, 4)
    return prm, edges


def box_polygon(xmin: float, xmax: float, ymin: float, ymax: float) -> tuple[tuple[float, float], ...]:
    """Counter-clockwise footprint of an axis-aligned box."""
    return ((xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax))
