"""The flight room's parts on their own, without simulating vehicles: the radio link, what a
UAV decides on board (which plan it takes, when it holds, its reflex), and when the ground
station sends a re-plan."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from staghunt import load_scenario
from staghunt.engine import get_engine
from staghunt.flight import FlyConfig
from staghunt.flight.known import TAIL_GAP_M, route_beyond
from staghunt.flight.link import GROUND, Ack, Beacon, Heartbeat, HoldReason, Outage, PlanMessage, RadioLink, Telemetry
from staghunt.flight.onboard import START_TOLERANCE, Onboard, hold_piece
from staghunt.flight.records import Cause, ReplanRecord, ReplanStatus
from staghunt.flight.replan import Replanner
from staghunt.flight.station import PLAN_COPIES, GroundStation
from staghunt.task import VehicleLimits
from staghunt.trajectory.quintic import Reference, timed_path
from staghunt.trajectory.team import RowTeam, Still, Track
from staghunt.world import Cylinder
from staghunt.world.dynamic import Dynamics, Link

LIMITS = VehicleLimits()


def test_the_link_delays_jitters_and_loses_as_configured_and_from_its_seed():
    def run(seed: int):
        radio = RadioLink(Link(0.1, 0.03, 0.05), np.random.default_rng(seed), (Outage(1, 5.0, 6.0),))
        for k in range(20000):
            radio.send(k * 0.001, GROUND, 0, k)
        for k in range(100):
            radio.send(5.0 + 0.01 * k, GROUND, 1, -k)  # in UAV 1's radio shadow
        return radio, radio.deliver(1e9)

    radio, got = run(7)
    assert radio.sent == 20100 and all(dst == 0 for dst, _ in got)  # nothing through the shadow
    sent_at = {m: m * 0.001 for _, m in got}
    assert 0.04 < 1 - len(got) / 20000 < 0.06  # 5 % lost
    # delays: 0.1 + 0.03 z, z clipped to [-3, 3]; delivered in arrival order, so out of send order
    order = [m for _, m in got]
    assert order != sorted(order)
    again = run(7)[1]
    assert [m for _, m in again] == order  # the same seed, the same messages lost and late
    radio = RadioLink(Link(0.1, 0.03, 0.0), np.random.default_rng(1))
    for k in range(5000):
        radio.send(0.0, GROUND, 0, k)
    assert radio.deliver(0.1 - 3 * 0.03 - 1e-6) == []
    assert len(radio.deliver(0.1 + 3 * 0.03 + 1e-6)) == 5000 and radio.worst_delay == pytest.approx(0.19)
    del sent_at


def _plan(y: float = 0.0, t0: float = 0.0) -> Reference:
    """Two UAVs flying east from x = 0 along y and y + 10."""
    line = np.array([[0.0, y, 10.0], [30.0, y, 10.0], [60.0, y, 10.0]])
    return Reference((timed_path(np.stack([line, line + [0.0, 10.0, 0.0]]), t0, LIMITS),))


def _onboard(ref: Reference, n: int = 0) -> Onboard:
    return Onboard(n, Track(((0.0, ref, n),)), LIMITS, 1.0, 0.05, 2.0, 1.0, np.array([0.5, 0.5]))


def _spliced(ref: Reference, t_s: float, dy: float) -> Reference:
    """A plan that starts at ``t_s`` where ``ref`` is (moved ``dy`` aside) and bends away."""
    s = ref.state(np.array([t_s]))[:, :, 0]
    here = s[0] + [0.0, dy, 0.0]
    pts = np.stack([here, here + [10.0, 5.0, 0.0], here + [30.0, 5.0, 0.0]], axis=1)
    return Reference((timed_path(pts, t_s, LIMITS, s[1], s[2]),))


def test_a_plan_in_time_from_where_the_uav_is_is_taken_at_its_start():
    ref = _plan()
    uav = _onboard(ref)
    new = _spliced(ref, 3.0, 0.0)
    acks: list[Ack] = []
    pos = ref.state(np.array([2.5]))[0][0, 0]
    uav.receive(2.5, PlanMessage(1, new, 3.0, (0, 1)), pos, acks)
    assert acks == [Ack(0, 1, True)] and uav.pending is not None
    uav.step(2.99, 0.01)
    assert uav.version == 0  # the old plan stays valid until the start
    uav.step(3.0, 0.01)
    assert uav.version == 1 and uav.pending is None
    t = np.array([4.0])
    assert np.allclose(uav.track.state(t)[0][0, 0], new.state(t)[0][0, 0])
    uav.receive(3.1, PlanMessage(1, new, 3.0, (0, 1)), pos, acks)  # a copy: acknowledged again
    assert acks[-1] == Ack(0, 1, True)



def test_a_plan_made_from_a_pending_one_is_taken_and_both_are_flown_in_turn():
    """The station makes plan 2 from plan 1 (sent, not started yet: it believes the UAV will fly
    it): plan 2 starts 2 s after plan 1, 2.9 m aside of the old path. The UAV takes it (it
    once checked plan 2's start against its track without plan 1, refused it and, with every
    re-plan made so, never took one), flies plan 1 from its start and plan 2 from its own."""
    ref = _plan()
    uav = _onboard(ref)
    one = _spliced(ref, 3.0, 0.0)  # bends 5 m aside
    two = _spliced(one, 5.0, 0.0)
    assert np.linalg.norm(two.state(np.array([5.0]))[0][0, 0] - ref.state(np.array([5.0]))[0][0, 0]) > START_TOLERANCE
    acks: list[Ack] = []
    pos = ref.state(np.array([2.5]))[0][0, 0]
    uav.receive(2.5, PlanMessage(1, one, 3.0, (0, 1)), pos, acks)
    uav.receive(2.6, PlanMessage(2, two, 5.0, (0, 1)), ref.state(np.array([2.6]))[0][0, 0], acks)
    assert acks == [Ack(0, 1, True), Ack(0, 2, True)] and uav.pending.version == 2
    for t, version in ((2.99, 0), (3.0, 1), (4.0, 1), (4.99, 1), (5.0, 2)):
        uav.receive(t, Heartbeat(2, 5.0), pos, acks)  # the station names plan 2
        uav.step(t, 0.01)
        assert uav.version == version and uav.hold is None
    for t, plan in ((2.0, ref), (4.5, one), (6.0, two)):
        assert np.allclose(uav.track.state(np.array([t]))[0][0, 0], plan.state(np.array([t]))[0][0, 0])
    late = _onboard(ref)  # a UAV that missed plan 1 still refuses plan 2: it would not start from there
    late.receive(2.6, PlanMessage(2, two, 5.0, (0, 1)), ref.state(np.array([2.6]))[0][0, 0], acks)
    assert acks[-1] == Ack(0, 2, False, "start")


def test_a_late_plan_or_one_from_elsewhere_is_refused_and_the_uav_holds_on_its_old_one():
    """A plan that opens with a path and arrives after its start, or whose start lies away from
    the UAV, is refused; the UAV does not switch, and since its team-mates may fly the plan it
    refused, it holds on its old path (the station re-plans on the refusal). A stop is taken
    late."""
    from staghunt.trajectory.quintic import stop_piece

    ref = _plan()
    for message, t, why in ((PlanMessage(1, _spliced(ref, 3.0, 0.0), 3.0, (0, 1)), 3.05, "late"),
                            (PlanMessage(1, _spliced(ref, 3.0, START_TOLERANCE + 0.3), 3.0, (0, 1)), 2.5, "start")):
        uav = _onboard(ref)
        acks: list[Ack] = []
        uav.receive(t, message, ref.state(np.array([t]))[0][0, 0], acks)
        assert acks == [Ack(0, 1, False, why)] and uav.pending is None
        uav.step(3.0, 0.01)
        assert uav.version == 0 and uav.track.segments[-1][1] is ref and uav.hold is None
        uav.step(3.02, 0.01)
        assert uav.version == 0 and uav.hold == (3.02, HoldReason.MISSED)
        assert uav.track.segments[-1][1].pieces[0].base.segments[0][1] is ref  # a stop of its old path
    uav = _onboard(ref)
    stop = Reference((stop_piece(ref, 4.0, LIMITS),))
    acks = []
    uav.receive(4.1, PlanMessage(2, stop, 4.0, (0, 1)), ref.state(np.array([4.1]))[0][0, 0], acks)
    assert acks == [Ack(0, 2, True)]


def test_a_missed_plan_or_silence_makes_the_uav_hold_and_the_station_rebuilds_the_same_hold():
    ref = _plan()
    uav = _onboard(ref)
    pos = ref.state(np.array([2.0]))[0][0, 0]
    uav.receive(2.0, Heartbeat(3, 2.5), pos, [])  # plan 3 starts at 2.5; it never came
    uav.step(2.5, 0.01)
    assert uav.hold is None  # it may still come
    uav.step(2.52, 0.01)
    assert uav.hold == (2.52, HoldReason.MISSED) and uav.holds == 1
    rest = uav.track.state(np.array([10.0]))
    assert np.allclose(rest[1], 0.0)  # at rest where it braked, on its own path
    assert abs(rest[0][0, 0, 1]) < 1e-9 and rest[0][0, 0, 0] < ref.state(np.array([5.0]))[0][0, 0, 0]
    # the station rebuilds the same hold from the telemetry (since, reason) on what it believes
    again = Track(((0.0, ref, 0),))
    again = again.then(2.52, hold_piece(again, 2.52, LIMITS, HoldReason.MISSED), 0)
    t = np.linspace(2.0, 6.0, 41)
    assert np.array_equal(again.state(t), uav.track.state(t))
    quiet = _onboard(ref)
    quiet.step(1.0, 0.01)
    assert quiet.hold is None
    quiet.step(1.01, 0.01)  # heard nothing for plan_timeout (1 s)
    assert quiet.hold == (1.01, HoldReason.TIMEOUT)
    braked = hold_piece(Track(((0.0, ref, 0),)), 5.0, LIMITS, HoldReason.MISSED).pieces[0]
    gentle = hold_piece(Track(((0.0, ref, 0),)), 5.0, LIMITS, HoldReason.TIMEOUT).pieces[0]
    assert braked.brake and not gentle.brake and braked.duration < gentle.duration / 2


def test_holds_and_stops_of_a_team_at_rest_do_not_nest_however_many():
    """A UAV that holds again and again while it hovers, and a team whose re-plans keep opening
    with a stop of the team as the station believes it: every stop used to wrap the whole track
    once more, and after some hundreds of them evaluating the track hit Python's recursion
    limit (a hovering team retrying for minutes)."""
    from staghunt.trajectory.quintic import stop_piece

    ref = _plan()
    track = Track(((0.0, ref, 0),))
    track = track.then(2.0, hold_piece(track, 2.0, LIMITS, HoldReason.MISSED), 0)
    first = track.segments[-1][1]
    for k in range(2000):  # holds while braking and while at rest keep the first hold's stop
        t = 2.0 + 0.01 * k
        track = track.then(t, hold_piece(track, t, LIMITS, HoldReason.REFLEX), 0)
        assert track.segments[-1][1] is first
    rest = first.state(np.array([30.0]))[0][:, 0]
    team = RowTeam((track,), (0,))
    for k in range(2000):  # the station's stops of the team, one per re-plan, at rest
        t = 30.0 + 0.1 * k
        track = track.then(t, Reference((stop_piece(team, t, LIMITS),)), 0)
        team = RowTeam((track,), (0,))
    s = team.state(np.array([30.0, 100.0, 229.95, 500.0]))
    assert np.allclose(s[0][:, :], rest[:, None], atol=1e-12) and np.all(s[1:] == 0.0)


def test_the_reflex_brakes_before_a_seen_obstacle_unless_the_coming_plan_avoids_it():
    ref = _plan()
    uav = _onboard(ref)
    at = ref.state(np.array([4.0]))[0][0, 0]
    v = float(np.linalg.norm(ref.state(np.array([3.0]))[1][0, 0]))
    uav.seen = {"box": Cylinder(float(at[0]), 0.0, 1.5, "box")}
    uav.reflex(0.0)
    assert uav.brake_at is None  # far ahead: the planner has time
    grid = np.arange(0.0, 4.0, 0.001)
    inside = np.hypot(ref.state(grid)[0][0, :, 0] - at[0], ref.state(grid)[0][0, :, 1]) - 1.5 - 0.5 < 1.0 - 0.1
    t_in = grid[np.argmax(inside)]  # the reference comes within the required clearance (less 0.1 m)
    window = 0.05 + v / (2 * 9.0 * 0.9) + 0.3  # latency, braking, margin
    t = t_in - window - 0.1
    uav.reflex(t)
    assert uav.brake_at is None
    uav.reflex(t + 0.15)
    assert uav.brake_at == pytest.approx(t + 0.2)  # one reflex latency later
    uav.heard = t  # the station is heard
    uav.step(t + 0.2, 0.01)
    assert uav.hold == (pytest.approx(t + 0.2), HoldReason.REFLEX)
    stop = uav.track.state(np.array([t + 5.0]))[0][0, 0]
    assert np.hypot(stop[0] - at[0], stop[1]) - 1.5 - 0.5 > 0.0  # it stops short of the box
    calm = _onboard(ref)  # a plan that swerves round is pending: no reflex
    calm.seen = dict(uav.seen)
    acks: list[Ack] = []
    calm.receive(t, PlanMessage(1, _spliced(ref, t + 0.1, 0.0), t + 0.1, (0, 1)), ref.state(np.array([t]))[0][0, 0], acks)
    assert acks[-1].ok
    calm.reflex(t + 0.05)
    assert calm.brake_at is None


def test_the_reflex_keeps_off_a_holding_team_mate():
    ref = _plan()
    uav = _onboard(ref)
    ahead = ref.state(np.array([3.0]))[0][0, 0]
    uav.receive(2.0, Beacon(1, 2.0, ahead + [0.0, 1.0, 0.0], True), ref.state(np.array([2.0]))[0][0, 0], [])
    uav.reflex(2.0)
    assert uav.brake_at is not None  # its path runs into the team-mate that holds
    other = _onboard(ref)
    other.receive(2.0, Beacon(1, 2.0, ahead + [0.0, 1.0, 0.0], False), ref.state(np.array([2.0]))[0][0, 0], [])
    other.reflex(2.0)
    assert other.brake_at is None  # a team-mate flying its plan reserves nothing


def _station_on_two_straight_paths():
    """A ground station (fixed latency 0.3 s, no receding horizon) over two UAVs flying straight
    across flight_small: the team's reference and the station."""
    sc = load_scenario(str(Path(__file__).parent / "data" / "flight_small.toml"))
    pts = np.array([[[5, 15, 12], [30, 15, 12], [55, 15, 12]], [[5, 23, 12], [30, 23, 12], [55, 23, 12]]], float)
    ref = Reference((timed_path(pts, 0.0, sc.vehicle),))
    dyn = Dynamics()
    config = FlyConfig(latency=0.3, replan_rate=0)
    planner = Replanner(replace(sc, dynamics=dyn), dyn, config, get_engine("numba", threads=1), np.random.default_rng(0))
    return ref, GroundStation(planner, dyn, config, ref, 0.01, Link().worst_delay)


