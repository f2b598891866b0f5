"""The team: each UAV's start, goal, body radius and cost weights."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from staghunt.task.airframes import DEFAULT_AIRFRAME

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


@dataclass(frozen=True)
class VehicleLimits:
    """Flight limits shared by the team's vehicles (used to time the trajectories of a plan).

    ``max_speed`` (m/s) and ``max_acceleration`` (m/s^2) are hard limits that a timed
    trajectory never exceeds; ``cruise_speed`` (m/s, at most ``max_speed``) is the speed a
    mission is flown at where nothing forces it slower. The defaults fit small multirotors
    (a DJI Mini/Mavic or a PX4/ArduPilot quadcopter with its default mission speeds).
    ``airframe``: the simulated vehicles' airframe (a name of
    :data:`staghunt.task.airframes.AIRFRAMES`), flown by ``fly`` and ``export --simulate``."""

    max_speed: float = 12.0
    max_acceleration: float = 3.0
    cruise_speed: float = 5.0
    airframe: str = DEFAULT_AIRFRAME
