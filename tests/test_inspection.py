"""Inspections: cameras (QGroundControl's CameraCalc, the pinhole GSD), coverage on known
geometry, capture plans, allocation and its bound, the planned inspection, the flown one with a
lost UAV, and the exported camera actions read back by their users' libraries."""

from __future__ import annotations

import csv
import io
import json
import math
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from staghunt.acquisition.coverage import Photos, area_cells, facade_patches, measure
from staghunt.acquisition.plan import keepout, plan_captures
from staghunt.acquisition.survey import qgc_photos
from staghunt.camera import camera_table, get_camera
from staghunt.camera.projection import surface_gsd
from staghunt.inspection.allocation import Problem, greedy, lower_bound
from staghunt.inspection.routing import solve
from staghunt.inspection.planner import InspectConfig, fleet_of, plan_inspection
from staghunt.inspection.tasks import make_tasks
from staghunt.scenario import SolverSettings, load_scenario
from staghunt.solvers.response import CertifyOptions
from staghunt.task.objectives import AreaObjective, FacadeObjective, Inspection, Payload

DATA = Path(__file__).parent / "data"
SMALL = DATA / "objectives_small.toml"
M3E = get_camera("DJI Mavic 3E Wide")


# ------------------------------------------------------------------------------------------------
# cameras
# ------------------------------------------------------------------------------------------------


def test_camera_calc_matches_hand_computed_values():
    # GSD = d * sw * 100 / (iw * f); the worked examples of QGroundControl's formulas
    assert M3E.gsd_cm(100.0) == pytest.approx(100 * 17.3 * 100 / (5280 * 12.29))  # 2.666 cm/px
    assert M3E.gsd_cm(100.0) == pytest.approx(2.666, abs=1e-3)
    assert M3E.footprint_m(M3E.gsd_cm(100.0)) == pytest.approx((140.76, 105.47), abs=0.01)
    assert M3E.distance_m(1.0) == pytest.approx(5280 * 1.0 * 12.29 / (17.3 * 100))  # 37.51 m
    assert M3E.footprint_m(1.0) == pytest.approx((52.80, 39.56))
    assert M3E.line_spacing_m(1.0, 0.65) == pytest.approx(52.80 * 0.35)
    assert M3E.trigger_distance_m(1.0, 0.75) == pytest.approx(39.56 * 0.25)
    p4 = get_camera("DJI Phantom 4 RTK")  # DJI: GSD = H / 36.5 cm/px
    assert p4.gsd_cm(100.0) == pytest.approx(100 / 36.5, rel=2e-3)
    portrait = replace(M3E, landscape=False)
    assert portrait.footprint_m(1.0) == pytest.approx((39.56, 52.80))
    assert M3E.blur_px(5.0, 1.0) == pytest.approx(0.5)  # 5 m/s x 1 ms over 1 cm
    assert M3E.speed_for_blur(1.0, 0.5) == pytest.approx(5.0)


def test_the_camera_table_has_real_cameras_with_sources():
    table = camera_table()
    assert len(table) >= 3
    for name in ("DJI Mavic 3E Wide", "DJI Phantom 4 RTK", "Sony a6000 16mm"):
        assert table[name].source
    assert table["Sony a6000 16mm"].sensor_width_mm == 23.5 and table["Sony a6000 16mm"].min_trigger_interval_s == 1.0
    with pytest.raises(KeyError, match="unknown camera"):
        get_camera("Hasselblad 500C")


