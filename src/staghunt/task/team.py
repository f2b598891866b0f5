"""The team: each UAV's start, goal, body radius and cost weights."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

WEIGHT_NAMES = ("length", "threat", "altitude", "turning", "climb")


@dataclass(frozen=True)
class Weights:
    """Per-UAV cost weights: ``J_n = J_s + beta * J_f`` and ``J_s = sum_i w_i * term_i``."""

    beta: float
    w1: float  # length
    w2: float  # threat
    w3: float  # altitude
    w4: float  # turning
    w5: float  # climb

    def as_array(self) -> np.ndarray:
        """``(5,)`` array ``(w1..w5)``."""
        return np.array([self.w1, self.w2, self.w3, self.w4, self.w5], dtype=float)


@dataclass(frozen=True)
class UAV:
    """One team member. ``start`` and ``goal`` are ``(x, y, h)`` with ``h`` height above ground."""

    name: str
    start: tuple[float, float, float]
    goal: tuple[float, float, float]
    radius: float
    weights: Weights


Team = tuple[UAV, ...]
