"""The compiled engine against the NumPy reference.

- ``evaluate`` twins: on random and adversarial populations (obstacles grazed at exactly
  ``R + r`` and ``R + r + Delta``, heights below ground, repeated points, vertical segments,
  team-mates touching at waypoints and crossing between them; flat and DEM terrain; thresholds
  0 and 45 degrees; zero weights and zero ``beta``), every cost agrees within 1e-9 relative,
  ``inf`` and zero-violation patterns are identical, and so are all Pareto-dominance decisions.
- The swarm: decoding and objectives agree with :class:`SwarmProblem` (team sum, fixed members,
  offsets); a seed gives the same result for any thread count; ``game`` and ``rigid`` find
  feasible plans on paper scenario 2 with a small budget.

Populations are tiny; the one-time compile is shared with every other test (Numba's cache).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("numba")

from staghunt import plan  # noqa: E402
from staghunt.costs import CostModel, evaluate  # noqa: E402
from staghunt.encoding import search_space  # noqa: E402
from staghunt.engine import NumpyEngine, get_engine  # noqa: E402
from staghunt.engine import fastmath as fm  # noqa: E402
from staghunt.engine import kernels as kn  # noqa: E402
from staghunt.engine.numba_engine import NumbaEngine  # noqa: E402
from staghunt.engine.numba_engine import evaluate as fast_evaluate  # noqa: E402
from staghunt.engine.threads import AdaptiveThreads  # noqa: E402
from staghunt.scenario import load_scenario  # noqa: E402
from staghunt.scenario.model import SolverSettings  # noqa: E402
from staghunt.solvers.dominance import best_index, dominates  # noqa: E402
from staghunt.solvers.problem import SwarmProblem, team_problem  # noqa: E402
from staghunt.solvers.rigid import rigid_problem  # noqa: E402
from staghunt.world import Terrain  # noqa: E402

RTOL = 1e-9


def frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def make_model(
    n: int,
    terrain: Terrain | None = None,
    thresholds: float = 0.0,
    weights: np.ndarray | None = None,
    beta: np.ndarray | None = None,
    continuous: bool = True,
) -> CostModel:
    """``n`` UAVs on a row flying north through a field of four cylinders; chain formation."""
    terrain = terrain if terrain is not None else Terrain()
    starts = np.array([[10.0 + 10.0 * i, 10.0, 20.0] for i in range(n)])
    goals = np.array([[10.0 + 10.0 * i, 90.0, 20.0] for i in range(n)])

    def absolute(p: np.ndarray) -> np.ndarray:
        out = p.copy()
        out[:, 2] = terrain.absolute(p[:, 0], p[:, 1], p[:, 2])
        return out

    heads = np.arange(max(n - 1, 0), dtype=np.intp)
    tails = heads + 1
    mu = np.zeros((n, len(heads)))
    for e in range(len(heads)):
        mu[heads[e], e] = 1.0
        mu[tails[e], e] = 0.5
    ref = goals
    return CostModel(
        terrain=terrain,
        lower=frozen(np.array([0.0, 0.0, 0.0])),
        upper=frozen(np.array([100.0, 100.0, 40.0])),
        starts=frozen(starts),
        goals=frozen(goals),
        start_abs=frozen(absolute(starts)),
        goal_abs=frozen(absolute(goals)),
        radius=frozen(np.full(n, 1.0)),
        beta=frozen(beta if beta is not None else np.linspace(1.0, 3.0, n)),
        weights=frozen(weights if weights is not None else np.tile([5.0, 1.0, 10.0, 1.0, 1.0], (n, 1))),
        cylinders=frozen(np.array([[30.0, 40.0, 4.0], [52.0, 55.0, 6.0], [20.0, 70.0, 3.0], [75.0, 30.0, 5.0]])),
        heads=frozen(heads),
        tails=frozen(tails),
        mu=frozen(mu),
        ref_diff=frozen(ref[heads] - ref[tails]),
        reference=frozen(ref),
        danger_margin=10.0,
        safe_distance=2.0,
        turning_threshold_deg=thresholds,
        climb_threshold_deg=thresholds,
        h_ref=20.0,
        continuous_separation=continuous,
    )


def dem(sampling: str, dtype: type) -> Terrain:
    rng = np.random.default_rng(5)
    grid = (rng.random((12, 12)) * 8.0).astype(dtype)
    grid.setflags(write=False)
    return Terrain(elevation=grid, origin=(1.0, 1.0), cell_size=9.0, sampling=sampling)


def population(model: CostModel, P: int, K: int, seed: int) -> np.ndarray:
    """``(P, N, K, 3)``: random paths around the start-goal lines, then adversarial rows."""
    rng = np.random.default_rng(seed)
    N = model.n_uavs
    t = (np.arange(1, K + 1) / (K + 1))[None, None, :, None]
    line = model.starts[None, :, None, :] + t * (model.goals - model.starts)[None, :, None, :]
    wp = line + rng.normal(0.0, [8.0, 8.0, 6.0], size=(P, N, K, 3))
    wp[..., :2] = np.clip(wp[..., :2], 0.0, 100.0)
    wp[..., 2] = np.round(wp[..., 2], 1)
    # Adversarial rows (each on one allocation):
    wp[0, :, :, 2] = -1.0  # below ground everywhere
    wp[1, :, :, 2] = 0.0  # exactly on the ground (finite)
    wp[2, 0, :] = wp[2, 0, :1]  # repeated points: zero-length segments
    wp[3, 0, :, :2] = model.starts[0, :2]  # vertical segments above the start
    wp[3, 0, :, 2] = np.linspace(5.0, 30.0, K)
    cx, cy, R = model.cylinders[0]
    for i, gap in ((4, R + 1.0), (5, R + 1.0 + 10.0), (6, R + 1.0 - 1e-12), (7, R + 11.0 + 1e-12)):
        wp[i, 0, :, 0] = cx + gap  # a north-south line at exactly this distance from the axis
        wp[i, 0, :, 1] = np.linspace(cy - 20.0, cy + 20.0, K)
    if N > 1:
        wp[8, 1] = wp[8, 0]  # two UAVs on the same waypoints
        wp[9, 1] = wp[9, 0] + np.array([4.0, 0.0, 0.0])  # exactly at the separation limit
        wp[10, 1] = wp[10, 0] + np.array([4.0 + 1e-9, 0.0, 0.0])  # just clear at waypoints
        if K >= 2:  # crossing between waypoints: swap sides from one waypoint to the next
            wp[11, 1, ::2] = wp[11, 0, ::2] + np.array([6.0, 0.0, 0.0])
            wp[11, 1, 1::2] = wp[11, 0, 1::2] - np.array([6.0, 0.0, 0.0])
    wp[12, :, :, 0] = 100.0  # on the site edge
    wp[13] = np.round(wp[13])  # integer coordinates: many exact ties and right angles
    return wp


def assert_costs_agree(model: CostModel, wp: np.ndarray) -> None:
    ref = evaluate(model, wp)
    got = fast_evaluate(model, wp)
    for name in ("terms", "single", "formation", "total"):
        a, b = getattr(got, name), getattr(ref, name)
        assert np.array_equal(np.isinf(a), np.isinf(b)), f"{name}: inf pattern differs"
        assert not np.isnan(a).any(), f"{name}: NaN"
        fin = np.isfinite(b)
        np.testing.assert_allclose(a[fin], b[fin], rtol=RTOL, atol=1e-9, err_msg=name)
    np.testing.assert_allclose(got.violation, ref.violation, rtol=RTOL, atol=1e-12)
    assert np.array_equal(got.violation == 0, ref.violation == 0)
    # Every pairwise dominance decision, and the preferred allocation.
    for cost_a, cost_b in ((got.total, ref.total),):
        va, vb = got.total_violation, ref.total_violation
        da = dominates(cost_a[:, None], va[:, None], cost_a[None], va[None])
        db = dominates(cost_b[:, None], vb[:, None], cost_b[None], vb[None])
        assert np.array_equal(da, db)
        assert best_index(cost_a, va) == best_index(cost_b, vb)


@pytest.mark.parametrize("n", [1, 3, 5])
@pytest.mark.parametrize("K", [1, 3, 10])
def test_evaluate_agrees_flat(n, K):
    model = make_model(n)
    assert_costs_agree(model, population(model, 64, K, seed=10 * n + K))


@pytest.mark.parametrize(
    "terrain",
    [dem("nearest", np.float32), dem("nearest", np.float64), dem("bilinear", np.float32)],
    ids=["nearest-float32", "nearest-float64", "bilinear"],
)
def test_evaluate_agrees_dem(terrain):
    model = make_model(3, terrain=terrain)
    wp = population(model, 64, 10, seed=3)
    wp[20:30, :, :, :2] = np.round(wp[20:30, :, :, :2] / 9.0) * 9.0 + 1.0 + 4.5  # half-cell ties
    assert_costs_agree(model, wp)


@pytest.mark.parametrize("thresholds", [0.0, 45.0])
def test_evaluate_agrees_thresholds(thresholds):
    model = make_model(3, thresholds=thresholds)
    wp = population(model, 64, 10, seed=4)
    # Exact 45-degree turns and climbs: right-angle zigzags on integer coordinates.
    zig = np.array([[10.0 * k, 10.0 * k + (10.0 if k % 2 else 0.0), 20.0 + (10.0 if k % 2 else 0.0)]
                    for k in range(1, 11)])
    wp[30, 0] = zig
    wp[31, 0] = zig[:, [1, 0, 2]]
    assert_costs_agree(model, wp)


def test_evaluate_agrees_zero_weights_and_beta():
    n = 3
    weights = np.array([[5.0, 0.0, 10.0, 1.0, 1.0], [0.0, 1.0, 0.0, 0.0, 1.0], [1.0, 1.0, 1.0, 1.0, 0.0]])
    model = make_model(n, weights=weights, beta=np.array([0.0, 1.0, 0.0]))
    assert_costs_agree(model, population(model, 64, 10, seed=5))
    assert_costs_agree(make_model(n, continuous=False), population(model, 64, 10, seed=6))


@pytest.mark.parametrize("continuous", [True, False])
def test_pruned_pair_check_misses_no_near_pair(continuous):
    """Past N = 4 the pair check is pruned by boxes over the block's lanes (exact). On a
    site 40 km from its origin, with team-mates flying parallel at the separation limit plus or
    minus 1e-7 m, 1e-3 m and 0, or crossing between waypoints, every collision and deficit is
    the reference's."""
    import dataclasses

    shift = np.array([40000.0, -25000.0, 0.0])
    base = make_model(8, continuous=continuous)
    model = dataclasses.replace(
        base, lower=frozen(base.lower + shift), upper=frozen(base.upper + shift),
        starts=frozen(base.starts + shift), goals=frozen(base.goals + shift),
        start_abs=frozen(base.start_abs + shift), goal_abs=frozen(base.goal_abs + shift),
        reference=frozen(base.reference + shift), cylinders=frozen(base.cylinders + [shift[0], shift[1], 0.0]))
    rng = np.random.default_rng(8)
    P, N, K = 96, 8, 6
    t = (np.arange(1, K + 1) / (K + 1))[None, None, :, None]
    wp = model.starts[None, :, None, :] + t * (model.goals - model.starts)[None, :, None, :]
    wp = wp + rng.normal(0.0, [4.0, 4.0, 3.0], size=(P, N, K, 3))
    limit = model.safe_distance + 2.0 * model.radius[0]
    for q in range(16, P):
        a = int(rng.integers(0, N - 1))
        c = a + 1
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        if q % 6 == 5:  # crossing between waypoints: sides swap from one waypoint to the next
            wp[q, c, ::2] = wp[q, a, ::2] + 3.0 * u
            wp[q, c, 1::2] = wp[q, a, 1::2] - 3.0 * u
        else:
            wp[q, c] = wp[q, a] + (limit + (-1e-7, 0.0, 1e-7, -1e-3, 1e-3)[q % 6]) * u
    got = fast_evaluate(model, wp)
    ref = evaluate(model, wp)
    assert np.array_equal(got.violation == 0, ref.violation == 0)
    assert (ref.violation[:, :, 2] > 0).sum() > 40 and (ref.violation[16:, :, 2] == 0).any()
    assert_costs_agree(model, wp)