def test_pinhole_gsd_is_exact_for_known_surfaces():
    d = M3E.distance_m(1.0)
    pts = np.array([[0.0, 0.0, 0.0], [20.0, 12.0, 0.0], [-25.0, -18.0, 0.0]])
    gsd, inc = surface_gsd(M3E, pts, np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, d]), 0.3, -math.pi / 2)
    assert gsd == pytest.approx([1.0, 1.0, 1.0])  # level ground under a nadir camera: CameraCalc's GSD everywhere
    assert inc[0] == pytest.approx(0.0) and inc[1] == pytest.approx(math.degrees(math.atan(math.hypot(20, 12) / d)))
    # a wall seen square on from 10 m: GSD of 10 m; tilted by 40 degrees about the image's up axis,
    # the image centre's pixel stretches by 1 / cos(40 degrees)
    wall = np.array([[10.0, 0.0, 5.0]])
    g0, _ = surface_gsd(M3E, wall, np.array([-1.0, 0.0, 0.0]), np.array([0.0, 0.0, 5.0]), 0.0, 0.0)
    tilt = math.radians(40)
    g1, i1 = surface_gsd(M3E, wall, np.array([-math.cos(tilt), math.sin(tilt), 0.0]), np.array([0.0, 0.0, 5.0]), 0.0, 0.0)
    assert g0[0] == pytest.approx(M3E.gsd_cm(10.0))
    assert g1[0] == pytest.approx(M3E.gsd_cm(10.0) / math.cos(tilt))
    assert i1[0] == pytest.approx(40.0)


# ------------------------------------------------------------------------------------------------
# coverage and capture plans
# ------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def scenario2():
    return load_scenario("scenario2", objectives=SMALL)


def _photos(positions, yaw, pitch, objective="a", speed=0.0):
    n = len(positions)
    return Photos(np.arange(n, dtype=float), np.zeros(n, int), np.asarray(positions, float), np.full(n, yaw),
                  np.full(n, pitch), np.full(n, speed), np.full(n, objective), np.zeros(n, int))


def test_coverage_of_one_nadir_photo_is_its_footprint(scenario2):
    """On flat ground, one nadir photo from the target GSD's height images exactly the cells of
    its 52.8 x 39.6 m footprint, each at the target GSD."""
    obj = AreaObjective("a", ((0.0, 0.0), (100.0, 0.0), (100.0, 100.0), (0.0, 100.0)), 1.0)
    surf = area_cells(obj, scenario2, 1.0)
    d = M3E.distance_m(1.0)
    cov = measure(surf, _photos([[50.0, 50.0, d]], 0.0, -math.pi / 2), M3E, scenario2, 1.0, min_images=1)
    w, h = M3E.footprint_m(1.0)  # across (east-west, yaw 0 = up towards east) x along
    inside = (np.abs(surf.points[:, 1] - 50.0) <= w / 2) & (np.abs(surf.points[:, 0] - 50.0) <= h / 2)
    assert cov.target_share == pytest.approx(inside.mean(), abs=2e-3)
    assert cov.best_gsd_cm["max"] == pytest.approx(1.0, rel=1e-9)
    assert cov.blur_px["max"] == 0.0


def test_coverage_of_a_wall_respects_gsd_incidence_and_occlusion(scenario2):
    """A box's walls: a level photo square on to one wall sees its own wall only (the far walls
    face away, the sides are edge on), at a GSD that grows with the distance."""
    box = replace(scenario2.world.prisms[0], polygon=((40.0, 80.0), (60.0, 80.0), (60.0, 90.0), (40.0, 90.0)),
                  base=-np.inf, top=15.0, name="box") if scenario2.world.prisms else None
    from staghunt.world import Prism

    box = Prism(((40.0, 80.0), (60.0, 80.0), (60.0, 90.0), (40.0, 90.0)), -np.inf, 15.0, "box")
    sc = replace(scenario2, world=replace(scenario2.world, prisms=(box,), cylinders=()))
    obj = FacadeObjective("f", "box", 1.0, 60.0)
    surf = facade_patches(obj, sc, 0.5)
    d = M3E.distance_m(1.0)  # 37.5 m south of the south wall, looking north
    cov = measure(surf, _photos([[50.0, 80.0 - d, 7.5]], math.pi / 2, 0.0), M3E, sc, 1.0, 60.0, min_images=1)
    south = np.isclose(surf.points[:, 1], 80.0) & (surf.normals[:, 1] < -0.9)
    assert cov.target_share == pytest.approx(south.mean(), abs=1e-3)  # the south wall, all of it, nothing else


