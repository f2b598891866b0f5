"""The one safety judge: contact against breach for every kind (clearance, separation, ground,
ceiling), where and when, moving obstacles and their windows, the world as it changes, and the
four places that use it (the flight's verdict, the mission judge, the export's in-time check,
the planner's acceptance)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from staghunt import load_scenario
from staghunt.safety import BreachKind, Margins, Scene, Severity, judge
from staghunt.safety.measure import nearest_mates, static_nearest
from staghunt.world import Cylinder, Prism, box_polygon
from staghunt.world.dynamic import Dynamics, Event, MovingCylinder

SCENARIO = load_scenario("scenario2")


def _open(ceiling: float = np.inf):
    """Scenario 2's flat site without obstacles, with a ceiling."""
    w = replace(SCENARIO.world, cylinders=(), prisms=(), ceiling=ceiling)
    return replace(SCENARIO, world=w)


def _line(x0: float, x1: float, y: float, z: float, T: int = 11) -> np.ndarray:
    return np.column_stack([np.linspace(x0, x1, T), np.full(T, y), np.full(T, z)])


def test_margins_are_the_scenarios_and_grow_per_body():
    m = Margins.required(SCENARIO)
    assert (m.clearance, m.separation, m.ground, m.ceiling) == (1.0, 2.0, 1.0, 0.0)
    g = m.grown(0.25)
    assert (g.clearance, g.separation, g.ground, g.ceiling) == (1.25, 2.5, 1.25, 0.25)


def test_clearance_contact_and_breach_are_told_apart_with_where_and_when():
    sc = _open()
    post = Cylinder(50.0, 0.0, 2.0, "post")
    scene = Scene.fixed(sc.world, (post,), ())
    t = np.linspace(0.0, 10.0, 11)
    r = np.array([1.0])
    near = _line(40.0, 60.0, 3.5, 20.0)[None]  # passes 3.5 m from the axis: clearance 0.5 m
    v = judge(scene, r, t, near, Margins(clearance=1.0), ["A"])
    (b,) = v.breaches
    assert b.kind is BreachKind.CLEARANCE and b.severity is Severity.BREACH and b.other == "post"
    assert b.value == pytest.approx(0.5) and b.required == 1.0 and b.time == 5.0
    assert b.position == pytest.approx((50.0, 3.5, 20.0)) and b.since == 5.0
    assert not v.contact and not v.safe and v.min_clearance[0] == pytest.approx(0.5)
    assert "breach: A's clearance to post fell to 0.50 m (required 1.00 m) at t = 5.00 s" in v.problems(["A"])[0]
    through = _line(40.0, 60.0, 2.5, 20.0)[None]  # 2.5 m from the axis: the bodies overlap by 0.5 m
    v = judge(scene, r, t, through, Margins(clearance=1.0))
    assert v.contact and v.breaches[0].severity is Severity.CONTACT and v.breaches[0].value == pytest.approx(-0.5)
    far = _line(40.0, 60.0, 5.0, 20.0)[None]
    assert judge(scene, r, t, far, Margins(clearance=1.0)).safe


def test_separation_breach_at_the_limit_and_contact_when_bodies_touch():
    sc = _open()
    scene = Scene.fixed(sc.world)
    t = np.linspace(0.0, 1.0, 3)
    a = np.zeros((3, 3)) + [10.0, 10.0, 20.0]
    r = np.array([1.0, 0.5])
    for gap, severity in ((4.0, None), (3.5, Severity.BREACH), (1.4, Severity.CONTACT)):
        b = a + [gap, 0.0, 0.0]
        v = judge(scene, r, t, np.stack([a, b]), Margins(separation=2.0), ["A", "B"])
        if severity is None:  # 4 m > d_s + r_A + r_B = 3.5 m
            assert v.safe and v.min_separation == pytest.approx([4.0, 4.0])
            continue
        kinds = {(x.uav, x.kind, x.severity, x.other) for x in v.breaches}
        assert kinds == {(0, BreachKind.SEPARATION, severity, "B"), (1, BreachKind.SEPARATION, severity, "A")}
        assert v.breaches[0].required == pytest.approx(3.5)


def test_ground_and_ceiling_are_in_the_verdict():
    sc = _open(ceiling=30.0)
    scene = Scene.fixed(sc.world)
    t = np.array([0.0, 1.0, 2.0])
    r = np.array([1.0, 1.0, 1.0])
    pos = np.array([[[10.0, 10.0, 20.0], [10.0, 10.0, 1.5], [10.0, 10.0, 20.0]],    # body 0.5 m above ground
                    [[30.0, 10.0, 20.0], [30.0, 10.0, 0.5], [30.0, 10.0, 20.0]],    # body in the ground
                    [[50.0, 10.0, 20.0], [50.0, 10.0, 31.0], [50.0, 10.0, 29.9]]])  # above the ceiling
    v = judge(scene, r, t, pos, Margins.required(sc), ["A", "B", "C"])
    got = {(b.uav, b.kind, b.severity) for b in v.breaches}
    assert got == {(0, BreachKind.GROUND, Severity.BREACH), (1, BreachKind.GROUND, Severity.CONTACT),
                   (2, BreachKind.CEILING, Severity.BREACH)}
    assert v.contact and v.breaches[0].uav == 1  # contacts first
    c = next(b for b in v.breaches if b.kind is BreachKind.CEILING)
    assert c.value == pytest.approx(-1.0) and c.time == 1.0 and c.since == 1.0
    assert v.min_ground == pytest.approx([0.5, -0.5, 19.0]) and v.min_headroom[2] == pytest.approx(-1.0)


