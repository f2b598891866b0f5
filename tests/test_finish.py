"""The end of ``game``'s search with several starts (docs/model.md section 6.1, step 4): the team
shift that takes a route down to the lower edge of its family, the repair that adopts a failed
certificate's better replies, and no certificate for a plan that a certified one dominates."""

from __future__ import annotations

import numpy as np
import pytest

from staghunt import plan
from staghunt.costs import CostModel, evaluate
from staghunt.engine import get_engine
from staghunt.scenario import load_scenario
from staghunt.solvers.finish import POWELL_PLANS, adopt_replies, finish
from staghunt.solvers.response import Certificate, CertifyOptions, UAVGap
from staghunt.solvers.rigid import formation_offsets
from staghunt.solvers.selection import Candidate
from staghunt.solvers.team_search import shift_moves, team_polish, team_powell, team_refine, team_shift


@pytest.fixture(scope="module")
def case():
    """Scenario 1 and a weak rigid plan (100 particles x 40 iterations, seed 3) whose waypoints
    3-6 are raised 1.5 m for every UAV: in formation, but with two climb bends."""
    scenario = load_scenario("scenario1")
    model = CostModel.from_scenario(scenario)
    rigid = plan(scenario, "rigid", 3, scenario.solver.with_(particles=100, iterations=40), engine="numba",
                 certify=None)
    wiggled = rigid.waypoints.copy()
    wiggled[:, 3:7, 2] += 1.5
    return scenario, model, wiggled


def _in_formation(model: CostModel, plan_: np.ndarray) -> bool:
    route = plan_ - formation_offsets(model)[:, None]
    return bool(np.allclose(route, route.mean(axis=0)[None], atol=1e-9))


