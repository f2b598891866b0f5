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


def row_of(traj: TeamTrajectory, n: int) -> tuple[TeamTrajectory, int]:
    """The trajectory and row UAV ``n`` of ``traj`` flies, out of any :class:`RowTeam` (so that
    one UAV is evaluated without its team-mates)."""
    while isinstance(traj, RowTeam):
        traj, n = traj.parts[n], traj.rows[n]
    return traj, n


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


@dataclass(frozen=True, eq=False)
class Track:
    """One UAV's reference as it flies it: ``segments`` ``(start, trajectory, row)`` in time
    order, each flown from its start until the next one's (a :class:`TeamTrajectory` of one
    UAV). A new plan or a hold is one more segment (:meth:`then`)."""

    segments: tuple[tuple[float, TeamTrajectory, int], ...]

    @property
    def n_uavs(self) -> int:
        return 1

    @property
    def span(self) -> tuple[np.ndarray, np.ndarray]:
        first, last = self.segments[0], self.segments[-1]
        return np.array([first[1].span[0][first[2]]]), np.array([max(last[0], float(last[1].span[1][last[2]]))])

    def then(self, start: float, traj: TeamTrajectory, row: int) -> "Track":
        """This track with ``row`` of ``traj`` flown from ``start`` on (what came after is dropped)."""
        keep = tuple(s for s in self.segments if s[0] < start)
        return Track(keep + ((float(start), traj, int(row)),))

    def segment_at(self, t: float) -> tuple[float, TeamTrajectory, int]:
        for s in reversed(self.segments):
            if t >= s[0]:
                return s
        return self.segments[0]

    def state(self, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        starts = np.array([s[0] for s in self.segments])
        idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(self.segments) - 1)
        out = np.zeros((4, 1, len(t), 3))
        for i in np.unique(idx):
            sel = idx == i
            _, traj, row = self.segments[i]
            out[:, :, sel] = traj.state(t[sel])[:, row:row + 1]
        return out


@dataclass(frozen=True, eq=False)
class Still:
    """A team at rest at ``positions`` ``(N, 3)`` from ``t0`` on (and before it)."""

    positions: np.ndarray
    t0: float

    @property
    def n_uavs(self) -> int:
        return int(self.positions.shape[0])

    @property
    def span(self) -> tuple[np.ndarray, np.ndarray]:
        return np.full(self.n_uavs, self.t0), np.full(self.n_uavs, self.t0)

    def state(self, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        out = np.zeros((4, self.n_uavs, len(t), 3))
        out[0] = self.positions[:, None, :]
        return out
