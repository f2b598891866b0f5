"""Pareto dominance (paper eq. 9) with the feasibility-first rule for inf costs, and best_index."""

from __future__ import annotations

import math

import numpy as np

from staghunt.solvers.dominance import best_index, dominates, preference

INF = math.inf


def dom(a, va, b, vb) -> bool:
    out = dominates(np.asarray(a, float), np.asarray(va, float), np.asarray(b, float), np.asarray(vb, float))
    assert out.dtype == bool
    return bool(out)


def test_pareto_feasible():
    assert dom([1, 2, 3], 0, [1, 2, 4], 0)  # <= all, < one
    assert dom([0, 0, 0], 0, [1, 1, 1], 0)
    assert not dom([1, 2, 3], 0, [1, 2, 3], 0)  # equal: no
    assert not dom([1, 2, 5], 0, [1, 3, 4], 0)  # trade-off: neither
    assert not dom([1, 3, 4], 0, [1, 2, 5], 0)
    assert not dom([1, 2, 4], 0, [1, 2, 3], 0)  # worse


def test_feasibility_first():
    # feasible dominates infeasible, even with larger finite costs
    assert dom([100, 100], 0, [1, INF], 0.5)
    assert not dom([1, INF], 0.5, [100, 100], 0)
    # less violation dominates more, whatever the costs
    assert dom([INF, 9], 0.1, [1, INF], 0.2)
    assert not dom([1, INF], 0.2, [INF, 9], 0.1)
    # equal violation: neither (inf <= inf must not make one drift to the other)
    assert not dom([INF, 1], 0.3, [INF, 2], 0.3)
    assert not dom([INF, 2], 0.3, [INF, 1], 0.3)
    assert not dom([INF, INF], 0.3, [INF, INF], 0.3)


def test_inf_never_gives_nan_decisions_broadcast():
    rng = np.random.default_rng(1)
    P, C = 300, 3
    cost = rng.uniform(1, 10, size=(P, C))
    viol = np.where(rng.random(P) < 0.5, rng.choice([0.1, 0.2, 0.3], size=P), 0.0)
    infeasible = viol > 0
    cost[infeasible, rng.integers(0, C, size=infeasible.sum())] = INF
    with np.errstate(all="raise"):
        d = dominates(cost[:, None], viol[:, None], cost[None, :], viol[None, :])  # (P, P)
    assert d.shape == (P, P) and d.dtype == bool
    # irreflexive and antisymmetric
    assert not d.diagonal().any()
    assert not (d & d.T).any()
    # check every pair against the rule written out
    for i in range(0, P, 7):
        for j in range(0, P, 5):
            if viol[i] == 0 and viol[j] == 0:
                e = np.all(cost[i] <= cost[j]) and np.any(cost[i] < cost[j])
            else:
                e = viol[i] < viol[j]
            assert d[i, j] == e


def test_preference_key():
    cost = np.array([[1.0, np.e], [INF, 1.0], [0.0, 5.0]])
    viol = np.array([0.0, 0.4, 0.0])
    key, v = preference(cost, viol)
    assert key[0] == 1.0  # log 1 + log e
    assert key[1] == INF  # infeasible sorts after every feasible
    assert np.isfinite(key[2]) and key[2] < -600  # log of 0 is floored, not -inf / NaN
    np.testing.assert_array_equal(v, viol)


def test_best_index_tie_breaks():
    # among feasible: smallest sum of logs. (2,8): log16; (4,3): log12; (1,20): log20.
    cost = np.array([[2.0, 8.0], [4.0, 3.0], [1.0, 20.0], [0.5, INF]])
    viol = np.array([0.0, 0.0, 0.0, 0.2])
    assert best_index(cost, viol) == 1
    # sum of logs, not sum of costs: (5, 5) has sum 10 but log 25; (1, 20) has sum 21, log 20.
    c2 = np.array([[5.0, 5.0], [1.0, 20.0]])
    assert best_index(c2, np.zeros(2)) == 1
    # exact ties: lowest index
    c3 = np.array([[3.0, 4.0], [4.0, 3.0], [2.0, 6.0], [6.0, 2.0]])
    assert best_index(c3, np.zeros(4)) == 0
    assert best_index(c3, np.zeros(4), mask=np.array([False, True, True, True])) == 1
    # mask restricts the choice
    assert best_index(cost, viol, mask=np.array([True, False, True, True])) == 0
    # no feasible at all: least violation, lowest index on a tie
    ci = np.array([[INF, 1.0], [1.0, INF], [INF, INF], [2.0, INF]])
    assert best_index(ci, np.array([0.5, 0.2, 0.9, 0.2])) == 1
    assert best_index(ci, np.array([0.5, 0.2, 0.9, 0.2]), mask=np.array([True, False, True, True])) == 3
    # feasible beats any infeasible whatever the costs
    assert best_index(np.array([[INF, 0.1], [1e6, 1e6]]), np.array([0.01, 0.0])) == 1
    # in-mask infeasible only, out-of-mask feasible: stay inside the mask
    assert best_index(cost, viol, mask=np.array([False, False, False, True])) == 3
    # mask with no True -> -1
    assert best_index(cost, viol, mask=np.zeros(4, bool)) == -1