def test_a_plan_due_at_a_tick_that_starts_another_replan_is_still_sent():
    """Two pop-ups reported 0.3 s apart, each re-planned with a fixed latency of 0.3 s: the first
    plan is due at the very tick whose telemetry triggers the second re-plan. It leaves the
    station at that tick (the second job once replaced it, and its plan was never sent: the team
    flew on towards what it avoided)."""
    ref, station = _station_on_two_straight_paths()
    pops = [Cylinder(30.0, 15.0, 2.0, "popA"), Cylinder(42.0, 23.0, 2.0, "popB")]

    def telemetry(t: float, n: int, seen: tuple[Cylinder, ...]) -> Telemetry:
        p, v = ref.state(np.array([t]))[:2, n, 0]
        return Telemetry(n, t, p, v, 0, None, tuple((s.name, s) for s in seen))

    assert [m for _, m in station.tick(2.0, [telemetry(1.95, 0, pops[:1])]) if isinstance(m, PlanMessage)] == []
    first = station.records[-1]
    assert first.version == 1 and first.effect_time == pytest.approx(2.3) and first.status.solved
    out = station.tick(2.3, [telemetry(2.25, 1, pops[1:])])  # the second pop-up: a re-plan now
    assert station.records[-1].time == pytest.approx(2.3) and len(station.records) == 2
    sent = [(n, m.version) for n, m in out if isinstance(m, PlanMessage)]
    assert sorted(sent) == sorted([(0, 1), (1, 1)] * PLAN_COPIES)  # plan 1 leaves now, twice to each UAV
    assert station.released[0] == 1 and 1 in station.plans
    assert [m.version for _, m in out if isinstance(m, Heartbeat)] == [1, 1]  # the heartbeat names it
    assert station.release(2.3) == []  # the second job is not due yet
    later = [m.version for _, m in station.release(2.6) if isinstance(m, PlanMessage)]
    assert later == [2] * (2 * PLAN_COPIES) and station.released[0] == 2


