"""Cubic Hermite team curves through sampled positions and velocities: how an exported mission's
``trajectories.csv`` is flown (a :class:`~staghunt.trajectory.team.TeamTrajectory`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicHermiteSpline


@dataclass(frozen=True, eq=False)
class HermiteTeam:
    """Every UAV follows the cubic Hermite curve through its samples: positions and velocities
    ``(N, S, 3)`` at times ``t`` ``(S,)`` exactly as given, acceleration and jerk their
    derivatives; at rest on the first sample before ``t[0]`` and on the last after ``t[-1]``."""

    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    curve: CubicHermiteSpline = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "curve", CubicHermiteSpline(self.t, self.pos, self.vel, axis=1))

    @property
    def n_uavs(self) -> int:
        return int(self.pos.shape[0])

    @property
    def span(self) -> tuple[np.ndarray, np.ndarray]:
        return np.full(self.n_uavs, float(self.t[0])), np.full(self.n_uavs, float(self.t[-1]))

    def state(self, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        inside = (t >= self.t[0]) & (t <= self.t[-1])
        out = np.zeros((4, self.n_uavs, len(t), 3))
        for d in range(4):
            out[d][:, inside] = self.curve(t[inside], d)
        out[0][:, t < self.t[0]] = self.pos[:, :1]
        out[0][:, t > self.t[-1]] = self.pos[:, -1:]
        return out
