"""Geo-referencing of the site frame with pyproj (no hand-written geodesy).

The site frame is a local east-north frame at the scenario's :class:`GeoOrigin`: an azimuthal
equidistant projection centred on the origin (WGS84), which agrees with local east-north-up to
millimetres over a site of a few kilometres. Heights: site ``z = altitude AMSL - origin.altitude``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from staghunt.world.site import GeoOrigin


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
    return t.transform(np.asarray(x, dtype=float), np.asarray(y, dtype=float))


def crs_to_site(origin: GeoOrigin, crs: str, X: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates in ``crs`` -> site ``x, y`` (m)."""
    t = _transformer(origin.latitude, origin.longitude, crs, True)
    x, y = t.transform(np.asarray(X, dtype=float), np.asarray(Y, dtype=float))
    return np.asarray(x), np.asarray(y)


def lonlat_to_site(origin: GeoOrigin, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """WGS84 longitude, latitude (degrees) -> site ``x, y`` (m)."""
    return crs_to_site(origin, "EPSG:4326", lon, lat)