def test_the_station_does_not_believe_a_holding_uav_flies_a_plan_made_before_its_hold():
    """The newest plan sent counts in the station's belief from its start, except for a UAV whose
    hold it did not know of: that UAV refuses it, and a plan made from it would start where the
    UAV is not (scenario2 episode 8: UAV1 refused every later plan, 'start', until the flight
    broke off)."""
    ref, station = _station_on_two_straight_paths()
    station._observe(2.1, [Telemetry(0, 2.0, *ref.state(np.array([2.0]))[:2, 0, 0], 0, (2.0, HoldReason.REFLEX), ())])
    assert station.held == [2.0, None]
    swerve = _spliced(ref, 3.0, 0.0)
    station.plans[1] = PlanMessage(1, swerve, 3.0, (0, 1), (None, None))  # made before the hold was known
    station.released = (1, 3.0)
    at = np.array([5.0])
    believed = station.team.state(at)[0][:, 0]
    assert np.allclose(believed[1], swerve.state(at)[0][1, 0])  # UAV2 will fly it
    assert np.allclose(believed[0], station.tracks[0].state(at)[0][0, 0])  # UAV1 holds
    assert np.linalg.norm(believed[0] - swerve.state(at)[0][0, 0]) > 1.0
    station.plans[2] = PlanMessage(2, swerve, 3.0, (0, 1), (2.0, None))  # one made knowing it
    station.released = (2, 3.0)
    assert np.allclose(station.team.state(at)[0][:, 0], swerve.state(at)[0][:, 0])