@pytest.mark.parametrize("continuous", [True, False])
def test_pair_pruning_follows_the_relative_position(continuous):
    """The pair check skips a pair's segment when the pair's relative position stays farther
    than its limit on some axis in every lane of the block, even though the two UAVs' boxes
    of the segment overlap (a team-mate right ahead, both moving along the segment). At the
    limit plus or minus 1e-7 m and 1e-3 m, ahead and behind, and with the team-mate passing
    through the UAV between waypoints (apart at both ends), every collision and deficit is
    the reference's."""
    import dataclasses

    team = make_model(8, continuous=continuous)  # flying north, 10 m apart on a row
    limit = team.safe_distance + 2.0 * team.radius[0]
    P, K = 8, 6  # one block
    rng = np.random.default_rng(31)
    t = (np.arange(1, K + 1) / (K + 1))[None, None, :, None]
    line = team.starts[None, :, None, :] + t * (team.goals - team.starts)[None, :, None, :]
    base = line + rng.normal(0.0, 0.3, size=(P, team.n_uavs, K, 3))
    gaps = (-1e-3, -1e-7, 0.0, 1e-7, 2e-6, 1e-3, 0.5)  # beyond the limit
    cases = [(side, gap) for side in (1.0, -1.0) for gap in gaps] + [(0.0, 1.5)]
    deficits = {}
    for side, gap in cases:
        wp = base.copy()
        north = np.zeros((P, K, 3))  # UAV 1 from UAV 0, ahead (1) or behind (-1) it
        if side == 0.0:  # 5.5 m ahead at one waypoint, behind at the next: passing through
            north[:, :, 1] = np.where(np.arange(K) % 2 == 0, 1.0, -1.0) * (limit + gap)
        else:
            north[:, :, 1] = side * (limit + gap)
        wp[:, 1] = wp[:, 0] + north
        ends = [np.array(team.starts), np.array(team.goals)]  # UAV 1's placed likewise
        for e, i in zip(ends, (0, K - 1)):
            e[1] = e[0] + north[0, i]
        model = dataclasses.replace(team, starts=frozen(ends[0]), goals=frozen(ends[1]),
                                    start_abs=frozen(ends[0]), goal_abs=frozen(ends[1]))
        got = fast_evaluate(model, wp)
        ref = evaluate(model, wp)
        assert np.array_equal(got.violation == 0, ref.violation == 0), (side, gap)
        assert_costs_agree(model, wp)
        deficits[side, gap] = ref.violation[:, :2, 2]
    for side in (1.0, -1.0):
        assert (deficits[side, -1e-3] > 0).all() and (deficits[side, -1e-7] > 0).all()
        assert (deficits[side, 1e-3] == 0).all() and (deficits[side, 0.5] == 0).all()
    assert (deficits[0.0, 1.5] > 0).all() == continuous


