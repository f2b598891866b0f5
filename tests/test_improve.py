"""The game's loops of a re-plan (solvers/improve.py): best-response rounds that stop at a
deadline with the plan they have, and the certify-and-improve loop."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from staghunt import load_scenario
from staghunt.costs import CostModel
from staghunt.costs.single import segment_axis_distance
from staghunt.engine import get_engine
from staghunt.solvers.clear import CLEAR_PAD, pushed_clear
from staghunt.solvers.game import best_response_rounds
from staghunt.solvers.improve import ESTIMATE_DECAY, Deadline, anytime_rounds, certify_and_improve
from staghunt.solvers.response import CertifyOptions, check_search

SMALL = str(Path(__file__).parent / "data" / "flight_small.toml")


def _cut(sc):
    """The small site with a pop-up (radius 3 m at (30, 13)) across UAV1's straight route at
    y = 15, and the straight plan ``(2, 6, 3)`` through it."""
    from dataclasses import replace

    from staghunt.world import Cylinder

    sc = replace(sc, world=replace(sc.world, cylinders=sc.world.cylinders + (Cylinder(30.0, 13.0, 3.0, "pop-up"),)))
    x = np.linspace(5.0, 55.0, sc.solver.waypoints + 2)[1:-1]
    plan = np.stack([np.column_stack([x, np.full_like(x, y), np.full_like(x, 12.0)]) for y in (15.0, 23.0)])
    return sc, plan


def _zigzag(sc):
    """A zigzag plan ``(N, K, 3)`` (x, y, h) of the small site: feasible, no equilibrium."""
    K = sc.solver.waypoints
    x = np.linspace(5.0, 55.0, K + 2)[1:-1]
    zig = np.where(np.arange(K) % 2 == 0, 2.0, -2.0)
    return np.stack([np.column_stack([x, 15.0 + zig, np.full(K, 12.0)]),
                     np.column_stack([x, 23.0 + zig, np.full(K, 12.0)])])


def test_without_a_deadline_the_rounds_are_the_games():
    sc = load_scenario(SMALL)
    model, engine = CostModel.from_scenario(sc), get_engine("numba")
    settings = sc.solver.with_(particles=40, iterations=30)
    budget = settings.particles * (settings.iterations + 1) * sc.n_uavs
    a = best_response_rounds(model, _zigzag(sc), settings, np.random.default_rng(3), engine.run_swarm,
                             engine, budget, 0, None, repair=True)
    b = anytime_rounds(model, _zigzag(sc), settings, np.random.default_rng(3), engine.run_swarm, engine,
                       budget, Deadline(), repair=True)
    assert np.array_equal(a.plan, b.plan) and a.evaluations == b.evaluations and a.converged == b.converged


def test_a_deadline_stops_the_rounds_with_the_plan_they_have():
    sc = load_scenario(SMALL)
    model, engine = CostModel.from_scenario(sc), get_engine("numba")
    settings = sc.solver.with_(particles=60, iterations=60)
    budget = 50 * settings.particles * (settings.iterations + 1) * sc.n_uavs  # far more than the deadline allows
    warm = _zigzag(sc)
    t0 = time.perf_counter()
    out = anytime_rounds(model, warm, settings, np.random.default_rng(3), engine.run_swarm, engine,
                         budget, Deadline.after(0.0), repair=True)
    took = time.perf_counter() - t0
    assert not out.converged and out.evaluations < budget / 10
    assert took < 5.0  # one reply, not the budget
    J = engine.evaluate(model, out.plan[None]).total[0]
    assert np.allclose(J, out.costs)  # the costs are the plan's
    start = engine.evaluate(model, warm[None]).total[0]
    assert np.array_equal(out.plan[1], warm[1])  # stopped after UAV 1's reply: UAV 2 has not replied
    assert J[0] < start[0] and not np.array_equal(out.plan[0], warm[0])  # UAV 1's better reply was kept


def test_certificate_rounds_adopt_a_better_reply_and_keep_the_plan_flown():
    """A zigzag plan is no equilibrium: its first certificate finds better replies. With
    certificate rounds the replies are adopted (``accept`` flies them) and certified again; the
    plan kept has a smaller largest gap than the first, and is one ``accept`` flew. With none
    the plan stays as it was. Without time for a certificate, none is made."""
    sc = load_scenario(SMALL)
    engine = get_engine("numba")
    options = CertifyOptions(100, 60, 0.01)
    search = check_search(sc.solver, options, "test")
    plan = _zigzag(sc)
    flown_plans: list[np.ndarray] = []

    def accept(p: np.ndarray) -> str:
        flown_plans.append(p.copy())
        return f"flown {len(flown_plans)}"

    gaps = {}
    for rounds in (0, 4):
        flown_plans.clear()
        out = certify_and_improve(sc, plan, "first", accept, search, options, rounds, np.random.default_rng(5),
                                  engine.run_swarm, engine, engine, np.pi / 4)
        assert out.certificate is not None and out.spent >= sum(u.evaluations - u.taken for u in out.certificate.uavs)
        gaps[rounds] = out.certificate.max_relative_gap
        if rounds == 0:
            assert out.flown == "first" and np.array_equal(out.plan, plan) and out.certificates == 1
            assert out.certificate.max_relative_gap > 0.01
        else:
            assert out.flown != "first"  # replies (or the local searches before) adopted and flown
            assert any(np.array_equal(out.plan, p) for p in flown_plans)
    assert gaps[4] < gaps[0]
    # The zigzag's certificate stops at its first refutation; its time, not a full certificate's,
    # leaves the running estimate alone.
    roomy = Deadline.after(600.0)
    quick = certify_and_improve(sc, plan, "first", accept, search, options, 0, np.random.default_rng(5),
                                engine.run_swarm, engine, engine, np.pi / 4, deadline=roomy)
    assert quick.certificate is not None and not quick.certificate.complete and roomy.certificate_s == 0.0
    # With the UAVs' searches side by side, it runs to the end: every UAV's gap (and better
    # reply) is found, its time enters the estimate, and the verdict is the same.
    pinned = get_engine("numba", threads=1)
    roomy = Deadline.after(600.0)
    full = certify_and_improve(sc, plan, "first", accept, search, options, 0, np.random.default_rng(5),
                               pinned.run_swarm, pinned, pinned, np.pi / 4, workers=2, deadline=roomy)
    assert full.certificate is not None and full.certificate.complete and roomy.certificate_s > 0.0
    assert not full.certificate.is_equilibrium and full.certificate.max_relative_gap >= quick.certificate.max_relative_gap
    assert all(u.best is not None for u in full.certificate.uavs)
    # Time for one certificate only: its better replies are not adopted (the plan they would
    # make could not be certified before the deadline, and adopting them is not watched by it).
    # UAV 2 6 m out of the formation: the plan still fails its certificate after the local passes.

    class OneCertificate(Deadline):
        def fits_certificate(self, *then: str) -> bool:
            self.asked = getattr(self, "asked", 0) + 1
            return self.asked == 1

    far = plan.copy()
    far[1, :, 1] += 6.0
    made = {}
    for name, deadline in (("one", OneCertificate(time.perf_counter() + 600.0)), ("roomy", Deadline.after(600.0))):
        flown_plans.clear()
        made[name] = certify_and_improve(sc, far, "first", accept, search, options, 4, np.random.default_rng(5),
                                         engine.run_swarm, engine, engine, np.pi / 4, deadline=deadline), len(flown_plans)
    one, flown_once = made["one"]
    assert one.certificates == 1 and not one.certificate.is_equilibrium
    assert "certify the better replies" in one.notes[-1]
    roomy_out, flown_roomy = made["roomy"]
    assert roomy_out.certificates > 1 and not np.array_equal(roomy_out.plan, one.plan)  # with time, they are adopted
    assert flown_once == flown_roomy == 1  # only the plan kept is flown, once
    # Flying a plan is known to take longer than the time left after a certificate: no local
    # pass (its gains could not be flown) and no reply adopted; the certificate is still made.
    slow = Deadline(time.perf_counter() + 600.0, 10.0, steps={"accept": 595.0, "local pass": 10.0})
    flown_plans.clear()
    held = certify_and_improve(sc, far, "first", accept, search, options, 4, np.random.default_rng(5),
                               engine.run_swarm, engine, engine, np.pi / 4, deadline=slow)
    assert not flown_plans and held.flown == "first" and np.array_equal(held.plan, far)
    assert held.certificates == 1 and "certify the better replies" in held.notes[-1]
    assert slow.steps == {"accept": 595.0, "local pass": 10.0}  # nothing was timed
    late = certify_and_improve(sc, plan, "first", accept, search, options, 4, np.random.default_rng(5),
                               engine.run_swarm, engine, engine, np.pi / 4,
                               deadline=Deadline(time.perf_counter() - 1.0))
    assert late.certificate is None and late.certificates == 0 and "deadline" in late.notes[0]
    # An estimate grown past the time left (one slow certificate) shrinks while it blocks: else
    # no certificate would ever measure it again.
    grown = Deadline(time.perf_counter() + 60.0, 100.0)
    for k in range(2):
        out = certify_and_improve(sc, plan, "first", accept, search, options, 4, np.random.default_rng(5),
                                  engine.run_swarm, engine, engine, np.pi / 4, deadline=grown)
        assert out.certificates == 0 and grown.certificate_s == pytest.approx(100.0 * ESTIMATE_DECAY ** (k + 1))


def test_a_certificate_still_searching_at_the_deadline_is_abandoned():
    """A certificate that its running estimate let start but that is still searching when the
    deadline passes is abandoned (it is all or nothing) rather than carrying the re-plan past
    its deadline; the estimate grows to what the share of its searches done implies."""
    import re

    from staghunt.engine import NumpyEngine

    from staghunt.solvers.local import local_pass
    from staghunt.solvers.response import LOCAL_SHARE

    sc = load_scenario(SMALL)
    slow, fast = NumpyEngine(), get_engine("numba")  # swarms slow enough that the certificate cannot end in time
    options = CertifyOptions(400, 300, 0.01)
    search = check_search(sc.solver, options, "test")
    # A plan no local search improves beyond epsilon: the certificate's own local searches from
    # it (made first, compiled) refute nothing, and its swarms run.
    model = CostModel.from_scenario(sc)
    plan = _zigzag(sc)
    J = fast.evaluate(model, plan[None]).total[0]
    for _ in range(20):
        done = local_pass(model, plan, J, int(LOCAL_SHARE * 400 * 301), 0.01, fast)
        plan, J = done.plan, done.costs
        if not done.gains.any():
            break
    assert not done.gains.any()
    deadline = Deadline.after(0.3)
    t0 = time.perf_counter()
    out = certify_and_improve(sc, plan, "first", lambda p: "flown", search, options, 0,
                              np.random.default_rng(5), slow.run_swarm, fast, fast, np.pi / 4,
                              deadline=deadline)
    took = time.perf_counter() - t0
    assert out.certificate is None and out.certificates == 0 and out.flown == "first"
    note = next(n for n in out.notes if "abandoned" in n)
    share = float(re.search(r"(\d+) % done", note).group(1)) / 100
    assert share < 1.0 and took < 0.3 + 1.0  # stopped at its next progress report, not at its end
    assert deadline.certificate_s >= 0.1  # at least the time it ran (over the share it had done)


def test_a_plan_cut_by_an_obstacle_is_pushed_clear_to_the_side_it_passed():
    """UAV1's straight route passes 2 m from the pop-up's axis, inside its hard clearance
    (3 + 0.5 + 1 m): pushed, every segment passes at least that plus the pad from the axis,
    on the side it passed (y > 13), at the same heights; UAV2 (10 m away) and the start and
    goal do not move, and a plan already clear comes back as it is."""
    sc, plan = _cut(load_scenario(SMALL))
    model, engine = CostModel.from_scenario(sc), get_engine("numpy")
    assert engine.evaluate(model, plan[None]).violation[0, 0, 0] > 0
    out = pushed_clear(model, plan)
    assert engine.evaluate(model, out[None]).total_violation[0] == 0
    full = np.concatenate([model.starts[:, None], out, model.goals[:, None]], axis=1)
    d = segment_axis_distance(full[None, :, :, :2], model.cylinders)[0, 0, :, -1]  # UAV1 to the pop-up
    assert d.min() >= 3.0 + 0.5 + 1.0 + CLEAR_PAD - 1e-6
    assert np.all(out[0, :, 1] >= 15.0) and out[0, :, 1].max() > 17.0  # away from the axis at y = 13
    assert np.array_equal(out[1], plan[1]) and np.array_equal(out[..., 2], plan[..., 2])
    assert pushed_clear(model, out) is out  # clear already: as it is


def test_rounds_that_end_cutting_an_obstacle_end_pushed_clear(monkeypatch):
    """A re-plan's rounds (``repair``) whose last plan still cuts the pop-up (stand-in rounds
    that end on the cut plan) return that plan pushed clear, feasible and with its costs, one
    evaluation more; without ``repair``, as the rounds ended."""
    import staghunt.solvers.improve as improve
    from staghunt.solvers.game import RoundsOutcome

    sc, plan = _cut(load_scenario(SMALL))
    model, engine = CostModel.from_scenario(sc), get_engine("numpy")
    J = engine.evaluate(model, plan[None]).total[0]
    assert not np.all(np.isfinite(J))
    monkeypatch.setattr(improve, "best_response_rounds", lambda *a, **k: RoundsOutcome(plan.copy(), J, 100, [], 1, False))
    settings = sc.solver.with_(particles=20, iterations=10)
    out = anytime_rounds(model, plan, settings, np.random.default_rng(3), engine.run_swarm, engine, 10_000,
                         Deadline(), repair=True)
    assert np.array_equal(out.plan, pushed_clear(model, plan)) and out.evaluations == 101
    np.testing.assert_array_equal(out.costs, engine.evaluate(model, out.plan[None]).total[0])
    assert np.all(np.isfinite(out.costs))
    kept = anytime_rounds(model, plan, settings, np.random.default_rng(3), engine.run_swarm, engine, 10_000, Deadline())
    assert np.array_equal(kept.plan, plan) and not np.all(np.isfinite(kept.costs))


def test_the_rounds_of_a_cut_plan_start_from_it_pushed_clear():
    """A re-plan's rounds (``repair``) from a plan a pop-up cuts, stopped after their first
    reply: the plan they return is feasible, and UAV2's part is the pushed plan's."""
    sc, plan = _cut(load_scenario(SMALL))
    model, engine = CostModel.from_scenario(sc), get_engine("numba")
    settings = sc.solver.with_(particles=20, iterations=10)
    budget = settings.particles * (settings.iterations + 1) * sc.n_uavs * 10
    out = anytime_rounds(model, plan, settings, np.random.default_rng(3), engine.run_swarm, engine,
                         budget, Deadline.after(0.0), repair=True)
    assert engine.evaluate(model, out.plan[None]).total_violation[0] == 0
    assert np.array_equal(out.plan[1], pushed_clear(model, plan)[1])  # stopped after UAV1's reply