def test_the_station_keeps_a_plan_a_uav_acknowledged_while_the_uav_still_flies_the_one_before():
    """A UAV flies its old plan until the one it acknowledged starts, and its telemetry names the
    plan it flies. That alone does not take the acknowledged plan out of the station's belief:
    the UAV drops a pending plan only when it holds (site_wedge episode 17: with UAV7's newer
    plan refused, every plan made from the belief without its pending one started where UAV7
    would not be, and UAV7 refused 15 in a row, 'start')."""
    at = np.array([3.5])
    for hold in (None, (2.3, HoldReason.REFLEX)):
        ref, station = _station_on_two_straight_paths()
        swerve, other = _spliced(ref, 3.0, 0.0), _spliced(ref, 4.0, 2.0)
        station.plans[1] = PlanMessage(1, swerve, 3.0, (0, 1), (None, None))
        station.released = (1, 3.0)
        station._observe(2.1, [Ack(0, 1, True), Ack(1, 1, True)])
        station.plans[2] = PlanMessage(2, other, 4.0, (0, 1), (None, None))
        station.released = (2, 4.0)
        station._observe(2.2, [Ack(0, 2, False, "start")])
        p, v = ref.state(np.array([2.3]))[:2, 0, 0]
        station._observe(2.4, [Telemetry(0, 2.3, p, v, 0, hold, ())])  # still on plan 0
        believed = station.team.state(at)[0][0, 0]
        if hold is None:  # plan 1 is pending on board
            assert station.taken[0] == 1 and np.allclose(believed, swerve.state(at)[0][0, 0])
        else:  # the hold dropped it: the UAV stops on plan 0
            stop = hold_piece(Track(((0.0, ref, 0),)), 2.3, station.scenario.vehicle, HoldReason.REFLEX)
            assert station.taken[0] == 0 and np.allclose(believed, stop.state(at)[0][0, 0])