def test_memory_estimate_uses_the_kernels_block_size():
    """``staghunt.budget`` (which must not import Numba) repeats the block size's formula: at
    least 64 lanes, at most 256, a multiple of 8."""
    from staghunt.budget import _block

    for N in (1, 3, 8, 24, 60):
        for K in (1, 10, 20, 40, 100):
            assert _block(N, K) == kn.block_size(N, K)
            assert 64 <= kn.block_size(N, K) <= 256 and kn.block_size(N, K) % 8 == 0
    assert kn.block_size(24, 20) == 64 and kn.block_size(3, 10) == 256


def test_kept_evaluation_passes_return_their_own_arrays_on_every_thread():
    """Small batches reuse a pass kept per thread: a result is never overwritten by the next
    evaluation of the same shape, a batch too large to keep gives the same values, and threads
    evaluating at once get what one thread gets."""
    from concurrent.futures import ThreadPoolExecutor

    from staghunt.engine.passes import EVALUATION_ROWS

    model = make_model(3)
    a, b = population(model, 20, 10, seed=21), population(model, 20, 10, seed=22)
    first = fast_evaluate(model, a)
    kept = {name: np.array(getattr(first, name)) for name in ("terms", "single", "formation", "total", "violation")}
    second = fast_evaluate(model, b)
    for name, value in kept.items():
        assert np.array_equal(getattr(first, name), value), name
    assert not np.array_equal(first.total, second.total)
    big = population(model, EVALUATION_ROWS + 1, 10, seed=23)
    big[:20] = a
    assert np.array_equal(fast_evaluate(model, big).total[:20], first.total)
    batches = [population(model, 20, 10, seed=s) for s in range(30, 38)]
    alone = [fast_evaluate(model, w).total for w in batches]
    with ThreadPoolExecutor(2) as pool:
        together = list(pool.map(lambda w: fast_evaluate(model, w).total, batches * 4))
    assert all(np.array_equal(t, alone[i % len(batches)]) for i, t in enumerate(together))


