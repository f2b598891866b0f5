"""The default ``game`` method (best responses to an equilibrium) and its parts: the potential,
the formation target, the polish, the deviation problem's own violation, the certificate in
every plan."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from staghunt import plan
from staghunt.costs import CostModel, evaluate
from staghunt.scenario import load_scenario
from staghunt.solvers.dominance import dominates
from staghunt.solvers.game import SLIDE_FRACTIONS, formation_target, polish, team_slide
from staghunt.solvers.problem import solo_problem
from staghunt.solvers.response import CertifyOptions, certify_plan, check_certify


@pytest.fixture(scope="module")
def scenario1():
    return load_scenario("scenario1")


@pytest.fixture(scope="module")
def model1(scenario1):
    return CostModel.from_scenario(scenario1)


@pytest.fixture(scope="module")
def reduced(scenario1):
    """A reduced, fast case: scenario 1 at 500 particles x 300 iterations, seed 1, the compiled
    engine; the default method and the rigid baseline on the same seed and budget."""
    settings = scenario1.solver.with_(particles=500, iterations=300)
    cert = CertifyOptions(particles=400, iterations=200)
    game = plan(scenario1, "game", 1, settings, engine="numba", certify=cert)
    rigid = plan(scenario1, "rigid", 1, settings, engine="numba", certify=cert)
    return settings, game, rigid


def _potential(model: CostModel, waypoints: np.ndarray) -> float:
    """docs/model.md eq. (17): sum_n J_s,n / beta_n + 1/2 sum_n J_f,n."""
    c = evaluate(model, waypoints[None])
    return float(np.sum(c.single[0] / model.beta) + 0.5 * np.sum(c.formation[0]))


def _random_plan(model: CostModel, rng: np.random.Generator, K: int = 6) -> np.ndarray:
    """Free waypoints near the straight lines, well clear of the scenario-1 cylinders' insides
    (costs finite is not required: the identity holds term by term)."""
    t = (np.arange(1, K + 1) / (K + 1))[None, :, None]
    straight = model.starts[:, None, :] + t * (model.goals - model.starts)[:, None, :]
    return straight + rng.normal(0.0, 3.0, straight.shape) * np.array([1.0, 1.0, 0.3])


def test_the_paper_game_is_a_weighted_potential_game(model1):
    """A change of UAV n's path alone changes Phi by Delta J_n / beta_n (eq. 17)."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = _random_plan(model1, rng)
        n = int(rng.integers(model1.n_uavs))
        b = a.copy()
        b[n] = _random_plan(model1, rng)[n]
        ja = evaluate(model1, a[None]).total[0]
        jb = evaluate(model1, b[None]).total[0]
        if not (np.isfinite(ja[n]) and np.isfinite(jb[n])):
            continue
        dphi = _potential(model1, b) - _potential(model1, a)
        assert dphi == pytest.approx((jb[n] - ja[n]) / model1.beta[n], rel=1e-9, abs=1e-6)


def test_formation_target_zeroes_the_uavs_own_formation_error(model1):
    rng = np.random.default_rng(1)
    plan_ = _random_plan(model1, rng)
    for n in range(model1.n_uavs):
        moved = plan_.copy()
        moved[n] = formation_target(model1, plan_, n)
        before = evaluate(model1, plan_[None]).formation[0, n]
        after = evaluate(model1, moved[None]).formation[0, n]
        # its edges pull towards two different team-mates, so the error is minimised, not 0:
        assert after <= before
        # with the others in formation around UAV 1, the target is exact
    team = np.repeat(plan_[:1], 3, axis=0) + (model1.reference - model1.reference[0])[:, None, :]
    for n in (1, 2):
        np.testing.assert_allclose(formation_target(model1, team, n), team[n], atol=1e-9)


def test_polish_never_worsens_and_stays_feasible(model1, reduced):
    _, game, _ = reduced
    wp = np.array(game.waypoints)
    wp[1] = wp[1] + np.array([0.7, -0.6, 0.4])  # off its best response
    before = evaluate(model1, wp[None])
    assert before.total_violation[0] == 0
    out, spent = polish(model1, wp, 1, 3000)
    after = evaluate(model1, out[None])
    assert 0 < spent <= 3000
    assert after.total_violation[0] == 0
    assert after.total[0, 1] < before.total[0, 1]
    np.testing.assert_array_equal(out[[0, 2]], wp[[0, 2]])  # the others did not move


