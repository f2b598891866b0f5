"""Geo-reference: the site frame (local east-north-up at the scenario's origin) and WGS84.

The conversions themselves live in :mod:`staghunt.world.georef` (pyproj), the one module every
input (GeoTIFF, GeoJSON) and output (mission files) goes through; they are re-exported here. A
site point ``(x, y, z)`` lies at the azimuthal-equidistant position ``(x, y)`` around the origin
and ``origin.altitude + z`` metres above mean sea level (AMSL). Heights above the WGS84
ellipsoid (``h = AMSL + N``, for formats that want them) use the EGM2008 geoid height ``N`` of
:mod:`staghunt.geo.geoid`.
"""

from __future__ import annotations

import math

from staghunt.world import GeoOrigin
from staghunt.world.georef import geodetic_to_site, site_to_geodetic

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
