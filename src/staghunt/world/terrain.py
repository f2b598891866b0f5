"""Ground elevation ``g(x, y)``: flat, or a DEM grid sampled at the nearest cell or bilinearly."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

Sampling = Literal["nearest", "bilinear"]


def round_half_away(v: np.ndarray) -> np.ndarray:
    """MATLAB's ``round``: halves go away from zero (NumPy's ``round`` goes to even).

    Exact for every double: ``floor(|v| + 0.5)`` would round ``0.49999999999999994`` (and odd
    integers above ``2**52``) wrongly, because the addition itself rounds; ``|v| - floor(|v|)``
    is exact.
    """
    a = np.abs(v)
    f = np.floor(a)
    return np.sign(v) * (f + (a - f >= 0.5))


@dataclass(frozen=True, eq=False)
class Terrain:
    """Ground elevation above the datum, in metres.

    ``elevation`` is ``None`` for flat ground (``g = 0``), else a read-only ``(rows, cols)`` grid
    with rows along ``y`` and columns along ``x``. The centre of cell ``(row i, col j)`` sits at
    ``(origin_x + j * cell_size, origin_y + i * cell_size)``. The SPSO reference's convention
    (``H(round(y), round(x))``, 1-based) is ``origin = (1, 1)``, ``cell_size = 1``,
    ``sampling = "nearest"``. Points outside the grid take the nearest edge cell.

    A ``float32`` grid keeps the reference's single-precision arithmetic: the absolute altitude is
    ``float32(h) + g`` rounded in single precision (see :meth:`absolute`).
    """

    elevation: np.ndarray | None = None
    origin: tuple[float, float] = (0.0, 0.0)
    cell_size: float = 1.0
    sampling: Sampling = "nearest"
    source: str | None = field(default=None)
    georef: dict | None = field(default=None)
    """How a geo-referenced DEM was read (``{"kind": "geotiff", "nodata_fill": ...}``), so a
    scenario written back reads it again the same way; ``None`` for other grids."""

    @property
    def is_flat(self) -> bool:
        return self.elevation is None

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Ground elevation at ``x, y`` (any broadcastable shapes), in the grid's dtype."""
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        if self.elevation is None:
            return np.zeros(np.broadcast_shapes(x.shape, y.shape))
        grid = self.elevation
        rows, cols = grid.shape
        u = (x - self.origin[0]) / self.cell_size  # fractional column
        v = (y - self.origin[1]) / self.cell_size  # fractional row
        if self.sampling == "nearest":
            j = np.clip(round_half_away(u), 0, cols - 1).astype(np.intp)
            i = np.clip(round_half_away(v), 0, rows - 1).astype(np.intp)
            return grid[i, j]
        u = np.clip(u, 0.0, cols - 1.0)
        v = np.clip(v, 0.0, rows - 1.0)
        j0 = np.clip(np.floor(u).astype(np.intp), 0, max(cols - 2, 0))
        i0 = np.clip(np.floor(v).astype(np.intp), 0, max(rows - 2, 0))
        j1 = np.minimum(j0 + 1, cols - 1)
        i1 = np.minimum(i0 + 1, rows - 1)
        fu = u - j0
        fv = v - i0
        g = grid.astype(float)
        top = g[i0, j0] * (1 - fu) + g[i0, j1] * fu
        bottom = g[i1, j0] * (1 - fu) + g[i1, j1] * fu
        return top * (1 - fv) + bottom * fv

    def absolute(self, x: np.ndarray, y: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Absolute altitude ``z = h + g(x, y)`` as float64 (single-precision sum for a float32 grid)."""
        g = self.height(x, y)
        if g.dtype == np.float32:
            return (np.asarray(h).astype(np.float32) + g).astype(np.float64)
        return np.asarray(h, dtype=float) + g

    def extent(self) -> tuple[float, float, float, float] | None:
        """``(xmin, xmax, ymin, ymax)`` of the cell centres, or ``None`` for flat ground."""
        if self.elevation is None:
            return None
        rows, cols = self.elevation.shape
        x0, y0 = self.origin
        return (x0, x0 + (cols - 1) * self.cell_size, y0, y0 + (rows - 1) * self.cell_size)
