"""The simulated vehicles: batched dynamics and control agree with rotorpy's ``Multirotor`` and
``SE3Control`` flown one by one; the airframes come from the scenario, with rotorpy's own
Hummingbird parameters; the controller keeps the scenario's limits; wind is reproducible."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from staghunt.costs import to_absolute
from staghunt.flight.mission import fly_mission
from staghunt.flight.vehicles import DrydenGust, RotorpyTeam, SimulatedTeam
from staghunt.scenario import ScenarioError, load_scenario, scenario_from_dict, scenario_to_dict
from staghunt.task import VehicleLimits
from staghunt.task.airframes import AIRFRAMES, G, HUMMINGBIRD, M300

DT = 0.01


def loops(t: float, starts: np.ndarray, size: float, offset: float) -> np.ndarray:
    """``(4, N, 3)`` reference, the same for each UAV from its start: from rest ``offset`` m east
    of it (a transient to begin with), ``x = a (1 - cos wt)``, ``y = a sin^2 wt``, ``z`` a gentle
    climb, ``w = 0.5`` rad/s (speeds up to ``1.4 a w``, accelerations up to ``2.2 a w^2``)."""
    om = 0.5
    c, s, c2, s2 = math.cos(om * t), math.sin(om * t), math.cos(2 * om * t), math.sin(2 * om * t)
    pos = starts + [size * (1 - c) + offset, size * s**2, 0.5 * (1 - c)]
    one = np.ones((len(starts), 1))
    vel = one * [size * om * s, size * om * s2, 0.5 * om * s]
    acc = one * [size * om**2 * c, 2 * size * om**2 * c2, 0.5 * om**2 * c]
    return np.stack([pos, vel, acc, np.zeros_like(pos)])


@pytest.mark.parametrize("name, n, offset, wind", [("hummingbird", 2, 0.5, 4.0), ("m300", 1, 0.5, 3.0)])
def test_batched_team_agrees_with_rotorpy_within_a_centimetre_over_ten_seconds(name, n, offset, wind):
    """Both fly 10 s from rest at the same starts, the same reference (0.5 m off at the start,
    then loops of 4 m at up to 2.8 m/s) and the same Dryden gusts (one seed each)."""
    vehicle = VehicleLimits(airframe=name)
    starts = np.array([[0.0, 0.0, 10.0], [20.0, 0.0, 12.0]])[:n]
    mean = np.array([wind, wind / 2, 0.0])
    ours = SimulatedTeam(starts, DT, DrydenGust(mean, 10.0, DT, np.random.default_rng(3)), vehicle)
    theirs = RotorpyTeam(starts, DT, DrydenGust(mean, 10.0, DT, np.random.default_rng(3)), vehicle)
    gap = 0.0
    for k in range(1000):
        ref = loops(k * DT, starts, 4.0, offset)
        ours.step(k * DT, ref)
        theirs.step(k * DT, ref)
        gap = max(gap, float(np.abs(ours.positions() - theirs.positions()).max()))
    assert gap < 0.01
    assert np.abs(ours.velocities() - theirs.velocities()).max() < 0.01
    assert not ours.saturated().any()  # within the limits: rotorpy's controller exactly
    # they did fly: the transient and the gusts moved them, and they track the circle
    assert np.linalg.norm(ours.velocities(), axis=1).min() > 1.5
    assert np.abs(ours.positions() - loops(10.0, starts, 4.0, offset)[0]).max() < 0.5


def test_hummingbird_is_rotorpys_own_parameter_set():
    from rotorpy.vehicles.hummingbird_params import quad_params

    ours = HUMMINGBIRD.rotorpy_params()
    assert set(ours) == set(quad_params)
    for key, value in quad_params.items():
        if key == "rotor_pos":
            assert set(ours[key]) == set(value)
            for r in value:
                np.testing.assert_allclose(ours[key][r], value[r], rtol=1e-12)
        else:
            np.testing.assert_allclose(ours[key], value, rtol=1e-12, err_msg=key)


def test_airframes_published_figures_and_model():
    assert (HUMMINGBIRD.mass, HUMMINGBIRD.body_radius) == (0.5, pytest.approx(0.27))
    assert HUMMINGBIRD.max_thrust == pytest.approx(4 * 5.57e-6 * 1500**2)
    # the Matrice 300 RTK: 6.3 kg, 895 mm wheelbase, 21-inch propellers, 23 m/s at 30 degrees
    assert M300.mass == 6.3 and 3 <= M300.mass <= 9
    assert M300.arm_length == pytest.approx(0.4475) and M300.rotor_radius == pytest.approx(0.2667)
    assert M300.top_speed() == pytest.approx(23.0, abs=0.05)
    assert M300.max_thrust == pytest.approx(2 * 9.0 * G)
    for frame in AIRFRAMES.values():
        assert 1.5 < frame.thrust_to_weight
        assert frame.rotor_speed_min < frame.hover_rotor_speed < frame.rotor_speed_max
        assert frame.max_horizontal_acceleration() == pytest.approx(G * math.tan(math.radians(frame.max_tilt_deg)))


@pytest.mark.parametrize("frame", list(AIRFRAMES.values()), ids=list(AIRFRAMES))
def test_top_speed_is_a_level_balance_of_rotorpys_forces(frame):
    """At the top speed and the tilt limit, rotorpy's own dynamics give no acceleration."""
    from rotorpy.vehicles.multirotor import Multirotor

    v = frame.top_speed()
    force, w = frame.level_flight(v)
    tilt = math.radians(frame.max_tilt_deg)
    state = {"x": np.zeros(3), "v": np.array([v, 0.0, 0.0]), "w": np.zeros(3), "wind": np.zeros(3),
             "q": np.array([0.0, math.sin(tilt / 2), 0.0, math.cos(tilt / 2)]), "rotor_speeds": np.full(4, w)}
    dot = Multirotor(frame.rotorpy_params(), initial_state=state).statedot(state, {"cmd_motor_speeds": np.full(4, w)}, DT)
    assert abs(force) < 1e-6
    np.testing.assert_allclose(dot["vdot"], 0.0, atol=1e-6)