def test_qgc_photo_count_follows_its_transect_rules():
    """QGroundControl's count: lines every spacing from an offset set by the bounding box (its
    centre minus 1050 m here), each spanning the polygon, ceil(length / trigger distance) photos.
    A 100 x 40 m rectangle, lines along x every 10 m: y = 0, 10, 20, 30, 40 (the edges' lines meet
    the side edges at their ends), 5 lines of ceil(100 / 9) = 12 photos; every 15 m: y = 5, 20, 35."""
    from shapely.geometry import Polygon

    poly = Polygon([(0, 0), (100, 0), (100, 40), (0, 40)])
    assert qgc_photos(poly, 0.0, 10.0, 9.0) == 5 * 12
    assert qgc_photos(poly, 0.0, 15.0, 9.0) == 3 * 12


def test_area_plan_reaches_the_targets_on_flat_ground(scenario2):
    insp = scenario2.inspection
    plan = plan_captures(scenario2, insp).of("excavation")
    assert plan.kind == "area" and plan.segments
    for seg in plan.segments:  # never faster than the camera's interval or the blur allows
        assert seg.trigger_distance / seg.speed >= M3E.min_trigger_interval_s
        assert M3E.blur_px(seg.speed, seg.gsd_cm) <= insp.max_blur_px + 1e-9
    photos = []
    for i, seg in enumerate(plan.segments):
        pos, yaw, pitch = seg.photo_poses()
        photos.append(Photos(np.arange(len(pos)) + 100.0 * i, np.zeros(len(pos), int), pos, yaw, pitch,
                             np.full(len(pos), seg.speed), np.full(len(pos), "excavation"), np.full(len(pos), i)))
    cov = measure(area_cells(insp.objectives[0], scenario2, 0.5), Photos.concat(photos), M3E, scenario2, 1.0,
                  overlaps=(0.75, 0.65))
    assert cov.min_images_share >= 0.99
    assert cov.front_overlap["reached_share"] == 1.0 and cov.side_overlap["reached_share"] == 1.0


def test_a_capture_that_cannot_be_reached_is_reported(scenario2):
    """Survey lines over the crane of scenario 2 at (40, 48): the stretches too near it are cut
    out and reported, never dropped silently; what is kept is safe."""
    from staghunt.acquisition.plan import plan_objective

    obj = AreaObjective("over the crane", ((20.0, 30.0), (70.0, 30.0), (70.0, 66.0), (20.0, 66.0)), 1.0)
    plan = plan_objective(scenario2, scenario2.inspection, obj)
    assert any("cannot be flown safely" in u and "clearance" in u for u in plan.unreached), plan.unreached
    keep = keepout(scenario2)
    for seg in plan.segments:
        assert keep.point_ok(seg.points).all() and keep.segment_ok(seg.points).all()


# ------------------------------------------------------------------------------------------------
# allocation
# ------------------------------------------------------------------------------------------------


def _problem(scenario):
    insp = scenario.inspection
    tasks = make_tasks(insp, plan_captures(scenario, insp))
    return Problem(tuple(tasks), fleet_of(scenario, insp), slack=1.0)


def test_the_lower_bound_holds_and_is_exact_for_one_task(scenario2):
    pb = _problem(scenario2)
    lb = lower_bound(pb)
    for alloc in (greedy(pb), solve(pb, "ortools", solutions=10, rounds=3, time_cap_s=1.0)):
        assert alloc.ok and alloc.makespan >= lb - 1e-9
    one = replace(pb, tasks=(pb.tasks[0],), stop_s=0.0)
    t, f = one.tasks[0], one.fleet
    best = min(f.travel(k, f.starts[k], w.entry) + t.duration + f.travel(k, w.exit, f.goals[k])
               for k in range(f.n) for w in t.ways)
    assert lower_bound(one) == pytest.approx(max(best, max(f.travel(k, f.starts[k], f.goals[k]) for k in range(f.n))))
    assert greedy(one).makespan == pytest.approx(lower_bound(one))  # one task, no stop: the bound is met