def test_deviation_problem_judges_the_deviating_uav_only(model1):
    """Fixed team-mates that violate a constraint among themselves do not make a deviation of
    another UAV infeasible (docs/model.md eq. (19))."""
    t = (np.arange(1, 7) / 7)[None, :, None]
    team = model1.starts[:, None, :] + t * (model1.goals - model1.starts)[:, None, :]
    team[2] = team[0] + np.array([0.5, 0.0, 0.0])  # UAV 3 on top of UAV 1: they collide
    problem = solo_problem(model1, team, 1, 0.5)
    X = problem.space.sample(np.random.default_rng(3), 40, 6)
    cost, viol, J = problem.evaluate(X)
    full = evaluate(model1, problem.team_waypoints(X))
    assert np.all(full.total_violation > 0)  # the team as a whole is infeasible
    np.testing.assert_allclose(viol, full.violation[:, 1].sum(axis=1), rtol=1e-12)
    assert np.any(viol == 0)  # yet some deviations of UAV 2 are feasible for UAV 2
    assert np.all(np.isnan(J[:, [0, 2]])) and np.array_equal(cost[:, 0], full.total[:, 1])


def test_default_method_returns_an_equilibrium_that_rigid_does_not_dominate(reduced):
    settings, game, rigid = reduced
    assert game.method == "game" and game.feasible, game.message
    assert game.evaluations <= settings.particles * (settings.iterations + 1) * 3
    c = game.certificate
    assert c is not None and c.particles == 400 and c.iterations == 200
    assert c.is_equilibrium, c.verdict
    swarm = 400 * 201  # then two local searches of at most a quarter of that each
    assert all(swarm <= u.evaluations <= swarm + 2 * (swarm // 4) for u in c.uavs)
    assert not dominates(rigid.costs.total[0], rigid.costs.total_violation[0],
                         game.costs.total[0], game.costs.total_violation[0])
    d = game.details
    assert d["seed"] == "rigid" and d["rounds"] and all(len(r["relative_gains"]) == 3 for r in d["rounds"])
    # Every accepted reply, and only those, shows as a positive gain in its round (a reply's, or
    # the local search's made before a certificate).
    assert d["accepted_replies"] == sum(g > 0 for r in d["rounds"]
                                        for g in r["relative_gains"] + r.get("local_check_gains", []))
    assert isinstance(d["converged"], bool)


def test_certificate_is_near_zero_on_the_equilibrium_and_large_when_perturbed(scenario1, reduced):
    settings, game, _ = reduced
    budget = CertifyOptions(particles=200, iterations=60)
    again = certify_plan(check_certify(scenario1, game.waypoints, budget, seed=5, settings=settings))
    assert again.max_relative_gap < 0.01
    wp = np.array(game.waypoints)
    wp[2, 3:7, 2] += 6.0  # UAV 3 climbs 6 m out of the formation mid-way
    bad = certify_plan(check_certify(scenario1, wp, budget, seed=5, settings=settings))
    assert bad.feasible and not bad.is_equilibrium
    assert bad.uavs[2].relative > 10 * budget.epsilon and bad.worst == 2  # far outside the tolerance


def test_same_seed_same_plan_and_certificate(scenario1):
    settings = scenario1.solver.with_(particles=40, iterations=20, waypoints=5)
    cert = CertifyOptions(particles=20, iterations=5)
    a = plan(scenario1, "game", 3, settings, engine="numpy", certify=cert)
    b = plan(scenario1, "game", 3, settings, engine="numpy", certify=cert)
    np.testing.assert_array_equal(a.waypoints, b.waypoints)
    assert [u.gap for u in a.certificate.uavs] == [u.gap for u in b.certificate.uavs]
    assert a.details == b.details


def test_certificate_refuses_settings_that_disable_the_search(scenario1, reduced):
    _, game, _ = reduced
    for bad in (dict(velocity_fraction=0.0), dict(c1=0.0, c2=0.0), dict(c0="1")):
        with pytest.raises(ValueError, match="certificate settings"):
            check_certify(scenario1, game.waypoints, CertifyOptions(particles=10, iterations=5),
                          settings=scenario1.solver.with_(**bad))


def test_certificate_is_the_same_with_its_searches_side_by_side(scenario1, reduced):
    """Certificate searches run concurrently (the UAVs' swarms and local searches as separate
    tasks, one compiled thread each) give the very same certificate as one after the other
    (each UAV's search has its own seed), evaluations included, on two or three workers."""
    from staghunt.engine import get_engine

    _, game, _ = reduced
    engine = get_engine("numba", threads=1)
    request = check_certify(scenario1, game.waypoints, CertifyOptions(particles=60, iterations=20), seed=4)
    one = certify_plan(request, runner=engine.run_swarm, workers=1, engine=engine)
    assert sum(u.evaluations for u in one.uavs) > 3 * 60 * 21  # the local searches ran
    for workers in (2, 3):
        many = certify_plan(request, runner=engine.run_swarm, workers=workers, engine=engine)
        fields = [(u.current, u.best, u.gap, u.relative, u.roundtrip_error, u.evaluations, u.taken)
                  for u in many.uavs]
        assert fields == [(u.current, u.best, u.gap, u.relative, u.roundtrip_error, u.evaluations, u.taken)
                          for u in one.uavs]
        assert all(np.array_equal(a.deviation, b.deviation) for a, b in zip(one.uavs, many.uavs))


def test_a_certificate_stopped_at_its_first_refutation_has_the_full_verdict_and_completes_to_it(scenario1, reduced):
    """``refute=True``: every UAV's local search from the plan first, then each UAV's swarm and
    local search in turn, up to the first deviation beyond epsilon. A plan where the leader
    climbed out of formation is refuted by those first local searches, the leader's, with under a
    fifth of the full certificate's searches; marked not complete. Completed with the same
    ``work``, it is the full certificate, field for field. A plan refuted only by a swarm (the
    local searches from the plan handed in, as the rounds of ``game`` do) is refuted too. An
    equilibrium is searched in full either way. The same certificates on one worker and on two."""
    from staghunt.engine import get_engine
    from staghunt.solvers.response import CertificateWork

    _, game, _ = reduced
    engine = get_engine("numba", threads=1)
    budget = CertifyOptions(particles=60, iterations=20)
    wp = np.array(game.waypoints)
    wp[0, 3:7, 2] += 6.0  # the leader climbs 6 m out of the formation mid-way
    summed = plan(scenario1, "weighted", 1, scenario1.solver.with_(particles=100, iterations=30), engine="numba")

    def fields(cert):
        return [(u.current, u.best, u.gap, u.relative, u.evaluations, u.taken) for u in cert.uavs]

    seen = {}
    for workers in (1, 2):
        kw = dict(runner=engine.run_swarm, workers=workers, engine=engine)
        request = check_certify(scenario1, wp, budget, seed=4)
        full = certify_plan(request, **kw)
        work = CertificateWork()
        quick = certify_plan(request, **kw, refute=True, work=work)
        assert not full.is_equilibrium and full.complete
        assert not quick.is_equilibrium and not quick.complete and quick.status == "deviation"
        assert quick.uavs[quick.worst].relative > budget.epsilon
        assert sum(u.evaluations for u in quick.uavs) < 0.2 * sum(u.evaluations for u in full.uavs)
        assert any("searched only from the plan" in note for note in quick.notes)
        assert certify_plan(request, **kw, work=work) is not None
        completed = certify_plan(request, **kw, work=CertificateWork(**{k: dict(v) for k, v in vars(work).items()}))
        assert completed.complete and fields(completed) == fields(full)
        assert all(np.array_equal(a.deviation, b.deviation) for a, b in zip(completed.uavs, full.uavs))
        ok = check_certify(scenario1, game.waypoints, budget, seed=4)
        both = certify_plan(ok, **kw, refute=True), certify_plan(ok, **kw)
        assert both[0].complete and fields(both[0]) == fields(both[1])
        # A budget too small for local searches (under 6 K + 1 evaluations each): the swarms refute.
        small = check_certify(scenario1, summed.waypoints, CertifyOptions(particles=20, iterations=10), seed=4)
        late = certify_plan(small, **kw, refute=True)
        assert not late.complete and late.uavs[0].relative > budget.epsilon
        assert [u.evaluations for u in late.uavs] == [20 * 11, 0, 0]
        seen[workers] = fields(quick), fields(late)
    assert seen[1] == seen[2]


def test_a_failing_search_side_by_side_raises_in_the_caller(scenario1, reduced):
    """An error in one of the certificate's concurrent searches reaches the caller as itself."""
    _, game, _ = reduced

    def broken(*args, **kwargs):
        raise RuntimeError("search failed")

    request = check_certify(scenario1, game.waypoints, CertifyOptions(particles=20, iterations=5), seed=1)
    with pytest.raises(RuntimeError, match="search failed"):
        certify_plan(request, runner=broken, workers=2)


def test_stop_when_certified_returns_the_certificate_it_stopped_on(scenario1):
    """``stop="certified"``: the search stops at a certified plan, whose certificate is the
    result's (the same as certifying the result afterwards); without ``certify`` it is refused."""
    settings = scenario1.solver.with_(particles=300, iterations=200)
    cert = CertifyOptions(particles=100, iterations=40)
    early = plan(scenario1, "game", 2, settings, engine="numba", certify=cert, stop="certified")
    full = plan(scenario1, "game", 2, settings, engine="numba")
    assert early.evaluations <= full.evaluations
    from staghunt.engine import get_engine

    again = certify_plan(check_certify(scenario1, early.waypoints, cert, seed=2),
                         runner=get_engine("numba", threads=1).run_swarm)
    assert [u.gap for u in early.certificate.uavs] == [u.gap for u in again.uavs]
    if any("certified" in r for r in early.details["rounds"]):
        assert early.certificate.is_equilibrium
    with pytest.raises(ValueError, match="certify"):
        plan(scenario1, "game", 2, settings, engine="numba", stop="certified")


def _open_sky(model: CostModel) -> CostModel:
    """``model`` without its obstacles, so that straight lines are feasible."""
    return dataclasses.replace(model, cylinders=np.zeros((0, 3)), prisms=np.zeros((0, 8)),
                               prism_edges=np.zeros((0, 4)))


def _lagging_team(model: CostModel, K: int = 6, exponent: float = 1.1) -> np.ndarray:
    """Straight lines start to goal at even spacing, but UAV 1 (the leader) spaced as
    ``t ** exponent``: the same routes, UAV 1 behind its place in the formation."""
    t = np.arange(1, K + 1) / (K + 1)
    plan = model.starts[:, None, :] + t[None, :, None] * (model.goals - model.starts)[:, None, :]
    plan[0] = model.starts[0] + (t ** exponent)[:, None] * (model.goals[0] - model.starts[0])
    return plan


def test_team_slide_resynchronises_a_lagging_uav_without_changing_any_route(model1):
    """Waypoints slide along the routes only: every UAV's J_s (length, threats, altitude, turns
    on straight lines) is unchanged, the formation error of the lagging leader goes from 91.7
    to nothing, and no UAV is worse off."""
    model = _open_sky(model1)
    lag = _lagging_team(model)
    before = evaluate(model, lag[None])
    assert before.total_violation[0] == 0 and before.formation[0, 0] == pytest.approx(91.724, abs=1e-3)
    slid, spent = team_slide(model, lag, 100_000)
    after = evaluate(model, slid[None])
    assert 0 < spent <= 100_000 and spent % model.n_uavs == 0
    np.testing.assert_allclose(after.single[0], before.single[0], rtol=1e-9)
    assert np.all(after.formation[0] < 1e-6) and after.total_violation[0] == 0
    assert np.all(after.total[0] < before.total[0])
    # The routes themselves are kept: every new waypoint lies on its UAV's straight line.
    d = (model.goals - model.starts)[:, None, :]
    u = slid - model.starts[:, None, :]
    assert np.abs(np.cross(u, d)).max() < 1e-9


def test_team_slide_moves_one_waypoint_of_every_uav_per_sweep(model1):
    """With the budget of one sweep: either the plan itself (nothing dominates it) or the plan
    with waypoint k of every UAV moved the first fraction of the way to waypoint k - 1 or k + 1
    (the start or the goal at the ends), the same k and side for all."""
    model = _open_sky(model1)
    lag = _lagging_team(model)
    N, K = lag.shape[:2]
    one, spent = team_slide(model, lag, N * (2 * K + 1))
    assert spent == N * (2 * K + 1)
    moved = np.flatnonzero(np.any(one != lag, axis=(0, 2)))
    assert len(moved) == 1
    k = int(moved[0])
    full = np.concatenate([model.starts[:, None], lag, model.goals[:, None]], axis=1)
    options = [lag[:, k] + SLIDE_FRACTIONS[0] * (full[:, k + side] - lag[:, k]) for side in (0, 2)]
    assert any(np.allclose(one[:, k], o, rtol=0, atol=1e-12) for o in options)
    c0, c1 = evaluate(model, lag[None]), evaluate(model, one[None])
    assert dominates(c1.total[0], c1.total_violation[0], c0.total[0], c0.total_violation[0])
    # Too small a budget, or an infeasible plan: the plan itself, untouched.
    same, none = team_slide(model, lag, N * 2 * K)
    assert same is lag and none == 0
    bad = lag.copy()
    bad[1] = bad[2]  # UAVs 2 and 3 on top of each other
    same, spent = team_slide(model, bad, 100_000)
    assert same is bad and spent == N


def test_the_certificate_finds_small_moves_the_swarm_cannot(scenario1, reduced, monkeypatch):
    """A swarm without iterations only samples paths far from the plan; the certificate's local
    search from the current path still finds UAV 3's way back into the formation (1 m steps), and
    without that search the same certificate sees nothing."""
    from staghunt.solvers import response

    settings, game, _ = reduced
    wp = np.array(game.waypoints)
    wp[2, 3:7, 2] += 6.0  # UAV 3 climbs 6 m out of the formation mid-way
    request = check_certify(scenario1, wp, CertifyOptions(particles=300, iterations=0), seed=5, settings=settings)
    with_local = certify_plan(request)
    u = with_local.uavs[2]
    assert u.relative > 0.01 and not with_local.is_equilibrium
    assert 300 < u.evaluations <= 300 + 2 * 75
    assert np.abs(u.deviation - wp[2]).max() > 0  # a different path, found locally
    monkeypatch.setattr(response, "LOCAL_SHARE", 0.0)
    swarm_only = certify_plan(request)
    assert swarm_only.uavs[2].relative < u.relative and swarm_only.uavs[2].evaluations == 300


def test_local_pass_side_by_side_makes_the_same_decisions(model1, reduced):
    """``local_pass`` with its searches made side by side (each standing until a gain changes the
    plan) gives the plan, costs, gains, evaluations and searches of one search at a time, also
    when a gain mid-pass makes the later UAV search again from the new plan."""
    from staghunt.engine import get_engine
    from staghunt.solvers.local import local_pass

    ev = get_engine("numba", threads=1)
    _, game, _ = reduced
    wp = np.array(game.waypoints)
    wp[1, 3:7, 2] += 6.0  # UAV 2 climbs 6 m out of the formation: its local search gains
    J = ev.evaluate(model1, wp[None]).total[0]
    one = local_pass(model1, wp, J, 3000, 0.01, ev)
    two = local_pass(model1, wp, J, 3000, 0.01, ev, workers=2)
    assert one.gains[1] > 0.01  # taken mid-pass: UAV 3 searches again from the new plan
    assert np.array_equal(one.plan, two.plan) and np.array_equal(one.costs, two.costs)
    assert np.array_equal(one.gains, two.gains) and one.evaluations == two.evaluations
    assert [(m.n, m.evaluations) for m in one.searches] == [(m.n, m.evaluations) for m in two.searches]
    for a, b in zip(one.searches, two.searches):
        assert np.array_equal(a.plan, b.plan) and np.array_equal(a.path, b.path)
    assert np.array_equal(one.searches[2].plan, one.plan)  # UAV 3's search: from the plan after the gain
    assert not np.array_equal(one.searches[0].plan, one.plan)


def test_the_certificate_takes_the_local_searches_made_just_before(scenario1, model1, reduced, monkeypatch):
    """The local searches of a pass that took nothing are the certificate's own searches from the
    plan: handed to it, they are not made again and the certificate is the same, evaluations
    included; searches with another budget are not taken."""
    from staghunt.engine import get_engine
    from staghunt.solvers import response
    from staghunt.solvers.local import local_pass

    engine = get_engine("numba", threads=1)
    _, game, _ = reduced
    options = CertifyOptions(particles=60, iterations=20)
    budget = int(response.LOCAL_SHARE * 60 * 21)  # the certificate's local search of one UAV
    wp = np.array(game.waypoints)
    done = local_pass(model1, wp, engine.evaluate(model1, wp[None]).total[0], budget, 0.01, engine)
    assert not done.gains.any() and len(done.searches) == 3  # an equilibrium: nothing taken
    request = check_certify(scenario1, wp, options, seed=3)
    calls = []
    original = response.polish

    def counted(*args, **kwargs):
        calls.append(args[2])
        return original(*args, **kwargs)

    monkeypatch.setattr(response, "polish", counted)
    kw = dict(runner=engine.run_swarm, engine=engine)
    alone = certify_plan(request, **kw)
    made = len(calls)
    taken = certify_plan(request, **kw, searched=done.searches)
    assert made - (len(calls) - made) == 3  # one local search per UAV not made again
    assert [(u.current, u.best, u.gap, u.evaluations) for u in alone.uavs] == \
        [(u.current, u.best, u.gap, u.evaluations) for u in taken.uavs]
    assert all(np.array_equal(a.deviation, b.deviation) for a, b in zip(alone.uavs, taken.uavs))
    assert [u.taken for u in taken.uavs] == [m.evaluations for m in done.searches]
    assert all(u.taken == 0 for u in alone.uavs)
    other = local_pass(model1, wp, engine.evaluate(model1, wp[None]).total[0], budget + 1, 0.01, engine)
    before = len(calls)
    certify_plan(request, **kw, searched=other.searches)
    assert len(calls) - before == made