def _scenario(**vehicle):
    data = scenario_to_dict(load_scenario("scenario2"))
    data["vehicle"].update(vehicle)
    return data


def test_scenario_chooses_the_airframe_and_the_flight_uses_it():
    assert load_scenario("scenario2").vehicle.airframe == "hummingbird"  # the default
    sc = scenario_from_dict(_scenario(airframe="m300"), name="x")
    assert sc.vehicle.airframe == "m300"
    assert scenario_from_dict(scenario_to_dict(sc), name="y").vehicle == sc.vehicle
    team = SimulatedTeam(sc.starts(), DT, None, sc.vehicle)
    assert team.airframe is M300
    np.testing.assert_allclose(team.rotor_speeds(), M300.hover_rotor_speed)
    for k in range(100):  # it hovers: the weight is its own
        team.step(k * DT, np.stack([sc.starts(), *np.zeros((3,) + sc.starts().shape)]))
    np.testing.assert_allclose(team.positions(), sc.starts(), atol=1e-6)


def test_an_unknown_airframe_is_refused_with_one_line():
    for value, got in (("x500", "'x500'"), (3, "3")):
        with pytest.raises(ScenarioError) as err:
            scenario_from_dict(_scenario(airframe=value), name="x")
        assert str(err.value) == f"vehicle.airframe: must be one of 'hummingbird' or 'm300', got {got}"


