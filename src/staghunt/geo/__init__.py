"""Geo-reference: the site frame (local east-north-up at the scenario's origin) and WGS84.

Conversions use pymap3d (``enu2geodetic`` / ``geodetic2enu``), never hand-written formulas. The
origin's altitude is metres above mean sea level (AMSL) of the site point ``(0, 0, 0)``; pymap3d
treats it as the height of the ENU origin and returns heights on the same datum, so a site point
at ``z`` (absolute, ``z = g(x, y) + h``) lies ``origin.altitude + z`` AMSL up to the curvature of
the earth (under 1 mm over 100 m, 0.1 m over 1 km, included by pymap3d). Heights above the WGS84
ellipsoid (``h = AMSL + N``, for formats that want them) use the EGM2008 geoid height ``N`` of
:mod:`staghunt.geo.geoid`.
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d

from staghunt.world import GeoOrigin

__all__ = ["GeoOrigin", "check_origin", "geodetic_to_site", "parse_origin", "site_to_geodetic"]


def check_origin(origin: GeoOrigin, what: str = "origin") -> GeoOrigin:
    """Raise ``ValueError`` (one line) for an origin outside valid latitude/longitude/altitude."""
    lat, lon, alt = origin.latitude, origin.longitude, origin.altitude
    for name, v in (("latitude", lat), ("longitude", lon), ("altitude", alt)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"{what}: {name} must be a finite number, got {v!r}")
    if not -90.0 <= lat <= 90.0:
        raise ValueError(f"{what}: latitude must lie in [-90, 90] degrees, got {lat:g}")
    if not -180.0 <= lon <= 180.0:
        raise ValueError(f"{what}: longitude must lie in [-180, 180] degrees, got {lon:g}")
    if not -500.0 <= alt <= 10000.0:
        raise ValueError(f"{what}: altitude must lie in [-500, 10000] m above mean sea level, got {alt:g}")
    return origin


def parse_origin(text: str) -> GeoOrigin:
    """``"LAT,LON,ALT"`` (degrees, degrees, metres AMSL), e.g. ``"-33.8837,151.2006,30"``."""
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != 3:
        raise ValueError(f"origin must be LAT,LON,ALT (three numbers separated by commas), got {text[:80]!r}")
    try:
        lat, lon, alt = (float(p) for p in parts)
    except ValueError:
        raise ValueError(f"origin must be LAT,LON,ALT with numbers, got {text[:80]!r}") from None
    return check_origin(GeoOrigin(latitude=lat, longitude=lon, altitude=alt))


def site_to_geodetic(points: np.ndarray, origin: GeoOrigin) -> np.ndarray:
    """``(..., 3)`` absolute site ``(x east, y north, z up)`` metres -> ``(..., 3)``
    ``(latitude, longitude, altitude AMSL)``."""
    p = np.asarray(points, dtype=float)
    lat, lon, alt = pymap3d.enu2geodetic(p[..., 0], p[..., 1], p[..., 2], origin.latitude,
                                         origin.longitude, origin.altitude)
    return np.stack([np.asarray(lat), np.asarray(lon), np.asarray(alt)], axis=-1)


def geodetic_to_site(geo: np.ndarray, origin: GeoOrigin) -> np.ndarray:
    """Inverse of :func:`site_to_geodetic`: ``(..., 3)`` ``(lat, lon, alt AMSL)`` -> site ``(x, y, z)``."""
    g = np.asarray(geo, dtype=float)
    e, n, u = pymap3d.geodetic2enu(g[..., 0], g[..., 1], g[..., 2], origin.latitude,
                                   origin.longitude, origin.altitude)
    return np.stack([np.asarray(e), np.asarray(n), np.asarray(u)], axis=-1)
