"""result.json: strict JSON, "inf" for infinity, every field with the right shape, atomic writes."""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest

import staghunt
from staghunt.api import assemble
from staghunt.costs import TERM_NAMES
from staghunt.io import read_result, result_to_dict, write_result
from staghunt.io import result_json
from staghunt.scenario import load_scenario

PARTICLES, ITERATIONS, K = 20, 5, 4


def _strict_loads(text: str):
    def reject(token: str):
        raise AssertionError(f"non-standard JSON constant {token!r} in result.json")

    return json.loads(text, parse_constant=reject)


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("scenario1")


@pytest.fixture(scope="module")
def settings(scenario):
    return scenario.solver.with_(particles=PARTICLES, iterations=ITERATIONS, waypoints=K)


@pytest.fixture(scope="module", params=["game", "rigid"])
def result(request, scenario, settings):
    return staghunt.plan(scenario, request.param, seed=1, settings=settings)


def straight_waypoints(scenario, k: int) -> np.ndarray:
    """``(N, k, 3)`` waypoints on the straight start-goal lines (through the obstacles)."""
    s, g = scenario.starts(), scenario.goals()
    t = np.arange(1, k + 1) / (k + 1)
    return s[:, None, :] + t[None, :, None] * (g - s)[:, None, :]


@pytest.fixture(scope="module")
def infeasible_result(scenario, settings):
    wp = straight_waypoints(scenario, K)
    n = scenario.n_uavs
    history = np.array([[np.inf] * n, [1.0, 2.0, np.inf]])
    return assemble(scenario, "game", 0, settings.with_(iterations=1), wp, history, history, 6, 0.5)


def test_strict_json_and_fields(result, tmp_path, settings):
    path = write_result(result, tmp_path / "result.json")
    data = _strict_loads(path.read_text(encoding="utf-8"))
    n = result.scenario.n_uavs
    for key in ("method", "seed", "status", "message", "wall_time_s", "evaluations", "version",
                "scenario", "settings", "uavs", "metrics", "objective_history", "notes"):
        assert key in data, key
    assert data["version"] == staghunt.__version__
    assert data["method"] == result.method and data["seed"] == 1
    assert data["status"] in ("feasible", "infeasible") and data["status"] == result.status.value
    assert data["evaluations"] == result.evaluations > 0
    assert '"inf"' in data["notes"]["infinity"]
    assert data["settings"] == {
        "particles": PARTICLES, "iterations": ITERATIONS, "waypoints": K, "c0": settings.c0,
        "damping": settings.damping, "c1": settings.c1, "c2": settings.c2,
        "velocity_fraction": settings.velocity_fraction, "starts": settings.starts,
    }
    assert data["scenario"]["name"] == "scenario1"
    assert len(data["scenario"]["team"]) == n
    assert len(data["objective_history"]) == ITERATIONS + 1
    top = data["metrics"]
    for key in ("collision_free_waypoints", "collision_free_continuous", "obstacle_free"):
        assert isinstance(top[key], bool)
    for key in ("min_separation_waypoints", "min_separation_segments", "min_clearance"):
        assert isinstance(top[key], float)
    assert len(data["uavs"]) == n
    for u, name in zip(data["uavs"], result.uav_names):
        assert u["name"] == name
        assert np.array(u["path"]).shape == (K + 2, 3)
        assert np.array(u["heights"]).shape == (K + 2,)
        assert len(u["history"]) == ITERATIONS + 1
        assert set(u["cost"]) == {"total", "single", "formation", "terms", "weighted_terms"}
        assert list(u["cost"]["terms"]) == list(TERM_NAMES)
        assert list(u["cost"]["weighted_terms"]) == list(TERM_NAMES)
        m = u["metrics"]
        assert len(m["formation_error"]) == K
        for key in ("path_length", "min_clearance", "min_separation_waypoints",
                    "min_separation_segments", "separation_limit", "formation_rms", "min_height"):
            assert isinstance(m[key], float), key
    assert ("leader_path" in data) == (result.method == "rigid")
    if result.method == "rigid":
        assert np.array(data["leader_path"]).shape == (K + 2, 3)


def test_values_round_trip_exactly(result, tmp_path):
    path = write_result(result, tmp_path / "result.json")
    data = read_result(path)
    np.testing.assert_array_equal(np.array([u["path"] for u in data["uavs"]]), result.paths)
    np.testing.assert_array_equal(np.array([u["heights"] for u in data["uavs"]]), result.heights)
    np.testing.assert_array_equal(np.array([u["history"] for u in data["uavs"]]).T, result.history)
    np.testing.assert_array_equal(np.array(data["objective_history"]), result.objective_history)
    for n, u in enumerate(data["uavs"]):
        assert u["cost"]["total"] == result.costs.total[0, n]
        assert u["cost"]["single"] == result.costs.single[0, n]
        assert u["cost"]["formation"] == result.costs.formation[0, n]
        w = result.scenario.team[n].weights.as_array()
        for i, name in enumerate(TERM_NAMES):
            assert u["cost"]["terms"][name] == result.costs.terms[0, n, i]
            assert u["cost"]["weighted_terms"][name] == w[i] * result.costs.terms[0, n, i]
        assert u["metrics"]["formation_error"] == result.metrics.formation_error[n].tolist()


