"""Scenario files: the built-ins, every validation rule, the round trip and DEM loading."""

from __future__ import annotations

import copy
import json
import math
import pickle
import sys
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

from staghunt.scenario import (
    CostParams,
    Scenario,
    ScenarioError,
    SolverSettings,
    builtin_names,
    builtin_path,
    load_scenario,
    scenario_from_dict,
    scenario_to_dict,
)

PAPER_STARTS = [(15.0, 18.66, 20.0), (10.0, 10.0, 20.0), (20.0, 10.0, 20.0)]
PAPER_GOALS = [(85.0, 88.66, 20.0), (80.0, 80.0, 20.0), (90.0, 80.0, 20.0)]
PAPER_INCIDENCE = [[1, 1, 0], [-1, 0, 1], [0, -1, -1]]
PAPER_EDGE_WEIGHTS = [[1, 1, 0], [1, 0, 1], [0, 1, 1]]
PAPER_BETA_W = [[1, 100, 100, 1, 1, 1], [100, 1, 100, 1, 1, 1], [100, 1, 100, 1, 1, 1]]


def valid() -> dict[str, Any]:
    """A small valid scenario (two UAVs, one obstacle), as parsed TOML."""
    return {
        "name": "t",
        "description": "test",
        "site": {"xmin": 0.0, "xmax": 100.0, "ymin": 0.0, "ymax": 100.0, "hmin": 5.0, "hmax": 35.0},
        "ground": {"kind": "flat"},
        "obstacles": [{"x": 40.0, "y": 48.0, "radius": 4.0, "name": "crane 1"}],
        "team": [
            {
                "name": "A",
                "start": [10.0, 10.0, 20.0],
                "goal": [80.0, 80.0, 20.0],
                "radius": 1.0,
                "beta": 1.0,
                "weights": [1.0, 1.0, 1.0, 1.0, 1.0],
            },
            {
                "name": "B",
                "start": [20.0, 10.0, 20.0],
                "goal": [90.0, 80.0, 20.0],
                "radius": 1.0,
                "beta": 1.0,
                "weights": [1.0, 1.0, 1.0, 1.0, 1.0],
            },
        ],
        "formation": {"incidence": [[1], [-1]], "edge_weights": [[1.0], [1.0]]},
        "costs": {"danger_margin": 10.0, "safe_distance": 2.0},
        "solver": {"particles": 10, "iterations": 5, "waypoints": 3},
    }


# ---------------------------------------------------------------------------------------------
# Built-ins
# ---------------------------------------------------------------------------------------------


def test_builtin_names() -> None:
    assert builtin_names() == ["scenario1", "scenario2", "site_grid24", "site_inspection", "site_inspection3", "site_wedge"]
    assert builtin_path("scenario1").is_file()
    with pytest.raises(ScenarioError, match="scenario1"):
        builtin_path("nope")


@pytest.mark.parametrize("name", ["scenario1", "scenario2"])
def test_builtin_paper_values(name: str) -> None:
    s = load_scenario(name)
    assert isinstance(s, Scenario)
    assert s.name == name
    b = s.world.bounds
    assert (b.xmin, b.xmax, b.ymin, b.ymax, b.hmin, b.hmax) == (0, 100, 0, 100, 5, 35)
    assert s.world.terrain.is_flat
    assert [u.start for u in s.team] == PAPER_STARTS
    assert [u.goal for u in s.team] == PAPER_GOALS
    assert [u.name for u in s.team] == ["UAV1", "UAV2", "UAV3"]
    assert all(u.radius == 1.0 for u in s.team)
    bw = [[u.weights.beta, *u.weights.as_array()] for u in s.team]
    assert bw == PAPER_BETA_W
    np.testing.assert_array_equal(s.formation.incidence, PAPER_INCIDENCE)
    np.testing.assert_array_equal(s.formation.edge_weights, PAPER_EDGE_WEIGHTS)
    np.testing.assert_array_equal(s.formation.reference, PAPER_GOALS)
    for a in (s.formation.incidence, s.formation.edge_weights, s.formation.reference):
        assert not a.flags.writeable
    assert s.costs == CostParams(
        danger_margin=10.0,
        safe_distance=2.0,
        turning_threshold_deg=0.0,
        climb_threshold_deg=0.0,
        desired_height=20.0,
        continuous_separation=True,
        min_clearance=1.0,
    )
    assert s.origin is not None and (s.origin.latitude, s.origin.longitude) == (47.397742, 8.545594)
    assert (s.vehicle.max_speed, s.vehicle.max_acceleration, s.vehicle.cruise_speed) == (12.0, 3.0, 5.0)
    assert s.h_ref == 20.0
    assert s.solver == SolverSettings(
        particles=2000,
        iterations=1500,
        waypoints=10,
        c0=0.999,
        damping=0.98,
        c1=1.5,
        c2=1.5,
        velocity_fraction=0.5,
    )
    obstacles = [(c.x, c.y, c.radius) for c in s.world.cylinders]
    if name == "scenario1":
        assert obstacles == [(40, 40, 9), (60, 60, 9)]
    else:
        assert obstacles == [(40, 48, 4), (74, 43, 4), (20, 70, 4), (70, 60, 4)]
        names = [c.name for c in s.world.cylinders]
        assert names == ["crane 1", "crane 2", "virtual 1", "virtual 2"]


