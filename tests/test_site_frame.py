"""One site frame (issue 19): every input (GeoJSON, GeoTIFF) and output (mission files) goes
through :mod:`staghunt.world.georef`; GeoJSON features far from the site are pruned before they
become obstacles; a fine GeoTIFF is read decimated; a GeoTIFF changed after planning is refused."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")
rasterio = pytest.importorskip("rasterio")
pyproj = pytest.importorskip("pyproj")

from rasterio.transform import from_origin  # noqa: E402

from staghunt.geo import geodetic_to_site, site_to_geodetic  # noqa: E402
from staghunt.scenario import ScenarioError, load_scenario, scenario_from_dict  # noqa: E402
from staghunt.scenario.dump import scenario_to_dict  # noqa: E402
from staghunt.world import GeoOrigin  # noqa: E402
from staghunt.world.georef import site_to_crs, site_to_lonlat  # noqa: E402

ORIGIN = GeoOrigin(47.397742, 8.545594, 488.0)
GEOD = pyproj.Geod(ellps="WGS84")


def site_toml(xmin: float, ymin: float, size: float = 200.0, body: str = "") -> str:
    cx, cy = xmin + size / 2, ymin + size / 2
    return f"""
name = "t"
[site]
xmin = {xmin}
xmax = {xmin + size}
ymin = {ymin}
ymax = {ymin + size}
hmin = 5.0
hmax = 40.0
[origin]
latitude = {ORIGIN.latitude}
longitude = {ORIGIN.longitude}
altitude = {ORIGIN.altitude}
{body}
[[team]]
start = [{cx - 0.4 * size}, {cy - 0.4 * size}, 20.0]
goal = [{cx + 0.4 * size}, {cy - 0.4 * size}, 20.0]
radius = 1.0
beta = 1.0
weights = [1.0, 1.0, 1.0, 1.0, 1.0]
"""


def feature(lonlat_ring=None, point=None, **props) -> dict:
    if point is not None:
        geom = {"type": "Point", "coordinates": list(point)}
    else:
        geom = {"type": "Polygon", "coordinates": [[list(p) for p in lonlat_ring]]}
    return {"type": "Feature", "properties": props, "geometry": geom}


def square(x: float, y: float, half: float) -> list[tuple[float, float]]:
    xs = np.array([x - half, x + half, x + half, x - half, x - half])
    ys = np.array([y - half, y - half, y + half, y + half, y - half])
    lon, lat = site_to_lonlat(ORIGIN, xs, ys)
    return list(zip(lon.tolist(), lat.tolist()))


def write_geojson(tmp_path: Path, feats: list[dict], name: str = "b.geojson") -> Path:
    p = tmp_path / name
    p.write_text(json.dumps({"type": "FeatureCollection", "features": feats}))
    return p


# ------------------------------------------------------------------------------------------------
# One frame: GeoJSON in, mission out
# ------------------------------------------------------------------------------------------------


def test_geojson_point_5_km_out_comes_back_within_1_cm(tmp_path):
    """A GeoJSON point 5 km from the origin, read in as a site point and written through the
    mission export's conversion, lands on the same latitude/longitude within 1 cm."""
    bearing = 37.0
    lon, lat, _ = GEOD.fwd(ORIGIN.longitude, ORIGIN.latitude, bearing, 5000.0)
    # the site box around it (so the feature is not pruned)
    x0, y0 = 5000.0 * np.sin(np.radians(bearing)), 5000.0 * np.cos(np.radians(bearing))
    gj = write_geojson(tmp_path, [feature(point=(lon, lat), name="mast", radius=2.0)])
    body = f'[[geojson]]\nfile = "{gj}"\n'
    p = tmp_path / "s.toml"
    p.write_text(site_toml(round(x0) - 100.0, round(y0) - 100.0 + 60.0, body=body))
    s = load_scenario(str(p))
    (c,) = [c for c in s.world.cylinders if c.name == "mast"]
    assert np.hypot(c.x, c.y) == pytest.approx(5000.0, abs=0.01)  # azimuthal equidistant: geodesic range
    lat2, lon2, alt2 = site_to_geodetic(np.array([c.x, c.y, 12.5]), s.origin)
    _, _, dist = GEOD.inv(lon, lat, lon2, lat2)
    assert dist < 0.01
    assert alt2 == pytest.approx(ORIGIN.altitude + 12.5, abs=1e-9)  # z: height above the origin's altitude
    back = geodetic_to_site(np.array([lat2, lon2, alt2]), s.origin)
    np.testing.assert_allclose(back, [c.x, c.y, 12.5], atol=1e-6)