def test_allocation_is_reproducible_and_no_worse_than_greedy(scenario2):
    pb = _problem(scenario2)
    a = solve(pb, "ortools", solutions=10, rounds=3, time_cap_s=5.0)
    b = solve(pb, "ortools", solutions=10, rounds=3, time_cap_s=5.0)
    assert [r.visits for r in a.routes] == [r.visits for r in b.routes]
    assert a.makespan <= greedy(pb).makespan + 1e-9
    assert sorted(v.task for r in a.routes for v in r.visits) == list(range(len(pb.tasks)))


def test_endurance_too_short_is_refused_with_what_is_missing(scenario2):
    insp = replace(scenario2.inspection, payloads=tuple(replace(p, endurance_s=20.0) for p in scenario2.inspection.payloads))
    with pytest.raises(ValueError, match="endurance too short for any allocation"):
        plan_inspection(replace(scenario2, inspection=insp), insp, InspectConfig(allocation="greedy"))


# ------------------------------------------------------------------------------------------------
# the planned inspection, exported and flown
# ------------------------------------------------------------------------------------------------

FAST = InspectConfig(leg_settings=SolverSettings(particles=200, iterations=80, waypoints=8, starts=1),
                     certify=CertifyOptions(particles=40, iterations=15), solutions=10, rounds=3)


@pytest.fixture(scope="module")
def planned(scenario2, tmp_path_factory):
    from staghunt.inspection.files import write_inspection

    plan = plan_inspection(scenario2, scenario2.inspection, FAST, seed=3)
    path = write_inspection(plan, tmp_path_factory.mktemp("insp") / "inspection.json")
    return plan, path


def test_the_planned_inspection_is_safe_and_covers_its_objectives(planned):
    plan, _ = planned
    assert plan.status.value == "planned", plan.message
    assert plan.safety.safe and plan.outbound is not None
    # the team's game to the first captures: certified, or (no feasible joint plan at this budget)
    # said so, each UAV then leaving alone and waiting for the others
    assert plan.outbound.certificate is not None or "the game found no feasible plan" in plan.message
    area, point = plan.coverage
    assert area["min_images_share"] >= 0.99 and point["visits_done"] == 1
    photos = plan.photos()
    hook = photos.take(photos.objective == "crane hook")
    assert len(hook) == 1 and 20.0 <= hook.t[0] <= 90.0  # within its time window
    assert plan.makespan >= plan.allocation.lower_bound


def test_the_plan_is_reproducible(scenario2, planned):
    plan, _ = planned
    again = plan_inspection(scenario2, scenario2.inspection, FAST, seed=3)
    assert [r.visits for r in again.allocation.routes] == [r.visits for r in plan.allocation.routes]
    assert np.array_equal(again.timeline.positions(np.arange(0, 40.0, 0.5)), plan.timeline.positions(np.arange(0, 40.0, 0.5)))


@pytest.fixture(scope="module")
def site3():
    """The built-in 3-UAV inspection at small game budgets (its outbound game is feasible)."""
    scenario = load_scenario("site_inspection3")
    return plan_inspection(scenario, scenario.inspection, FAST, seed=3)


