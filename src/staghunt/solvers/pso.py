"""Vectorised particle-swarm operators (pure functions; random draws are arguments).

Shapes: ``X``, ``V``, ``pbest``: ``(P, N, K, 3)``; ``gbest``: ``(N, K, 3)``; ``lower``, ``upper``,
``vmax``: ``(N, 3)`` per swarm and spherical component.
"""

from __future__ import annotations

import numpy as np


def velocity_step(
    X: np.ndarray,
    V: np.ndarray,
    pbest: np.ndarray,
    gbest: np.ndarray,
    inertia: float,
    c1: float,
    c2: float,
    r1: np.ndarray,
    r2: np.ndarray,
    vmax: np.ndarray,
) -> np.ndarray:
    """``V' = clip(w V + c1 r1 (Q_i - X) + c2 r2 (Q_g - X), -vmax, vmax)`` (paper eq. 10, corrected)."""
    V = inertia * V + c1 * r1 * (pbest - X) + c2 * r2 * (gbest[None] - X)
    vm = vmax[None, :, None, :]
    return np.clip(V, -vm, vm)


def position_step(
    X: np.ndarray, V: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``X' = X + V``; components leaving the range are clamped and their velocity mirrored."""
    X = X + V
    lo = lower[None, :, None, :]
    hi = upper[None, :, None, :]
    out = (X < lo) | (X > hi)
    return np.clip(X, lo, hi), np.where(out, -V, V)