def test_dominance_kernels_match_reference():
    rng = np.random.default_rng(0)
    C, P = 3, 200
    cost = rng.choice([1.0, 2.0, 3.0, np.inf], size=(C, P))
    viol = np.where(np.isinf(cost).any(axis=0), rng.choice([0.5, 1.0, 2.0], size=P), 0.0)
    for i in range(P):
        for j in range(0, P, 7):
            want = bool(dominates(cost[:, i], viol[i], cost[:, j], viol[j]))
            assert kn.dominates_at(cost, i, viol[i], cost, j, viol[j]) == want
    g = np.array([[2.0], [2.0], [2.0]])
    for gv in (0.0, 1.0):
        mask = dominates(cost.T, viol, g[:, 0], np.float64(gv))
        assert kn.select_global(cost, viol, g, gv, True) == best_index(cost.T, viol, mask)
    assert kn.select_global(cost, viol, g, 0.0, False) == best_index(cost.T, viol)


def test_fast_math_matches_libm_where_it_decides():
    for y in (0.0, -0.0, 1.0, -1.0, 1e-300):
        for x in (0.0, -0.0, 1.0, -1.0, 3.0, -2.5):
            a, b = fm.atan2(y, x), math.atan2(y, x)
            assert a == b and math.copysign(1.0, a) == math.copysign(1.0, b)
    rng = np.random.default_rng(1)
    for _ in range(2000):
        y, x = rng.normal(size=2) * 10.0 ** rng.uniform(-3, 3, size=2)
        assert abs(fm.atan2(y, x) - math.atan2(y, x)) <= 4e-16 * max(1.0, abs(math.atan2(y, x)))
        s, c = fm.sincos(x)
        assert abs(s - math.sin(x)) <= 4e-16 and abs(c - math.cos(x)) <= 4e-16
    bits = [fm.unit_bits(np.uint64(fm.counter_hash(np.uint64(9), np.uint64(i)))) for i in range(4000)]
    u = np.array(bits, dtype=np.uint64).view(np.float64) - 1.0  # the kernels' uniform draws
    assert 0.0 <= u.min() and u.max() < 1.0 and abs(u.mean() - 0.5) < 0.02


def scenario2_problem() -> tuple[CostModel, SwarmProblem]:
    model = CostModel.from_scenario(load_scenario("scenario2"))
    return model, team_problem(model, 10, 0.5, "players")


def single_particle_cost(problem: SwarmProblem, X0: np.ndarray) -> tuple[np.ndarray, float]:
    """The compiled engine's compared cost of one particle (placed as the warm start)."""
    settings = SolverSettings(particles=1, iterations=0, waypoints=X0.shape[1])
    out = NumbaEngine(threads=1).run_swarm(problem, settings, np.random.default_rng(0), initial=X0)
    return out.best_cost, out.best_violation


@pytest.mark.parametrize("kind", ["players", "sum", "rigid", "fixed", "fixed-dem"])
def test_decoding_and_objectives_agree_with_problem(kind):
    model, problem = scenario2_problem()
    if kind == "fixed-dem":  # a deviation search on a DEM: the fixed paths' ground, once per block
        import dataclasses

        grid = np.random.default_rng(6).random((30, 30)) * 10.0
        grid.setflags(write=False)
        terrain = Terrain(elevation=grid, origin=(0.0, 0.0), cell_size=7.0, sampling="bilinear")
        def absolute(p: np.ndarray) -> np.ndarray:
            return frozen(np.c_[p[:, :2], terrain.absolute(p[:, 0], p[:, 1], p[:, 2])])

        model = dataclasses.replace(model, terrain=terrain, start_abs=absolute(model.starts),
                                    goal_abs=absolute(model.goals))
        kind = "fixed"
    if kind == "sum":
        problem = team_problem(model, 10, 0.5, "sum")
    elif kind == "rigid":
        problem = rigid_problem(model, 10, 0.5)
    elif kind == "fixed":  # one swarm for UAV 2, the others fly fixed paths; UAV 2's own J
        t = (np.arange(1, 11) / 11)[:, None]
        fixed = model.starts[:, None, :] + t[None] * (model.goals - model.starts)[:, None, :]
        problem = SwarmProblem(
            model=model, space=search_space(model.starts[1:2], model.goals[1:2], 10),
            starts=model.starts[1:2], lower=model.lower[None], upper=model.upper[None],
            member_of=np.array([-1, 0, -1]), offsets=np.zeros((3, 3)), objective="players",
            players=(1,), fixed=fixed,
        )
    X = problem.space.sample(np.random.default_rng(2), 12, 10)
    want_cost, want_viol, _ = problem.evaluate(X)
    for i in range(len(X)):
        cost, viol = single_particle_cost(problem, X[i])
        assert (viol == 0) == (want_viol[i] == 0)
        np.testing.assert_allclose(viol, want_viol[i], rtol=1e-9, atol=1e-9)
        assert np.array_equal(np.isinf(cost), np.isinf(want_cost[i]))
        fin = np.isfinite(want_cost[i])
        np.testing.assert_allclose(cost[fin], want_cost[i][fin], rtol=1e-9)


@pytest.mark.parametrize("particles", [70, 230])  # one thread below MIN_SHARED_PARTICLES; blocks split unevenly
def test_same_seed_same_result_for_any_thread_count(particles):
    from staghunt.engine.numba_engine import MIN_SHARED_PARTICLES

    assert 70 < MIN_SHARED_PARTICLES <= 230
    _, problem = scenario2_problem()
    settings = SolverSettings(particles=particles, iterations=30, waypoints=10)
    outs = [NumbaEngine(threads=t).run_swarm(problem, settings, np.random.default_rng(42)) for t in (1, 2, 3, 1)]
    for out in outs[1:]:
        assert np.array_equal(out.best, outs[0].best)
        assert np.array_equal(out.history, outs[0].history)
        assert np.array_equal(out.record_history, outs[0].record_history)
    other = NumbaEngine(threads=1).run_swarm(problem, settings, np.random.default_rng(43))
    assert not np.array_equal(other.best, outs[0].best)


