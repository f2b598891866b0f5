"""Missions: geo-reference, timed synchronised trajectories, exports read back by the loaders
their users use (pymavlink, fastkml with the KML 2.2 schema, geojson, QGroundControl's fields,
DJI WPML's required fields, Litchi's header), and the bad inputs of ``staghunt export``."""

from __future__ import annotations

import csv
import json
import math
import zipfile
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from staghunt import plan
from staghunt.cli import main
from staghunt.costs import CostModel
from staghunt.geo import geodetic_to_site, parse_origin, site_to_geodetic
from staghunt.io.result_json import write_result
from staghunt.missions import export_result
from staghunt.missions.formats import LITCHI_HEADER
from staghunt.scenario import load_scenario
from staghunt.task import VehicleLimits
from staghunt.trajectory import check_in_time, time_plan
from staghunt.trajectory.timing import merge_waypoints
from staghunt.world import GeoOrigin

TOL = 0.5  # metres: points read back must match the plan within this
WPML = "{http://www.dji.com/wpmz/1.0.2}"
KML = "{http://www.opengis.net/kml/2.2}"


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    scenario = load_scenario("scenario2")
    result = plan(scenario, "rigid", 1, scenario.solver.with_(particles=200, iterations=60), engine="numba")
    assert result.feasible, result.message
    path = tmp_path_factory.mktemp("plan") / "result.json"
    write_result(result, path)
    return scenario, result, path


@pytest.fixture(scope="module")
def exported(planned, tmp_path_factory):
    _, _, path = planned
    out = tmp_path_factory.mktemp("mission")
    report = export_result(str(path), str(out), plots=False)
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
    assert slow.duration > 2 * fast.duration and slow.stretch > 1


def test_in_time_checks_keep_separation_and_clearance_at_every_sample(planned):
    scenario, result, _ = planned
    model = CostModel.from_scenario(scenario)
    traj = time_plan(result.paths, scenario.vehicle)
    report = check_in_time(model, traj, result.uav_names)
    assert report.safe, report.problems
    assert report.step <= 0.1 and report.times > 100
    assert min(report.min_separation) > max(report.separation_limit)
    assert min(report.min_clearance) >= model.min_clearance
    # the same minima by brute force on the samples
    pos, _ = traj.sample(traj.grid())
    d = np.linalg.norm(pos[0] - pos[1], axis=-1).min()
    assert d >= min(report.min_separation[:2]) - 1e-9
    # pulling UAV 2 onto UAV 1 halfway is seen in time
    bad = result.paths.copy()
    bad[1, 1:-1] = bad[0, 1:-1] + 1.0
    assert not check_in_time(model, time_plan(bad, scenario.vehicle), result.uav_names).safe


# ----------------------------------------------------------------------------------- the files


def test_every_file_is_written(exported):
    out, report = exported
    names = {p.name for p in report.files}
    for n in (1, 2, 3):
        assert {f"uav{n}.plan", f"uav{n}.waypoints", f"uav{n}.kmz", f"uav{n}.litchi.csv"} <= names
    assert {"mission.kml", "mission.geojson", "trajectories.csv", "mission.json"} <= names
    summary = json.loads((out / "mission.json").read_text())
    assert summary["safe"] and summary["duration_s"] == pytest.approx(report.duration)


def test_waypoints_file_read_by_pymavlink(planned, exported):
    from pymavlink import mavwp

    scenario, result, _ = planned
    out, _ = exported
    for n in range(3):
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


def test_plan_file_has_every_field_qgroundcontrol_reads(planned, exported):
    """The fields of QGroundControl's plan file format (its developer guide, "Plan File Format")
    that its mission loader reads, checked strictly: top level, mission, SimpleItem (7 params),
    geoFence and rallyPoints version 2."""
    scenario, result, _ = planned
    out, _ = exported
    for n in range(3):
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


def test_kml_valid_against_the_kml_schema_and_read_by_fastkml(planned, exported):
    import lxml.etree as et
    from fastkml import kml
    from fastkml.validator import validate

    scenario, result, _ = planned
    out, _ = exported
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


def test_geojson_valid_and_read_by_geojson(planned, exported):
    import geojson

    scenario, result, _ = planned
    out, _ = exported
    fc = geojson.loads((out / "mission.geojson").read_text())
    assert fc.is_valid and fc["type"] == "FeatureCollection" and len(fc["features"]) == 3
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


def test_dji_kmz_has_the_required_wpml_fields(planned, exported):
    scenario, result, _ = planned
    out, _ = exported
    for n in range(3):
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
        ref = [float(v) for v in template.find(f".//{WPML}takeOffRefPoint").text.split(",")]
        pts = []
        for m in marks:
            lon, lat = (float(v) for v in m.find(f"{KML}Point/{KML}coordinates").text.split(","))
            pts.append((lat, lon, ref[2] + float(m.find(f"{WPML}executeHeight").text)))
        pts = np.array(pts)
        np.testing.assert_allclose(_site(scenario, pts[:, 0], pts[:, 1], pts[:, 2]), _flown(result)[n], atol=TOL)


def test_litchi_csv_has_the_documented_header(planned, exported):
    scenario, result, _ = planned
    out, _ = exported
    rows = list(csv.reader((out / "uav1.litchi.csv").open()))
    assert rows[0] == LITCHI_HEADER and len(rows[0]) == 46
    body = rows[1:]
    assert len(body) == _flown(result).shape[1]
    col = {name: i for i, name in enumerate(rows[0])}
    assert all(r[col["altitudemode"]] == "0" and 0 <= float(r[col["speed(m/s)"]]) <= 15 for r in body)
    assert all(float(r[col["altitude(m)"]]) >= 0 for r in body)
    # relative to the takeoff point on the ground under the start: the start's height
    assert float(body[0][col["altitude(m)"]]) == pytest.approx(result.heights[0, 0], abs=0.01)


def test_trajectories_csv_one_grid_for_the_team(exported):
    out, report = exported
    rows = list(csv.DictReader((out / "trajectories.csv").open()))
    assert list(rows[0]) == ["t", "uav", "x", "y", "z", "vx", "vy", "vz"]
    t = np.array(sorted({float(r["t"]) for r in rows}))
    assert t[0] == 0 and t[-1] == pytest.approx(report.duration, abs=1e-3)
    assert np.diff(t).max() <= 0.1 + 1e-3
    assert len(rows) == 3 * len(t) and {r["uav"] for r in rows} == {"1", "2", "3"}


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
            time_plan(result.paths, bad)


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
