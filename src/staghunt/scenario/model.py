"""The scenario: world + team + formation + cost parameters + solver settings, all immutable."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from staghunt.task import UAV, Formation, VehicleLimits
from staghunt.task.objectives import Inspection
from staghunt.world import GeoOrigin, World
from staghunt.world.dynamic import Dynamics


@dataclass(frozen=True)
class CostParams:
    """Parameters of the cost terms (docs/model.md eqs. (2b), (2c), (2d), (2e), (6)).

    - ``danger_margin``: ``Delta`` (m), width of the penalised band around an obstacle.
    - ``safe_distance``: ``d_s`` (m); UAVs ``n`` and ``m`` collide when closer than ``d_s + 2 r_n``.
    - ``turning_threshold_deg`` / ``climb_threshold_deg``: a turning angle or climb-angle change
      counts (whole) only where strictly greater than this (0 = the paper, 45 = the reference).
    - ``desired_height``: ``h_ref`` (m above ground); ``None`` = middle of the height band.
    - ``continuous_separation``: also require separation *between* waypoints (closest approach of
      synchronised segments) as a constraint; the paper checks waypoints only.
    - ``min_clearance``: hard minimum clearance (m) between a UAV's body and an obstacle's
      surface: a segment whose horizontal distance to a cylinder's axis is below
      ``R + r + min_clearance`` is infeasible. The danger band still ends at ``R + r + Delta``.
      ``0`` = the paper (only touching is forbidden).
    """

    danger_margin: float = 10.0
    safe_distance: float = 2.0
    turning_threshold_deg: float = 0.0
    climb_threshold_deg: float = 0.0
    desired_height: float | None = None
    continuous_separation: bool = True
    min_clearance: float = 0.0


@dataclass(frozen=True)
class SolverSettings:
    """Swarm settings. Paper: 2000 particles, 1500 iterations, K = 10, c0 = 0.999, c1 = c2 = 1.5.

    ``damping`` multiplies the inertia ``c0`` after every iteration (the reference uses 0.98).
    ``velocity_fraction``: velocity limit per component as a fraction of its range (0.5).
    ``starts``: the starts of the ``game`` method's equilibrium search (docs/model.md section
    6.1; other methods ignore it).
    """

    particles: int = 2000
    iterations: int = 1500
    waypoints: int = 10
    c0: float = 0.999
    damping: float = 0.98
    c1: float = 1.5
    c2: float = 1.5
    velocity_fraction: float = 0.5
    starts: int = 3

    def with_(self, **changes: object) -> "SolverSettings":
        """A copy with the given fields replaced (``None`` values are ignored)."""
        return replace(self, **{k: v for k, v in changes.items() if v is not None})


@dataclass(frozen=True, eq=False)
class Scenario:
    """A validated planning problem. Build it with :func:`staghunt.scenario.load_scenario`.

    ``origin``: the geodetic origin of the site frame (``None``: the scenario is not
    geo-referenced; exports then need one given explicitly). ``vehicle``: the team's flight
    limits. ``dynamics``: what changes in flight (moving obstacles, events, sensing; empty for a
    frozen site), used by ``fly``. ``inspection``: the cameras the UAVs carry and the objectives
    to capture (``None``: no camera given), used by ``inspect``, ``plan``, ``fly`` and ``export``."""

    name: str
    description: str
    world: World
    team: tuple[UAV, ...]
    formation: Formation
    costs: CostParams
    solver: SolverSettings
    origin: GeoOrigin | None = None
    vehicle: VehicleLimits = VehicleLimits()
    dynamics: Dynamics = Dynamics()
    inspection: Inspection | None = None

    @property
    def n_uavs(self) -> int:
        return len(self.team)

    @property
    def h_ref(self) -> float:
        if self.costs.desired_height is not None:
            return float(self.costs.desired_height)
        b = self.world.bounds
        return 0.5 * (b.hmin + b.hmax)

    def starts(self) -> np.ndarray:
        """``(N, 3)`` starts as ``(x, y, h)``."""
        return np.array([u.start for u in self.team], dtype=float)

    def goals(self) -> np.ndarray:
        """``(N, 3)`` goals as ``(x, y, h)``."""
        return np.array([u.goal for u in self.team], dtype=float)

    def with_solver(self, **changes: object) -> "Scenario":
        return replace(self, solver=self.solver.with_(**changes))


def check_settings(s: SolverSettings, what: str = "solver settings") -> None:
    """Raise ``ValueError`` with one clear line (``what: ...``) for unusable solver settings."""
    def integer(v: object, low: int) -> bool:
        return isinstance(v, int) and not isinstance(v, bool) and v >= low

    def real(v: object) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

    checks = [
        (integer(s.particles, 1), "particles must be an integer >= 1"),
        (integer(s.iterations, 0), "iterations must be an integer >= 0"),
        (integer(s.waypoints, 1), "waypoints must be an integer >= 1"),
        (integer(s.starts, 1), "starts must be an integer >= 1"),
        (all(real(v) and v >= 0 for v in (s.c0, s.c1, s.c2, s.damping)),
         "c0, c1, c2 and damping must be finite numbers >= 0"),
        (real(s.velocity_fraction) and 0 < s.velocity_fraction <= 1,
         "velocity_fraction must be a number in (0, 1]"),
    ]
    for ok, msg in checks:
        if not ok:
            raise ValueError(f"{what}: {msg}")
