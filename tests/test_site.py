"""Real sites: the GeoTIFF DEM reader in two CRSs (UTM and EPSG:4326), GeoJSON obstacles,
formation templates, the built-in sites, and bad input (exit 2, one line naming the file and the
element, nothing written)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")
rasterio = pytest.importorskip("rasterio")
pyproj = pytest.importorskip("pyproj")

from rasterio.transform import from_origin  # noqa: E402

from staghunt.cli import main  # noqa: E402
from staghunt.scenario import ScenarioError, load_scenario  # noqa: E402
from staghunt.task.templates import TEMPLATES, template_edges, template_offsets  # noqa: E402
from staghunt.task import is_connected  # noqa: E402
from staghunt.task.templates import graph_matrices  # noqa: E402
from staghunt.world import GeoOrigin  # noqa: E402
from staghunt.world.georef import lonlat_to_site, site_to_crs  # noqa: E402

ORIGIN = GeoOrigin(47.397742, 8.545594, 488.0)
TINY = ["--particles", "20", "--iterations", "5", "--certify-particles", "6", "--certify-iterations", "2",
        "--no-plots", "--quiet"]


def write_dem(path: Path, crs: str, pixel: float, fn, hole=None, nodata=-9999.0, margin=300.0, with_crs=True):  # noqa: ANN001
    """A float32 GeoTIFF in ``crs`` around ORIGIN whose elevation is ``fn(X, Y)`` at pixel centres."""
    X0, Y0 = site_to_crs(ORIGIN, crs, 0.0, 0.0)
    dx, dy = site_to_crs(ORIGIN, crs, margin, margin)
    half_x, half_y = abs(dx - X0), abs(dy - Y0)
    west, north = X0 - half_x, Y0 + half_y
    w, h = int(np.ceil(2 * half_x / pixel)), int(np.ceil(2 * half_y / pixel))
    cols, rows = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    z = fn(west + cols * pixel, north - rows * pixel).astype(np.float32)
    if hole is not None:
        z[hole(west + cols * pixel, north - rows * pixel)] = nodata
    profile = dict(driver="GTiff", width=w, height=h, count=1, dtype="float32",
                   transform=from_origin(west, north, pixel, pixel), nodata=nodata)
    if with_crs:
        profile["crs"] = crs
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(z, 1)
    return X0, Y0


SITE = """
name = "t"
[site]
xmin = -100.0
xmax = 100.0
ymin = -80.0
ymax = 80.0
hmin = 5.0
hmax = 40.0
[origin]
latitude = 47.397742
longitude = 8.545594
altitude = 488.0
"""
TEAM = """
[[team]]
start = [-80.0, 0.0, 20.0]
goal = [80.0, 0.0, 20.0]
radius = 1.0
beta = 1.0
weights = [1.0, 1.0, 1.0, 1.0, 1.0]
"""


def scenario_file(tmp_path: Path, body: str, team: str = TEAM, site: str = SITE) -> Path:
    p = tmp_path / "site.toml"
    p.write_text(site + body + team)
    return p


@pytest.mark.parametrize("crs, pixel", [("EPSG:32632", 4.0), ("EPSG:4326", 4e-5)], ids=["utm", "lonlat"])
@pytest.mark.parametrize("sampling", ["nearest", "bilinear"])
def test_geotiff_reader_in_two_crs(tmp_path, crs, pixel, sampling):
    # Elevation linear in the DEM's own coordinates: bilinear resampling is exact for it.
    X0, Y0 = site_to_crs(ORIGIN, crs, 0.0, 0.0)
    sx, sy = (0.05, 0.02) if crs != "EPSG:4326" else (0.05 / pixel * 4.0, 0.02 / pixel * 4.0)

    def fn(X, Y):  # noqa: ANN001, ANN202
        return 500.0 + sx * (X - X0) + sy * (Y - Y0)

    write_dem(tmp_path / "dem.tif", crs, pixel, fn)
    s = load_scenario(scenario_file(tmp_path, f'[ground]\nkind = "geotiff"\nfile = "dem.tif"\ncell_size = 4.0\n'
                                              f'sampling = "{sampling}"\n'))
    t = s.world.terrain
    assert t.elevation is not None and t.origin == (-100.0, -80.0) and t.cell_size == 4.0
    rows, cols = t.elevation.shape
    assert cols == 51 and rows == 41
    gx, gy = np.meshgrid(-100.0 + 4.0 * np.arange(cols), -80.0 + 4.0 * np.arange(rows))
    X, Y = site_to_crs(ORIGIN, crs, gx, gy)
    np.testing.assert_allclose(t.elevation, fn(np.asarray(X), np.asarray(Y)) - 488.0, atol=1e-3)
    assert abs(float(t.height(np.array([0.0]), np.array([0.0]))[0]) - 12.0) < 1e-3  # 500 - 488 at the origin
    # The scenario written back reads the same DEM the same way.
    from staghunt.scenario import scenario_from_dict, scenario_to_dict

    again = scenario_from_dict(scenario_to_dict(s), name="t")
    np.testing.assert_array_equal(again.world.terrain.elevation, t.elevation)


def test_nodata_fill(tmp_path):
    write_dem(tmp_path / "dem.tif", "EPSG:32632", 4.0, lambda X, Y: 500.0 + 0 * X,
              hole=lambda X, Y: np.hypot(*(np.asarray(site_to_crs(ORIGIN, "EPSG:32632", 0.0, 0.0))[:, None, None]
                                          - np.array([X, Y]))) < 12.0)
    with pytest.raises(ScenarioError, match=r"no data under the site"):
        load_scenario(scenario_file(tmp_path, '[ground]\nkind = "geotiff"\nfile = "dem.tif"\ncell_size = 4.0\n'))
    s = load_scenario(scenario_file(tmp_path, '[ground]\nkind = "geotiff"\nfile = "dem.tif"\ncell_size = 4.0\n'
                                              'nodata_fill = 490.0\n'))
    assert float(s.world.terrain.height(np.array([0.0]), np.array([0.0]))[0]) == pytest.approx(2.0)


def test_geojson_obstacles(tmp_path):
    to_ll = pyproj.Transformer.from_crs(
        pyproj.CRS.from_proj4(f"+proj=aeqd +lat_0={ORIGIN.latitude} +lon_0={ORIGIN.longitude} +datum=WGS84"),
        "EPSG:4326", always_xy=True)

    def ring(pts):  # noqa: ANN001, ANN202
        out = [list(to_ll.transform(x, y)) for x, y in pts]
        return out + [out[0]]

    doc = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "house", "height": 12.0},
         "geometry": {"type": "Polygon", "coordinates": [ring([(0, 30), (20, 30), (20, 50), (0, 50)])]}},
        {"type": "Feature", "properties": {"name": "two", "height": 9.0, "base": 3.0},
         "geometry": {"type": "MultiPolygon", "coordinates": [[ring([(-50, 30), (-40, 30), (-40, 40)])],
                                                              [ring([(40, -60), (50, -60), (50, -50)])]]}},
        {"type": "Feature", "properties": {"name": "mast", "radius": 2.5},
         "geometry": {"type": "Point", "coordinates": list(to_ll.transform(-30.0, -40.0))}},
    ]}
    (tmp_path / "o.geojson").write_text(json.dumps(doc))
    s = load_scenario(scenario_file(tmp_path, '[[geojson]]\nfile = "o.geojson"\n'))
    names = [p.name for p in s.world.prisms]
    assert names == ["house", "two", "two"]
    house = s.world.prisms[0]
    np.testing.assert_allclose(house.polygon, [(0, 30), (20, 30), (20, 50), (0, 50)], atol=1e-6)
    assert house.base == -np.inf and house.top == pytest.approx(12.0)
    assert s.world.prisms[1].base == pytest.approx(3.0) and s.world.prisms[1].top == pytest.approx(9.0)
    (c,) = s.world.cylinders
    assert (c.x, c.y, c.radius) == (pytest.approx(-30.0, abs=1e-6), pytest.approx(-40.0, abs=1e-6), 2.5)
    x, y = lonlat_to_site(ORIGIN, np.array([ORIGIN.longitude]), np.array([ORIGIN.latitude]))
    assert abs(x[0]) < 1e-6 and abs(y[0]) < 1e-6


@pytest.mark.parametrize("template", TEMPLATES)
@pytest.mark.parametrize("n", [2, 3, 8, 24])
def test_templates(template, n):
    uv = template_offsets(template, n, 10.0)
    assert uv.shape == (n, 2) and np.allclose(uv.mean(axis=0), 0.0)
    d = np.hypot(*(uv[:, None] - uv[None]).transpose(2, 0, 1))
    assert d[~np.eye(n, dtype=bool)].min() >= 10.0 - 1e-9
    inc, mu = graph_matrices(n, template_edges(template, n))
    assert is_connected(inc)
    for a, b in template_edges(template, n):  # graph edges join template neighbours
        assert d[a, b] <= 10.0 * np.sqrt(2) * 2 + 1e-9


def test_fleet(tmp_path):
    fleet = """
