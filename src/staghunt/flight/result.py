"""How a flight ended (:class:`FlightStatus`) and what it recorded (:class:`FlightResult`): the
flown states judged by the one safety judge against the true world, at every simulation step."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np

from staghunt.flight.config import FlyConfig
from staghunt.flight.records import ReplanRecord
from staghunt.safety import Margins, Scene, Verdict, judge
from staghunt.scenario import Scenario
from staghunt.trajectory.quintic import Reference
from staghunt.world.dynamic import Dynamics

ARRIVAL_TOLERANCE = 1.0
"""A UAV has arrived once it stays within this distance (m) of its goal."""


class FlightStatus(str, Enum):
    """How an episode ended, worst first: ``UNSAFE`` a contact (a body touched an obstacle, a
    team-mate or the ground; exit code 5); ``BREACH`` a required margin broken without contact
    (clearance, separation, ground or ceiling; exit code 4); ``STOPPED`` the team stopped
    safely because no plan reached the goals (exit code 3); ``ARRIVED`` every UAV at its goal
    with every margin kept (exit code 0)."""

    ARRIVED = "arrived"
    STOPPED = "stopped"
    BREACH = "breach"
    UNSAFE = "unsafe"

    @property
    def exit_code(self) -> int:
        return {FlightStatus.ARRIVED: 0, FlightStatus.STOPPED: 3, FlightStatus.BREACH: 4, FlightStatus.UNSAFE: 5}[self]


@dataclass(frozen=True, eq=False)
class FlightResult:
    """A simulated closed-loop flight of ``N`` UAVs, sampled at ``T`` simulation steps.

    - ``times``: ``(T,)`` s after take-off; ``actual``, ``reference``: ``(N, T, 3)`` absolute
      site positions of the vehicles and of the references they track; ``velocity``: ``(N, T, 3)``.
    - ``replans``: one :class:`ReplanRecord` per re-plan.
    - ``verdict``: the one safety judge on the flown states (:class:`staghunt.safety.Verdict`:
      the breaches, contacts first, where and when); ``min_separation``: ``(N,)`` least
      distance to a team-mate; ``separation_limit``: ``(N,)`` ``d_s + 2 r``;
      ``min_clearance``: ``(N,)`` least clearance to any obstacle where it truly was at that
      instant (static, appeared, moving); ``required_clearance``: the scenario's.
    - ``tracking_rms``, ``tracking_max``: ``(N,)`` |actual - reference| (m).
    - ``arrival``: ``(N,)`` time each UAV arrived for good (``nan``: never);
      ``baseline_arrival``: when the plan without events arrives; ``extra_time``: the last
      arrival minus that.
    - ``stops``: synchronised stops to hover; ``holds``: UAVs that held on their own (plan
      timeout, missed plan, reflex); ``plan_*``: the offline plan before take-off
      (``plan_margins``: which margins it was solved with,
      :data:`staghunt.flight.offline.PLAN_MARGINS`).
    - ``link``: messages sent and lost.
    """

    scenario: Scenario
    dynamics: Dynamics
    config: FlyConfig
    seed: int
    status: FlightStatus
    message: str
    times: np.ndarray
    actual: np.ndarray
    velocity: np.ndarray
    reference: np.ndarray
    replans: tuple[ReplanRecord, ...]
    verdict: Verdict
    separation_limit: np.ndarray
    required_clearance: float
    tracking_rms: np.ndarray
    tracking_max: np.ndarray
    arrival: np.ndarray
    baseline_arrival: float
    stops: int
    holds: int
    plan_waypoints: np.ndarray
    plan_windows: tuple[tuple[str, float, float], ...]
    plan_margins: str
    wall_time_s: float
    link: dict[str, Any] = field(default_factory=dict)
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def min_separation(self) -> np.ndarray:
        return self.verdict.min_separation

    @property
    def min_clearance(self) -> np.ndarray:
        return self.verdict.min_clearance

    @property
    def extra_time(self) -> float:
        return float(np.max(self.arrival) - self.baseline_arrival) if np.all(np.isfinite(self.arrival)) else math.inf

    @property
    def safe(self) -> bool:
        """No contact (a breach of a margin is not a contact)."""
        return self.status is not FlightStatus.UNSAFE

    @property
    def uav_names(self) -> list[str]:
        return [u.name for u in self.scenario.team]


def arrival_times(times: np.ndarray, pos: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """``(N,)`` the time from which each of ``pos`` ``(N, T, 3)`` stays within
    :data:`ARRIVAL_TOLERANCE` of its goal ``(N, 3)`` (``nan``: it never does)."""
    away = np.linalg.norm(pos - goals[:, None], axis=-1) > ARRIVAL_TOLERANCE  # (N, T)
    last = np.where(away.any(axis=1), (away.shape[1] - 1) - np.argmax(away[:, ::-1], axis=1), -1)
    return np.array([times[i + 1] if i + 1 < len(times) else np.nan for i in last])


def baseline_arrival(ref: Reference) -> float:
    """When the plan flown without events arrives (by :func:`arrival_times` on its reference)."""
    t = np.arange(0.0, ref.arrival + 0.01, 0.01)
    pos = ref.state(t)[0]
    return float(np.nanmax(arrival_times(t, pos, pos[:, -1])))


def verdict_of(scenario: Scenario, dyn: Dynamics, flight: dict[str, Any], stopped: str
               ) -> tuple[Verdict, np.ndarray, FlightStatus, str]:
    """The flight's verdict (the true world at each step, the scenario's required margins),
    its arrival times, its status and message; ``stopped``: the station's message if the team
    gave up (else empty)."""
    t, x = flight["times"], flight["actual"]
    names = [u.name for u in scenario.team]
    r = np.array([u.radius for u in scenario.team])
    verdict = judge(Scene.true(scenario.world, dyn), r, t, x, Margins.required(scenario), names, keep=True)
    goals = scenario.goals()
    goals[:, 2] = scenario.world.terrain.absolute(goals[:, 0], goals[:, 1], goals[:, 2])
    arrival = arrival_times(t, x, goals)
    if verdict.breaches:
        first = verdict.breaches[0].describe(names)
        more = f" (and {len(verdict.breaches) - 1} more)" if len(verdict.breaches) > 1 else ""
        status = FlightStatus.UNSAFE if verdict.contact else FlightStatus.BREACH
        return verdict, arrival, status, f"{status.value}: {first}{more}"
    if stopped or not np.all(np.isfinite(arrival)):
        return verdict, arrival, FlightStatus.STOPPED, stopped or "the team stopped to hover and never resumed"
    return verdict, arrival, FlightStatus.ARRIVED, (
        f"arrived: least separation {verdict.min_separation.min():.2f} m, least clearance "
        f"{verdict.min_clearance.min():.2f} m")