@pytest.mark.parametrize("name", ["scenario1", "scenario2"])
def test_builtin_file_says_what_the_paper_leaves_open(name: str) -> None:
    lines = builtin_path(name).read_text().splitlines()
    keys = ("hmin", "hmax", "danger_margin", "safe_distance", "turning_threshold_deg", "damping")
    for key in keys:
        line = next(l for l in lines if l.startswith(f"{key} ="))
        assert "# open" in line, line
    assert any("open: body radius 1" in l for l in lines)


def test_load_from_path_and_name_default(tmp_path: Path) -> None:
    text = builtin_path("scenario2").read_text().replace('name = "scenario2"\n', "")
    p = tmp_path / "site_b.toml"
    p.write_text(text)
    s = load_scenario(p)
    assert s.name == "site_b"
    assert len(s.world.cylinders) == 4


def test_missing_file_and_bad_toml(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario(tmp_path / "nope.toml")
    p = tmp_path / "bad.toml"
    p.write_text("name = \n")
    with pytest.raises(ScenarioError, match="invalid TOML") as info:
        load_scenario(p)
    assert str(p) in str(info.value)


def test_error_names_the_file(tmp_path: Path) -> None:
    text = builtin_path("scenario1").read_text().replace("particles = 2000", "particles = 0")
    p = tmp_path / "s.toml"
    p.write_text(text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(p)
    msg = str(info.value)
    assert msg.startswith(str(p)) and "solver.particles" in msg and "\n" not in msg
    assert info.value.key == "solver.particles"
    assert pickle.loads(pickle.dumps(info.value)).args == info.value.args


# ---------------------------------------------------------------------------------------------
# Validation: break one thing in a valid dict, expect the key path in the message
# ---------------------------------------------------------------------------------------------


def setter(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    """Set ``data[a][b]...`` for a dotted path with integer parts as indices."""

    def apply(d: dict[str, Any]) -> None:
        parts = [int(p) if p.isdigit() else p for p in path.split(".")]
        for p in parts[:-1]:
            d = d[p]
        d[parts[-1]] = value

    return apply


def deleter(path: str) -> Callable[[dict[str, Any]], None]:
    def apply(d: dict[str, Any]) -> None:
        parts = [int(p) if p.isdigit() else p for p in path.split(".")]
        for p in parts[:-1]:
            d = d[p]
        del d[parts[-1]]

    return apply


def three_uavs(d: dict[str, Any]) -> None:
    """Add a third UAV far from the others (formation left as 2 rows)."""
    d["team"].append(
        {
            "name": "C",
            "start": [30.0, 10.0, 20.0],
            "goal": [70.0, 80.0, 20.0],
            "radius": 1.0,
            "beta": 1.0,
            "weights": [1.0, 1.0, 1.0, 1.0, 1.0],
        }
    )


def three_uavs_disconnected(d: dict[str, Any]) -> None:
    three_uavs(d)
    d["formation"] = {"incidence": [[1], [-1], [0]], "edge_weights": [[1.0], [1.0], [0.0]]}


CASES: list[tuple[str, Callable[[dict[str, Any]], None], str]] = [
    # unknown keys at every level
    ("unknown top", setter("colour", "red"), "colour: unknown key"),
    ("unknown site", setter("site.zmax", 3.0), "site.zmax: unknown key"),
    ("unknown ground", setter("ground.file_name", "x"), "ground.file_name: unknown key"),
    ("flat with file", setter("ground.file", "x.npy"), "ground.file"),
    ("unknown obstacle", setter("obstacles.0.height", 3.0), "obstacles[0].height: unknown key"),
    ("unknown uav", setter("team.1.speed", 3.0), "team[1].speed: unknown key"),
    ("unknown formation", setter("formation.shape", 1), "formation.shape: unknown key"),
    ("unknown costs", setter("costs.delta", 1.0), "costs.delta: unknown key"),
    ("unknown solver", setter("solver.npop", 1), "solver.npop: unknown key"),
    # wrong types
    ("site string", setter("site.xmax", "100"), "site.xmax: expected a number"),
    ("site bool", setter("site.xmax", True), "site.xmax: expected a number"),
    ("name type", setter("name", 3), "name: expected a string"),
    ("site not table", setter("site", [1, 2]), "site: expected a table"),
    ("team not array", setter("team", {"a": 1}), "team: expected an array"),
    ("start scalar", setter("team.0.start", 3.0), "team[0].start: expected an array"),
    ("start length", setter("team.0.start", [1.0, 2.0]), "team[0].start"),
    ("particles float", setter("solver.particles", 10.0), "solver.particles: expected an integer"),
    (
        "continuous not bool",
        setter("costs.continuous_separation", 1),
        "costs.continuous_separation",
    ),
    ("kind bad", setter("ground.kind", "hilly"), "ground.kind"),
    # NaN / inf
    ("nan site", setter("site.ymax", math.nan), "site.ymax: must be a finite number"),
    ("inf obstacle", setter("obstacles.0.x", math.inf), "obstacles[0].x: must be a finite number"),
    ("nan start", setter("team.1.start", [20.0, math.nan, 20.0]), "team[1].start[1]"),
    ("nan desired", setter("costs.desired_height", math.nan), "costs.desired_height"),
    ("nan c1", setter("solver.c1", math.nan), "solver.c1"),
    # radii
    ("negative uav radius", setter("team.0.radius", -1.0), "team[0].radius: must be >= 0"),
    ("zero obstacle radius", setter("obstacles.0.radius", 0.0), "obstacles[0].radius: must be > 0"),
    # site box
    ("xmin >= xmax", setter("site.xmin", 100.0), "site.xmax: must be greater than site.xmin"),
    ("ymin >= ymax", setter("site.ymax", -1.0), "site.ymax"),
    ("hmin < 0", setter("site.hmin", -1.0), "site.hmin: must be >= 0"),
    ("hmin > hmax", setter("site.hmax", 4.0), "site.hmax: must be >= site.hmin"),
    ("missing site key", deleter("site.ymin"), "site.ymin: required key is missing"),
    ("missing site", deleter("site"), "site: required key is missing"),
    # start / goal placement
    (
        "start outside x",
        setter("team.0.start", [-1.0, 10.0, 20.0]),
        "team[0].start: (-1.0, 10.0, 20.0)",
    ),
    ("goal outside h", setter("team.1.goal", [90.0, 80.0, 40.0]), "team[1].goal"),
    ("start below hmin", setter("team.0.start", [10.0, 10.0, 4.0]), "team[0].start"),
    (
        "start in obstacle",
        setter("team.0.start", [37.0, 48.0, 20.0]),
        "team[0].start: (37.0, 48.0, 20.0) of 'A' lies inside obstacle 'crane 1' "
        "(x=40, y=48, R=4) plus body radius 1",
    ),
    ("goal in obstacle", setter("team.1.goal", [44.5, 48.0, 20.0]), "team[1].goal"),
    (
        "starts too close",
        setter("team.1.start", [13.0, 10.0, 20.0]),
        "team[1].start: 'B' start is 3 m from 'A'",
    ),
    (
        "goals too close",
        setter("team.1.goal", [80.0, 84.0, 20.0]),
        "team[1].goal: 'B' goal is 4 m from 'A'",
    ),
    ("start == goal", setter("team.0.goal", [10.0, 10.0, 20.0]), "team[0].goal: equals the start"),
    ("empty team", setter("team", []), "team: the team needs at least one UAV"),
    ("duplicate names", setter("team.1.name", "A"), "team[1].name"),
    # weights
    (
        "negative weight",
        setter("team.0.weights", [1.0, -1.0, 1.0, 1.0, 1.0]),
        "team[0].weights[1]: must be >= 0",
    ),
    ("nan weight", setter("team.0.weights", [1.0, 1.0, math.nan, 1.0, 1.0]), "team[0].weights[2]"),
    ("weights length", setter("team.0.weights", [1.0, 1.0, 1.0, 1.0]), "team[0].weights"),
    ("weights with beta", setter("team.0.weights", [1.0] * 6), "team[0].weights"),
    ("negative beta", setter("team.1.beta", -2.0), "team[1].beta: must be >= 0"),
    ("missing beta", deleter("team.1.beta"), "team[1].beta: required key is missing"),
    # formation
    ("formation missing", deleter("formation"), "formation: required for a team of 2 UAVs"),
    (
        "incidence rows",
        setter("formation.incidence", [[1], [-1], [0]]),
        "formation.incidence: must have one row per UAV",
    ),
    ("incidence ragged", setter("formation.incidence", [[1, 0], [-1]]), "formation.incidence"),
    (
        "incidence column two heads",
        setter("formation.incidence", [[1], [1]]),
        "formation.incidence: column 0",
    ),
    (
        "incidence column value 2",
        setter("formation.incidence", [[2], [-1]]),
        "formation.incidence: column 0",
    ),
    (
        "edge weights shape",
        setter("formation.edge_weights", [[1.0, 1.0], [1.0, 1.0]]),
        "formation.edge_weights: must have",
    ),
    (
        "edge weights negative",
        setter("formation.edge_weights", [[1.0], [-1.0]]),
        "formation.edge_weights[1][0]",
    ),
    (
        "disconnected",
        three_uavs_disconnected,
        "formation.incidence: the formation graph is not connected",
    ),
    (
        "no edges",
        setter("formation", {"incidence": [[], []], "edge_weights": [[], []]}),
        "not connected",
    ),
    (
        "reference shape",
        setter("formation.reference", [[1.0, 2.0], [3.0, 4.0]]),
        "formation.reference: must be N x 3",
    ),
    ("reference rows", setter("formation.reference", [[1.0, 2.0, 3.0]]), "formation.reference"),
    # solver
    ("particles < 1", setter("solver.particles", 0), "solver.particles: must be >= 1"),
    ("iterations < 0", setter("solver.iterations", -1), "solver.iterations: must be >= 0"),
    ("waypoints < 1", setter("solver.waypoints", 0), "solver.waypoints: must be >= 1"),
    ("c0 negative", setter("solver.c0", -0.1), "solver.c0: must be >= 0"),
    ("c2 negative", setter("solver.c2", -0.1), "solver.c2"),
    ("damping negative", setter("solver.damping", -1.0), "solver.damping"),
    (
        "velocity_fraction 0",
        setter("solver.velocity_fraction", 0.0),
        "solver.velocity_fraction: must lie in (0, 1]",
    ),
    ("velocity_fraction > 1", setter("solver.velocity_fraction", 1.5), "solver.velocity_fraction"),
    # costs
    (
        "turning > 180",
        setter("costs.turning_threshold_deg", 181.0),
        "costs.turning_threshold_deg: must lie in [0, 180]",
    ),
    ("climb < 0", setter("costs.climb_threshold_deg", -1.0), "costs.climb_threshold_deg"),
    ("danger margin < 0", setter("costs.danger_margin", -1.0), "costs.danger_margin: must be >= 0"),
    ("safe distance < 0", setter("costs.safe_distance", -0.5), "costs.safe_distance: must be >= 0"),
    ("big safe distance", setter("costs.safe_distance", 9.0), "team[1].start"),
    ("clearance < 0", setter("costs.min_clearance", -1.0), "costs.min_clearance: must be >= 0"),
    ("origin not a table", lambda d: d.update(origin=5), "origin: expected a table"),
    ("origin lat", lambda d: d.update(origin={"latitude": 91.0, "longitude": 0.0, "altitude": 0.0}),
     "origin.latitude: must lie in [-90, 90]"),
    ("origin lon", lambda d: d.update(origin={"latitude": 0.0, "longitude": -181.0, "altitude": 0.0}),
     "origin.longitude: must lie in [-180, 180]"),
    ("origin missing alt", lambda d: d.update(origin={"latitude": 0.0, "longitude": 0.0}),
     "origin.altitude: required key is missing"),
    ("origin unknown key", lambda d: d.update(origin={"lat": 0.0}), "origin.lat: unknown key"),
    ("vehicle zero speed", lambda d: d.update(vehicle={"max_speed": 0.0}), "vehicle.max_speed: must be > 0"),
    ("vehicle nan", lambda d: d.update(vehicle={"max_acceleration": float("nan")}),
     "vehicle.max_acceleration: must be a finite number"),
    ("vehicle string", lambda d: d.update(vehicle={"cruise_speed": "fast"}), "vehicle.cruise_speed: expected a number"),
    ("cruise > max", lambda d: d.update(vehicle={"cruise_speed": 20.0}), "vehicle.cruise_speed: must not exceed"),
]


@pytest.mark.parametrize("label, breaker, expected", CASES, ids=[c[0] for c in CASES])
def test_validation(label: str, breaker: Callable[[dict[str, Any]], None], expected: str) -> None:
    data = valid()
    breaker(data)
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(data, name="t", base_dir=None)
    msg = str(info.value)
    assert expected in msg, msg
    assert "\n" not in msg


def test_valid_dict_loads_with_defaults() -> None:
    data = valid()
    del data["costs"], data["solver"], data["ground"], data["obstacles"], data["description"]
    s = scenario_from_dict(data, name="t", base_dir=None)
    assert s.costs == CostParams()
    assert s.solver == SolverSettings()
    assert s.world.cylinders == ()
    assert s.description == ""
    assert s.h_ref == 20.0  # middle of [5, 35]


def test_single_uav_without_formation() -> None:
    data = valid()
    data["team"] = data["team"][:1]
    del data["formation"]
    s = scenario_from_dict(data, name="solo", base_dir=None)
    assert s.formation.incidence.shape == (1, 0)
    assert s.formation.edge_weights.shape == (1, 0)
    np.testing.assert_array_equal(s.formation.reference, [[80.0, 80.0, 20.0]])
    again = scenario_from_dict(scenario_to_dict(s), name="x", base_dir=None)
    assert scenario_to_dict(again) == scenario_to_dict(s)


def test_touching_obstacle_is_allowed() -> None:
    data = valid()
    data["team"][0]["start"] = [35.0, 48.0, 20.0]  # distance 5 = R + r exactly
    scenario_from_dict(data, name="t", base_dir=None)


def test_explicit_reference_and_frozen_arrays() -> None:
    data = valid()
    data["formation"]["reference"] = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]]
    s = scenario_from_dict(data, name="t", base_dir=None)
    np.testing.assert_array_equal(s.formation.reference, [[0, 0, 0], [10, 0, 0]])
    with pytest.raises(ValueError):
        s.formation.reference[0, 0] = 1.0
    assert isinstance(s.team[0].start, tuple)


# ---------------------------------------------------------------------------------------------
# Round trip
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["scenario1", "scenario2"])
def test_round_trip(name: str) -> None:
    s = load_scenario(name)
    d = scenario_to_dict(s)
    d_json = json.loads(json.dumps(d))  # JSON-able, and unchanged by JSON
    assert d_json == d
    again = scenario_from_dict(d_json, name="other", base_dir=None)
    assert scenario_to_dict(again) == d
    assert again.name == s.name and again.description == s.description
    assert again.world.bounds == s.world.bounds
    assert again.world.cylinders == s.world.cylinders
    assert again.team == s.team
    assert again.costs == s.costs and again.solver == s.solver
    for field in ("incidence", "edge_weights", "reference"):
        np.testing.assert_array_equal(getattr(again.formation, field), getattr(s.formation, field))