def test_geotiff_and_export_use_the_same_horizontal_conversion():
    x, y = np.array([0.0, 4000.0, -2500.0]), np.array([0.0, -3000.0, 4500.0])
    lon, lat = site_to_crs(ORIGIN, "EPSG:4326", x, y)
    g = site_to_geodetic(np.column_stack([x, y, np.zeros(3)]), ORIGIN)
    np.testing.assert_array_equal(g[:, 0], lat)
    np.testing.assert_array_equal(g[:, 1], lon)


# ------------------------------------------------------------------------------------------------
# GeoJSON: pruning, nothing near the site
# ------------------------------------------------------------------------------------------------


def test_features_far_from_the_site_do_not_become_obstacles(tmp_path):
    feats = [feature(square(50.0, 50.0, 10.0), name="near", height=10.0),
             feature(square(205.0, 50.0, 2.0), name="edge", height=10.0)]  # 3 m beyond xmax: within the margin
    feats += [feature(square(2000.0 + 30.0 * k, -1500.0, 5.0), name=f"far {k}", height=10.0) for k in range(60)]
    mast = site_to_lonlat(ORIGIN, np.array([-900.0]), np.array([0.0]))
    feats.append(feature(point=(float(mast[0][0]), float(mast[1][0])), name="far mast", radius=3.0))
    gj = write_geojson(tmp_path, feats)
    p = tmp_path / "s.toml"
    p.write_text(site_toml(0.0, 0.0, body=f'[[geojson]]\nfile = "{gj}"\n'))
    s = load_scenario(str(p))
    assert sorted(q.name for q in s.world.prisms) == ["edge", "near"]
    assert not s.world.cylinders


def test_pruned_features_are_still_checked(tmp_path):
    feats = [feature(square(50.0, 50.0, 10.0), name="near", height=10.0),
             feature(square(3000.0, 0.0, 5.0), name="far", height=1e300)]
    gj = write_geojson(tmp_path, feats)
    p = tmp_path / "s.toml"
    p.write_text(site_toml(0.0, 0.0, body=f'[[geojson]]\nfile = "{gj}"\n'))
    with pytest.raises(ScenarioError, match=r"features\[1\] \('far'\): property 'height' .* beyond the supported magnitude"):
        load_scenario(str(p))


def test_a_file_with_nothing_near_the_site_is_refused(tmp_path):
    far = square(700_000.0, 700_000.0, 10.0)  # ~1000 km away: e.g. longitude and latitude swapped
    gj = write_geojson(tmp_path, [feature(far, name="block", height=10.0)])
    p = tmp_path / "s.toml"
    p.write_text(site_toml(0.0, 0.0, body=f'[[geojson]]\nfile = "{gj}"\n'))
    with pytest.raises(ScenarioError, match=r"geojson\[0\]\.file: none of the 1 features .* 98\d\.?\d* km .*swapped"):
        load_scenario(str(p))


def test_too_many_features_near_the_site_are_refused(tmp_path, monkeypatch):
    from staghunt.scenario import shapes

    monkeypatch.setattr(shapes, "MAX_GEOJSON_OBSTACLES", 3)
    feats = [feature(square(20.0 + 30.0 * k, 150.0, 5.0), name=f"b{k}", height=10.0) for k in range(5)]
    gj = write_geojson(tmp_path, feats)
    p = tmp_path / "s.toml"
    p.write_text(site_toml(0.0, 0.0, body=f'[[geojson]]\nfile = "{gj}"\n'))
    with pytest.raises(ScenarioError, match=r"5 features .* come within .* of the site box \(at most 3\)"):
        load_scenario(str(p))


# ------------------------------------------------------------------------------------------------
# GeoTIFF: decimated read, checksum
# ------------------------------------------------------------------------------------------------


