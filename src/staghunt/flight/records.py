"""What a flight records of its re-plans: why each was made (:class:`Cause`), what came out
(:class:`ReplanStatus`), what a solve decided (:class:`Solved`) and the figures of one re-plan
(:class:`ReplanRecord`)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np

from staghunt.scenario import Scenario
from staghunt.trajectory.quintic import Reference


class Cause(str, Enum):
    """Why the ground station re-planned."""

    SENSED = "sensed"  # an obstacle appeared within a UAV's sensing range
    PREDICTED = "predicted"  # the plan conflicts with a known motion within the horizon
    HOLDING = "holding"  # a UAV holds on its own (timeout, missed plan, reflex) or refused a plan
    UNCOMMITTED = "uncommitted"  # a plan was not acknowledged by every UAV before its start
    RETRY = "retry"  # the team hovers after a stop: try again
    RECEDING = "receding"  # the receding horizon's periodic re-plan, nothing sensed


class ReplanStatus(str, Enum):
    """What a re-plan sent the team: ``REPLANNED`` a new plan from the team's state;
    ``STOP_REPLANNED`` a synchronised stop, then a new plan from rest; ``STOP`` a synchronised
    stop to hover, no plan yet; ``EMERGENCY_STOP`` the same at once, braking at two or three
    times the acceleration; ``SIDESTEP`` a hovering team moved as a whole out of a known
    motion's way; ``KEPT`` nothing: the current plan stays (a receding-horizon re-plan that
    found nothing better, or no plan or a late one while the current one stays safe);
    ``DEFERRED`` no plan yet from the moving state, but a stop decided at the next re-plan
    still passes: the current plan stays and the station solves again at once; ``YIELD`` the
    current plan's paths flown on, slowed in sync, so that the known motions in their way pass
    first (the moving state had no plan, or only one arriving later)."""

    REPLANNED = "replanned"
    STOP_REPLANNED = "stop, replanned"
    STOP = "stop"
    EMERGENCY_STOP = "emergency stop"
    SIDESTEP = "sidestep"
    KEPT = "kept"
    DEFERRED = "deferred"
    YIELD = "yield"

    @property
    def solved(self) -> bool:
        """A new plan was sent (possibly after a stop)."""
        return self in (ReplanStatus.REPLANNED, ReplanStatus.STOP_REPLANNED)

    @property
    def stopped(self) -> bool:
        """The team comes to rest (a stop to hover, before a new plan or instead of one)."""
        return self in (ReplanStatus.STOP_REPLANNED, ReplanStatus.STOP, ReplanStatus.EMERGENCY_STOP)


@dataclass(frozen=True)
class ReplanRecord:
    """One re-plan: when (``time`` = the triggering tick; ``effect_time`` = when its result left
    the ground station, ``time`` plus the latency rounded up to a step; ``switch_time`` = when
    the new plan starts), why (``cause``, ``trigger`` in words), what it cost (``latency_s``
    the measured wall time of the whole re-plan, certificate included, against
    ``deadline_s``; ``latency_mode``: ``"measured"`` or ``"fixed"``, which one decided
    ``effect_time``; ``evaluations`` path evaluations; ``attempts`` solves), what came out
    (``status``; ``late``: the plan would have started before it reached the UAVs and was
    dropped for the fallback) and the certificate (``nash_gaps`` relative per UAV,
    ``verdict``, ``certified``: an epsilon-equilibrium). ``state_error_m``: the largest
    distance between a UAV's measured state carried to the switch time and its believed
    reference there (tracking error, sensor noise and delay). ``version``: the plan's number
    (0: none sent); ``committed``: every UAV acknowledged it before it started;
    ``certified_after_s``: a plan sent uncertified at its deadline is certified by the station's
    next job, this long (wall time) after it was sent (0: certified before). ``phases``: where
    the wall time went (:class:`Laps`), ``(part, seconds)`` in the order first timed.
    ``later``: the plan sent still conflicts with these known motions ``(name, from, to)``, all
    more than the conflict horizon after it starts (:attr:`Solved.later`)."""

    time: float
    switch_time: float
    cause: Cause
    trigger: str
    status: ReplanStatus
    latency_s: float
    deadline_s: float
    latency_mode: str
    effect_time: float
    evaluations: int
    attempts: int
    nash_gaps: tuple[float, ...] = ()
    certified: bool = False
    verdict: str = ""
    problems: tuple[str, ...] = ()
    windows: tuple[tuple[str, float, float], ...] = ()
    state_error_m: float = 0.0
    late: bool = False
    version: int = 0
    committed: bool = False
    certified_after_s: float = 0.0
    phases: tuple[tuple[str, float], ...] = ()
    later: tuple[tuple[str, float, float], ...] = ()

    @property
    def solved(self) -> bool:
        return self.status.solved

    @property
    def stopped(self) -> bool:
        return self.status.stopped

    @property
    def overran(self) -> bool:
        """The re-plan took longer than its deadline."""
        return self.latency_s > self.deadline_s

    def to_dict(self) -> dict[str, Any]:
        return {
            "time": round(self.time, 4), "effect_time": round(self.effect_time, 4),
            "switch_time": round(self.switch_time, 4), "cause": self.cause.value, "trigger": self.trigger,
            "status": self.status.value, "latency_s": self.latency_s, "latency_mode": self.latency_mode,
            "deadline_s": self.deadline_s, "overran": self.overran, "late": self.late,
            "evaluations": self.evaluations, "attempts": self.attempts, "nash_gaps": list(self.nash_gaps),
            "certified": self.certified, "verdict": self.verdict, "problems": list(self.problems),
            "windows": [{"obstacle": w[0], "from": round(w[1], 3), "to": round(w[2], 3)} for w in self.windows],
            "later_conflicts": [{"obstacle": w[0], "from": round(w[1], 3), "to": round(w[2], 3)} for w in self.later],
            "state_error_m": self.state_error_m, "version": self.version, "committed": self.committed,
            "certified_after_s": self.certified_after_s, "phases": dict(self.phases),
        }


@dataclass
class Laps:
    """A re-plan's wall time by part: :meth:`lap` adds the time since the last lap (or since
    this was made) to ``part``."""

    parts: dict[str, float] = field(default_factory=dict)
    last: float = field(default_factory=time.perf_counter)

    def lap(self, part: str) -> None:
        now = time.perf_counter()
        self.parts[part] = self.parts.get(part, 0.0) + now - self.last
        self.last = now

    def items(self) -> tuple[tuple[str, float], ...]:
        return tuple(self.parts.items())


@dataclass(frozen=True)
class Solved:
    """What :meth:`Replanner.solve` decided: the ``plan`` to send (``None``: keep the current
    one), its ``status``, the path ``evaluations`` and ``attempts`` spent, its certificate
    (``nash_gaps``, ``certified``, ``verdict``), the ``problems`` that stopped it (of a stop
    and a plan from rest, :attr:`ReplanStatus.STOP_REPLANNED`: why the plan from the moving
    state failed) and the conflict ``windows`` solved around."""

    plan: Reference | None
    status: ReplanStatus
    evaluations: int = 0
    attempts: int = 0
    nash_gaps: tuple[float, ...] = ()
    certified: bool = False
    verdict: str = ""
    problems: tuple[str, ...] = ()
    windows: tuple[tuple[str, float, float], ...] = ()
    game: tuple[Scenario, np.ndarray, float] | None = None
    """The game the plan is a solution of (its problem, the ``(N, K, 3)`` plan, the heading
    half-width), to certify the plan later if no certificate fit before the deadline."""
    later: tuple[tuple[str, float, float], ...] = ()
    """Conflicts with known motions ``(name, from, to)`` the plan still has, all more than the
    conflict horizon after it starts: left to the station's predicted-conflict re-plans
    (``FlyConfig.later_conflicts``)."""