def test_a_moving_team_with_no_plan_yet_flies_on_and_solves_again_while_a_later_stop_passes():
    """A re-plan of a moving team that finds no plan from its state does not stop it while a
    stop decided at the next re-plan still passes: the team flies on (no stop sent), the station
    solves again at its next tick, warm-started, at most ``deferrals`` times in a row; then the
    stop (or the plan from rest) as before."""
    from staghunt.flight.records import Solved

    ref, station = _station_on_two_straight_paths()
    station.config = replace(station.config, deferrals=2)
    asked: list[float] = []
    answers = [ReplanStatus.DEFERRED, ReplanStatus.DEFERRED, ReplanStatus.STOP]

    def solve(start, soon, scale, windows, deadline, horizon, fallback, defer):
        asked.append(defer)
        return Solved(None, answers[len(asked) - 1])

    station.replanner.solve = solve
    p, v = ref.state(np.array([1.95]))[:2, 0, 0]
    seen = (("pop", Cylinder(40.0, 15.0, 2.0, "pop")),)
    tick = 1.0 / station.dyn.sensing.rate
    assert station.tick(2.0, [Telemetry(0, 1.95, p, v, 0, None, seen)]) == [(n, Heartbeat(0, 0.0)) for n in range(2)]
    assert station.records[-1].status is ReplanStatus.DEFERRED and station.stops == 0 and station.stopped_at < 0
    assert asked == [pytest.approx(0.3 + 2 * tick)]  # the next re-plan's start, at the latest
    station.tick(2.2, [])
    assert len(asked) == 1  # busy for the fixed latency
    station.tick(2.3, [])
    assert len(asked) == 2 and station.records[-1].trigger.endswith("(deferred)")
    assert station.records[-1].cause is station.records[0].cause
    station.tick(2.6, [])
    assert asked[2] == 0.0  # no third deferral: the stop now
    assert station.records[-1].status is ReplanStatus.STOP and station.stops == 1


def test_a_stop_can_wait_while_the_team_can_still_brake_clear_of_what_it_knows():
    """:meth:`Fallback.stop_later`: two UAVs at 5 m/s towards a pop-up on UAV1's line; a stop
    0.3 s from now passes while the UAV is far, and not once the pop-up is within its braking
    distance (v^2 / 2a = 4.2 m) plus the required clearance."""
    ref, station = _station_on_two_straight_paths()
    planner = station.replanner
    planner.known.sensed["pop"] = Cylinder(45.0, 15.0, 2.0, "pop")
    fb, lim = planner.fallback, planner.scenario.vehicle
    r = planner.scenario.team[0].radius
    margin = planner.acceptance.margins.clearance

    def gap(t: float) -> float:  # UAV1's distance to the pop-up's surface, less body and margin
        return 45.0 - 2.0 - r - margin - float(ref.state(np.array([t]))[0][0, 0, 0])

    v = float(np.linalg.norm(ref.state(np.array([5.0]))[1][0, 0]))
    brake = v ** 2 / (2 * lim.max_acceleration)
    early = next(t for t in np.arange(0.0, 20.0, 0.1) if gap(t) < 4 * brake + v)
    late = next(t for t in np.arange(0.0, 20.0, 0.1) if gap(t + 0.3) < brake)
    assert early < late
    assert fb.stop_later(ref, early, early + 0.3)
    assert not fb.stop_later(ref, late, late + 0.3)


def test_a_replan_from_the_hover_goes_on_from_the_last_ones_best_try():
    """A hovering team's re-plans are short (the flight's deadline each): one that finds no plan
    leaves its game's best try as the next one's warm start, so sixteen slices search on from
    each other rather than sixteen times from the stop."""
    from types import SimpleNamespace

    from staghunt.flight.known import Start
    from staghunt.flight.replan import _Attempt
    from staghunt.trajectory.quintic import stop_piece

    ref, station = _station_on_two_straight_paths()
    planner = station.replanner
    stopped = Reference((stop_piece(ref, 2.0, planner.scenario.vehicle),))
    t_s = stopped.arrival + 1.0
    s = stopped.state(np.array([t_s]))[:, :, 0]
    start = Start(t_s, stopped, s[0], s[1], s[2])
    warm_starts, tries = [], []

    def attempts(start_, windows, warm, *args, **kwargs):
        warm_starts.append(warm.copy())
        best = warm + 0.5 * (len(warm_starts))  # the game's best try: somewhere new each time
        tries.append(best)
        return _Attempt(None, SimpleNamespace(plan=best), None, ["no feasible plan"], 1, 10, 0.0, [])

    planner._attempts = attempts
    for _ in range(3):
        planner.solve(start, lambda: t_s, 1, [], None, 0.0, fallback=True)
    assert len(warm_starts) == 3
    assert np.array_equal(warm_starts[1], tries[0]) and np.array_equal(warm_starts[2], tries[1])
    assert not np.array_equal(warm_starts[0], tries[0])


