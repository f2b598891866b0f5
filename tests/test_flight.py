"""The closed loop's pieces: references, splices and stops, the changing world, the events file
and its bad inputs (the flights themselves: tests/test_flight_loop.py)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from staghunt import load_scenario
from staghunt.trajectory.quintic import Reference, stop_piece, timed_path
from staghunt.safety.measure import moving_clearance, point_polygon_distance, separations
from staghunt.flight.vehicles import DrydenGust
from staghunt.scenario.dynamics import load_events
from staghunt.task import VehicleLimits
from staghunt.world import Cylinder
from staghunt.world.dynamic import Dynamics, MovingCylinder, SlewingJib, Trigger

pytest.importorskip("rotorpy")

DATA = Path(__file__).parent / "data"
SMALL = str(DATA / "flight_small.toml")
LIMITS = VehicleLimits()


def run_cli(argv: list[str]) -> int:
    from staghunt import cli

    return cli.main(argv)


# ------------------------------------------------------------------------------------------------
# References: timing, splices, stops
# ------------------------------------------------------------------------------------------------


def _team_points() -> np.ndarray:
    a = np.array([[0, 0, 10], [10, 4, 10], [22, 0, 12], [40, 8, 10]], dtype=float)
    return np.stack([a, a + [0, 6, 0]])  # (2, 4, 3)


def test_timed_path_within_limits_near_polyline_and_at_rest_at_both_ends():
    piece = timed_path(_team_points(), 0.0, LIMITS)
    t = np.linspace(piece.t0, piece.t1, 4000)
    s = Reference((piece,)).state(t)
    assert np.linalg.norm(s[1], axis=-1).max() <= LIMITS.max_speed
    assert np.linalg.norm(s[2], axis=-1).max() <= LIMITS.max_acceleration * 1.01
    assert np.allclose(s[1][:, [0, -1]], 0.0, atol=1e-9)
    assert np.allclose(s[0][:, -1], _team_points()[:, -1])
    # every sample within 0.3 m of the planned polyline
    p = _team_points()[0]
    a, b = p[:-1], p[1:]
    q = s[0][0][:, None]
    u = np.clip(((q - a) * (b - a)).sum(-1) / ((b - a) ** 2).sum(-1), 0, 1)
    dev = np.linalg.norm(q - (a + u[..., None] * (b - a)), axis=-1).min(axis=1)
    assert dev.max() < 0.3
    # the team shares its waypoint times: every planned point is reached at the same knot
    at = Reference((piece,)).state(piece.knots)[0]
    assert np.allclose(at, piece.points, atol=1e-6)


def test_timed_path_times_a_run_of_millimetre_legs_as_one_point():
    """Waypoints slid together at the start (legs of 1.3 mm, then 39 m: a plan of the default
    method once made this) are not timed apart: within the limits, the same end points."""
    a = np.array([[15.0, 18.66, 20.0]] * 3 + [[15.0004, 18.6612, 20.0], [15.0008, 18.6624, 20.0],
                                              [15.0011, 18.6636, 20.0], [15.0012, 18.6637, 20.0],
                                              [26.7, 55.8, 20.0], [36.8, 65.1, 20.0], [85.0, 88.66, 20.0]])
    points = np.stack([a, a + [-5.0, -8.66, 0.0], a + [5.0, -8.66, 0.0]])  # (3, 10, 3)
    piece = timed_path(points, 0.0, LIMITS)
    s = Reference((piece,)).state(np.linspace(piece.t0, piece.t1, 4000))
    assert np.linalg.norm(s[1], axis=-1).max() <= LIMITS.max_speed
    assert np.linalg.norm(s[2], axis=-1).max() <= LIMITS.max_acceleration * 1.01
    assert np.allclose(s[0][:, 0], points[:, 0]) and np.allclose(s[0][:, -1], points[:, -1])
    assert len(piece.knots) < 40  # the millimetre legs left no knots of their own


def test_splice_is_continuous_in_position_velocity_and_acceleration():
    ref = Reference((timed_path(_team_points(), 0.0, LIMITS),))
    ts = 3.7
    s = ref.state(np.array([ts]))[:, :, 0]
    rest = _team_points()[:, 2:] + [0, -3, 1]
    new = ref.spliced(timed_path(np.concatenate([s[0][:, None], rest], axis=1), ts, LIMITS, s[1], s[2]))
    e = 1e-7
    before, after = new.state(np.array([ts - e, ts + e]))[:3].transpose(2, 0, 1, 3)
    assert np.abs(after - before).max() < 1e-4
    assert len(new.pieces) == 2 and new.pieces[1].t0 == ts


@pytest.mark.parametrize("brake", [False, True])
def test_stop_is_continuous_synchronised_and_comes_to_rest(brake):
    ref = Reference((timed_path(_team_points(), 0.0, LIMITS),))
    ts = 4.0
    stop = stop_piece(ref, ts, LIMITS, brake=brake)
    new = ref.spliced(stop)
    e = 1e-7
    before, after = new.state(np.array([ts - e, ts + e]))[:3].transpose(2, 0, 1, 3)
    assert np.abs(after - before).max() < 1e-4
    t = np.linspace(ts, ts + stop.duration + 2, 500)
    s = new.state(t)
    assert np.linalg.norm(s[2], axis=-1).max() <= LIMITS.max_acceleration * 1.001
    assert np.allclose(s[1][:, -1], 0.0)
    # synchronised: both UAVs are where the original plan had them at one common instant
    tau = stop.warp(t)[0]
    assert np.allclose(s[0], ref.state(tau)[0], atol=1e-9)


def test_braking_stop_is_shorter_than_the_smooth_one():
    """The emergency warp stops in v^2 / (2 a (1 - ramp)) against 1.5 v^2 / (2 a): hand-computed
    on the warp itself (tau(T) = T / 2 for both, T = v / (a (1 - ramp)) against 1.5 v / a)."""
    from staghunt.trajectory.quintic import BRAKE_RAMP, brake_warp

    u = np.linspace(0.0, 1.0, 2001)
    tau, d1, d2 = brake_warp(u)
    assert tau[-1] == pytest.approx(0.5, abs=1e-6) and d1[0] == 1.0 and d1[-1] == pytest.approx(0.0, abs=1e-9)
    assert d2[0] == 0.0 and d2[-1] == 0.0  # continuous acceleration at both ends
    assert -d2.min() == pytest.approx(1.0 / (1.0 - BRAKE_RAMP), rel=1e-3)
    line = np.array([[0, 0, 10], [100, 0, 10]], dtype=float)
    ref = Reference((timed_path(np.stack([line, line + [0, 6, 0]]), 0.0, LIMITS),))
    ts = 10.0  # cruising at 5 m/s on a straight line
    travel = {}
    for brake in (False, True):
        stop = stop_piece(ref, ts, LIMITS, brake=brake)
        p = ref.spliced(stop).state(np.array([ts, ts + stop.duration + 1.0]))[0]
        travel[brake] = np.linalg.norm(p[:, 1] - p[:, 0], axis=-1).max()
    v = float(np.linalg.norm(ref.state(np.array([ts]))[1][0, 0]))
    assert travel[False] == pytest.approx(1.5 * v**2 / (2 * 0.98 * LIMITS.max_acceleration), rel=0.02)
    assert travel[True] == pytest.approx(v**2 / (2 * 0.98 * LIMITS.max_acceleration * (1 - BRAKE_RAMP)), rel=0.02)


# ------------------------------------------------------------------------------------------------
# The changing world
# ------------------------------------------------------------------------------------------------


def test_moving_cylinder_and_jib_kinematics():
    m = MovingCylinder("truck", 2.0, ((0.0, 0.0), (10.0, 0.0), (10.0, 10.0)), 2.0, start_time=1.0,
                       repeat="reverse")
    xy = m.xy(np.array([0.0, 1.0, 6.0, 11.0, 16.0, 21.0]))
    assert np.allclose(xy, [[0, 0], [0, 0], [10, 0], [10, 10], [10, 0], [0, 0]])
    j = SlewingJib("jib", (0.0, 0.0), 10.0, 2.0, 5.0, 7.0, 0.0, 90.0, 10.0)
    assert np.allclose(np.degrees(j.angle(np.array([0.0, 4.5, 9.0, 20.0]))), [0, 45, 90, 90])
    poly = j.polygons(np.array([9.0]))[0]
    assert np.allclose(poly.min(axis=0), [-1, 0], atol=1e-9) and np.allclose(poly.max(axis=0), [1, 10])


def test_swept_stand_ins_cover_the_motion_over_the_window():
    m = MovingCylinder("truck", 3.0, ((0.0, 0.0), (40.0, 10.0)), 4.0)
    j = SlewingJib("jib", (50.0, 50.0), 20.0, 2.0, 0.0, 30.0, 0.0, 120.0, 8.0, counter=4.0)
    dyn = Dynamics(moving=(m,), jibs=(j,))
    cyl, prm = dyn.swept(2.0, 7.0)
    t = np.linspace(2.0, 7.0, 400)
    centres = m.xy(t)
    on_rim = centres[:, None] + 3.0 * np.stack([np.cos(np.linspace(0, 2 * np.pi, 16)),
                                                np.sin(np.linspace(0, 2 * np.pi, 16))], -1)
    pts = on_rim.reshape(-1, 2)
    inside = np.zeros(len(pts), bool)
    for c in cyl:
        inside |= np.hypot(pts[:, 0] - c.x, pts[:, 1] - c.y) <= c.radius + 1e-9
    assert inside.all()
    corners = j.polygons(t).reshape(-1, 2)
    hit = np.zeros(len(corners), bool)
    for p in prm:
        v = np.asarray(p.polygon)
        edges = np.concatenate([v, np.roll(v, -1, 0)], 1)
        hit |= point_polygon_distance(corners[:, 0], corners[:, 1], edges) <= 1e-9
    assert hit.all()


def test_moving_clearance_at_the_same_instant():
    m = MovingCylinder("truck", 2.0, ((0.0, 0.0), (100.0, 0.0)), 10.0)
    pos = np.array([[[50.0, 5.0, 10.0], [50.0, 5.0, 10.0]]])  # (1, 2, 3)
    c, which = moving_clearance(Dynamics(moving=(m,)), pos, np.array([0.0, 5.0]), np.array([1.0]))
    assert np.allclose(c, [[math.hypot(50, 5) - 3, 2.0]])
    assert which.tolist() == [[0, 0]]
    assert np.allclose(separations(np.array([[[0, 0, 0.0]], [[3, 4, 0.0]]])), [[5.0], [5.0]])


def test_dryden_gust_statistics_and_seed():
    def run(seed: int) -> np.ndarray:
        g = DrydenGust(np.array([5.0, 0.0, 0.0]), 12.0, 0.01, np.random.default_rng(seed))
        return np.array([g.step() for _ in range(60000)]), g.sigma

    w, sigma = run(3)
    assert np.array_equal(w, run(3)[0])
    # MIL-F-8785C low altitude: sigma_w = 0.1 W, sigma_u = sigma_w / (0.177 + 0.000823 h_ft)^0.4
    assert sigma[2] == pytest.approx(0.5)
    assert sigma[0] == pytest.approx(0.5 / (0.177 + 0.000823 * 12.0 * 3.281) ** 0.4)
    assert abs(w[:, 0].mean() - 5.0) < 0.3
    assert np.all(np.abs(w.std(axis=0) / sigma - 1.0) < 0.35)
    calm = DrydenGust(np.zeros(3), 12.0, 0.01, np.random.default_rng(0))
    assert np.array_equal(calm.step(), np.zeros(3))


# ------------------------------------------------------------------------------------------------
# Events files: the required form, richer kinds, and bad input
# ------------------------------------------------------------------------------------------------

POPUP = """
[[events]]
time = 6.0          # s after take-off
kind = "appear"
x = 52.0            # site frame, m
y = 20.0
radius = 3.0        # a cylinder through the whole height band
"""


def test_events_file_minimal_form_and_richer_kinds(tmp_path):
    f = tmp_path / "ev.toml"
    f.write_text(POPUP + """
