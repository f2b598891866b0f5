"""The radio between the ground station and the UAVs, and the messages it carries.

Every message takes the link's delay plus jitter (a normal draw clipped to three standard
deviations, at least 0), so messages can arrive out of order, and is lost with the link's
probability, or always within an outage (a radio shadow of one UAV). Draws come from the
flight's generator: the same seed, the same messages lost and late.

Messages (ground station ``GROUND``, UAVs by index):

- :class:`PlanMessage` down: a new team plan, its number and the time it starts;
- :class:`Heartbeat` down, every planner tick: the newest plan's number and start;
- :class:`Ack` up: a UAV took a plan (or refused it, and why);
- :class:`Telemetry` up, every sensor tick: measured state, the plan flown, a hold, what the
  UAV's own sensor saw;
- :class:`Beacon` between UAVs, every sensor tick: position and whether it holds.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np

from staghunt.trajectory.quintic import Reference
from staghunt.world import Cylinder, Prism
from staghunt.world.dynamic import Link

GROUND = -1
"""The ground station's address."""


class HoldReason(str, Enum):
    """Why a UAV holds on its own: it heard nothing for ``plan_timeout`` (``TIMEOUT``), a newer
    plan started that it did not take, lost, late or refused (``MISSED``), or its reflex braked
    (``REFLEX``)."""

    TIMEOUT = "timeout"
    MISSED = "missed plan"
    REFLEX = "reflex"


@dataclass(frozen=True, eq=False)
class PlanMessage:
    """Plan number ``version``: every UAV in ``uavs`` flies its row of ``plan`` from ``splice``
    on. A plan that opens with a path must arrive before ``splice``; one that opens with a
    stop (a fallback) is taken late too (a stop slows the path already flown)."""

    version: int
    plan: Reference
    splice: float
    uavs: tuple[int, ...]
    holds: tuple[float | None, ...] = ()
    """For every UAV, the start of the hold the station knew of when it made the plan (``None``:
    none): a UAV holding on its own takes only a plan made knowing its hold."""

    @property
    def stop_first(self) -> bool:
        return self.plan.pieces[0].kind == "stop"


@dataclass(frozen=True)
class Heartbeat:
    version: int
    splice: float


@dataclass(frozen=True)
class Ack:
    uav: int
    version: int
    ok: bool
    reason: str = ""


@dataclass(frozen=True, eq=False)
class Telemetry:
    """UAV ``uav`` at ``time``: measured ``pos``, ``vel`` ``(3,)``, the plan it flies
    (``version``), its hold (``(since, reason)`` or ``None``) and the obstacles its sensor has
    seen (name, shape)."""

    uav: int
    time: float
    pos: np.ndarray
    vel: np.ndarray
    version: int
    hold: tuple[float, HoldReason] | None
    sensed: tuple[tuple[str, Cylinder | Prism], ...]


@dataclass(frozen=True, eq=False)
class Beacon:
    uav: int
    time: float
    pos: np.ndarray
    holding: bool


@dataclass(frozen=True)
class Outage:
    """Every message to or from UAV ``uav`` is lost from ``start`` to ``end`` (s)."""

    uav: int
    start: float
    end: float


class RadioLink:
    """Messages in flight: :meth:`send` one, :meth:`deliver` those that have arrived."""

    def __init__(self, link: Link, rng: np.random.Generator, outages: tuple[Outage, ...] = ()) -> None:
        self.link, self.rng, self.outages = link, rng, outages
        self._queue: list[tuple[float, int, int, Any]] = []
        self._seq = 0
        self.sent = 0
        self.lost = 0

    def send(self, t: float, src: int, dst: int, message: Any) -> None:
        """Send ``message`` from ``src`` to ``dst`` at ``t``."""
        self.sent += 1
        uav = src if dst == GROUND else dst
        lost = self.rng.random() < self.link.loss
        jitter = float(np.clip(self.rng.normal(), -3.0, 3.0))
        if lost or any(o.uav in (uav, src) and o.start <= t < o.end for o in self.outages):
            self.lost += 1
            return
        delay = max(0.0, self.link.delay + self.link.jitter * jitter)
        heapq.heappush(self._queue, (t + delay, self._seq, dst, message))
        self._seq += 1

    def deliver(self, t: float) -> list[tuple[int, Any]]:
        """``(destination, message)`` of every message arrived by ``t``, in arrival order."""
        out = []
        while self._queue and self._queue[0][0] <= t + 1e-9:
            _, _, dst, message = heapq.heappop(self._queue)
            out.append((dst, message))
        return out

    @property
    def worst_delay(self) -> float:
        return self.link.worst_delay if self.link.loss < 1 else math.inf
