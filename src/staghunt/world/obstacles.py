"""Obstacles ("threats"): vertical cylinders, infinitely tall as in the SPSO reference."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np


@dataclass(frozen=True)
class Cylinder:
    """A vertical cylinder with axis at ``(x, y)`` and radius ``radius`` (metres)."""

    x: float
    y: float
    radius: float
    name: str = ""


def cylinder_array(cylinders: Sequence[Cylinder]) -> np.ndarray:
    """``(T, 3)`` array of ``(x, y, radius)`` rows."""
    if not cylinders:
        return np.zeros((0, 3))
    return np.array([[c.x, c.y, c.radius] for c in cylinders], dtype=float)