[[events]]
time = 9.0
kind = "appear"
name = "skip"
polygon = [[60, 60], [66, 60], [66, 64], [60, 64]]
height = 12.0

[[events]]
time = 20.0
kind = "disappear"
name = "crane 1"

[[moving]]
name = "truck"
radius = 2.5
path = [[10, 90], [90, 90], [90, 10]]
speed = 3.0
repeat = "reverse"

[[jibs]]
name = "jib"
pivot = [40, 48]
length = 25
width = 2
base = 22
height = 25
angle_from = 180
angle_to = 270
rate = 6

[sensing]
range = 25.0
position_noise = 0.05

[link]
delay = 0.3
loss = 0.05
""", encoding="utf-8")
    dyn = load_events(f, load_scenario("scenario2"))
    assert [e.name for e in dyn.events] == ["pop-up 1", "skip", "crane 1"]
    assert isinstance(dyn.events[0].shape, Cylinder) and dyn.events[0].shape.radius == 3.0
    assert dyn.events[1].shape.top == 12.0
    assert dyn.moving[0].repeat == "reverse" and dyn.jibs[0].top == 25.0
    assert dyn.sensing.range == 25.0 and dyn.sensing.position_noise == 0.05
    assert (dyn.link.delay, dyn.link.jitter, dyn.link.loss) == (0.3, 0.03, 0.05)  # jitter: the default


def test_events_schema_validates_the_minimal_form():
    jsonschema = pytest.importorskip("jsonschema")
    import tomllib

    from staghunt.scenario.schema import EventsFile, json_schema

    schema = json_schema(EventsFile)
    jsonschema.validate(tomllib.loads(POPUP), schema)
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({"events": [{"time": -1, "kind": "appear", "x": 1, "y": 1, "radius": 1}]}, schema)


BAD_EVENTS = [
    ("[[events]]\ntime = 1.0\nkind = 'appear'\nx = 20.0\ny = 20.0\nradius = 2.0\ncolour = 'red'\n", "colour"),
    ("[[events]]\ntime = -1.0\nkind = 'appear'\nx = 20.0\ny = 20.0\nradius = 2.0\n", "time"),
    ("[[events]]\ntime = nan\nkind = 'appear'\nx = 20.0\ny = 20.0\nradius = 2.0\n", "time"),
    ("[[events]]\ntime = 1.0\nkind = 'appear'\nx = 20.0\ny = 20.0\nradius = -2.0\n", "radius"),
    ("[[events]]\ntime = 1.0\nkind = 'explode'\nx = 20.0\ny = 20.0\nradius = 2.0\n", "kind"),
    ("[[events]]\ntime = 1.0\nkind = 'appear'\nx = 20.0\nradius = 2.0\n", "events[0].y"),
    ("[[events]]\ntime = 1.0\nkind = 'disappear'\nname = 'nothing'\n", "nothing"),
    ("[[moving]]\nname = 't'\nradius = 2.0\npath = [[10, 10], [120, 10]]\nspeed = 2.0\n", "outside the site"),
    ("[[jibs]]\nname = 'j'\npivot = [50, 5]\nlength = 30\nwidth = 2\nbase = 2\nheight = 20\n"
     "angle_from = 0\nangle_to = 90\nrate = 5\n", "leaves the site"),
    ("[[events]]\ntime = 0.0\nkind = 'appear'\nx = 5.0\ny = 15.0\nradius = 2.0\n", "on top of UAV1"),
    ("[[events]]\ntime = 9.0\nkind = 'appear'\nx = 20.0\ny = 20.0\nradius = 2.0\n"
     "trigger = { uav = 'UAV9', within = 5.0 }\n", "no UAV named 'UAV9'"),
    ("[[events]]\ntime = 9.0\nkind = 'appear'\nx = 20.0\ny = 20.0\nradius = 2.0\n"
     "trigger = { uav = 'UAV1', within = -5.0 }\n", "trigger.within"),
    ("[[events]]\ntime = 9.0\nkind = 'disappear'\nname = 'crane 1'\ntrigger = { uav = 'UAV1', within = 5.0 }\n",
     "trigger"),
    ("events = 3\n", "events"),
    ("[link]\ndelay = -0.1\n", "link.delay"),
    ("[link]\nloss = 1.0\n", "link.loss"),
]


@pytest.mark.parametrize("text,needle", BAD_EVENTS)
def test_bad_events_exit_2_with_one_line_before_any_simulation(tmp_path, capsys, text, needle):
    f = tmp_path / "ev.toml"
    f.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    code = run_cli(["fly", SMALL, "--events", str(f), "--out", str(out), "--no-plots", "--latency", "0.3"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and needle in err and "Traceback" not in err
    assert not out.exists()


def test_documented_and_example_events_files_load(tmp_path):
    import re

    root = Path(__file__).resolve().parent.parent
    text = (root / "docs" / "scenario-format.md").read_text(encoding="utf-8")
    section = text.split("## A site that changes", 1)[1]
    block = re.search(r"```toml\n(.*?)```", section, re.S).group(1)
    f = tmp_path / "doc.toml"
    f.write_text(block, encoding="utf-8")
    scenario = load_scenario("scenario2")
    doc = load_events(f, scenario)
    assert len(doc.events) == 4 and len(doc.moving) == 1 and len(doc.jibs) == 1
    assert [e.trigger for e in doc.events if e.trigger is not None] == [Trigger("UAV2", 8.0)]
    assert (doc.link.delay, doc.link.jitter, doc.link.loss) == (0.1, 0.03, 0.01)
    example = load_events(root / "examples" / "events_popup.toml", scenario)
    assert example.events[0].time == 6.0 and example.jibs[0].name == "crane 1 jib"


def test_schema_events_command(capsys):
    assert run_cli(["schema", "--events"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema["title"] == "staghunt events"
    assert set(schema["properties"]) == {"events", "moving", "jibs", "sensing", "link"}




def test_the_smooth_curve_rounds_corners_the_dense_one_turns_at():
    """A re-plan times its paths twice (:func:`timings`): through sub-legs of at most 3 m, which
    keep within 0.3 m of the polyline and slow down at every corner, and through the planned
    points alone (``SMOOTH_SPACING``), which swings wide of the corners. On a zigzag of 40-degree
    turns every 8 m, flown from cruise speed, the smooth curve is sooner; both pass through the
    planned points together, start at the switch state and stay within the limits."""
    from staghunt.trajectory.quintic import DENSE_SPACING, SMOOTH_SPACING, timings

    x = np.arange(0.0, 81.0, 8.0)
    y = np.where(np.arange(x.size) % 2 == 1, 8.0 * math.tan(math.radians(20.0)), 0.0)
    a = np.column_stack([x, y, np.full(x.size, 12.0)])
    pts = np.stack([a, a + [0.0, 8.0, 0.0]])  # (2, 11, 3)
    v0 = np.tile([4.0, 0.0, 0.0], (2, 1))
    pieces = timings(pts, 3.0, LIMITS, v0, np.zeros((2, 3)), max_stretch=2.0,
                     spacings=(DENSE_SPACING, SMOOTH_SPACING))
    assert {p.spacing for p in pieces} == {DENSE_SPACING, SMOOTH_SPACING}
    dense = min((p for p in pieces if p.spacing == DENSE_SPACING), key=lambda p: p.t1)
    smooth = min((p for p in pieces if p.spacing == SMOOTH_SPACING), key=lambda p: p.t1)
    assert pieces[0] is smooth and smooth.t1 < 0.9 * dense.t1
    for p in (dense, smooth):
        t = np.linspace(p.t0, p.t1, 4000)
        s = p.state(t)
        assert np.linalg.norm(s[1], axis=-1).max() <= LIMITS.max_speed
        assert np.linalg.norm(s[2], axis=-1).max() <= LIMITS.max_acceleration * 1.001
        np.testing.assert_allclose(s[1][:, 0], v0, atol=1e-6)
        np.testing.assert_allclose(s[0][:, -1], pts[:, -1], atol=1e-6)
    # the smooth curve goes through every planned point at one time for the team
    at = smooth.state(smooth.knots)[0]
    np.testing.assert_allclose(at, pts, atol=1e-6)
