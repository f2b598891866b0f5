"""The equilibrium certificate on cases whose answer is known, and ``staghunt certify``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from staghunt import plan
from staghunt.analysis.certify import (
    DEFAULT_EPSILON,
    certificate_table,
    certificate_to_dict,
    certify_on_engine,
    certify_result_file,
)
from staghunt.costs import CostModel, evaluate
from staghunt.io.result_json import write_result
from staghunt.scenario import load_scenario, scenario_from_dict

K = 4


def _uav(name, y, weights=(1.0, 1.0, 1.0, 1.0, 1.0)):
    return {"name": name, "start": [10.0, y, 20.0], "goal": [90.0, y, 20.0], "radius": 1.0,
            "beta": 1.0, "weights": list(weights)}


def _scenario(team, formation=None, obstacles=()):
    data = {
        "name": "known",
        "site": {"xmin": 0.0, "xmax": 100.0, "ymin": 0.0, "ymax": 100.0, "hmin": 5.0, "hmax": 35.0},
        "obstacles": [{"x": x, "y": y, "radius": r} for x, y, r in obstacles],
        "team": team,
        "costs": {"desired_height": 20.0},
        "solver": {"particles": 40, "iterations": 30, "waypoints": K},
    }
    if formation is not None:
        data["formation"] = formation
    return scenario_from_dict(data, name="known")


def _straight(y):
    """The optimum of a lone UAV flying along y = const at h_ref: K evenly spaced waypoints."""
    x = 10.0 + 80.0 * np.arange(1, K + 1) / (K + 1)
    return np.column_stack([x, np.full(K, y), np.full(K, 20.0)])


@pytest.fixture(scope="module")
def alone():
    return _scenario([_uav("solo", 50.0)])


@pytest.fixture(scope="module")
def pair():
    return _scenario(
        [_uav("A", 40.0), _uav("B", 60.0)],
        formation={"incidence": [[1], [-1]], "edge_weights": [[1.0], [1.0]]},
    )


def test_lone_uav_at_its_optimum_has_zero_gap(alone):
    wp = _straight(50.0)[None]
    J = evaluate(CostModel.from_scenario(alone), wp[None]).total[0, 0]
    assert J == pytest.approx(80.0)  # w1 * |G - S|: no turn, no climb, at h_ref
    cert = certify_on_engine(alone, wp, particles=40, iterations=30, seed=1)
    u = cert.uavs[0]
    assert u.current == J
    assert 0.0 <= u.gap <= 1e-9 * J
    assert u.roundtrip_error < 1e-12  # the warm start is the current path
    assert cert.is_equilibrium and cert.status == "equilibrium"
    assert cert.epsilon == DEFAULT_EPSILON == 0.01
    assert "epsilon-equilibrium with epsilon = 0.01" in cert.verdict


def test_perturbed_lone_uav_has_a_large_gap(alone):
    wp = _straight(50.0)
    wp[1, 1] += 15.0  # a 15 m detour at waypoint 2
    cert = certify_on_engine(alone, wp[None], particles=40, iterations=30, seed=1)
    u = cert.uavs[0]
    assert u.current > 200.0
    assert u.best < 0.6 * u.current  # the search finds most of the way back to 80
    assert u.gap == pytest.approx(u.current - u.best)
    assert u.relative > 0.4
    assert not cert.is_equilibrium and cert.status == "deviation"
    assert cert.worst == 0 and "solo would deviate" in cert.verdict
    # The deviation found is a path with that cost.
    model = CostModel.from_scenario(alone)
    assert evaluate(model, u.deviation[None, None]).total[0, 0] == pytest.approx(u.best, rel=1e-12)


def test_gap_is_never_negative_even_without_iterations(alone):
    wp = _straight(50.0)
    wp[2, 2] = 31.0
    for iterations in (0, 1):
        cert = certify_on_engine(alone, wp[None], particles=3, iterations=iterations, seed=5)
        assert cert.uavs[0].gap >= 0.0 and cert.uavs[0].best <= cert.uavs[0].current


def test_team_equilibrium_and_the_uav_that_would_deviate(pair):
    wp = np.stack([_straight(40.0), _straight(60.0)])
    cert = certify_on_engine(pair, wp, particles=40, iterations=30, seed=2)
    assert cert.is_equilibrium
    assert all(u.gap <= 1e-9 * u.current for u in cert.uavs)
    wp[1, 1, 1] += 10.0  # B leaves both its straight line and the formation at waypoint 2
    cert = certify_on_engine(pair, wp, particles=40, iterations=30, seed=2)
    a, b = cert.uavs
    assert not cert.is_equilibrium
    assert cert.worst == 1 and "B would deviate" in cert.verdict
    assert b.relative > 0.5
    assert 0.0 <= a.relative < b.relative  # A would follow B a little, B would go back


def test_certificate_is_seeded(pair):
    wp = np.stack([_straight(40.0), _straight(60.0)])
    wp[0, 2, 0] += 6.0
    one = certify_on_engine(pair, wp, particles=15, iterations=5, seed=9)
    two = certify_on_engine(pair, wp, particles=15, iterations=5, seed=9)
    assert certificate_to_dict(one) == certificate_to_dict(two)


def test_infeasible_plan_gets_no_certificate():
    sc = _scenario([_uav("solo", 50.0)], obstacles=[(50.0, 50.0, 4.0)])
    cert = certify_on_engine(sc, _straight(50.0)[None], particles=5, iterations=2)
    assert cert.status == "infeasible" and not cert.is_equilibrium
    assert math.isinf(cert.uavs[0].gap) and cert.uavs[0].best is None
    assert "infeasible plan" in cert.verdict
    data = certificate_to_dict(cert)
    json.dumps(data, allow_nan=False)  # strict JSON
    assert data["uavs"][0]["gap"] == "inf"
    assert "inf" in certificate_table(cert)


def test_bad_inputs_are_value_errors(alone):
    with pytest.raises(ValueError, match="shape"):
        certify_on_engine(alone, np.zeros((2, K, 3)))
    with pytest.raises(ValueError, match="epsilon"):
        certify_on_engine(alone, _straight(50.0)[None], epsilon=-1.0)
    with pytest.raises(ValueError, match="particles"):
        certify_on_engine(alone, _straight(50.0)[None], particles=0)


# ------------------------------------------------------------------------------------------------
# From result.json, and the command line
# ------------------------------------------------------------------------------------------------


def run_cli(argv: list[str]) -> int:
    """``staghunt`` in-process."""
    from staghunt import cli

    return cli.main(argv)


@pytest.fixture(scope="module")
def result_file(tmp_path_factory):
    scenario = load_scenario("scenario2")
    r = plan(scenario, "paper", 4, scenario.solver.with_(particles=12, iterations=3, waypoints=6),
             engine="numpy")
    path = tmp_path_factory.mktemp("certify") / "result.json"
    write_result(r, path)
    return path, r


def test_certify_result_file_reads_the_plan_back(result_file):
    path, r = result_file
    cert, data = certify_result_file(str(path), particles=8, iterations=3, seed=1)
    assert [u.current for u in cert.uavs] == list(r.costs.total[0])
    assert cert.notes == ()  # exact round trip of the warm starts, stored costs agree
    assert data["method"] == "paper"


def test_cli_certify(result_file, tmp_path, capsys):
    path, _ = result_file
    out = tmp_path / "cert.json"
    code = run_cli(["certify", str(path), "--particles", "8", "--iterations", "3", "--quiet",
                    "--out", str(out), "--epsilon", "100%"])
    text = capsys.readouterr().out
    assert "verdict:" in text and "UAV1" in text
    data = json.loads(out.read_text())
    # With epsilon = 100 %, any finite gap passes.
    assert code == 0 and data["status"] == "equilibrium" and data["epsilon"] == 1.0
    code = run_cli(["certify", str(path), "--particles", "8", "--iterations", "3", "--quiet",
                    "--epsilon", "0"])
    assert code in (0, 3)
    assert code == (0 if "epsilon-equilibrium with" in capsys.readouterr().out else 3)


@pytest.mark.parametrize(
    "argv",
    [
        ["certify", "no/such/result.json"],
        ["certify", "RESULT", "--particles", "0"],
        ["certify", "RESULT", "--epsilon", "abc"],
        ["certify", "RESULT", "--epsilon", "-1"],
        ["certify", "NOTRESULT"],
    ],
)
def test_cli_certify_bad_input(argv, result_file, tmp_path, capsys):
    path, _ = result_file
    bogus = tmp_path / "bogus.json"
    bogus.write_text('{"format": "something else"}')
    argv = [str(path) if a == "RESULT" else str(bogus) if a == "NOTRESULT" else a for a in argv]
    assert run_cli(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("staghunt: error: ") and err.count("\n") == 1 and "Traceback" not in err


def test_check_certify_returns_a_checked_request_run_as_is(alone):
    from staghunt.solvers.base import RequestError
    from staghunt.solvers.response import CertifyOptions, CertifyRequest, check_certify
    from staghunt.solvers.response import certify_plan as run_request

    request = check_certify(alone, _straight(50.0)[None], CertifyOptions(particles=5, iterations=2), seed=3)
    assert isinstance(request, CertifyRequest) and not request.waypoints.flags.writeable
    assert (request.settings.particles, request.settings.iterations, request.settings.waypoints) == (5, 2, K)
    cert = run_request(request)
    assert (cert.particles, cert.iterations, cert.seed) == (5, 2, 3)
    for options, settings, field in ((CertifyOptions(particles=0), None, "certify"),
                                     (CertifyOptions(), alone.solver.with_(c1=0.0, c2=0.0), "certify"),
                                     (CertifyOptions(), alone.solver.with_(velocity_fraction=0.0), "settings")):
        with pytest.raises(RequestError) as info:
            check_certify(alone, _straight(50.0)[None], options, settings=settings)
        assert info.value.field == field
        assert "--" not in str(info.value)  # the library never names flags


def test_a_carried_search_stands_for_the_uav_that_flies_its_reply(pair):
    """After a certificate round adopts B's better reply (only B moved), the next certificate
    keeps B's search: gap 0 from that search, no evaluation spent, a note; A is searched
    again, exactly as a fresh certificate searches it."""
    from staghunt.solvers.response import CertifyOptions, certify_plan, check_certify

    budget = CertifyOptions(particles=40, iterations=30)
    wp = np.stack([_straight(40.0), _straight(60.0)])
    wp[1, 1, 1] += 10.0
    first = certify_plan(check_certify(pair, wp, budget, seed=2))
    b = first.uavs[1]
    assert b.relative > 0.5
    moved = wp.copy()
    moved[1] = b.deviation
    again = certify_plan(check_certify(pair, moved, budget, seed=3), carried={1: b})
    fresh = certify_plan(check_certify(pair, moved, budget, seed=3))
    J = evaluate(CostModel.from_scenario(pair), moved[None]).total[0]
    kept = again.uavs[1]
    assert kept.current == J[1] and kept.evaluations == 0
    assert kept.best == min(b.best, J[1]) and 0.0 <= kept.gap <= 1e-9 * J[1]
    assert np.array_equal(kept.deviation, moved[1])
    assert any("B: the others' paths are those of the previous search" in n for n in again.notes)
    assert again.uavs[0].gap == fresh.uavs[0].gap and again.uavs[0].evaluations == fresh.uavs[0].evaluations > 0