def test_every_uav_flies_on_without_a_jump_and_the_work_is_allocated_again_from_the_way_out(planned, site3):
    from staghunt.inspection.planner import SLACK, Flight, from_way_out

    def continuous(timeline):
        for pieces in timeline.pieces:
            for a, b in zip(pieces[:-1], pieces[1:]):
                assert b.t0 == pytest.approx(a.t1, abs=1e-9)
                end_a = a.state(np.array([a.t1]))[0, 0] if a.spline is not None else a.hold
                start_b = b.state(np.array([b.t0]))[0, 0] if b.spline is not None else b.hold
                assert np.allclose(end_a, start_b, atol=1e-6)

    continuous(planned[0].timeline)
    continuous(site3.timeline)
    assert site3.status.value == "planned" and site3.safety.safe and site3.outbound.feasible
    # the work allocated again from where and when the team's game leaves each UAV: the game's
    # pieces kept as they are, every capture after them, the first allocation's bound
    problem = Problem(site3.tasks, fleet_of(site3.scenario, site3.inspection), slack=SLACK)
    fly = Flight(site3.scenario, site3.inspection, FAST, site3.seed, list(site3.tasks))
    alloc, timeline, built = from_way_out(fly, problem, site3.allocation, site3.timeline)
    assert not built.problems
    continuous(timeline)
    out = [[p for p in pieces if p.label == "outbound"] for pieces in site3.timeline.pieces]
    t_out = max(h[-1].t1 for h in out if h)
    for k, pieces in enumerate(timeline.pieces):
        assert [p.label for p in pieces[:len(out[k])]] == ["outbound"] * len(out[k])
        assert all(p is q for p, q in zip(pieces, out[k]))
    assert min(r.visits[0].start for r in alloc.routes if r.visits) >= t_out - 1e-6
    assert sorted(v.task for r in alloc.routes for v in r.visits) == sorted(t.index for t in site3.tasks)
    assert alloc.lower_bound == site3.allocation.lower_bound <= timeline.end
    # the plan keeps whichever ends earlier (the same again when it kept this one: deterministic)
    assert site3.makespan <= timeline.end + 1e-6


def test_the_timeline_state_is_its_splines_and_their_derivatives(planned):
    plan, _ = planned
    checked = 0
    for pieces in plan.timeline.pieces:
        for p in pieces:
            if p.spline is None:
                continue
            tau = np.linspace(0.0, float(p.spline.x[-1]), 23)
            ref = np.stack([p.spline(tau, nu) for nu in range(4)])
            ref = ref if p.column is None else ref[:, :, p.column]
            assert np.allclose(p.state(p.t0 + tau), ref, rtol=1e-9, atol=1e-9)
            checked += 1
    assert checked >= 5
    # past its last piece a UAV holds where it ended, at rest
    late = plan.timeline.state(np.array([plan.timeline.end + 5.0]))
    assert np.allclose(late[1:], 0.0)
    assert np.allclose(late[0, :, 0], plan.timeline.positions(np.array([plan.timeline.end]))[:, 0])


def test_inspection_json_gives_the_same_timeline_back(planned):
    from staghunt.inspection.files import read_inspection, read_timeline

    plan, path = planned
    _, tl = read_timeline(read_inspection(path))
    ts = np.arange(0.0, plan.makespan, 0.25)
    assert np.allclose(tl.positions(ts), plan.timeline.positions(ts), atol=1e-6)


@pytest.fixture(scope="module")
def exported(planned, tmp_path_factory):
    from staghunt.missions.inspection import export_inspection

    _, path = planned
    out = tmp_path_factory.mktemp("mission")
    from staghunt.geo import parse_origin

    summary = export_inspection(str(path), str(out), origin=parse_origin("-33.88,151.2,30"), plots=False)
    return out, summary


def test_waypoints_carry_the_camera_actions_read_by_pymavlink(exported):
    from pymavlink import mavwp

    out, _ = exported
    loader = mavwp.MAVWPLoader()
    n = loader.load(str(out / "uav1.waypoints"))
    items = [loader.wp(i) for i in range(n)]
    cmds = [w.command for w in items]
    starts = [w for w in items if w.command == 206 and w.param1 > 0]
    stops = [w for w in items if w.command == 206 and w.param1 == 0]
    assert starts and len(starts) == len(stops)
    assert all(w.param3 == 1 for w in starts)  # a photo at once, then every trigger distance
    mounts = [w for w in items if w.command == 205]
    assert mounts and all(w.param1 == pytest.approx(-90.0) and w.z == 2 for w in mounts)  # nadir, MAVLink targeting
    first = cmds.index(206)
    assert cmds[first - 1] == 16 and cmds[:first].count(205) >= 1  # gimbal set before the capture's first waypoint