[fleet]
count = 6
template = "grid"
columns = 3
spacing = 10.0
start = [-60.0, 0.0, 20.0]
goal = [60.0, 0.0, 20.0]
radius = 1.0
beta = 1.0
weights = [1.0, 1.0, 1.0, 1.0, 1.0]
"""
    s = load_scenario(scenario_file(tmp_path, "", team=fleet))
    assert s.n_uavs == 6 and s.formation.n_edges == 7
    starts = s.starts()
    np.testing.assert_allclose(starts[:, :2].mean(axis=0), [-60.0, 0.0], atol=1e-9)
    assert starts[0, 0] > starts[3, 0]  # row 0 ahead (east)


def test_builtin_sites_load():
    w = load_scenario("site_wedge")
    g = load_scenario("site_grid24")
    assert w.n_uavs == 8 and g.n_uavs == 24
    assert any(p.is_nofly for p in w.world.prisms) and any(p.kind == "box" for p in w.world.prisms)
    assert w.world.terrain.georef is not None and np.isfinite(w.world.ceiling)


# --------------------------------------------------------------------------------------------
# Bad input through the CLI
# --------------------------------------------------------------------------------------------

GROUND = '[ground]\nkind = "geotiff"\nfile = "dem.tif"\ncell_size = 4.0\n'
FLAT_DEM = lambda X, Y: 500.0 + 0.0 * X  # noqa: E731


def _bad_cases(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    (tmp_path / "text.tif").write_text("not a raster\n")
    write_dem(tmp_path / "nocrs.tif", "EPSG:32632", 4.0, FLAT_DEM, with_crs=False)
    write_dem(tmp_path / "small.tif", "EPSG:32632", 4.0, FLAT_DEM, margin=50.0)
    X0 = float(site_to_crs(ORIGIN, "EPSG:32632", 30.0, 0.0)[0])
    write_dem(tmp_path / "holes.tif", "EPSG:32632", 4.0, FLAT_DEM, hole=lambda X, Y: np.abs(X - X0) < 6.0)
    poly = lambda pts: "[[prisms]]\nname = \"p\"\npolygon = " + json.dumps(pts) + "\nheight = 10.0\n"  # noqa: E731
    too_many = """
