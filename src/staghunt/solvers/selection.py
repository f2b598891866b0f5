"""Equilibrium selection: among the equilibria a multi-start search reached, the payoff-dominant
one if it exists, else the one rule (9c) prefers among those no other dominates.

The paper's claim is a *payoff-dominant* equilibrium: one that Pareto-dominates every other
equilibrium of the game (docs/model.md, section 6.1). A search can only compare the equilibria
it found, so the verdict reads "payoff-dominant among the equilibria found".

- An **equilibrium** here is a candidate plan whose certificate accepts it (every relative Nash
  gap at most ``epsilon``, :class:`~staghunt.solvers.response.Certificate`).
- Two equilibria are **the same** when every UAV's ``J_n`` agrees within ``epsilon`` (relative):
  the certificate cannot tell them apart, so neither may dominate the other on a difference
  smaller than the tolerance that admitted both. The representative of a group is the one (9c)
  prefers (the least ``sum_n ln J_n``).
- Among the distinct equilibria, one is **dominated** when another dominates it (eq. (9a)).
- The **payoff-dominant** equilibrium dominates every other distinct one (with one equilibrium
  found, it is that one). When none does, the rule is (9c) among the undominated ones: the least
  ``sum_n ln J_n`` (the geometric mean of the players' costs, scale-free).
- With no certified candidate (certificates off, or none accepted), the plan is the candidate
  (9c) prefers: the least violation, then the least ``sum_n ln J_n``; nothing is claimed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from staghunt.solvers.dominance import dominates, preference
from staghunt.solvers.response import Certificate

RULE_PAYOFF_DOMINANT = "payoff-dominant: the equilibrium found that Pareto-dominates every other one found"
RULE_FRONT = ("no equilibrium found dominates all the others: among the undominated ones, the least "
              "sum_n ln J_n (eq. 9c)")
RULE_UNCERTIFIED = ("no certified equilibrium among the starts: the least violation, then the least "
                    "sum_n ln J_n (eq. 9c)")


@dataclass(frozen=True, eq=False)
class Candidate:
    """Where one start ended: its ``start`` kind, the ``(N, K, 3)`` ``plan``, its ``(N,)`` ``J``
    and total ``violation``, its ``certificate`` (``None``: not certified) and the path
    ``evaluations`` the start spent."""

    start: str
    plan: np.ndarray
    J: np.ndarray
    violation: float
    certificate: Certificate | None
    evaluations: int

    @property
    def certified(self) -> bool:
        return self.certificate is not None and self.certificate.is_equilibrium


@dataclass(frozen=True)
class Selection:
    """The outcome of :func:`select` over a list of candidates (indices into it).

    ``chosen``: the plan returned. ``equilibria``: the distinct certified ones (representatives),
    best (9c) first; ``dominated[i]`` whether another of them dominates ``equilibria[i]``;
    ``same_as[j]``: for every candidate, the representative it was merged into (``-1``: not an
    equilibrium). ``payoff_dominant``: whether ``chosen`` dominates every other distinct
    equilibrium found; ``rule``: the sentence saying why ``chosen`` was chosen."""

    chosen: int
    equilibria: tuple[int, ...]
    dominated: tuple[bool, ...]
    same_as: tuple[int, ...]
    payoff_dominant: bool
    rule: str


def same_equilibrium(J_a: np.ndarray, J_b: np.ndarray, epsilon: float) -> bool:
    """Whether two ``(N,)`` cost vectors agree within ``epsilon`` (relative) for every UAV."""
    a, b = np.asarray(J_a, dtype=float), np.asarray(J_b, dtype=float)
    return bool(np.all(np.abs(a - b) <= epsilon * np.maximum(np.abs(a), np.abs(b))))


def select(candidates: list[Candidate], epsilon: float) -> Selection:
    """Select the plan among ``candidates`` (module docstring); ``epsilon``: the certificate's
    relative tolerance, which also decides when two equilibria are the same."""
    if not candidates:
        raise ValueError("no candidate to select from")
    J = np.array([c.J for c in candidates], dtype=float)  # (M, N)
    v = np.array([c.violation for c in candidates], dtype=float)
    logs, _ = preference(J, v)
    order = sorted(range(len(candidates)), key=lambda i: (v[i], logs[i], i))
    same_as = [-1] * len(candidates)
    reps: list[int] = []
    for i in order:
        if not candidates[i].certified:
            continue
        home = next((r for r in reps if same_equilibrium(J[i], J[r], epsilon)), None)
        if home is None:
            reps.append(i)
            home = i
        same_as[i] = home
    if not reps:
        return Selection(order[0], (), (), tuple(same_as), False, RULE_UNCERTIFIED)
    zero = np.zeros(())
    dominated = tuple(bool(any(dominates(J[o], zero, J[r], zero) for o in reps if o != r)) for r in reps)
    # reps[0] is never dominated: whatever dominates it would have a smaller sum_n ln J_n. So it
    # is the payoff-dominant equilibrium if there is one, and rule (9c)'s choice otherwise.
    top = reps[0]
    payoff = all(bool(dominates(J[top], zero, J[o], zero)) for o in reps[1:])
    return Selection(top, tuple(reps), dominated, tuple(same_as), payoff,
                     RULE_PAYOFF_DOMINANT if payoff else RULE_FRONT)


def summary(c: Candidate) -> dict[str, Any]:
    """A candidate's entry in the run's details: its start, ``J``, feasibility and certificate."""
    cert = c.certificate
    return {
        "start": c.start,
        "J": [float(x) for x in c.J],
        "feasible": bool(c.violation == 0),
        "evaluations": int(c.evaluations),
        "certificate": None if cert is None else {
            "status": cert.status,
            "epsilon": float(cert.epsilon),
            "max_relative_gap": float(cert.max_relative_gap),
            "relative_gaps": [float(u.relative) for u in cert.uavs],
            "complete": bool(cert.complete),
            "particles": int(cert.particles),
            "iterations": int(cert.iterations),
        },
    }