def test_qgc_plan_dji_wpml_and_litchi_carry_the_camera(exported):
    import lxml.etree as et

    out, summary = exported
    names = sorted(p.name for p in out.iterdir())
    assert "uav1.plan" in names and summary["kind"] == "inspection"
    plans = [json.loads((out / n).read_text()) for n in names if n.endswith(".plan")]
    cmds = [it["command"] for p in plans for it in p["mission"]["items"]]
    assert 206 in cmds and 205 in cmds and 2000 in cmds  # the viewpoint's photo is one UAV's
    for it in (it for p in plans for it in p["mission"]["items"]):
        assert len(it["params"]) == 7 and it["autoContinue"] is True
    kmzs = [n for n in names if n.endswith(".kmz")]
    ns = {"wpml": "http://www.dji.com/wpmz/1.0.2", "kml": "http://www.opengis.net/kml/2.2"}
    funcs, triggers = [], []
    for n in kmzs:
        with zipfile.ZipFile(out / n) as z:
            for member in ("wpmz/template.kml", "wpmz/waylines.wpml"):
                root = et.fromstring(z.read(member))
                funcs += [e.text for e in root.iterfind(".//wpml:actionActuatorFunc", ns)]
                triggers += [e.text for e in root.iterfind(".//wpml:actionTriggerType", ns)]
    assert {"gimbalRotate", "takePhoto", "hover"} <= set(funcs) and "multipleDistance" in triggers
    rows = []
    for n in names:
        if n.endswith(".litchi.csv"):
            rows += list(csv.DictReader(io.StringIO((out / n).read_text())))
    assert any(r["actiontype1"] == "5" and r["actionparam1"] == "-90" for r in rows)  # tilt the camera to nadir
    assert any(float(r["photo_distinterval"]) > 0 for r in rows)
    assert any("1" in (r[f"actiontype{i}"] for i in range(1, 16)) for r in rows)  # the viewpoint's photo


def test_a_lost_uav_leaves_its_work_to_the_others(planned):
    """UAV2 is lost 25 s after take-off: it lands where it is, the others re-allocate what is left
    and finish; every cell is still imaged five times at the target GSD, nobody comes too close."""
    from staghunt.flight.inspection import captures_csv, fly_inspection
    from staghunt.world.dynamic import Event

    plan, _ = planned
    flight = fly_inspection(plan.scenario, plan.timeline, (Event(25.0, "uav_lost", "UAV2"),), seed=1, config=FAST)
    assert flight.lost == {"UAV2": pytest.approx(25.0)}
    assert len(flight.decisions) == 1 and flight.decisions[0].switch >= 25.0 + 0.1
    assert flight.decisions[0].switch == pytest.approx(25.0 + math.ceil(flight.decisions[0].latency_s / 0.1 - 1e-9) * 0.1)
    assert not flight.problems, flight.problems
    area = next(c for c in flight.coverage if c["objective"] == "excavation")
    assert area["min_images_share"] >= 0.99
    after = flight.photos.take((flight.photos.uav == 1) & (flight.photos.t > 25.0))
    assert len(after) == 0  # the lost UAV takes no photo after it is lost
    rows = list(csv.DictReader(io.StringIO(captures_csv(flight))))
    assert set(rows[0]) >= {"t", "uav", "x", "y", "z", "heading_deg", "gimbal_pitch_deg"}
    for uav in {r["uav"] for r in rows}:  # never faster than the camera's minimum interval
        t = np.array([float(r["t"]) for r in rows if r["uav"] == uav])
        assert np.all(np.diff(t) >= M3E.min_trigger_interval_s - 1e-9)


# ------------------------------------------------------------------------------------------------
# bad input: exit 2, one line naming the element, nothing written
# ------------------------------------------------------------------------------------------------