[fleet]
count = 24
template = "line"
spacing = 10.0
start = [-80.0, 0.0, 20.0]
goal = [80.0, 0.0, 20.0]
heading_deg = 0.0
radius = 1.0
beta = 1.0
weights = [1.0, 1.0, 1.0, 1.0, 1.0]
"""
    cases = {
        "not a raster": (GROUND.replace("dem.tif", "text.tif"), TEAM, "ground.file"),
        "no CRS": (GROUND.replace("dem.tif", "nocrs.tif"), TEAM, "no CRS"),
        "does not cover": (GROUND.replace("dem.tif", "small.tif"), TEAM, "does not cover the site box"),
        "nodata": (GROUND.replace("dem.tif", "holes.tif"), TEAM, "no data under the site"),
        "self-intersecting": (poly([[0, 0], [20, 20], [20, 0], [0, 20]]), TEAM,
                              "prisms[0].polygon: polygon is not a simple polygon: Self-intersection"),
        "empty polygon": (poly([[0, 0], [10, 10], [20, 20]]), TEAM, "empty"),
        "height below base": (poly([[0, 0], [10, 0], [10, 10]]).replace("height = 10.0", "base = 12.0\nheight = 10.0"),
                              TEAM, "prisms[0].height"),
        "start in prism": (poly([[-90, -10], [-70, -10], [-70, 10], [-90, 10]]).replace("10.0", "30.0"), TEAM,
                           "team[0].start"),
        "start in no-fly": ('[[nofly]]\nname = "zone"\npolygon = [[-90, -10], [-70, -10], [-70, 10]]\n', TEAM,
                            "no-fly zone 'zone'"),
        "start above ceiling": ("[airspace]\nceiling = 15.0\n", TEAM, "ceiling"),
        "too many UAVs": ("", too_many, "fleet"),
        "spacing too small": ("", too_many.replace("count = 24", "count = 4").replace("spacing = 10.0", "spacing = 3.0"),
                              "fleet.spacing"),
    }
    ll = [[8.5455, 47.3977], [8.5457, 47.3977], [8.5457, 47.3979], [8.5455, 47.3977]]
    gj = lambda props, geom: json.dumps({"type": "FeatureCollection", "features": [  # noqa: E731
        {"type": "Feature", "properties": props, "geometry": geom}]})
    geo = '[[geojson]]\nfile = "o.geojson"\n'
    geojson_docs = {
        "geojson without height": gj({"name": "shed"}, {"type": "Polygon", "coordinates": [ll]}),
        "geojson height below base": gj({"name": "shed", "height": 3, "base": 5}, {"type": "Polygon", "coordinates": [ll]}),
        "geojson line": gj({"name": "fence"}, {"type": "LineString", "coordinates": ll}),
        "geojson not a collection": json.dumps({"type": "Polygon", "coordinates": [ll]}),
    }
    needles = {"geojson without height": "features[0] ('shed'): the property 'height' is missing",
               "geojson height below base": "height 3 must be above base 5",
               "geojson line": "geometry type 'LineString' is not supported",
               "geojson not a collection": "not a GeoJSON FeatureCollection"}
    for name in geojson_docs:
        cases[name] = (geo, TEAM, needles[name])
    out = {}
    for name, (body, team, needle) in cases.items():
        d = tmp_path / name.replace(" ", "_")
        d.mkdir()
        for f in ("text.tif", "nocrs.tif", "small.tif", "holes.tif"):
            (d / f).write_bytes((tmp_path / f).read_bytes())
        if name in geojson_docs:
            (d / "o.geojson").write_text(geojson_docs[name])
        p = d / "site.toml"
        p.write_text(SITE + body + team)
        out[name] = (p, needle)
    return out


def test_bad_input_exit_2_one_line(tmp_path, capsys):
    for name, (path, needle) in _bad_cases(tmp_path).items():
        out = path.parent / "out"
        code = main(["plan", str(path), *TINY, "--out", str(out)])
        err = capsys.readouterr().err.strip()
        assert code == 2, f"{name}: exit {code}: {err}"
        assert len(err.splitlines()) == 1, f"{name}: {err}"
        assert str(path) in err and needle in err, f"{name}: {err}"
        assert "Traceback" not in err
        assert not out.exists(), name


def test_site_wedge_plans_feasible_on_a_small_budget(tmp_path):
    out = tmp_path / "run"
    code = main(["plan", "site_wedge", "--particles", "100", "--iterations", "60", "--no-certify", "--no-plots",
                 "--quiet", "--out", str(out)])
    assert code == 0
    r = json.loads((out / "result.json").read_text())
    assert r["status"] == "feasible" and r["metrics"]["collision_free_continuous"]
    # The result's scenario (GeoTIFF ground, prisms, no-fly zone, ceiling) reads back.
    from staghunt.scenario import scenario_from_dict

    s = scenario_from_dict(r["scenario"], name="x")
    assert s.n_uavs == 8 and len(s.world.prisms) == 6 and np.isfinite(s.world.ceiling)


def test_fleet_per_uav_ends_and_explicit_graph(tmp_path):
    fleet = """
[fleet]
count = 3
template = "line"
spacing = 10.0
starts = [[-80.0, -10.0, 20.0], [-80.0, 0.0, 20.0], [-80.0, 10.0, 20.0]]
goals = [[80.0, -10.0, 20.0], [80.0, 0.0, 20.0], [80.0, 10.0, 20.0]]
radius = 1.0
beta = 1.0
weights = [1.0, 1.0, 1.0, 1.0, 1.0]
[formation]
incidence = [[1, 1, 0], [-1, 0, 1], [0, -1, -1]]
edge_weights = [[1.0, 1.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]
"""
    s = load_scenario(scenario_file(tmp_path, "", team=fleet))
    np.testing.assert_array_equal(s.starts()[:, 1], [-10.0, 0.0, 10.0])
    assert s.formation.n_edges == 3  # the explicit graph, not the line's chain
    bad = fleet.replace("starts = [[-80.0, -10.0, 20.0], ", "starts = [")
    with pytest.raises(ScenarioError, match=r"fleet\.starts: must hold count = 3 points"):
        load_scenario(scenario_file(tmp_path, "", team=bad))