def test_output_is_deterministic(result):
    a = json.dumps(result_to_dict(result), allow_nan=False)
    b = json.dumps(result_to_dict(result), allow_nan=False)
    assert a == b


def test_infinity_is_the_string_inf(infeasible_result, tmp_path):
    assert infeasible_result.status.value == "infeasible"
    path = write_result(infeasible_result, tmp_path / "result.json")
    text = path.read_text(encoding="utf-8")
    data = _strict_loads(text)  # fails on a bare NaN or Infinity token
    assert data["status"] == "infeasible" and data["message"].startswith("infeasible")
    assert data["violations"]
    totals = [u["cost"]["total"] for u in data["uavs"]]
    assert "inf" in totals
    threats = [u["cost"]["terms"]["threat"] for u in data["uavs"]]
    assert "inf" in threats
    assert data["uavs"][0]["history"][0] == "inf"
    assert data["objective_history"][0] == ["inf", "inf", "inf"]
    # read_result decodes the numeric fields back to float infinity.
    back = read_result(path)
    assert back["uavs"][0]["history"][0] == math.inf
    assert math.inf in [u["cost"]["total"] for u in back["uavs"]]
    assert back["objective_history"][1] == [1.0, 2.0, math.inf]
    assert read_result(path, decode_inf=False)["uavs"][0]["history"][0] == "inf"


def test_zero_weight_times_inf_is_zero():
    w = np.array([0.0, 2.0, 0.0])
    t = np.array([np.inf, np.inf, 3.0])
    out = result_json.weighted_terms(w, t)
    assert out.tolist() == [0.0, math.inf, 0.0]


def test_nan_raises_and_writes_nothing(scenario, settings, tmp_path):
    wp = straight_waypoints(scenario, K)
    history = np.array([[1.0, np.nan, 3.0]])
    bad = assemble(scenario, "game", 0, settings.with_(iterations=0), wp, history, history, 3, 0.1)
    with pytest.raises(ValueError, match="NaN"):
        result_to_dict(bad)
    dest = tmp_path / "result.json"
    with pytest.raises(ValueError, match="NaN"):
        write_result(bad, dest)
    assert list(tmp_path.iterdir()) == []


def test_failed_serialisation_leaves_no_file(result, tmp_path, monkeypatch):
    def boom(*args, **kwargs):
        raise RuntimeError("serialisation failed")

    monkeypatch.setattr(json, "dumps", boom)
    with pytest.raises(RuntimeError):
        write_result(result, tmp_path / "result.json")
    assert list(tmp_path.iterdir()) == []


def test_failed_replace_removes_temp_and_keeps_old_file(result, tmp_path, monkeypatch):
    dest = tmp_path / "result.json"
    dest.write_text("old", encoding="utf-8")

    def boom(src, dst):
        raise OSError("disk on fire")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError):
        write_result(result, dest)
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]
    assert dest.read_text(encoding="utf-8") == "old"


def test_interrupted_write_removes_temp(result, tmp_path, monkeypatch):
    def interrupt(fd):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "fsync", interrupt)
    with pytest.raises(KeyboardInterrupt):
        write_result(result, tmp_path / "result.json")
    assert list(tmp_path.iterdir()) == []


def test_write_replaces_and_leaves_no_temp(result, tmp_path):
    dest = tmp_path / "result.json"
    dest.write_text("old", encoding="utf-8")
    write_result(result, dest)
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]
    assert _strict_loads(dest.read_text(encoding="utf-8"))["method"] == result.method


def test_new_file_gets_ordinary_permissions(result, tmp_path):
    dest = write_result(result, tmp_path / "result.json")
    umask = os.umask(0)
    os.umask(umask)
    assert dest.stat().st_mode & 0o777 == 0o666 & ~umask


def test_read_result_rejects_non_results(tmp_path):
    p = tmp_path / "x.json"
    p.write_text('{"a": 1}', encoding="utf-8")
    with pytest.raises(ValueError, match="not a staghunt result"):
        read_result(p)
    p.write_text('{"a": NaN}', encoding="utf-8")
    with pytest.raises(ValueError, match="NaN"):
        read_result(p)
    with pytest.raises(ValueError, match="no such file"):
        read_result(tmp_path / "missing.json")