BASE = """[camera]
sensor_width_mm = 17.3
sensor_height_mm = 13.0
image_width_px = 5280
image_height_px = 3956
focal_length_mm = 12.29
min_trigger_interval_s = 0.7
"""
AREA = '[[objectives]]\nkind = "area"\nname = "a"\npolygon = [[20.0, 20.0], [60.0, 20.0], [60.0, 45.0], [20.0, 45.0]]\n'


@pytest.mark.parametrize("text, key, what", [
    (BASE + AREA.replace("[60.0, 45.0]", "[160.0, 45.0]") + "gsd_cm = 1.0\n", "objectives[0].polygon", "outside the site"),
    (BASE + '[[objectives]]\nkind = "point"\nname = "p"\nx = 40.0\ny = 48.0\nz = 5.0\ndistance = 10.0\n',
     "objectives[0]", "inside obstacle"),
    ('camera = "Hasselblad 500C"\n' + AREA + "gsd_cm = 1.0\n", "camera", "unknown camera"),
    (BASE + AREA + "gsd_cm = 0.1\n", "objectives[0].gsd_cm", "cannot be reached"),
    (BASE + AREA + "gsd_cm = 1.0\nside_overlap = 1.0\n", "objectives[0].side_overlap", "must lie in [0, 1)"),
    (BASE + '[[objectives]]\nkind = "point"\nname = "p"\nx = 50.0\ny = 50.0\nz = 5.0\ndistance = 10.0\n'
     "time_window = [30.0, 20.0]\n", "objectives[0].time_window", "must end after it starts"),
    (BASE + '[[objectives]]\nkind = "point"\nname = "p"\nx = 50.0\ny = 50.0\nz = 5.0\ndistance = 10.0\n'
     "time_window = [0.0, 3.0]\n", "objectives[0].time_window", "no UAV can be there"),
    (BASE + '[[objectives]]\nkind = "facade"\nname = "f"\nprism = "block Z"\ngsd_cm = 1.0\n', "objectives[0].prism",
     "no prism or building named"),
])
def test_bad_objectives_are_refused_naming_the_element(tmp_path, capsys, text, key, what):
    from staghunt.cli import main

    f = tmp_path / "objectives.toml"
    f.write_text(text)
    out = tmp_path / "out"
    code = main(["plan", "scenario2", "--objectives", str(f), "--out", str(out), "--no-plots"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.count("\n") == 0 and key in err and what in err, err
    assert not out.exists()


def test_a_lost_uav_naming_no_uav_is_refused(tmp_path, capsys, planned):
    from staghunt.cli import main

    _, path = planned
    ev = tmp_path / "events.toml"
    ev.write_text('[[events]]\ntime = 10.0\nkind = "uav_lost"\nuav = "UAV9"\n')
    code = main(["fly", str(path), "--events", str(ev), "--out", str(tmp_path / "out"), "--no-plots"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "events[0].uav" in err and "no UAV named 'UAV9'" in err, err
    assert not (tmp_path / "out").exists()


def test_task_events_need_an_inspection(tmp_path, capsys):
    from staghunt.cli import main

    ev = tmp_path / "events.toml"
    ev.write_text('[[events]]\ntime = 10.0\nkind = "uav_lost"\nuav = "UAV2"\n')
    code = main(["fly", "scenario2", "--events", str(ev), "--out", str(tmp_path / "out"), "--no-plots"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "needs an inspection" in err, err


def test_the_objectives_file_schema_validates_the_minimal_form():
    import jsonschema

    from staghunt.inputs import parse_toml
    from staghunt.scenario.schema import ObjectivesFile, json_schema

    schema = json_schema(ObjectivesFile)
    jsonschema.validate(parse_toml(SMALL.read_text(), str(SMALL)), schema)
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({"objectives": [{"kind": "area", "name": "a", "gsd_cm": 1.0, "front_overlap": 1.5,
                                             "polygon": [[0, 0], [1, 0], [1, 1]]}]}, schema)


def test_the_builtin_inspections_load():
    for name in ("site_inspection", "site_inspection3"):
        s = load_scenario(name)
        assert s.inspection is not None and len(s.inspection.objectives) == 5
        assert {o.kind for o in s.inspection.objectives} == {"area", "facade", "point"}
        assert all(p.camera.name == "DJI Mavic 3E Wide" for p in s.inspection.payloads)
    assert isinstance(load_scenario("site_inspection3").inspection, Inspection)
    assert Payload(M3E).gimbal_pitch_min_deg == -90.0


def test_objectives_from_geojson_in_wgs84(tmp_path):
    """An area and a point given as GeoJSON features (WGS84) land where their site coordinates
    would have put them."""
    from staghunt.world.georef import site_to_lonlat

    s = load_scenario("site_wedge")
    poly = [(300.0, 40.0), (420.0, 40.0), (420.0, 110.0), (300.0, 110.0)]
    lon, lat = site_to_lonlat(s.origin, np.array([p[0] for p in poly]), np.array([p[1] for p in poly]))
    plon, plat = site_to_lonlat(s.origin, np.array([350.0]), np.array([200.0]))
    feats = [{"type": "Feature", "properties": {"name": "dig"},
              "geometry": {"type": "Polygon", "coordinates": [[[a, b] for a, b in zip(lon, lat)] + [[lon[0], lat[0]]]]}},
             {"type": "Feature", "properties": {"name": "mast"},
              "geometry": {"type": "Point", "coordinates": [float(plon[0]), float(plat[0])]}}]
    (tmp_path / "features.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": feats}))
    (tmp_path / "obj.toml").write_text('camera = "DJI Mavic 3E Wide"\n[[objectives]]\nkind = "area"\nname = "a"\n'
                                       'geojson = "features.geojson"\nfeature = "dig"\ngsd_cm = 1.5\n'
                                       '[[objectives]]\nkind = "point"\nname = "p"\ngeojson = "features.geojson"\n'
                                       'feature = "mast"\nz = 10.0\ndistance = 15.0\n')
    insp = load_scenario("site_wedge", objectives=tmp_path / "obj.toml").inspection
    area, point = insp.objectives
    assert np.allclose(area.polygon, poly, atol=1e-3)
    assert (point.x, point.y) == pytest.approx((350.0, 200.0), abs=1e-3)


def test_decisions_add_an_objective_and_cut_what_an_obstacle_blocks(planned):
    """An objective added in flight is planned and allocated; an obstacle that appears on a
    survey line cuts it where it is no longer safe, and the cut is reported."""
    from staghunt.inspection.decision import WorkLog, reallocate
    from staghunt.task.objectives import PointObjective
    from staghunt.world import Cylinder

    plan, _ = planned
    sc, insp, tl = plan.scenario, plan.inspection, plan.timeline
    alive = np.ones(tl.n, dtype=bool)
    extra = PointObjective("new mast", 70.0, 30.0, 8.0, 10.0)
    insp2 = replace(insp, objectives=insp.objectives + (extra,))
    log = WorkLog(list(plan.tasks))
    t = 25.0
    new, dec = reallocate(replace(sc, inspection=insp2), insp2, log, tl, t, alive, {}, FAST, 1, "objective", (extra,))
    assert any(log.tasks[p.task].objective == "new mast" for pieces in new.pieces for p in pieces if p.task is not None)
    assert dec.switch >= t and new.end >= t
    # an obstacle on the survey: a cylinder in the middle of the excavation
    blocked = replace(sc, world=replace(sc.world, cylinders=sc.world.cylinders + (Cylinder(40.0, 32.0, 3.0, "skip"),)))
    log = WorkLog(list(plan.tasks))
    new, dec = reallocate(blocked, insp, log, tl, 1.0, alive, {}, FAST, 1, "skip appears", check_site=True)
    assert any("no longer safe after the site changed" in n for n in dec.notes)
    from staghunt.acquisition.clearance import Keepout

    keep = Keepout(blocked, 1.0)
    for pieces in new.pieces:
        for p in pieces:
            if p.kind == "capture" and p.t0 >= 1.0 and len(p.points) > 1:
                assert keep.segment_ok(p.points).all()
