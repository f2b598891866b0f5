"""The site frame and the earth: the one module (and the one library, pyproj) through which every
input and output conversion goes (GeoTIFF ground, GeoJSON obstacles, mission export, ``--origin``).

The site frame is a local east-north-up frame at the scenario's :class:`GeoOrigin`:

- horizontally, an azimuthal equidistant projection centred on the origin (WGS84 ellipsoid):
  ``x`` east and ``y`` north in metres; it agrees with the tangent plane (ENU) to under a
  millimetre over 5 km and its inverse is exact to nanometres, so a point read from a GeoJSON
  file and written to a mission comes back where it was;
- vertically, ``z`` is the height above the origin's altitude: ``altitude AMSL = origin.altitude
  + z``, the same datum as a DEM's elevations, without the earth's curvature (a tangent-plane
  ENU ``u`` drops 2 m below the AMSL surface 5 km away; a UAV 20 m above the ground there must
  stay 20 m above it in the mission).

pyproj rather than pymap3d because the inputs come in arbitrary CRSs (a GeoTIFF in UTM, GeoJSON
in CRS84) that only pyproj transforms, and because pymap3d's ENU ``u`` carries the curvature
that the site frame's ``z`` does not. (:mod:`staghunt.geo` re-exports the geodetic functions.)
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from staghunt.world.site import GeoOrigin

__all__ = ["crs_to_site", "geodetic_to_site", "lonlat_to_site", "site_to_crs", "site_to_geodetic", "site_to_lonlat"]

WGS84 = "EPSG:4326"


@lru_cache(maxsize=16)
def _transformer(lat: float, lon: float, target: str, inverse: bool):  # noqa: ANN202
    from pyproj import CRS, Transformer

    site = CRS.from_proj4(f"+proj=aeqd +lat_0={lat!r} +lon_0={lon!r} +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs")
    other = CRS.from_user_input(target)
    if inverse:
        return Transformer.from_crs(other, site, always_xy=True)
    return Transformer.from_crs(site, other, always_xy=True)


def site_to_crs(origin: GeoOrigin, crs: str, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Site ``x, y`` (m, any shape) -> coordinates in ``crs`` (WKT, ``EPSG:...``; x/easting or
    longitude first)."""
    t = _transformer(origin.latitude, origin.longitude, crs, False)
    X, Y = t.transform(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    return np.asarray(X), np.asarray(Y)


def crs_to_site(origin: GeoOrigin, crs: str, X: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates in ``crs`` -> site ``x, y`` (m)."""
    t = _transformer(origin.latitude, origin.longitude, crs, True)
    x, y = t.transform(np.asarray(X, dtype=float), np.asarray(Y, dtype=float))
    return np.asarray(x), np.asarray(y)


def lonlat_to_site(origin: GeoOrigin, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """WGS84 longitude, latitude (degrees) -> site ``x, y`` (m)."""
    return crs_to_site(origin, WGS84, lon, lat)


def site_to_lonlat(origin: GeoOrigin, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Site ``x, y`` (m) -> WGS84 longitude, latitude (degrees)."""
    return site_to_crs(origin, WGS84, x, y)


def site_to_geodetic(points: np.ndarray, origin: GeoOrigin) -> np.ndarray:
    """``(..., 3)`` absolute site ``(x east, y north, z up)`` metres -> ``(..., 3)``
    ``(latitude, longitude, altitude AMSL)`` with ``altitude = origin.altitude + z``."""
    p = np.asarray(points, dtype=float)
    lon, lat = site_to_lonlat(origin, p[..., 0], p[..., 1])
    return np.stack([np.asarray(lat, dtype=float), np.asarray(lon, dtype=float), p[..., 2] + origin.altitude],
                    axis=-1)


def geodetic_to_site(geo: np.ndarray, origin: GeoOrigin) -> np.ndarray:
    """Inverse of :func:`site_to_geodetic`: ``(..., 3)`` ``(lat, lon, alt AMSL)`` -> site ``(x, y, z)``."""
    g = np.asarray(geo, dtype=float)
    x, y = lonlat_to_site(origin, g[..., 1], g[..., 0])
    return np.stack([np.asarray(x, dtype=float), np.asarray(y, dtype=float), g[..., 2] - origin.altitude], axis=-1)
