"""A swarm problem: how swarm particles become team paths, and what is compared.

Every method is expressed as one :class:`SwarmProblem`, so that every engine (the NumPy
reference, the compiled fast one) runs every method.

Shapes: ``S`` swarms, ``N`` UAVs, ``K`` free waypoints, ``P`` particles.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from staghunt.costs import CostModel, evaluate
from staghunt.encoding import ANGLE_RANGE, SearchSpace, decode, search_space

if TYPE_CHECKING:
    from staghunt.scenario.model import SolverSettings


@dataclass(frozen=True, eq=False)
class SwarmProblem:
    """- ``model``: the team's cost model (``N`` UAVs).
    - ``space``: search ranges of the ``S`` swarms; ``starts``: ``(S, 3)`` where each swarm's
      decoding starts; ``lower``/``upper``: ``(S, 3)`` decoding boxes in ``(x, y, h)``.
    - ``member_of``: ``(N,)`` the swarm each UAV follows, or ``-1`` for a UAV whose path is fixed
      (then ``fixed[n]`` holds its ``(K, 3)`` waypoints); ``offsets``: ``(N, 3)`` added to the
      decoded swarm path (rigid formation), else zeros.
    - ``objective``: ``"players"``: the compared cost vector is ``J_n`` of ``players`` (``C``
      of them, each its own objective: Pareto dominance); ``"sum"``: one objective,
      ``sum_n J_n`` over the whole team.
    """

    model: CostModel
    space: SearchSpace
    starts: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    member_of: np.ndarray
    offsets: np.ndarray
    objective: Literal["players", "sum"]
    players: tuple[int, ...]
    fixed: np.ndarray | None = None

    def path_evaluations(self, settings: "SolverSettings") -> int:
        """Single-UAV path evaluations a run spends: ``particles * (iterations + 1)`` joint
        evaluations, each counting once per UAV path that varies with the particle (the UAVs
        that follow a swarm; fixed paths are not counted). The one place budgets are counted."""
        varying = int(np.count_nonzero(self.member_of >= 0))
        return settings.particles * (settings.iterations + 1) * varying

    @property
    def n_objectives(self) -> int:
        return len(self.players) if self.objective == "players" else 1

    def team_waypoints(self, X: np.ndarray) -> np.ndarray:
        """Spherical ``(P, S, K, 3)`` -> team free waypoints ``(P, N, K, 3)``."""
        swarm_paths = decode(X, self.starts, self.lower, self.upper)  # (P, S, K, 3)
        follow = np.clip(self.member_of, 0, None)
        team = swarm_paths[:, follow] + self.offsets[None, :, None, :]
        if self.fixed is not None:
            team = np.where((self.member_of < 0)[None, :, None, None], self.fixed[None], team)
        return team

    def objective_values(self, total: np.ndarray) -> np.ndarray:
        """Per-UAV ``J`` ``(P, N)`` -> compared costs ``(P, C)``."""
        if self.objective == "sum":
            with np.errstate(invalid="ignore"):
                return total.sum(axis=1, keepdims=True)
        return total[:, list(self.players)]

    def evaluate(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """NumPy reference evaluation: (compared cost ``(P, C)``, violation ``(P,)``, ``J`` ``(P, N)``).

        With ``fixed`` paths (a unilateral deviation) the violation is the players' own
        (obstacles, ground, separation from any team-mate) and ``J`` of the other UAVs is NaN:
        what the fixed UAVs do among themselves does not depend on the particle."""
        c = evaluate(self.model, self.team_waypoints(X))
        if self.fixed is None or self.objective == "sum":
            return self.objective_values(c.total), c.total_violation, c.total
        own = list(self.players)
        violation = c.violation[:, own].reshape(X.shape[0], -1).sum(axis=1)
        J = np.full_like(c.total, np.nan)
        J[:, own] = c.total[:, own]
        return self.objective_values(c.total), violation, J


def team_problem(model: CostModel, waypoints: int, velocity_fraction: float,
                 objective: Literal["players", "sum"] = "players") -> SwarmProblem:
    """One swarm per UAV, each decoding from its own start (``game``, ``weighted``)."""
    n = model.n_uavs
    return SwarmProblem(
        model=model,
        space=search_space(model.starts, model.goals, waypoints, velocity_fraction),
        starts=model.starts,
        lower=np.broadcast_to(model.lower, (n, 3)),
        upper=np.broadcast_to(model.upper, (n, 3)),
        member_of=np.arange(n),
        offsets=np.zeros((n, 3)),
        objective=objective,
        players=tuple(range(n)),
    )


def solo_problem(model: CostModel, waypoints: np.ndarray, n: int, velocity_fraction: float,
                 azimuth: float = ANGLE_RANGE) -> SwarmProblem:
    """UAV ``n``'s unilateral deviation from the team plan ``waypoints`` ``(N, K, 3)``: one
    swarm for UAV ``n`` (``member_of = -1`` for the others, whose paths are ``fixed``); the
    compared cost is ``J_n`` alone (``players = (n,)``) and the violation its own.
    ``azimuth``: half-width of the heading range (:func:`~staghunt.encoding.search_space`)."""
    N, K = waypoints.shape[0], waypoints.shape[1]
    member_of = np.full(N, -1, dtype=np.intp)
    member_of[n] = 0
    one = slice(n, n + 1)
    fixed = np.array(waypoints, dtype=float, copy=True)
    fixed.setflags(write=False)
    return SwarmProblem(
        model=model,
        space=search_space(model.starts[one], model.goals[one], K, velocity_fraction, azimuth),
        starts=model.starts[one],
        lower=model.lower[None],
        upper=model.upper[None],
        member_of=member_of,
        offsets=np.zeros((N, 3)),
        objective="players",
        players=(n,),
        fixed=fixed,
    )