def test_round_trip_of_a_triggered_event_and_its_errors() -> None:
    from staghunt.world.dynamic import Trigger

    d = valid()
    d["events"] = [{"time": 30.0, "kind": "appear", "x": 60.0, "y": 60.0, "radius": 2.0,
                    "trigger": {"uav": "B", "within": 7.5}}]
    s = scenario_from_dict(d, name="t", base_dir=None)
    assert s.dynamics.events[0].trigger == Trigger("B", 7.5)
    out = scenario_to_dict(s)
    assert out["events"][0]["trigger"] == {"uav": "B", "within": 7.5}
    assert scenario_from_dict(out, name="t", base_dir=None).dynamics == s.dynamics
    d["events"][0]["trigger"]["uav"] = "C"
    with pytest.raises(ScenarioError, match=r"events\[0\]\.trigger\.uav.*no UAV named 'C'; the team: A, B"):
        scenario_from_dict(d, name="t", base_dir=None)
    d["events"][0]["trigger"] = {"lead": 2.5}  # any UAV, 2.5 s before it would breach its clearance
    s = scenario_from_dict(d, name="t", base_dir=None)
    assert s.dynamics.events[0].trigger == Trigger(None, 0.0, 2.5)
    assert scenario_to_dict(s)["events"][0]["trigger"] == {"lead": 2.5}
    for bad, where in (({}, r"trigger\.within.*give within, lead or both"), ({"lead": -1.0}, r"trigger\.lead"),
                       ({"lead": 2.0, "soon": 1.0}, r"trigger\.soon")):
        d["events"][0]["trigger"] = bad
        with pytest.raises(ScenarioError, match=where):
            scenario_from_dict(d, name="t", base_dir=None)


