"""The closed-loop benchmark's measure of how a flight met its pop-up (benchmarks/replan.py,
``popup_reach``): the episodes place the pop-up on the timing of the plan they were built on,
and the flown timing differs, so a row says when the pop-up really appeared."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from replan import _lead_drift, backward, popup_reach, popup_swerve, stop_causes  # noqa: E402

NOTICE = 0.2  # a sensor period, a reflex check and the reflex latency (s)


def _flight(x0: list[float], vx: list[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """UAVs on the x axis (y = 3 k) at ``x0`` flying along x at ``vx``, sampled at 10 Hz."""
    times = np.arange(0.0, 2.0, 0.1)
    x0a, vxa = np.array(x0), np.array(vx)
    actual = np.zeros((len(x0), len(times), 3))
    actual[:, :, 0] = x0a[:, None] + vxa[:, None] * times
    actual[:, :, 1] = 3.0 * np.arange(len(x0))[:, None]
    velocity = np.zeros_like(actual)
    velocity[:, :, 0] = vxa[:, None]
    return times, actual, velocity


@pytest.mark.parametrize(("x", "lead", "reach"), [(6.0, 0.75, False), (4.5, 0.375, True), (2.0, 0.0, True)])
def test_popup_reach_is_the_flown_lead_and_the_braking_reach(x: float, lead: float, reach: bool) -> None:
    """UAV1 at 4 m/s towards a pop-up (radius 2 m, body 1 m) appearing at t = 1 s: it touches it
    after (gap - 3 m) / 4 m/s; it can stop short if the gap beyond contact exceeds what it flies
    in 0.2 s plus a braking stop at 9 m/s^2 with its ramp (0.8 + 0.99 m). UAV2 flies away."""
    times, actual, velocity = _flight([-4.0, 0.0], [4.0, -4.0])
    popup = {"time": 1.0, "x": x, "y": 0.0, "radius": 2.0}
    out = popup_reach(times, actual, velocity, popup, [1.0, 1.0], 3.0, NOTICE)
    assert out["popup_flown_lead_s"] == pytest.approx(lead)
    assert out["popup_flown_uav"] == 0
    assert out["popup_within_reach"] is reach


def test_popup_reach_none_when_no_uav_closes_in() -> None:
    times, actual, velocity = _flight([0.0, 0.0], [-4.0, 0.0])
    out = popup_reach(times, actual, velocity, {"time": 1.0, "x": 8.0, "y": 0.0, "radius": 2.0}, [1.0, 1.0], 3.0,
                      NOTICE)
    assert out == {"popup_flown_lead_s": None, "popup_flown_uav": None, "popup_within_reach": False}


@pytest.mark.parametrize(("x", "y", "possible"), [(12.0, 0.0, True), (8.0, 0.0, False), (8.0, 2.5, True),
                                                  (8.0, 4.0, None)])
def test_popup_swerve_is_the_sideways_reach_in_the_time_left(x: float, y: float, possible: bool | None) -> None:
    """UAV1 at 4 m/s along y = 0 meets a pop-up (radius 2 m, body 1 m, clearance 1 m) appearing
    at t = 1 s with it at x = 0; the planner answers 0.5 s later, then it can move a T^2 / 2 m
    sideways at 3 m/s^2 (UAV2 flies away). Ahead at 12 m: contact in 2.25 s, 1.5 * 1.75^2 =
    4.59 m >= the 4 m it needs. At 8 m: 1.25 s, 0.84 m < 4 m. At 8 m, 2.5 m off its line: contact
    in 1.585 s, 1.5 * 1.085^2 = 1.77 m >= 4 - 2.5 m. 4 m off its line: it does not close in."""
    times, actual, velocity = _flight([-4.0, 0.0], [4.0, -4.0])
    popup = {"time": 1.0, "x": x, "y": y, "radius": 2.0}
    assert popup_swerve(times, actual, velocity, popup, [1.0, 1.0], 1.0, 3.0, 0.5) is possible


def test_a_popup_trigger_is_where_its_uav_is_lead_seconds_before_contact() -> None:
    """The episodes' trigger (replan_episodes._trigger): UAV1 at 4 m/s along x from 0 meets a
    pop-up of radius 2 m at x = 20 (body 1 m) when x = 17, at t = 4.25 s; 2 s before, at x = 9,
    it is 9 m from the outline (one 0.05 s sample: 0.2 m). The plain episode carries it; flown
    ``placed`` it is that trigger, by default any UAV within the episode's lead of a breach,
    ``timed`` none."""
    from types import SimpleNamespace

    from replan_episodes import _trigger, from_plain

    from staghunt.world import Cylinder
    from staghunt.world.dynamic import Trigger

    class Straight:
        arrival = 10.0

        def state(self, t: np.ndarray) -> tuple[np.ndarray]:
            pos = np.zeros((2, len(t), 3))
            pos[0, :, 0] = 4.0 * t
            pos[1, :, 1] = 30.0  # UAV2 far off
            return (pos,)

    team = SimpleNamespace(team=[SimpleNamespace(name="UAV1", radius=1.0), SimpleNamespace(name="UAV2", radius=1.0)])
    trig = _trigger(team, Straight(), 0, Cylinder(20.0, 0.0, 2.0, "pop-up"), 2.0)
    assert trig.uav == "UAV1" and trig.within == pytest.approx(9.0, abs=0.25)
    plain = {"waypoints": [[[1.0, 2.0, 3.0]]], "moving": [], "jibs": [],
             "events": [{"time": 6.0, "kind": "appear", "name": "pop-up", "x": 20.0, "y": 0.0, "radius": 2.0,
                         "trigger": {"uav": "UAV1", "within": 9.0}}], "popup_lead_s": 2.0}
    assert from_plain(plain, "placed")[1].events[0].trigger == Trigger("UAV1", 9.0)
    assert from_plain(plain)[1].events[0].trigger == Trigger(None, 0.0, 2.0)
    assert from_plain(plain, "timed")[1].events[0].trigger is None
    with pytest.raises(ValueError, match="popups: one of lead, placed, timed"):
        from_plain(plain, "soon")


def test_first_stops_are_counted_by_the_cause_the_record_gives():
    """An episode's first stop (``stop, replanned``, ``stop`` or ``emergency stop``) counts once,
    by its first problem; a deferred re-plan before it is no stop, and an episode with none is
    not counted."""
    def row(*replans):
        return {"replans": [{"status": s, "problems": p} for s, p in replans]}

    rows = [row(("deferred", []), ("stop, replanned", ["no feasible plan from the switch state"]),
                ("stop", ["contact: UAV1's clearance to pop-up fell to -0.1 m"])),
            row(("stop, replanned", ["breach: UAV3's clearance to pop-up fell to 0.4 m (required 1.25 m)"])),
            row(("stop", ["contact: UAV2's clearance to truck fell to -2.4 m (required 1.63 m)"])),
            row(("emergency stop", ["no timing of the new paths keeps speed <= 12 m/s"])),
            row(("stop", [])), row(("replanned", []))]
    assert stop_causes(rows) == {"no feasible plan": 1, "timed plan broke a margin at the pop-up": 1,
                                 "timed plan broke a margin elsewhere": 1, "timing over the limits": 1,
                                 "not recorded": 1}


def test_the_lead_drift_counts_popups_met_inside_their_drawn_lead():
    """Drawn leads 2, 3 and 4 s met 2.2, 2.5 and 3.0 s ahead: drifts +0.2, -0.5, -1.0 (median
    -0.5), two met half a second or more inside; a row where no UAV closed in is left out."""
    rows = [{"popup_lead_s": 2.0, "popup_flown_lead_s": 2.2}, {"popup_lead_s": 3.0, "popup_flown_lead_s": 2.5},
            {"popup_lead_s": 4.0, "popup_flown_lead_s": 3.0}, {"popup_lead_s": 5.0, "popup_flown_lead_s": None}]
    assert _lead_drift(rows) == {"popup_lead_s_median": 3.0, "popup_lead_drift_s_median": pytest.approx(-0.5),
                                 "popups_met_inside_lead": 2}


def test_backward_is_how_far_a_uav_went_away_from_its_goal_after_being_nearer() -> None:
    """UAV1 flies 6 m towards its goal, 3 m back, then on to it: 3 m backwards; UAV2 goes
    straight to its goal: none."""
    x = np.concatenate([np.linspace(0.0, 6.0, 7), np.linspace(5.0, 3.0, 3), np.linspace(4.0, 10.0, 7)])
    ref = np.zeros((2, x.size, 3))
    ref[0, :, 0] = x
    ref[1, :, 0] = np.linspace(0.0, 10.0, x.size)
    ref[1, :, 1] = 5.0
    goals = np.array([[10.0, 0.0, 0.0], [10.0, 5.0, 0.0]])
    assert backward(ref, goals) == pytest.approx(3.0)
    assert backward(ref[1:], goals[1:]) == 0.0
