"""The one protocol every team curve answers, and teams assembled from other teams' rows.

:class:`TeamTrajectory` is what a flight, a check or a judge needs of a team's motion: its
state at any times. Three curve types implement it: the quintic pieces of a flight, spliced and
stopped in flight (:class:`staghunt.trajectory.quintic.Reference`), the time-optimal TOPP-RA
timing of an exported mission (:class:`staghunt.trajectory.Trajectories`) and the cubic
Hermite curves through ``trajectories.csv`` (:class:`staghunt.trajectory.hermite.HermiteTeam`).

Nothing in the protocol assumes shared waypoint indices or a common timing: every UAV has its
own start and end (:attr:`TeamTrajectory.span`), and :class:`RowTeam` puts together a team
whose UAVs fly rows of different trajectories (a UAV that missed a plan, one holding on its
own, one flying a route of its own). Shapes: ``N`` UAVs, ``T`` instants.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class TeamTrajectory(Protocol):
    """A team's motion in time (absolute site coordinates, m, s)."""

    @property
    def n_uavs(self) -> int:
        """``N``."""
        ...

    @property
    def span(self) -> tuple[np.ndarray, np.ndarray]:
        """``(N,)`` each UAV's start and end time: before its start a UAV holds its first point,
        after its end its last one, at rest."""
        ...

    def state(self, t: np.ndarray) -> np.ndarray:
        """``(4, N, T, 3)``: position, velocity, acceleration and jerk at times ``t`` ``(T,)``."""
        ...


def end_time(traj: TeamTrajectory) -> float:
    """When the last UAV of ``traj`` comes to rest (s)."""
    return float(np.max(traj.span[1]))


@dataclass(frozen=True, eq=False)
class RowTeam:
    """A team whose UAV ``n`` flies row ``rows[n]`` of ``parts[n]`` (a :class:`TeamTrajectory`);
    parts shared by several UAVs are evaluated once per call."""

    parts: tuple[TeamTrajectory, ...]
    rows: tuple[int, ...]

    @property
    def n_uavs(self) -> int:
        return len(self.rows)

    @property
    def span(self) -> tuple[np.ndarray, np.ndarray]:
        spans = {id(p): p.span for p in self.parts}
        return (np.array([spans[id(p)][0][r] for p, r in zip(self.parts, self.rows)]),
                np.array([spans[id(p)][1][r] for p, r in zip(self.parts, self.rows)]))

    def state(self, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        out = np.zeros((4, len(self.rows), len(t), 3))
        done: dict[int, np.ndarray] = {}
        for n, (part, row) in enumerate(zip(self.parts, self.rows)):
            if id(part) not in done:
                done[id(part)] = part.state(t)
            out[:, n] = done[id(part)][:, row]
        return out