def test_a_trigger_without_a_uav_watches_the_whole_team_by_distance_or_lead() -> None:
    """A pop-up of radius 2 m at the origin; UAVs of radius 1 m, required clearance 1 m (a reach
    of 2 m). UAV1 hovers 3 m from its outline; UAV2's reference comes at it at 4 m/s from
    10.5 m (within 2 m of the outline in 2.125 s), or from 9.5 m (1.875 s). A lead of 2 s
    holds for the second only; never for the hovering UAV1, nor for UAV2 when the trigger names
    UAV1. A distance of 3 m holds for UAV1 at once."""
    from staghunt.flight.sensor import Sensor
    from staghunt.world import Cylinder
    from staghunt.world.dynamic import Dynamics, Event, Trigger

    def appeared(trigger: Trigger, x2: float) -> bool:
        dyn = Dynamics(events=(Event(100.0, "appear", "p", Cylinder(0.0, 0.0, 2.0, "p"), trigger=trigger),))
        sensor = Sensor(dyn, ["UAV1", "UAV2"], np.random.default_rng(0), reach=[2.0, 2.0])
        pos = np.array([[5.0, 0.0, 10.0], [-2.0 - x2, 0.0, 10.0]])

        def course(times: np.ndarray) -> np.ndarray:  # (2, G, 3): UAV1 still, UAV2 at 4 m/s along x
            out = np.repeat(pos[:, None], times.size, axis=1)
            out[1, :, 0] += 4.0 * (times - 1.0)
            return out

        sensor.detect(1.0, pos, course)
        return sensor.appeared == {0: 1.0}

    assert not appeared(Trigger(None, lead=2.0), 10.5) and appeared(Trigger(None, lead=2.0), 9.5)
    assert not appeared(Trigger("UAV1", lead=2.0), 9.5) and appeared(Trigger("UAV2", lead=2.0), 9.5)
    assert appeared(Trigger("UAV1", within=3.0), 10.5) and not appeared(Trigger("UAV1", within=2.9), 10.5)