def write_plane_dem(path: Path, pixel: float, half: float, offset: float = 0.0) -> None:
    """A UTM 32N GeoTIFF around ORIGIN, elevation 500 + 0.02 (E - E0) + 0.01 (N - N0) + offset."""
    crs = "EPSG:32632"
    X0, Y0 = (float(v) for v in site_to_crs(ORIGIN, crs, 0.0, 0.0))
    west, north = X0 - half, Y0 + half
    n = int(round(2 * half / pixel))
    cols, rows = np.meshgrid(np.arange(n) + 0.5, np.arange(n) + 0.5)
    z = (500.0 + 0.02 * (west + cols * pixel - X0) + 0.01 * (north - rows * pixel - Y0) + offset).astype(np.float32)
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32", crs=crs,
                       transform=from_origin(west, north, pixel, pixel)) as dst:
        dst.write(z, 1)


def test_fine_geotiff_is_read_decimated_with_the_same_heights(tmp_path, monkeypatch):
    tif = tmp_path / "fine.tif"
    write_plane_dem(tif, 0.05, 40.0)  # 1600 x 1600 pixels of 5 cm under a 40 m site, 5 m cells
    body = f'[ground]\nkind = "geotiff"\nfile = "{tif}"\ncell_size = 5.0\nsampling = "bilinear"\n'
    p = tmp_path / "s.toml"
    p.write_text(site_toml(-20.0, -20.0, size=40.0, body=body))
    shapes_read = []
    real_read = rasterio.io.DatasetReader.read

    def spy(self, *args, **kwargs):
        out = real_read(self, *args, **kwargs)
        shapes_read.append(out.shape)
        return out

    monkeypatch.setattr(rasterio.io.DatasetReader, "read", spy)
    s = load_scenario(str(p))
    assert shapes_read and max(shapes_read[0]) < 40  # not the ~800 x 800 pixel window
    t = s.world.terrain
    X, Y = site_to_crs(ORIGIN, "EPSG:32632", np.array([-20.0, 0.0, 20.0]), np.array([-20.0, 0.0, 20.0]))
    X0, Y0 = site_to_crs(ORIGIN, "EPSG:32632", 0.0, 0.0)
    expect = 500.0 + 0.02 * (X - X0) + 0.01 * (Y - Y0) - ORIGIN.altitude
    got = t.height(np.array([-20.0, 0.0, 20.0]), np.array([-20.0, 0.0, 20.0]))
    np.testing.assert_allclose(got, expect, atol=0.01)


def test_geotiff_changed_after_planning_is_refused(tmp_path):
    tif = tmp_path / "g.tif"
    write_plane_dem(tif, 2.0, 200.0)
    body = f'[ground]\nkind = "geotiff"\nfile = "{tif}"\ncell_size = 5.0\n'
    p = tmp_path / "s.toml"
    p.write_text(site_toml(-100.0, -100.0, body=body))
    data = scenario_to_dict(load_scenario(str(p)))
    assert len(data["ground"]["sha256"]) == 64
    scenario_from_dict(data, name="t")  # unchanged: accepted
    write_plane_dem(tif, 2.0, 200.0, offset=4.0)
    with pytest.raises(ScenarioError, match=r"ground\.sha256: the GeoTIFF .* does not match this checksum \(file changed\?\)"):
        scenario_from_dict(data, name="t")


def test_loading_a_geotiff_does_not_hash_the_file(tmp_path, monkeypatch):
    """A GeoTIFF can take seconds to hash: loading a scenario reads it but hashes nothing; its
    SHA-256 is made when asked for (the scenario's dump, a ``ground.sha256`` check), once for a
    file that did not change."""
    import hashlib

    import staghunt.scenario.dem as dem

    tif = tmp_path / "g.tif"
    write_plane_dem(tif, 2.0, 200.0)
    p = tmp_path / "s.toml"
    p.write_text(site_toml(-100.0, -100.0, body=f'[ground]\nkind = "geotiff"\nfile = "{tif}"\ncell_size = 5.0\n'))
    want = hashlib.sha256(tif.read_bytes()).hexdigest()
    hashes: list[object] = []
    real = hashlib.sha256
    monkeypatch.setattr(dem.hashlib, "sha256", lambda *a: hashes.append(a) or real(*a))
    scenario = load_scenario(str(p))
    assert hashes == []
    for _ in range(2):
        assert scenario_to_dict(scenario)["ground"]["sha256"] == want
    assert len(hashes) == 1
