"""Spherical-vector path encoding of the SPSO reference (docs/model.md eqs. (13), (14)).

A particle holds, per UAV and free waypoint, ``(rho, psi, phi)``: step length, elevation and
azimuth (from the x axis). Shapes: ``P`` particles, ``N`` UAVs (or swarms), ``K`` free waypoints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ANGLE_RANGE = np.pi / 4


@dataclass(frozen=True, eq=False)
class SearchSpace:
    """Per-swarm search ranges and velocity limits, each ``(N, 3)`` over ``(rho, psi, phi)``."""

    lower: np.ndarray
    upper: np.ndarray
    vmax: np.ndarray

    @property
    def n_swarms(self) -> int:
        return int(self.lower.shape[0])

    def sample(self, rng: np.random.Generator, particles: int, waypoints: int) -> np.ndarray:
        """Uniform ``(P, N, K, 3)`` positions in the ranges."""
        u = rng.random((particles, self.n_swarms, waypoints, 3))
        return self.lower[None, :, None, :] + u * (self.upper - self.lower)[None, :, None, :]


def search_space(
    starts: np.ndarray, goals: np.ndarray, waypoints: int, velocity_fraction: float = 0.5,
    azimuth: float = ANGLE_RANGE,
) -> SearchSpace:
    """Ranges of docs/model.md eq. (14) for ``(N, 3)`` starts and goals (``(x, y, h)``).

    ``rho in [0, 2 |G - S| / K]``, ``psi in [-pi/4, pi/4]``, ``phi in phi0 +- pi/4`` with
    ``phi0 = atan2(Gy - Sy, Gx - Sx)``; velocity limit ``velocity_fraction * (max - min)``.
    ``azimuth``: the half-width of the ``phi`` range (the paper's ``pi/4``; a re-plan from rest
    next to an obstacle widens it, docs/model.md section 8).
    """
    starts = np.atleast_2d(starts)
    goals = np.atleast_2d(goals)
    d = goals - starts
    phi0 = np.arctan2(d[:, 1], d[:, 0])
    rho_max = 2.0 * np.linalg.norm(d, axis=1) / waypoints
    zeros = np.zeros_like(phi0)
    lower = np.stack([zeros, zeros - ANGLE_RANGE, phi0 - azimuth], axis=1)
    upper = np.stack([rho_max, zeros + ANGLE_RANGE, phi0 + azimuth], axis=1)
    return SearchSpace(lower=lower, upper=upper, vmax=velocity_fraction * (upper - lower))


def decode(
    spherical: np.ndarray, starts: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> np.ndarray:
    """Spherical particles -> Cartesian free waypoints, clamped to the box after every step.

    ``spherical``: ``(P, N, K, 3)``; ``starts``: ``(N, 3)``; ``lower``/``upper``: ``(3,)`` or
    ``(N, 3)`` box in ``(x, y, h)``. Returns ``(P, N, K, 3)`` as ``(x, y, h)``.
    """
    rho, psi, phi = spherical[..., 0], spherical[..., 1], spherical[..., 2]
    cp = np.cos(psi)
    steps = np.stack([rho * cp * np.cos(phi), rho * cp * np.sin(phi), rho * np.sin(psi)], axis=-1)
    lo = np.broadcast_to(lower, (starts.shape[0], 3))
    hi = np.broadcast_to(upper, (starts.shape[0], 3))
    out = np.empty_like(steps)
    prev = np.broadcast_to(starts, steps[:, :, 0].shape)
    for k in range(steps.shape[2]):  # a scan over K (clamping makes it no plain cumsum)
        prev = np.clip(prev + steps[:, :, k], lo, hi)
        out[:, :, k] = prev
    return out


def encode(waypoints: np.ndarray, starts: np.ndarray, space: SearchSpace) -> np.ndarray:
    """Inverse of :func:`decode` for paths inside the box: ``(P, N, K, 3)`` -> spherical, clipped to the ranges.

    Exact (round trip) when every step already lies within the ranges; otherwise the nearest
    representable particle.
    """
    prev = np.concatenate(
        [np.broadcast_to(starts[None, :, None, :], (waypoints.shape[0], starts.shape[0], 1, 3)),
         waypoints[:, :, :-1]],
        axis=2,
    )
    d = waypoints - prev
    rho = np.linalg.norm(d, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        psi = np.where(rho > 0, np.arcsin(np.clip(d[..., 2] / rho, -1, 1)), 0.0)
    phi = np.arctan2(d[..., 1], d[..., 0])
    lo = space.lower[None, :, None, :]
    hi = space.upper[None, :, None, :]
    mid = 0.5 * (lo[..., 2] + hi[..., 2])
    phi = mid + (phi - mid + np.pi) % (2 * np.pi) - np.pi  # nearest branch to the range centre
    phi = np.where(rho > 0, phi, mid)
    return np.clip(np.stack([rho, psi, phi], axis=-1), lo, hi)