def test_round_trip_unset_desired_height() -> None:
    s = scenario_from_dict(valid(), name="t", base_dir=None)
    d = scenario_to_dict(s)
    assert d["costs"]["desired_height"] is None
    assert scenario_from_dict(d, name="t", base_dir=None).costs.desired_height is None


# ---------------------------------------------------------------------------------------------
# DEM ground
# ---------------------------------------------------------------------------------------------


def dem_dict(file: str, **ground: Any) -> dict[str, Any]:
    """A one-UAV scenario on a 6 x 8 DEM with the SPSO reference's convention (origin 1, cell 1)."""
    return {
        "site": {"xmin": 1.0, "xmax": 8.0, "ymin": 1.0, "ymax": 6.0, "hmin": 0.0, "hmax": 10.0},
        "ground": {"kind": "dem", "file": file, "origin": [1.0, 1.0], "cell_size": 1.0, **ground},
        "team": [
            {
                "name": "A",
                "start": [1.0, 1.0, 2.0],
                "goal": [7.5, 5.5, 3.0],
                "radius": 0.1,
                "beta": 1.0,
                "weights": [1.0, 1.0, 1.0, 1.0, 1.0],
            }
        ],
    }


def grid(dtype: Any = np.float64) -> np.ndarray:
    rows, cols = 6, 8
    return (np.arange(rows * cols).reshape(rows, cols) * 1.25 + 3.0).astype(dtype)