@pytest.mark.parametrize("change, radius, needle", [
    ({"airframe": "m300", "max_speed": 25.0}, 1.0,
     "vehicle.max_speed: 25 m/s is above the top speed of airframe 'm300' (23.00 m/s at its 30 degree tilt limit)"),
    ({"max_speed": 14.0}, 1.0, "vehicle.max_speed: 14 m/s is above the top speed of airframe 'hummingbird' (13.26"),
    ({"airframe": "m300", "max_acceleration": 6.0}, 1.0,
     "vehicle.max_acceleration: 6 m/s^2 is above what airframe 'm300' reaches at its 30 degree tilt limit (5.66"),
    ({"airframe": "m300"}, 0.7, "team[1].radius: 0.7 m is smaller than airframe 'm300' (vehicle.airframe): arm "
                                "0.448 m plus propeller 0.267 m = 0.714 m"),
    ({}, 0.2, "team[1].radius: 0.2 m is smaller than airframe 'hummingbird'"),
])
def test_a_team_its_airframe_cannot_fly_loads_but_is_refused_when_flown(change, radius, needle):
    """Planning needs no airframe: the scenario loads (today's scenarios all do); flying it in
    simulation (fly, export --simulate) is refused with one line before any step."""
    data = _scenario(**change)
    data["team"][1]["radius"] = radius
    sc = scenario_from_dict(data, name="x")
    radii = [u.radius for u in sc.team]
    with pytest.raises(ValueError) as err:
        SimulatedTeam(sc.starts(), DT, None, sc.vehicle, radii)
    assert str(err.value).startswith(needle) and "\n" not in str(err.value)
    t = np.array([0.0, 1.0])
    pos = np.repeat(to_absolute(sc.world.terrain, sc.starts()[:, None]), 2, axis=1)
    with pytest.raises(ValueError, match=re.escape(needle)):
        fly_mission(sc, t, pos, np.zeros_like(pos))  # export --simulate


def test_cli_refuses_an_unknown_airframe_with_exit_2(tmp_path, capsys):
    from staghunt.cli import main
    from staghunt.scenario import builtin_path

    src = builtin_path("scenario1").read_text(encoding="utf-8")
    bad = tmp_path / "bad.toml"
    assert 'airframe = "hummingbird"' in src
    bad.write_text(src.replace('airframe = "hummingbird"', 'airframe = "bumblebee"'), encoding="utf-8")
    assert main(["show", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "vehicle.airframe" in err and "bumblebee" in err


@pytest.mark.parametrize("name", list(AIRFRAMES))
def test_the_controller_keeps_the_scenarios_speed_and_the_airframes_tilt(name):
    """A reference 60 m away at once: the limited team flies there no faster than max_speed
    and never tilts beyond the airframe's limit; rotorpy's unlimited controller does both."""
    vehicle = VehicleLimits(max_speed=4.0, max_acceleration=2.0, cruise_speed=3.0, airframe=name)
    frame = AIRFRAMES[name]
    start = np.array([[0.0, 0.0, 20.0]])
    ref = np.stack([start + [60.0, 0.0, 0.0], *np.zeros((3, 1, 3))])
    ours, theirs = SimulatedTeam(start, DT, None, vehicle), RotorpyTeam(start, DT, None, vehicle)
    speed, tilt, their_speed = 0.0, 0.0, 0.0
    for k in range(300):
        ours.step(k * DT, ref)
        theirs.step(k * DT, ref)
        speed = max(speed, float(np.linalg.norm(ours.velocities())))
        their_speed = max(their_speed, float(np.linalg.norm(theirs.velocities())))
        q = ours.attitudes()[0]
        tilt = max(tilt, math.degrees(math.acos(1 - 2 * (q[0] ** 2 + q[1] ** 2))))
    assert 3.5 < speed <= 4.0 * 1.05 and their_speed > 8.0
    assert tilt <= frame.max_tilt_deg + 1.0
    assert ours.saturated()[0] > 100


def test_same_seed_same_flight_in_wind_and_another_seed_differs():
    starts = np.array([[0.0, 0.0, 10.0], [10.0, 0.0, 10.0], [0.0, 10.0, 10.0]])

    def fly(seed: int) -> np.ndarray:
        team = SimulatedTeam(starts, DT, DrydenGust(np.array([6.0, 0.0, 0.0]), 10.0, DT,
                                                    np.random.default_rng(seed)))
        out = []
        for k in range(200):
            team.step(k * DT, loops(k * DT, starts, 3.0, 0.0))
            out.append(team.positions())
        return np.array(out)

    a, b, c = fly(11), fly(11), fly(12)
    assert np.array_equal(a, b)
    assert np.abs(a - c).max() > 1e-3