@pytest.mark.parametrize("terrain", [None, "bilinear"])
def test_deviation_swarm_steps_on_the_fixed_paths(terrain, monkeypatch):
    """A deviation swarm's blocks leave the fixed team-mates' rows as the compiled loop filled
    them once per call, on every thread's buffers and lanes. Pooled buffers hold another
    deviation search's rows first, and the adaptive engine's probes switch between 1 and 2
    threads (blocks of 256 and of 32 lanes) after an initial draw on 2: the same run as on 1, 2
    and 3 pinned threads, and every best ``J_n`` is the NumPy reference's cost of that path
    against the fixed ones."""
    import staghunt.engine.numba_engine as ne
    from staghunt.solvers.problem import solo_problem

    model, base = _straight_routes(3, terrain, K=10)
    settings = SolverSettings(particles=230, iterations=40, waypoints=10)
    monkeypatch.setattr(ne, "usable_cores", lambda: 2)
    elsewhere = base + np.array([0.0, 6.0, 3.0])  # other fixed paths, the same shapes
    for t in (None, 1, 2, 3):  # leave their rows in the pooled buffers of every thread count
        NumbaEngine(threads=t).run_swarm(solo_problem(model, elsewhere, 1, 0.5), settings, np.random.default_rng(2))
    problem = solo_problem(model, base, 1, 0.5)
    outs = [NumbaEngine(threads=t).run_swarm(problem, settings, np.random.default_rng(8)) for t in (1, None, 2, 3)]
    for out in outs[1:]:
        assert np.array_equal(out.best, outs[0].best) and np.array_equal(out.history, outs[0].history)
    team = base.copy()
    team[1] = outs[0].best_waypoints[1]
    np.testing.assert_array_equal(outs[0].best_waypoints[[0, 2]], base[[0, 2]])
    want = evaluate(model, team[None])
    assert want.total_violation[0] == outs[0].best_violation == 0
    np.testing.assert_allclose(outs[0].best_cost[0], want.total[0, 1], rtol=1e-9)
    assert outs[0].history[-1, 0] < outs[0].history[0, 0]  # the swarm moved


def test_stretch_length_changes_calls_not_results(monkeypatch):
    """A run's iterations reach the compiled loop in stretches of at least ``CHUNK_ITERATIONS``,
    longer when the pace allows (``CHUNK_SECONDS``): fewer calls, the same run."""
    import staghunt.engine.loop as loop
    import staghunt.engine.numba_engine as ne

    assert loop.chunk_length(0.01, 25) == 125  # 0.4 ms an iteration: 0.05 s holds 125
    assert loop.chunk_length(1.0, 25) == loop.CHUNK_ITERATIONS == 25  # slow iterations: never fewer
    assert loop.chunk_length(0.0, 5) == 25
    _, problem = scenario2_problem()
    settings = SolverSettings(particles=40, iterations=60, waypoints=10)
    NumbaEngine(threads=1).prepare()  # its warm-up runs call the loop too
    calls = []
    real = ne.iterate_chunk
    monkeypatch.setattr(ne, "iterate_chunk", lambda it0, it1, *a: (calls.append((it0, it1)), real(it0, it1, *a))[1])
    outs = {}
    for seconds in (0.0, 1e9):
        monkeypatch.setattr(loop, "CHUNK_SECONDS", seconds)
        calls.clear()
        outs[seconds] = NumbaEngine(threads=1).run_swarm(problem, settings, np.random.default_rng(5))
        assert calls[0] == (0, 1) and calls[-1][1] == 61
        assert len(calls) == (1 + 3 if seconds == 0.0 else 2)  # 25 + 25 + 10, or the 60 at once
    assert np.array_equal(outs[0.0].best, outs[1e9].best)
    assert np.array_equal(outs[0.0].history, outs[1e9].history)
    assert np.array_equal(outs[0.0].record_history, outs[1e9].record_history)


def test_deviation_passes_give_their_buffers_back():
    """A deviation search borrows its block buffers for each call and gives them back (a fresh
    set per search, about 1 MB for 3 UAVs, cost more than a short polish), with the same costs
    on every call, whatever the buffers held before."""
    from staghunt.engine.deviations import Deviations

    model, base = _straight_routes(3, None)
    dev = Deviations(model, base, 1, fast_evaluate(model, base[None]))
    paths = base[1][None] + np.random.default_rng(3).normal(0.0, 2.0, size=(5, *base[1].shape))
    first = dev(paths)
    path, Jn, spent = dev.polish(float(evaluate(model, base[None]).total[0, 1]), 200, 1.0, 0.1)
    assert spent > 0 and np.isfinite(Jn)
    assert np.array_equal(dev(paths), first)
    assert dev._runs and all(not run.scratch for run in dev._runs.values())


def test_adaptive_threads_probe_and_choose():
    busy = AdaptiveThreads(2)  # two threads slower: keeps one thread after the probe
    seen = []
    for _ in range(20):
        n = busy.next()
        seen.append(n)
        busy.record(0.010 if n == 1 else 0.020)
    assert seen[:6] == [1, 2, 1, 2, 1, 2] and set(seen[6:]) == {1}
    idle = AdaptiveThreads(2)  # two threads faster: keeps two, re-probes when they slow down
    seen = []
    for i in range(40):
        n = idle.next()
        seen.append(n)
        idle.record((0.010 if n == 1 else 0.006) if i < 20 else (0.010 if n == 1 else 0.030))
    assert set(seen[6:20]) == {2} and seen[-1] == 1
    assert AdaptiveThreads(2, fixed=2).next() == 2 and AdaptiveThreads(1).next() == 1


@pytest.mark.parametrize("method", ["game", "paper", "rigid"])
def test_fast_engine_plans_feasibly_on_scenario2(method):
    scenario = load_scenario("scenario2")
    settings = scenario.solver.with_(particles=150, iterations=60)
    result = plan(scenario, method, 1, settings, engine="numba")
    assert result.feasible, result.message
    assert np.isfinite(result.history[-1]).all()
    again = plan(scenario, method, 1, settings, engine="numba", threads=2)
    assert np.array_equal(again.waypoints, result.waypoints)