def matlab_round(v: float) -> int:
    return int(math.floor(abs(v) + 0.5) * (1 if v >= 0 else -1))


def test_dem_npy_nearest_matches_matlab(tmp_path: Path) -> None:
    H = grid()
    np.save(tmp_path / "dem.npy", H)
    s = scenario_from_dict(dem_dict("dem.npy"), name="dem", base_dir=tmp_path)
    t = s.world.terrain
    assert t.sampling == "nearest"
    assert t.elevation is not None and not t.elevation.flags.writeable
    assert t.elevation.dtype == np.float64
    for x, y in [(1.0, 1.0), (2.5, 1.0), (2.49, 3.5), (8.0, 6.0), (4.5, 4.5), (7.6, 2.2)]:
        expected = H[matlab_round(y) - 1, matlab_round(x) - 1]  # H(round(y), round(x)), 1-based
        assert t.height(np.array(x), np.array(y)) == expected, (x, y)
    # x = 2.5: MATLAB round(2.5) = 3 (1-based) -> column index 2 (Python's round would give 1)
    assert t.height(np.array(2.5), np.array(1.0)) == H[0, 2]
    # the default reference is the goal's absolute position
    gx, gy, gh = s.team[0].goal
    np.testing.assert_array_equal(s.formation.reference, [[gx, gy, gh + H[5, 7]]])


