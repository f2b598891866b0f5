"""Site bounds: the box the team may fly in."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Bounds:
    """Horizontal site limits and the flight-height band, in metres.

    ``x`` in ``[xmin, xmax]`` (east), ``y`` in ``[ymin, ymax]`` (north), and height *above
    ground* ``h`` in ``[hmin, hmax]``. The spherical decoder clamps every waypoint into this box.
    """

    xmin: float
    xmax: float
    ymin: float
    ymax: float
    hmin: float
    hmax: float

    @property
    def lower(self) -> np.ndarray:
        """``(3,)`` lower corner ``(xmin, ymin, hmin)``."""
        return np.array([self.xmin, self.ymin, self.hmin])

    @property
    def upper(self) -> np.ndarray:
        """``(3,)`` upper corner ``(xmax, ymax, hmax)``."""
        return np.array([self.xmax, self.ymax, self.hmax])

    def contains_xy(self, x: float, y: float) -> bool:
        return self.xmin <= x <= self.xmax and self.ymin <= y <= self.ymax


@dataclass(frozen=True)
class GeoOrigin:
    """Geodetic position of the site frame's origin ``(0, 0, 0)``: WGS84 ``latitude`` and
    ``longitude`` in degrees and ``altitude`` in metres above mean sea level (AMSL). The site
    frame is local east-north-up at that point: ``x`` east, ``y`` north, ``z`` up, so a point
    at height ``h`` above ground ``g(x, y)`` lies at ``altitude + g(x, y) + h`` AMSL."""

    latitude: float
    longitude: float
    altitude: float