def test_the_plan_from_rest_leaves_the_fallbacks_running_time_free_at_the_deadlines_end():
    """A re-plan of a moving team that finds no plan, from where it flies or from rest, falls back
    (a stop, or flying on) after the plan from rest has had its share of the deadline: that share ends
    early enough for the fallback's running estimate (up to half the deadline), so a slow
    fallback does not carry the re-plan past its deadline (benchmarks/replan.py: every
    scenario-2 re-plan over 300 ms ended in a stop)."""
    from types import SimpleNamespace

    from staghunt.flight.known import Start
    from staghunt.flight.replan import FALLBACK_DECAY, REST_SHARE, _Attempt
    from staghunt.solvers.improve import Deadline

    ref, station = _station_on_two_straight_paths()
    planner = station.replanner
    t_s = 1.0
    s = ref.state(np.array([t_s]))[:, :, 0]
    start = Start(t_s, ref, s[0], s[1], s[2])
    ends = []

    def attempts(start_, windows, warm, *args, stop_retrying=None, **kwargs):
        assert stop_retrying is not None and not stop_retrying()  # asks for the plan from rest
        return _Attempt(None, SimpleNamespace(plan=warm), None, ["no feasible plan"], 1, 10, 0.0, [])

    def from_rest(base, soon, t_s_, windows, settings, rng, end, *, engine, cancel=None):
        ends.append(end)
        return None, None

    planner._attempts, planner.from_rest = attempts, from_rest
    for estimate, free in ((0.0, (1 - REST_SHARE) * 0.2), (0.08, 0.08), (0.5, 0.1)):
        planner.fallback_s = estimate
        deadline = Deadline.after(0.2)
        out = planner.solve(start, lambda: t_s, 1, [], deadline, 0.0, fallback=True)
        assert out.plan is None and out.status.value == "kept"  # the straight paths stay clear: flown on
        assert deadline.end - ends[-1] == pytest.approx(free, abs=0.01)
        assert planner.fallback_s >= FALLBACK_DECAY * estimate


def test_the_plan_from_rest_is_solved_once_per_replan_and_the_laps_say_where_the_time_went():
    """On one core the plan from rest is solved when the moving solve first ends infeasible, and
    only then, however often that solve asks again (it solved it anew each time, each one at
    least a reply past its deadline); the re-plan's wall time is split into its parts."""
    import time
    from types import SimpleNamespace

    from staghunt.flight.known import Start
    from staghunt.flight.replan import _Attempt

    ref, station = _station_on_two_straight_paths()
    planner = station.replanner
    s = ref.state(np.array([1.0]))[:, :, 0]
    start = Start(1.0, ref, s[0], s[1], s[2])
    rests = []

    def attempts(start_, windows, warm, *args, stop_retrying=None, **kwargs):
        time.sleep(0.02)
        assert stop_retrying is not None and not any([stop_retrying(), stop_retrying(), stop_retrying()])
        return _Attempt(None, SimpleNamespace(plan=warm), None, ["no feasible plan"], 3, 10, 0.0, [])

    def from_rest(*args, **kwargs):
        rests.append(args)
        time.sleep(0.2)
        return None, None

    planner._attempts, planner.from_rest = attempts, from_rest
    wall = time.perf_counter()
    out = planner.solve(start, lambda: 1.0, 1, [], None, 0.0, fallback=True)
    wall = time.perf_counter() - wall
    assert out.status.value == "kept" and len(rests) == 1
    laps = planner.laps.parts
    assert list(laps) == ["game", "rest", "fallback"]
    assert 0.02 <= laps["game"] < 0.2 <= laps["rest"]  # the plan from rest's time is its own, not the game's
    assert sum(laps.values()) <= wall


