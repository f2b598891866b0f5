"""Common time warps of a team trajectory: ``tau(t)``, the time along the trajectory flown at
time ``t``, the same for every UAV, so every UAV stays on its path and the team keeps its
relative timing (separations and clearances to what does not move are those already checked).

- :func:`brake_warp`: an emergency stop's, whose deceleration ramps up, holds and ramps down;
- :func:`slow_warp`: a slow-down that lets a known motion pass first (a *yield*): ``tau'``
  falls from 1 to ``factor`` along a smoothstep, holds there, and rises back to 1, so the team
  arrives ``(1 - factor) (T + hold)`` later on the same paths.

Both keep ``tau'' = 0`` at their ends, so position, velocity and acceleration stay continuous.
(The smooth stop of :func:`~staghunt.trajectory.quintic.stop_piece` is written in its piece.)
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

BRAKE_RAMP = 0.1
"""Share of a braking stop's duration over which its deceleration ramps up (and down)."""


@lru_cache(maxsize=1)
def _brake_table(n: int = 4001) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``u``, ``tau(u)``, ``tau'(u)``, ``tau''(u)`` of :func:`brake_warp` on a grid of ``n``."""
    u = np.linspace(0.0, 1.0, n)
    r = BRAKE_RAMP
    x = np.clip(np.minimum(u, 1.0 - u) / r, 0.0, 1.0)
    g = 3.0 * x**2 - 2.0 * x**3  # 0 at both ends, 1 in between
    du = u[1] - u[0]
    G = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * du)])
    d2 = -g / G[-1]
    d1 = 1.0 - G / G[-1]
    tau = np.concatenate([[0.0], np.cumsum(0.5 * (d1[1:] + d1[:-1]) * du)])
    return u, tau, d1, d2


def brake_warp(u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The warp of an emergency stop on ``u = (t - t_s) / T`` in ``[0, 1]``: ``tau / T``,
    ``tau'`` and ``T tau''``. Its deceleration ramps up over :data:`BRAKE_RAMP` of ``T`` (a
    smoothstep, so ``tau'' = 0`` at both ends and the splice stays continuous in acceleration),
    holds, and ramps down: it stops in ``v^2 / (2 a (1 - BRAKE_RAMP))`` at a peak deceleration
    ``a``, against ``1.5 v^2 / (2 a)`` for the smooth warp."""
    grid, tau, d1, d2 = _brake_table()
    return np.interp(u, grid, tau), np.interp(u, grid, d1), np.interp(u, grid, d2)


def slow_warp(s: np.ndarray, ramp: float, hold: float, factor: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A yield's warp at ``s`` ``(T,)`` seconds after it starts: ``tau - t_s``, ``tau'`` and
    ``tau''``. ``tau' = 1 - (1 - factor) g``, where ``g`` rises from 0 to 1 along a smoothstep
    over ``ramp`` seconds, holds 1 for ``hold`` seconds and falls back along a smoothstep over
    ``ramp`` seconds; after that the trajectory goes on ``(1 - factor) (ramp + hold)`` seconds
    behind its own time."""
    s = np.asarray(s, dtype=float)
    c = 1.0 - factor
    x1 = np.clip(s / ramp, 0.0, 1.0)
    x2 = np.clip((s - ramp - hold) / ramp, 0.0, 1.0)
    g = 3.0 * x1**2 - 2.0 * x1**3 - (3.0 * x2**2 - 2.0 * x2**3)
    dg = (6.0 * x1 * (1.0 - x1) - 6.0 * x2 * (1.0 - x2)) / ramp
    # the integral of g: ramp (x^3 - x^4 / 2) along each smoothstep, 1 per second in between
    G = (ramp * (x1**3 - 0.5 * x1**4) + np.clip(s - ramp, 0.0, hold)
         + ramp * (x2 - (x2**3 - 0.5 * x2**4)))
    return s - c * G, 1.0 - c * g, -c * dg