def test_engine_names():
    assert isinstance(get_engine("numpy"), NumpyEngine)
    assert get_engine("numba", threads=2).threads == 2
    assert get_engine("auto").name == "numba"
    with pytest.raises(ValueError):
        get_engine("fortran")
    with pytest.raises(ValueError):
        get_engine("numba", threads=0)


def test_numba_plan_keeps_the_paths_the_kernel_evaluated():
    """The plan is the team waypoints the kernel decoded and judged (its trigonometry rounds
    differently from NumPy's), so a plan grazing a constraint keeps its verdict; they agree with
    NumPy's decoding of the same particle to rounding."""
    import staghunt
    from staghunt.costs import CostModel
    from staghunt.solvers.problem import team_problem

    scenario = staghunt.load_scenario("scenario2")
    settings = scenario.solver.with_(particles=40, iterations=15)
    model = CostModel.from_scenario(scenario)
    problem = team_problem(model, settings.waypoints, settings.velocity_fraction, "players")
    engine = get_engine("numba", threads=1)
    out = engine.run_swarm(problem, settings, np.random.default_rng(3))
    np.testing.assert_allclose(out.best_waypoints, problem.team_waypoints(out.best[None])[0], rtol=0, atol=1e-9)
    result = staghunt.plan(scenario, "game", seed=3, settings=settings, engine="numba", threads=1)
    assert result.engine == "numba"
    np.testing.assert_allclose(result.costs.total[0], result.history[-1], rtol=1e-9)


@pytest.mark.parametrize("terrain", [None, "bilinear"])
@pytest.mark.parametrize("radii", [None, (1.0, 2.5, 0.5, 1.0, 3.0, 1.0)])
@pytest.mark.parametrize("n_uavs", [3, 6])
def test_deviation_costs_match_the_full_evaluation(n_uavs, radii, terrain):
    """The compiled deviation evaluation (``MODE_DEVIATE``, used by ``game``'s polish) gives the
    full evaluation's ``J_n`` bit for bit and ``inf`` exactly where its total violation is not
    zero, for paths that hit team-mates (different radii: a deficit seen by one UAV only),
    obstacles and the ground, with and without pair pruning (N > 4), on flat ground and on a
    DEM (the fixed team-mates' ground looked up once per block)."""
    import dataclasses

    from staghunt.solvers.local import _own_costs

    model = make_model(n_uavs, terrain=None if terrain is None else dem(terrain, np.float64))
    # No cylinder: the straight start-goal lines (10 m apart) are a feasible plan.
    model = dataclasses.replace(model, cylinders=frozen(np.zeros((0, 3))))
    if radii is not None:
        model = dataclasses.replace(model, radius=frozen(np.array(radii[:n_uavs])))
    K = 6
    t = (np.arange(1, K + 1) / (K + 1))[None, :, None]
    plan0 = model.starts[:, None, :] + t * (model.goals - model.starts)[:, None, :]
    rng = np.random.default_rng(3)
    engine = NumbaEngine(threads=1)
    for n in range(n_uavs):
        plan_n = plan0.copy()
        full = evaluate(model, plan_n[None])
        if full.total_violation[0] != 0:
            continue
        paths = plan_n[n][None] + rng.normal(0.0, [6.0, 6.0, 8.0], size=(40, K, 3)) * np.linspace(0.05, 1.0, 40)[:, None, None]
        mate = (n + 1) % n_uavs
        paths[0] = plan_n[mate]  # on a team-mate's waypoints
        limits = 2.0 + 2.0 * model.radius  # d_s + 2 r
        paths[1] = plan_n[mate] + np.array([0.5 * (limits[n] + limits[mate]) + 0.25, 0.0, 0.0])
        paths[2, :, 2] = -1.0  # below ground
        got = engine.deviations(model, plan_n, n)(paths)
        want = _own_costs(model, plan_n, n, paths, engine)
        assert np.array_equal(np.isinf(got), np.isinf(want))
        assert np.array_equal(got, want)
        assert np.isinf(got).any() and np.isfinite(got).any()


def _straight_routes(n_uavs: int, terrain: str | None, K: int = 5) -> tuple[CostModel, np.ndarray]:
    """A model of ``n_uavs`` with a cylinder between two routes (on flat ground or a DEM) and
    its ``(N, K, 3)`` plan of straight start-goal lines."""
    import dataclasses

    model = make_model(n_uavs, terrain=None if terrain is None else dem(terrain, np.float64))
    model = dataclasses.replace(model, cylinders=frozen(np.array([[15.0, 50.0, 2.0]])))  # between two routes
    t = (np.arange(1, K + 1) / (K + 1))[None, :, None]
    return model, model.starts[:, None, :] + t * (model.goals - model.starts)[:, None, :]


@pytest.mark.parametrize("terrain", [None, "bilinear"])
@pytest.mark.parametrize("n_uavs", [3, 6])
def test_compiled_polish_is_the_reference_loop(n_uavs, terrain):
    """``game``'s polish in one compiled call (``kernels.polish``) takes the very path, and
    spends the very evaluations, of its Python loop on the same deviation costs, for budgets
    that end it mid-sweep and after it converged, paths that start near obstacles and the site
    box's faces (clamped moves), on flat ground and on a DEM."""
    from staghunt.solvers.local import polish

    model, base = _straight_routes(n_uavs, terrain)
    K = base.shape[1]
    engine = NumbaEngine(threads=1)
    rng = np.random.default_rng(11)
    compared = moved = 0
    for trial in range(16):
        n = int(rng.integers(n_uavs))
        plan_ = base.copy()
        plan_[n] = np.clip(plan_[n] + rng.normal(0.0, [3.0, 3.0, 4.0], size=(K, 3)), model.lower, model.upper)
        if trial % 4 == 0:
            plan_[n, 0, 2] = model.upper[2]  # on the box's top face: some moves are clamped
        if evaluate(model, plan_[None]).total_violation[0] != 0:
            continue
        for budget in (6 * K, 6 * K + 1, 500, 4000):
            want, spent_want = polish(model, plan_, n, budget, engine, compiled=False)
            got, spent_got = polish(model, plan_, n, budget, engine)
            assert spent_got == spent_want
            np.testing.assert_array_equal(got, want)
            compared += 1
            moved += not np.array_equal(got, plan_)
    assert compared >= 20 and moved >= 10


