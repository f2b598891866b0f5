"""Generate the data of the built-in 'site_wedge' and 'site_grid24' scenarios (synthetic, made
here, no third-party data): a hilly GeoTIFF DEM in UTM zone 32N (EPSG:32632) around the
scenarios' geodetic origin, and a GeoJSON of the buildings (lon/lat, WGS84) and a site cabin.

    python scripts/make_site.py            # writes into src/staghunt/scenario/builtin/

The DEM holds elevations in metres above mean sea level: 488 m (the origin's ground) plus two
hills, a slope and a gentle wave (site heights 0 - ~45 m), at 5 m pixels, float32, with a
nodata hole (-9999) in a corner outside the site box (which the loader therefore accepts).
Deterministic: the same files on every run.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import rasterio
from pyproj import CRS, Transformer
from rasterio.transform import from_origin

ORIGIN = (47.397742, 8.545594, 488.0)  # latitude, longitude, altitude AMSL (PX4 SITL home)
UTM = "EPSG:32632"
PIXEL = 5.0
NODATA = -9999.0

BUILDINGS = [  # site-frame footprints (m), height above ground (m)
    ("block A", [(230, 160), (290, 160), (290, 240), (265, 240), (265, 190), (230, 190)], 22.0),
    ("block B", [(330, 262), (382, 262), (382, 318), (330, 318)], 18.0),
    ("hall C", [(130, 300), (190, 290), (200, 340), (140, 350)], 12.0),
]
CABIN = ("site cabin", (190.0, 95.0), 4.0)  # centre, radius (m)


def hills(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Ground height (m) above the origin's ground at site coordinates ``x, y``."""
    return (25.0 * np.exp(-((x - 120.0) ** 2 + (y - 330.0) ** 2) / (2 * 90.0**2))
            + 32.0 * np.exp(-((x - 470.0) ** 2 + (y - 90.0) ** 2) / (2 * 110.0**2))
            + 0.015 * (x + 100.0) + 4.0 * np.sin(x / 70.0) * np.cos(y / 90.0) + 4.0)


def site_crs() -> CRS:
    lat, lon, _ = ORIGIN
    return CRS.from_proj4(f"+proj=aeqd +lat_0={lat!r} +lon_0={lon!r} +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs")


def make_dem(path: Path) -> None:
    to_utm = Transformer.from_crs(site_crs(), UTM, always_xy=True)
    from_utm = Transformer.from_crs(UTM, site_crs(), always_xy=True)
    e0, n0 = to_utm.transform(0.0, 0.0)
    west, north = np.floor((e0 - 200.0) / PIXEL) * PIXEL, np.ceil((n0 + 700.0) / PIXEL) * PIXEL
    width, height = int(1050 / PIXEL), int(950 / PIXEL)
    cols, rows = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    E = west + cols * PIXEL
    N = north - rows * PIXEL
    x, y = from_utm.transform(E, N)
    z = (ORIGIN[2] + hills(np.asarray(x), np.asarray(y))).astype(np.float32)
    z[(np.asarray(x) < -120.0) & (np.asarray(y) < -120.0)] = NODATA  # a hole outside the site
    profile = dict(driver="GTiff", width=width, height=height, count=1, dtype="float32", crs=UTM,
                   transform=from_origin(west, north, PIXEL, PIXEL), nodata=NODATA, compress="deflate")
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(z, 1)


def make_geojson(path: Path) -> None:
    to_ll = Transformer.from_crs(site_crs(), "EPSG:4326", always_xy=True)

    def ll(pts):  # noqa: ANN001, ANN202
        out = [list(map(lambda v: round(float(v), 9), to_ll.transform(px, py))) for px, py in pts]
        return out + [out[0]]

    feats = [{"type": "Feature", "properties": {"name": n, "height": h},
              "geometry": {"type": "Polygon", "coordinates": [ll(p)]}} for n, p, h in BUILDINGS]
    (cx, cy), r = CABIN[1], CABIN[2]
    lon, lat = to_ll.transform(cx, cy)
    feats.append({"type": "Feature", "properties": {"name": CABIN[0], "radius": r},
                  "geometry": {"type": "Point", "coordinates": [round(lon, 9), round(lat, 9)]}})
    path.write_text(json.dumps({"type": "FeatureCollection", "features": feats}, indent=1) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "src/staghunt/scenario/builtin")
    a = ap.parse_args()
    make_dem(a.out / "site_hills.tif")
    make_geojson(a.out / "site_buildings.geojson")
    print(f"wrote {a.out / 'site_hills.tif'} and {a.out / 'site_buildings.geojson'}")


if __name__ == "__main__":
    main()