def test_a_hovering_team_waits_for_a_known_motion_to_pass_before_it_gives_up():
    """After a stop, re-plans from the hover that fail while a known motion's window (solved
    around) is still to come do not count the goal as unreachable: the team retries until the
    window has passed, then gives up after its retries as before."""
    from staghunt.flight.records import Solved

    ref, station = _station_on_two_straight_paths()
    cfg = station.config
    window = (("truck", 5.0, 12.0),)
    answers = iter([ReplanStatus.STOP] + [ReplanStatus.KEPT] * 20)

    def solve(start, soon, scale, windows, deadline, horizon, fallback, defer):
        return Solved(None, next(answers), windows=window)

    station.replanner.solve = solve
    p, v = ref.state(np.array([1.95]))[:2, 0, 0]
    station.tick(2.0, [Telemetry(0, 1.95, p, v, 0, None, (("pop", Cylinder(40.0, 15.0, 2.0, "pop")),))])
    assert station.stopped_at == 2.0
    gave_up = None
    for k in range(1, 200):
        t = 2.0 + 0.1 * k
        station.tick(t, [])
        if station.gave_up is not None:
            gave_up = station.gave_up
            break
    retries = [r.time for r in station.records if r.cause.value == "retry"]
    assert len(retries) > cfg.retries_after_stop  # went on retrying while the truck was to come
    assert gave_up is not None and gave_up >= 12.0 and gave_up < 12.0 + cfg.retry_interval + 0.5


def test_a_receding_horizons_tail_is_the_planned_route_not_samples_of_the_curve():
    """Beyond its horizon a receding re-plan keeps the current plan's planned points (its
    knots). Samples of the curve every half second carried its wobbles, and where it crawled
    points centimetres apart, into the next plan's path."""
    pts = np.array([[[0.0, 0.0, 10.0], [20.0, 0.0, 10.0], [20.0, 20.0, 10.0]],
                    [[0.0, 6.0, 10.0], [14.0, 6.0, 10.0], [14.0, 20.0, 10.0]]])
    piece = timed_path(pts, 0.0, LIMITS)
    ref = Reference((piece,))
    tracks = RowTeam(tuple(Track(((0.0, ref, n),)) for n in range(2)), (0, 1))
    t = float(piece.knots[3]) - 0.05  # just before a knot: that knot is too near to keep
    tail = route_beyond(tracks, t)
    here = piece.state(np.array([t]))[0][:, 0]
    later = piece.points[:, piece.knots > t]
    assert np.linalg.norm(later[:, 0] - here, axis=-1).max() < TAIL_GAP_M  # the near knot ...
    np.testing.assert_array_equal(tail, later[:, 1:])  # ... dropped, every later one kept as planned
    assert tail[:, -1].tolist() == pts[:, -1].tolist()  # up to the goals
    # UAVs on different curves (one holds): no common route, the caller samples the curves
    held = RowTeam((Track(((0.0, ref, 0),)), Track(((0.0, Still(pts[:, 0], 0.0), 1),))), (0, 0))
    assert route_beyond(held, t) is None


def test_a_plan_flown_uncertified_gives_way_to_a_certified_receding_plan_that_is_no_later():
    """A receding-horizon plan replaces a certified plan only if it arrives 0.5 s sooner; an event
    plan sent uncertified at its deadline (not an equilibrium) gives way to one arriving no
    later, so that the team flies an equilibrium again as soon as one is found."""
    ref, station = _station_on_two_straight_paths()
    base = station.team
    same, later = (Reference((replace(ref.pieces[0], t0=t0, t1=ref.arrival + t0),)) for t0 in (0.0, 0.1))
    assert same.arrival == ref.arrival and later.arrival > ref.arrival
    assert not station._better(same, base)  # the take-off plan: 0.5 s sooner wanted
    sent = ReplanRecord(1.0, 1.3, Cause.SENSED, "sensed pop-up", ReplanStatus.REPLANNED, 0.2, 0.2, "measured", 1.3,
                        100, 1, version=1)
    station.records.append(sent)
    station.released = (1, 1.3)
    assert station._better(same, base) and not station._better(later, base)
    station.records[-1] = replace(sent, certified=True)  # its later certificate: an equilibrium after all
    assert not station._better(same, base)


def test_a_receding_replan_gets_the_repair_budget_while_the_plan_flown_is_not_an_equilibrium():
    """``repair_budget_factor``: a receding-horizon re-plan while the team flies an event's plan
    sent uncertified has that many times the budget and the deadline; once the plan flown is
    certified, the flight's own again."""
    from staghunt.flight.records import Solved
    from staghunt.flight.station import Trigger

    ref, station = _station_on_two_straight_paths()
    station.config = replace(station.config, repair_budget_factor=3)
    scales: list[int] = []

    def solve(start, soon, scale, windows, deadline, horizon, fallback, defer):
        scales.append(scale)
        return Solved(None, ReplanStatus.KEPT)

    station.replanner.solve = solve
    sent = ReplanRecord(1.0, 1.3, Cause.SENSED, "sensed pop-up", ReplanStatus.REPLANNED, 0.3, 0.3, "fixed", 1.3,
                        100, 1, version=1)
    index = len(station.records)
    station.records.append(sent)
    station.released = (1, 1.3)
    receding = Trigger(Cause.RECEDING, "receding horizon")
    station._replan(2.0, receding)
    assert scales == [3] and station.records[-1].deadline_s == pytest.approx(0.9)
    station.records[index] = replace(sent, certified=True)  # its later certificate: an equilibrium
    station.job = None
    station._replan(3.0, receding)
    assert scales == [3, 1] and station.records[-1].deadline_s == pytest.approx(0.3)
    station.job = None
    station._replan(4.0, Trigger(Cause.SENSED, "sensed pop-up"))  # events keep the flight's budget
    assert scales == [3, 1, 1]