def test_dem_bilinear_at_cell_centre(tmp_path: Path) -> None:
    H = grid()
    np.save(tmp_path / "dem.npy", H)
    s = scenario_from_dict(dem_dict("dem.npy", sampling="bilinear"), name="d", base_dir=tmp_path)
    t = s.world.terrain
    for i, j in [(0, 0), (2, 3), (5, 7), (4, 1)]:
        x, y = 1.0 + j, 1.0 + i
        assert t.height(np.array(x), np.array(y)) == pytest.approx(H[i, j])


def test_dem_float32_kept(tmp_path: Path) -> None:
    np.save(tmp_path / "dem32.npy", grid(np.float32))
    np.save(tmp_path / "demint.npy", grid(np.int16))
    s32 = scenario_from_dict(dem_dict("dem32.npy"), name="d", base_dir=tmp_path)
    sint = scenario_from_dict(dem_dict("demint.npy"), name="d", base_dir=tmp_path)
    assert s32.world.terrain.elevation is not None
    assert s32.world.terrain.elevation.dtype == np.float32
    assert sint.world.terrain.elevation is not None
    assert sint.world.terrain.elevation.dtype == np.float64


def test_dem_from_toml_relative_path_and_round_trip(tmp_path: Path) -> None:
    sub = tmp_path / "maps"
    sub.mkdir()
    np.save(sub / "dem.npy", grid(np.float32))
    toml = tmp_path / "hill.toml"
    toml.write_text(
        """
[site]
xmin = 1.0
xmax = 8.0
ymin = 1.0
ymax = 6.0
hmin = 0.0
hmax = 10.0

[ground]
kind = "dem"
file = "maps/dem.npy"
origin = [1.0, 1.0]
cell_size = 1.0
sampling = "nearest"

[[team]]
name = "A"
start = [1.0, 1.0, 2.0]
goal = [7.0, 5.0, 3.0]
radius = 0.1
beta = 1.0
weights = [1.0, 1.0, 1.0, 1.0, 1.0]
"""
    )
    s = load_scenario(str(toml))
    assert s.name == "hill"
    d = scenario_to_dict(s)
    g = d["ground"]
    assert g["file"] == str((sub / "dem.npy").resolve())
    assert g["shape"] == [6, 8] and g["dtype"] == "float32"
    assert g["origin"] == [1.0, 1.0] and g["cell_size"] == 1.0 and g["sampling"] == "nearest"
    assert json.loads(json.dumps(d)) == d
    again = scenario_from_dict(d, name="x", base_dir=None)
    assert scenario_to_dict(again) == d
    # the recorded checksum guards against a changed file
    np.save(sub / "dem.npy", grid(np.float32) + 1)
    with pytest.raises(ScenarioError, match="ground.sha256"):
        scenario_from_dict(d, name="x", base_dir=None)