@pytest.mark.parametrize("terrain", [None, "bilinear"])
@pytest.mark.parametrize("n_uavs", [3, 6])
def test_compiled_team_search_is_the_reference_loop(n_uavs, terrain):
    """``game``'s team slide and team polish in one compiled call each (``kernels.team_search``)
    reach the very plan, spending the very evaluations, of their Python loops, for budgets that
    end them mid-sweep and after they converged, plans near an obstacle and the site box's top
    face (clamped moves), on flat ground and on a DEM; a plan they cannot improve is returned
    as itself. (After a cold compile the kernel may still be compiling beside the run: the
    Python loop is used meanwhile, with the same results; here it is waited for.)"""
    from staghunt.engine.numba_engine import team_search_ready
    from staghunt.solvers.game import team_polish, team_slide

    model, base = _straight_routes(n_uavs, terrain)
    engine = NumbaEngine(threads=1)
    J = engine.evaluate(model, base[None]).total[0]
    assert team_search_ready(wait=True) and engine.team_search(model, base, J, 0, 0) is not None
    rng = np.random.default_rng(5)
    compared = moved = 0
    for trial in range(8):
        plan_ = np.clip(base + rng.normal(0.0, [2.0, 2.0, 3.0], size=base.shape), model.lower, model.upper)
        if trial % 4 == 0:
            plan_[:, 0, 2] = model.upper[2]  # on the box's top face: some moves are clamped
        if evaluate(model, plan_[None]).total_violation[0] != 0:
            continue
        for search in (team_slide, team_polish):
            for budget in (n_uavs * 31, n_uavs * 200, 20_000):
                want, spent_want = search(model, plan_, budget, engine, compiled=False)
                got, spent_got = search(model, plan_, budget, engine)
                assert spent_got == spent_want
                np.testing.assert_array_equal(got, want)
                assert (got is plan_) == (want is plan_)
                compared += 1
                moved += got is not plan_
    assert compared >= 24 and moved >= 12


def test_team_search_runs_the_python_loop_while_its_kernel_compiles(monkeypatch):
    """After a cold compile the helper process may still be compiling ``team_search`` beside the
    first run: the engine then offers no compiled search and ``team_slide`` runs its Python loop,
    reaching the same plan; once the helper is done, the kernel is loaded and used."""
    import threading

    from staghunt.engine import compilation
    from staghunt.solvers.game import team_slide

    model, base = _straight_routes(3, None)
    engine = NumbaEngine(threads=1)
    engine.prepare()
    compiling = threading.Event()
    monkeypatch.setattr(compilation, "_later", {"done": compiling, "helper": None})
    monkeypatch.setattr(compilation, "_loaded", compilation._loaded - {"team_search"})
    J = engine.evaluate(model, base[None]).total[0]
    assert engine.team_search(model, base, J, 0, 0) is None and not compilation.team_search_ready()
    meanwhile = team_slide(model, base, 5000, engine)
    compiling.set()  # the helper has written it to the cache
    assert engine.team_search(model, base, J, 0, 0) is not None and "team_search" in compilation._loaded
    compiled = team_slide(model, base, 5000, engine)
    assert meanwhile[1] == compiled[1] and np.array_equal(meanwhile[0], compiled[0])
    assert meanwhile[0] is not base


def test_a_run_goes_on_one_thread_while_the_parallel_loop_compiles(monkeypatch):
    """After a cold compile the helper may still be compiling the parallel loop beside the first
    run: a run asked for two threads then runs on one (the serial loop), reports so, and gives the
    run of one thread; once the loop is loaded, it runs on two."""
    import threading

    from staghunt.engine import compilation
    from staghunt.engine import numba_engine as ne

    _, problem = scenario2_problem()
    settings = SolverSettings(particles=256, iterations=30, waypoints=10)
    monkeypatch.setattr(ne, "usable_cores", lambda: 2)
    monkeypatch.setattr(ne, "kernel_threads", lambda: 2)
    one = NumbaEngine(threads=1).run_swarm(problem, settings, np.random.default_rng(4))
    compiling = threading.Event()
    monkeypatch.setattr(compilation, "_later", {"done": compiling, "helper": None})
    monkeypatch.setattr(compilation, "_loaded", compilation._loaded - {"iterate"})
    engine = NumbaEngine(threads=2)
    meanwhile = engine.run_swarm(problem, settings, np.random.default_rng(4))
    assert engine.last_threads == {1: settings.iterations} and not compilation.parallel_ready()
    compiling.set()
    later = engine.run_swarm(problem, settings, np.random.default_rng(4))
    assert engine.last_threads == {2: settings.iterations} and "iterate" in compilation._loaded
    for out in (meanwhile, later):
        assert np.array_equal(out.best, one.best) and np.array_equal(out.history, one.history)