def test_shift_moves_every_block_of_consecutive_waypoints_along_each_axis():
    moves = shift_moves(4)
    assert moves.shape == (3 * 4 * 5, 1, 4, 3)
    # Each move is +-1 on one axis over one contiguous block, and every block appears.
    blocks = set()
    for m in moves[:, 0]:
        rows, axes = np.nonzero(m)
        assert len(set(axes)) == 1 and np.all(np.diff(rows) == 1) and len(set(m[rows, axes])) == 1
        blocks.add((rows.min(), rows.max() + 1, axes[0], m[rows[0], axes[0]]))
    assert len(blocks) == len(moves) == 2 * 3 * (4 * 5 // 2)


def test_team_shift_goes_below_the_polish_and_keeps_the_formation(case):
    _, model, wiggled = case
    engine = get_engine("numba", threads=1)
    J0 = evaluate(model, wiggled[None]).total[0]
    polished, _ = team_polish(model, wiggled, 200_000, engine)
    shifted, spent = team_shift(model, wiggled, 200_000, engine)
    Jp, Js = evaluate(model, polished[None]).total[0], evaluate(model, shifted[None]).total[0]
    assert np.all(Js <= J0) and np.all(Js < 0.99 * J0)  # no UAV worse off; here all better by > 1 %
    assert np.all(Js < Jp)  # the one-waypoint polish stops above it, for every UAV
    assert _in_formation(model, wiggled) and _in_formation(model, shifted)
    assert 0 < spent <= 200_000 and spent % (model.n_uavs * len(shift_moves(wiggled.shape[1]))) == model.n_uavs
    # Too small a budget for one sweep: nothing moves, nothing is spent.
    assert team_shift(model, wiggled, model.n_uavs * len(shift_moves(wiggled.shape[1])), engine) == (wiggled, 0)


def test_team_powell_goes_below_the_pattern_searches_without_making_any_uav_worse():
    """Scenario 1's rigid plan (200 particles x 100 iterations, seed 2) after slide, polish and
    block shifts: followers at 203.8, above the family's lower edge of 202. Powell's descent
    lowers every UAV's cost (the followers' by more than 0.5 %); it is deterministic, keeps within
    its budget and returns the plan itself when it cannot move."""
    scenario = load_scenario("scenario1")
    model = CostModel.from_scenario(scenario)
    engine = get_engine("numba", threads=1)
    rigid = plan(scenario, "rigid", 2, scenario.solver.with_(particles=200, iterations=100), engine="numba",
                 certify=None)
    refined, _ = team_refine(model, rigid.waypoints, 200_000, 1_000_000, engine)
    Jr = evaluate(model, refined[None]).total[0]
    descended, spent = team_powell(model, refined, 30_000, engine)
    Jd = evaluate(model, descended[None]).total[0]
    assert evaluate(model, descended[None]).total_violation[0] == 0
    assert np.all(Jd < Jr) and np.all(Jd[1:] < 0.995 * Jr[1:])  # every UAV better, none worse
    assert 0 < spent <= 30_000 and spent % model.n_uavs == 0
    again, spent_again = team_powell(model, refined, 30_000, engine)
    assert np.array_equal(again, descended) and spent_again == spent
    # Too small a budget to evaluate anything but the plan: nothing moves.
    assert team_powell(model, refined, model.n_uavs, engine) == (refined, 0)


def test_the_finish_makes_the_powell_descent_only_with_twice_its_plans_left():
    """The finish polishes the selected plan by team refine and then, if at least twice
    :data:`POWELL_PLANS` plans are left of the run's budget, by Powell's descent of its route."""
    scenario = load_scenario("scenario1")
    model = CostModel.from_scenario(scenario)
    engine = get_engine("numba", threads=1)
    rigid = plan(scenario, "rigid", 2, scenario.solver.with_(particles=200, iterations=100), engine="numba",
                 certify=None)
    J = evaluate(model, rigid.waypoints[None]).total[0]
    powell = POWELL_PLANS * model.n_uavs
    for left in (2 * powell, 1_000_000):  # the refine spends some first: then too little is left, or enough
        candidates = [Candidate("rigid", rigid.waypoints, J, 0.0, None, 0)]
        spent = finish(model, candidates, lambda _: None, engine, 200_000, left, 0.01)
        assert len(candidates) == 2 and candidates[1].start == "rigid (polished)" and spent <= left
        refined, used = team_refine(model, rigid.waypoints, 200_000, left, engine)
        J_refined = evaluate(model, refined[None]).total[0]
        if left - used < 2 * powell:
            assert spent == used and np.allclose(candidates[1].J, J_refined, rtol=1e-12)
        else:
            assert spent > used and np.all(candidates[1].J < J_refined)  # every UAV lower


def _certificate(J: np.ndarray, gaps: list[float], deviations: list[np.ndarray | None]) -> Certificate:
    uavs = tuple(UAVGap(f"U{n}", float(J[n]), float(J[n]) * (1 - g), float(J[n]) * g, g, d, 0.0, 1)
                 for n, (g, d) in enumerate(zip(gaps, deviations)))
    return Certificate(uavs, 0.01, True, 1, 1, 0)


def test_adopt_replies_takes_the_gains_beyond_epsilon_and_nothing_else(case):
    _, model, wiggled = case
    engine = get_engine("numba", threads=1)
    shifted, _ = team_shift(model, wiggled, 200_000, engine)
    # UAV 2 off the formation by 0.5 m; its better reply is its path in the shifted plan.
    off = shifted.copy()
    off[2, :, 0] += 0.5
    J = evaluate(model, off[None]).total[0]
    assert evaluate(model, shifted[None]).total[0][2] < 0.99 * J[2]
    cert = _certificate(J, [0.0, 0.0, 0.05], [None, None, shifted[2]])
    adopted, taken, spent = adopt_replies(model, off, cert, engine)
    assert adopted is not None and np.array_equal(adopted, shifted) and taken == 1 and spent == 2 * model.n_uavs
    # A gap within epsilon is no reason to move; a reply that does not gain beyond it is not kept.
    assert adopt_replies(model, off, _certificate(J, [0.0, 0.0, 0.005], [None, None, shifted[2]]), engine)[0] is None
    assert adopt_replies(model, off, _certificate(J, [0.05, 0.0, 0.0], [off[0], None, None]), engine)[0] is None


def test_a_plan_that_a_certified_candidate_dominates_is_not_certified():
    """With several starts, a candidate that a certified one dominates can be neither selected nor
    needed to judge payoff dominance: it gets no certificate (it would cost one for nothing)."""
    scenario = load_scenario("scenario1")
    settings = scenario.solver.with_(particles=200, iterations=100, starts=4)
    r = plan(scenario, "game", 25, settings, engine="numba", certify=CertifyOptions(particles=60, iterations=30))
    cands = r.details["candidates"]
    skipped = 0
    for i, c in enumerate(cands):
        earlier = [d for d in cands[:i] if d["certificate"] is not None and d["certificate"]["status"] == "equilibrium"]
        beaten = any(np.all(np.array(d["J"]) <= c["J"]) and np.any(np.array(d["J"]) < c["J"]) for d in earlier)
        if c["feasible"] and beaten:
            assert c["certificate"] is None
            skipped += 1
        elif c["feasible"]:
            assert c["certificate"] is not None
    assert skipped >= 1, "the case should have a dominated candidate (seed 25: the independent and random starts)"


def test_the_plan_that_failed_its_certificate_is_repaired_into_an_equilibrium():
    """Scenario 1 at 200 x 100, four starts, seed 1: no start ends certified, nor the polished
    selection; with its better replies adopted and a team refine, the polished plan passes, and
    it is the selected plan ("weighted (polished) (repaired)")."""
    scenario = load_scenario("scenario1")
    settings = scenario.solver.with_(particles=200, iterations=100, starts=4)
    r = plan(scenario, "game", 1, settings, engine="numba", certify=CertifyOptions(particles=60, iterations=30))
    cands = r.details["candidates"]
    assert all(c["certificate"]["status"] == "deviation" for c in cands[:-1])
    repaired = cands[-1]
    assert repaired["start"] == "weighted (polished) (repaired)" and repaired["feasible"]
    assert repaired["certificate"]["status"] == "equilibrium" and repaired["certificate"]["max_relative_gap"] <= 0.01
    assert r.details["selection"]["selected_start"] == repaired["start"] and r.certificate.is_equilibrium
    assert np.allclose(r.costs.total[0], repaired["J"], rtol=1e-12)