def test_dem_tiff(tmp_path: Path) -> None:
    tifffile = pytest.importorskip("tifffile")
    tifffile.imwrite(tmp_path / "dem.tif", grid(np.float32))
    s = scenario_from_dict(dem_dict("dem.tif"), name="d", base_dir=tmp_path)
    assert s.world.terrain.elevation is not None
    np.testing.assert_array_equal(s.world.terrain.elevation, grid(np.float32))
    assert s.world.terrain.elevation.dtype == np.float32


def test_dem_tiff_without_tifffile(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "dem.tif").write_bytes(b"II*\x00")
    monkeypatch.setitem(sys.modules, "tifffile", None)  # makes `import tifffile` fail
    with pytest.raises(ScenarioError, match=r"ground\.file: .*pip install staghunt\[geotiff\]"):
        scenario_from_dict(dem_dict("dem.tif"), name="d", base_dir=tmp_path)


def _dem_case(tmp_path: Path, array: np.ndarray, **ground: Any) -> str:
    np.save(tmp_path / "bad.npy", array)
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(dem_dict("bad.npy", **ground), name="d", base_dir=tmp_path)
    return str(info.value)


def test_dem_errors(tmp_path: Path) -> None:
    assert "ground.file" in _dem_case(tmp_path, np.zeros(48))  # 1-D
    bad = grid()
    bad[2, 3] = np.nan
    msg = _dem_case(tmp_path, bad)
    assert "ground.file" in msg and "row 2, column 3" in msg
    assert "ground.cell_size: must be > 0" in _dem_case(tmp_path, grid(), cell_size=0.0)
    assert "ground.cell_size" in _dem_case(tmp_path, grid(), cell_size=-1.0)
    assert "ground.sampling" in _dem_case(tmp_path, grid(), sampling="cubic")
    assert "ground.origin" in _dem_case(tmp_path, grid(), origin=[1.0])
    assert "ground.shape" in _dem_case(tmp_path, grid(), shape=[8, 6])
    assert "ground.unknown: unknown key" in _dem_case(tmp_path, grid(), unknown=1)
    # coverage: the grid is 6 x 8 cells centred at 1..8 x 1..6
    assert "ground: the DEM" in _dem_case(tmp_path, grid()[:, :6])  # x only up to 6.5
    assert "ground: the DEM" in _dem_case(tmp_path, grid(), origin=[1.6, 1.0])
    with pytest.raises(ScenarioError, match="ground.file: no such DEM file"):
        scenario_from_dict(dem_dict("missing.npy"), name="d", base_dir=tmp_path)
    with pytest.raises(ScenarioError, match="ground.file: unsupported DEM file type"):
        scenario_from_dict(dem_dict("dem.csv"), name="d", base_dir=tmp_path)


def test_dem_coverage_half_cell_rule(tmp_path: Path) -> None:
    np.save(tmp_path / "dem.npy", grid())
    # Nearest: cell centres may lie up to half a cell inside the site edge.
    scenario_from_dict(dem_dict("dem.npy", origin=[1.5, 1.5]), name="d", base_dir=tmp_path)
    # Bilinear: the cell centres themselves must cover the site.
    with pytest.raises(ScenarioError, match="ground: the DEM"):
        scenario_from_dict(
            dem_dict("dem.npy", origin=[1.5, 1.5], sampling="bilinear"), name="d", base_dir=tmp_path
        )
    scenario_from_dict(dem_dict("dem.npy", sampling="bilinear"), name="d", base_dir=tmp_path)


def test_validation_does_not_mutate_input() -> None:
    data = valid()
    before = copy.deepcopy(data)
    scenario_from_dict(data, name="t", base_dir=None)
    assert data == before