def test_kernel_arguments_bound_by_name_are_the_hand_written_ones():
    """The arguments bound from the kernels' parameter names (engine.arrays.kernel_args) are the
    very objects, in the order, that the hand-written calls they replaced passed."""
    from staghunt.engine.arrays import kernel_args, model_arrays, no_swarm
    from staghunt.engine.loop import ITERATE_PER_CALL, RunState
    from staghunt.engine.passes import TEAM_PASS_PER_CALL, UAV_PASS_PER_CALL, Pass
    from staghunt.engine.scratch import Scratch

    model = CostModel.from_scenario(load_scenario("scenario2"))
    N, K = model.n_uavs, 4
    run = Pass(model_arrays(model), no_swarm(N, K), N, K, 0, 1, 0, wp=np.zeros((8, N, K, 3)))
    run.key = np.uint64(99)  # the run's own key must not stand in for iterate's
    w, ma, sa = Scratch(N, K, 0, run.B), run.ma, run.sa
    uav = (run.X, run.V, run.PB, run.gbest, run.initial, sa.sw, sa.member, sa.offsets, sa.fixed, ma.par, run.wp,
           ma.uav, ma.cyl, ma.prm, ma.pedge, ma.grid, w.sww, w.px, w.py, w.pz, w.ph, w.stx, w.sty, w.sth,
           w.prev, w.bits1, w.bits2, w.ubits1, w.ubits2, w.seg, w.sub, w.ang, w.tmp, w.acc, w.acc2, w.flag, w.terms,
           w.vio)
    team = (w.px, w.py, w.pz, ma.uav, ma.weights, ma.heads, ma.tails, ma.mu, ma.ref_diff, ma.par, w.form, w.hit,
            w.tmp, w.acc, w.acc2, w.flag, w.better, w.box, w.near, w.terms, w.vio, w.res, run.X, run.PB,
            run.pcost, run.pviol, run.cost, run.viol, run.J, sa.players, run.terms_out, run.vio_out, run.res_out)
    extra = RunState(np.uint64(1), np.zeros(3), np.zeros((1, 1)), np.zeros((2, 1)), np.zeros((2, N)), np.zeros(2))
    loop = (extra.key, extra.state, run.X, run.V, run.PB, run.gbest, run.initial, sa.sw, sa.member, sa.offsets,
            sa.fixed, ma.par, ma.uav, ma.cyl, ma.prm, ma.pedge, ma.grid, ma.weights, ma.heads, ma.tails, ma.mu,
            ma.ref_diff, sa.players, run.pcost, run.pviol, run.cost, run.viol, run.J, extra.gcost, extra.history,
            extra.rhistory, extra.hviol, w.sww, w.px, w.py, w.pz, w.ph, w.stx, w.sty, w.sth, w.prev, w.bits1,
            w.bits2, w.ubits1, w.ubits2, w.seg, w.sub, w.ang, w.tmp, w.acc, w.acc2, w.flag, w.terms, w.vio, w.form,
            w.hit, w.better, w.box, w.near, w.res, run.wp, run.terms_out, run.vio_out, run.res_out, run.uav_entries,
            run.team_entries)
    for kernel, sources, per_call, expected in (
            (kn.uav_pass, (run, ma, sa, w), UAV_PASS_PER_CALL, uav),
            (kn.team_pass, (run, ma, sa, w), TEAM_PASS_PER_CALL, team),
            (kn.iterate, (extra, run, ma, sa, w), ITERATE_PER_CALL, loop),
            (kn.iterate_serial, (extra, run, ma, sa, w), ITERATE_PER_CALL, loop)):
        bound = kernel_args(kernel, *sources, per_call=per_call)
        assert len(bound) == len(expected) and all(a is b for a, b in zip(bound, expected)), kernel.__name__
    with pytest.raises(TypeError, match="does not start with"):
        kernel_args(kn.team_pass, run, ma, sa, w, per_call=("q0",))


def test_callers_reach_the_kernel_entries_through_their_addresses(monkeypatch):
    """``iterate`` and ``polish`` call the two entries through the table of their compiled code
    (engine.jit.entry_call): one row per overload, keyed by its signature's fingerprint; a table
    without the caller's signature stops the run with a clear error (from the serial loop, the
    parallel one and the polish), never a jump to a wrong address."""
    from staghunt.engine.jit import entry_table, signature_fingerprint
    from staghunt.engine.compilation import prepare
    from staghunt.engine.passes import Pass
    from staghunt.solvers.local import polish

    prepare()
    for entry in (kn.uav_pass, kn.team_pass):
        table = entry_table(entry)
        assert table.dtype == np.int64 and table.shape == (len(entry.overloads), 2)
        assert sorted(table[:, 0]) == sorted(signature_fingerprint(sig) for sig in entry.overloads)
        assert np.all(table[:, 1] != 0)
        assert entry_table(entry) is table  # made again only when the entry gains an overload
    model = CostModel.from_scenario(load_scenario("scenario2"))
    problem = team_problem(model, 4, 0.5)
    plan_ = plan(load_scenario("scenario2"), method="paper", seed=1,
                 settings=SolverSettings(particles=40, iterations=5, waypoints=4)).waypoints
    monkeypatch.setattr(Pass, "team_entries", property(lambda self: np.zeros((0, 2), dtype=np.int64)))
    for threads, particles in ((1, 16), (2, 256)):
        with pytest.raises(RuntimeError, match="no compiled team_pass"):
            NumbaEngine(threads=threads).run_swarm(problem, SolverSettings(particles=particles, iterations=2,
                                                                         waypoints=4), np.random.default_rng(0))
    with pytest.raises(RuntimeError, match="no compiled team_pass"):
        polish(model, np.array(plan_), 0, 100, NumbaEngine(threads=1))


def test_named_columns_fill_the_kernel_rows():
    from staghunt.engine.arrays import model_arrays

    model = CostModel.from_scenario(load_scenario("scenario2"))
    uav = model_arrays(model).uav
    assert uav.shape[1] == kn.U_COLUMNS
    np.testing.assert_array_equal(uav[:, kn.U_RADIUS], model.radius)
    np.testing.assert_array_equal(uav[:, kn.U_GOAL:kn.U_GOAL + 3], model.goals)
