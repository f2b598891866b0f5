"""Missions flown in simulation (``staghunt export --simulate``): ``trajectories.csv`` read back,
flown by rotorpy multirotors, judged against the plan's limits; a broken limit refuses the
export like an unsafe plan."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from staghunt.cli import main
from staghunt.flight import mission as fm_flight
from staghunt.flight.mission import judge_mission, read_trajectories_csv
from staghunt.missions import formats as fm
from staghunt.scenario import load_scenario


def test_trajectories_csv_reads_back_and_bad_files_are_refused():
    t = np.array([0.0, 0.1, 0.2])
    pos = np.arange(2 * 3 * 3, dtype=float).reshape(2, 3, 3)
    vel = -pos
    t2, p2, v2 = read_trajectories_csv(fm.trajectories_csv(t, pos, vel))
    np.testing.assert_allclose(t2, t)
    np.testing.assert_allclose(p2, pos)
    np.testing.assert_allclose(v2, vel)
    good = fm.trajectories_csv(t, pos, vel)
    for bad, match in ((good.replace("t,uav", "time,uav"), "header"),
                       (good.replace("0.100,2", "0.100,1"), "in order"),
                       (good.replace("0.200,1", "0.050,1").replace("0.200,2", "0.050,2"), "rise"),
                       (good.replace(",1.0000,", ",x,", 1), "number"),
                       (good.replace(",1.0000,", ",nan,", 1), "finite")):
        with pytest.raises(ValueError, match=match):
            read_trajectories_csv(bad)


def test_a_flight_is_judged_against_the_plans_limits():
    scenario = load_scenario("scenario2")
    open_world = replace(scenario, world=replace(scenario.world, cylinders=(), prisms=()))
    t = np.linspace(0.0, 1.0, 11)
    ref = np.zeros((3, 11, 3))
    ref[:, :, 2] = 20.0
    ref[1, :, 0] = 10.0
    ref[2, :, 0] = 20.0
    actual = ref.copy()
    actual[0, 5, 0] += 0.3  # a 0.3 m tracking error once
    f = judge_mission(open_world, t, actual, ref)
    assert f.tracking_max[0] == pytest.approx(0.3) and f.tracking_rms[0] == pytest.approx(0.3 / np.sqrt(11))
    assert f.tracking_max[1] == 0.0 and f.safe
    np.testing.assert_allclose(f.min_separation, [9.7, 9.7, 10.0])
    limit = scenario.costs.safe_distance + 2 * scenario.team[0].radius
    actual[1, 7, 0] = limit - 0.01  # UAV 2 flies into UAV 1's separation
    f = judge_mission(open_world, t, actual, ref)
    assert not f.safe and "UAV" in f.problems[0] and "team-mate" in f.problems[0]
    actual[1, 7, 0] = 10.0
    actual[2, 3, 2] = scenario.world.terrain.height(20.0, 0.0) - 0.5  # into the ground
    assert any("ground" in p for p in judge_mission(open_world, t, actual, ref).problems)
    # the obstacles of scenario 2: a UAV parked on the first cylinder's axis
    c = scenario.world.cylinders[0]
    actual[2, :, :2] = [c.x, c.y]
    ref[2, :, :2] = [c.x, c.y]
    f = judge_mission(scenario, t, actual, ref)
    assert f.min_clearance[2] == pytest.approx(-c.radius - scenario.team[2].radius)
    assert any("clearance" in p for p in f.problems)


def test_export_simulate_flies_the_mission_within_the_limits(planned, tmp_path, capsys):
    scenario, _, path = planned
    out = tmp_path / "m"
    code = main(["export", str(path), "--out", str(out), "--simulate", "--no-plots", "--formats", "trajectories"])
    assert code == 0, capsys.readouterr()
    summary = json.loads((out / "mission.json").read_text())
    flight = summary["flight"]
    assert flight["safe"] and flight["rate_hz"] == 100.0
    assert max(flight["tracking_rms_m"].values()) <= 0.3
    for name in flight["min_separation_m"]:
        assert flight["min_separation_m"][name] > flight["separation_limit_m"][name]
        assert flight["min_clearance_m"][name] >= flight["required_clearance_m"]
        # flown within a few centimetres of the planned (sampled) minima
        assert abs(flight["min_separation_m"][name] - summary["in_time"]["min_separation_m"][name]) < 0.3
    assert "in flight (simulated" in capsys.readouterr().out


def test_a_flight_that_breaks_a_limit_refuses_the_export(planned, tmp_path, monkeypatch, capsys):
    _, _, path = planned

    def crash(scenario, t, pos, vel, **kw):
        actual = pos.copy()
        actual[1] = actual[0] + 0.5  # UAV 2 on top of UAV 1
        return judge_mission(scenario, t, actual, pos)

    monkeypatch.setattr("staghunt.missions.export.fly_mission", crash)
    out = tmp_path / "m"
    assert main(["export", str(path), "--out", str(out), "--simulate", "--no-plots"]) == 3
    assert "in flight" in capsys.readouterr().err and not out.exists()
    assert main(["export", str(path), "--out", str(out), "--simulate", "--no-plots", "--force"]) == 0
    assert "in flight" in (out / "MISSION_UNSAFE.txt").read_text()
    assert json.loads((out / "mission.json").read_text())["flight"]["safe"] is False
    assert fm_flight.fly_mission is not crash  # the module itself is untouched