def test_prisms_name_the_nearest_obstacle():
    sc = _open()
    box = Prism(box_polygon(20.0, 30.0, 0.0, 10.0), 0.0, 25.0, "hall")
    cyl, which = static_nearest((Cylinder(80.0, 80.0, 1.0, "far"),), (box,), np.array([[[25.0, 11.5, 10.0]]]),
                                np.array([1.0]))
    assert cyl[0, 0] == pytest.approx(0.5) and which[0, 0] == 1
    v = judge(Scene.fixed(sc.world, (Cylinder(80.0, 80.0, 1.0, "far"),), (box,)), np.array([1.0]), np.array([0.0]),
              np.array([[[25.0, 11.5, 10.0]]]), Margins(clearance=1.0))
    assert v.breaches[0].other == "hall"
    assert judge(Scene.fixed(sc.world, (), (box,)), np.array([1.0]), np.array([0.0]),
                 np.array([[[25.0, 11.5, 27.0]]]), Margins(clearance=1.0)).safe  # above the hall


def test_moving_obstacles_at_the_same_instant_and_their_windows():
    sc = _open()
    truck = MovingCylinder("truck", 2.0, ((0.0, 20.0), (100.0, 20.0)), 10.0)
    scene = Scene.fixed(sc.world, (), (), Dynamics(moving=(truck,)))
    t = np.linspace(0.0, 10.0, 101)
    still = np.zeros((1, 101, 3)) + [50.0, 24.0, 20.0]  # the truck passes 4 m away at t = 5 s
    v = judge(scene, np.array([1.0]), t, still, Margins(clearance=1.0), motion_margin=0.5)
    assert v.min_clearance[0] == pytest.approx(1.0)
    (b,) = v.breaches
    assert b.other == "truck" and b.required == 1.5 and b.severity is Severity.BREACH
    (w,) = v.windows
    assert w[0] == "truck" and w[1] < 5.0 < w[2]
    assert judge(scene, np.array([1.0]), t, still, Margins(clearance=0.9)).safe


def test_the_true_world_changes_at_the_events():
    sc = _open()
    pop = Cylinder(50.0, 0.0, 2.0, "pop")
    dyn = Dynamics(events=(Event(4.0, "appear", "pop", pop), Event(8.0, "disappear", "pop")))
    scene = Scene.true(sc.world, dyn)
    assert [e.start for e in scene.epochs][1:] == [4.0, 8.0]
    t = np.linspace(0.0, 10.0, 11)
    on = np.zeros((1, 11, 3)) + [50.0, 2.5, 20.0]  # inside the pop-up while it is there
    v = judge(scene, np.array([1.0]), t, on, Margins(), keep=True)
    assert v.contact and v.breaches[0].since == 4.0 and v.breaches[0].other == "pop"
    assert np.isinf(v.clearance[0, :4]).all() and np.isinf(v.clearance[0, 8:]).all()


def test_nearest_mates_measures_by_the_bodies():
    pos = np.array([[[0.0, 0.0, 0.0]], [[5.0, 0.0, 0.0]], [[0.0, 5.5, 0.0]]])
    d, mate = nearest_mates(pos, np.array([0.5, 2.0, 0.5]))
    assert mate[:, 0].tolist() == [1, 0, 0]  # UAV 0's nearest surface: the big UAV 1 (gap 2.5 < 4.5)
    assert d[:, 0] == pytest.approx([5.0, 5.0, 5.5])


def test_a_uav_out_of_the_team_is_judged_against_nothing():
    """A UAV lost and landed (``active`` false from then on) sits on the ground next to a
    team-mate's path: neither its ground contact nor the team-mate passing it is a breach."""
    sc = _open()
    t = np.linspace(0.0, 2.0, 3)
    landed = np.array([[10.0, 10.0, 20.0], [10.0, 10.0, 0.2], [10.0, 10.0, 0.2]])
    passing = np.array([[30.0, 10.0, 20.0], [20.0, 10.0, 3.0], [10.5, 10.0, 3.0]])
    pos = np.stack([landed, passing])
    r = np.array([0.5, 0.5])
    v = judge(Scene.fixed(sc.world), r, t, pos, Margins.required(sc), ["A", "B"])
    assert v.contact and {b.kind for b in v.breaches} == {BreachKind.GROUND, BreachKind.SEPARATION}
    on = np.array([[True, False, False], [True, True, True]])
    v = judge(Scene.fixed(sc.world), r, t, pos, Margins.required(sc), ["A", "B"], active=on)
    assert v.safe and v.min_separation == pytest.approx([20.0, 20.0]) and v.min_ground[0] > 18.0  # at t = 0 only