def test_the_lead_in_is_the_stopping_distance_at_the_timings_braking_rate_where_there_is_room():
    """A re-plan from a moving state starts where each UAV has stopped at the timing's braking
    rate (``SCHEDULE_SHARE`` of ``max_acceleration``: the schedule can then turn sharply from the
    switch speed); a UAV whose longer lead-in would come within the game's clearance of a known
    obstacle takes the stopping distance at ``max_acceleration``; if even that cuts an obstacle,
    or the team is nearly at rest, the plan starts at the switch state."""
    from staghunt.flight.known import LEAD_IN_MIN_SPEED, Acceptance, KnownWorld, Start, game_margins, lead_in
    from staghunt.trajectory.schedule import SCHEDULE_SHARE

    sc = load_scenario(str(Path(__file__).parent / "data" / "flight_small.toml"))
    known = KnownWorld(sc)
    acc = Acceptance(sc, known, Dynamics(), 0.25)
    pos = np.array([[10.0, 15.0, 12.0], [10.0, 23.0, 12.0]])
    vel = np.array([[4.0, 0.0, 0.0], [4.0, 0.0, 0.0]])
    start = Start(0.0, Still(pos, 0.0), pos, vel, np.zeros((2, 3)))
    a = sc.vehicle.max_acceleration
    far, near = 16.0 / (2.0 * SCHEDULE_SHARE * a), 16.0 / (2.0 * a)
    np.testing.assert_allclose(lead_in(acc, start), pos + [[far, 0.0, 0.0]] * 2)
    # a block ahead of UAV2: its long lead-in would end at half the game's clearance from it
    need, r = game_margins(acc.margins)[0], sc.team[1].radius
    assert 0.5 * need + (far - near) >= acc.margins.clearance  # the short one stays clear of it
    known.sensed["block"] = Cylinder(10.0 + far + r + 1.0 + 0.5 * need, 23.0, 1.0, "block")
    np.testing.assert_allclose(lead_in(acc, start), pos + [[far, 0.0, 0.0], [near, 0.0, 0.0]])
    known.sensed["block"] = Cylinder(10.0 + near, 23.0, 1.0, "block")  # in the way of the short one too
    assert lead_in(acc, start) is None
    slow = Start(0.0, start.base, pos, vel * 0.9 * LEAD_IN_MIN_SPEED / 4.0, np.zeros((2, 3)))
    assert lead_in(acc, slow) is None


def test_a_smooth_curve_is_accepted_at_the_full_margins_a_dense_one_at_the_games_less_its_slack():
    """A re-plan's dense curve keeps within 0.15 m of the game's polyline, so it is judged at the
    game's clearance less ``CURVE_SLACK`` (the clearance a UAV already within the margins has,
    less the slack, when the game granted it that); the smooth curve rounds the polyline's
    corners by more, so it must keep the acceptance's full margins (required plus the tracking
    allowance) whatever the game granted."""
    from staghunt.flight.known import CURVE_SLACK, Acceptance, KnownWorld, game_margins

    sc = load_scenario(str(Path(__file__).parent / "data" / "flight_small.toml"))
    acc = Acceptance(sc, KnownWorld(sc), Dynamics(), 0.25)
    full = acc.margins.clearance
    assert full == pytest.approx(sc.costs.min_clearance + 0.25)  # 1.25 m
    game = game_margins(acc.margins)[0]  # 1.45 m
    assert acc.problem_margins(game).clearance == pytest.approx(full)
    assert acc.problem_margins(game, off_polyline=True).clearance == pytest.approx(full)
    assert acc.problem_margins(1.1).clearance == pytest.approx(1.1 - CURVE_SLACK)  # granted to a UAV within them
    assert acc.problem_margins(1.1, off_polyline=True).clearance == pytest.approx(full)
    assert acc.problem_margins(3.0, off_polyline=True).clearance == pytest.approx(3.0 - CURVE_SLACK)
    assert acc.problem_margins(1.1, off_polyline=True).separation == acc.margins.separation


def test_the_default_deadline_follows_the_team_size_and_gives_way_to_a_fixed_latency_or_a_given_one():
    measured = FlyConfig()
    assert [measured.deadline_for(n) for n in (1, 3)] == [pytest.approx(0.215)] * 2
    assert measured.deadline_for(4) == pytest.approx(0.375) and measured.deadline_for(7) == pytest.approx(0.855)
    assert measured.deadline_for(8) == measured.deadline_for(24) == pytest.approx(1.0)
    assert FlyConfig(latency=0.3).deadline_for(8) == pytest.approx(0.3)
    assert FlyConfig(deadline=0.2).deadline_for(3) == FlyConfig(latency=0.3, deadline=0.2).deadline_for(8) == 0.2
