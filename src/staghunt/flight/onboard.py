"""What each UAV decides on its own: which plan it flies, when it holds, and its reflex.

A UAV (:class:`Onboard`) flies its :class:`~staghunt.trajectory.team.Track`. A plan message
that reaches it in time, whose start agrees with where the UAV will be, becomes pending and is
acknowledged; the UAV switches to it at its start. It refuses (and says why) a plan that opens
with a path and arrives after its start, whose start lies more than :data:`START_TOLERANCE`
from where it will be, or, while it holds on its own, one made before the station knew of its
hold. The old plan stays valid until then (docs/model.md, section 8). A pending plan that
starts before a newer one it takes is flown until the newer one starts (the station made the
newer one from it).

It holds where it is (a stop along its own track) when it hears nothing from the ground
station for ``plan_timeout`` (at ``max_acceleration``), or when a newer plan has started that
it did not take (lost, late or refused: its team-mates may fly it; braking harder, the old
plan may lead into what the new one avoids). Its reflex checks, every :data:`REFLEX_PERIOD`, whether
its reference would, within the time its braking stop needs, come closer than the required
clearance to an obstacle its own sensor saw, or within ``d_s`` of a team-mate that holds (a
neighbour's reserved volume, from the team-mates' beacons), closing in; if so it brakes
``reflex_latency`` later, at three times the acceleration. A held UAV
resumes with the next plan it takes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from staghunt.flight.link import Ack, Beacon, Heartbeat, HoldReason, PlanMessage, Telemetry
from staghunt.safety.measure import static_clearance
from staghunt.task import VehicleLimits
from staghunt.trajectory.quintic import BRAKE_RAMP, Reference, stop_piece
from staghunt.trajectory.team import Track
from staghunt.world import Cylinder, Prism

START_TOLERANCE = 1.0
"""Metres a plan's start may lie from where the UAV expects to be at it (the same tracking
error carried forward by both sides; sensor noise, measurement delay, and the tracking error
changing meanwhile: a hard braking manoeuvre lags its reference by tenths of a metre)."""
REFLEX_PERIOD = 0.05
"""Seconds between two checks of the reflex."""
REFLEX_FACTOR = 3.0
"""The reflex (and a UAV that missed a plan) brakes at this multiple of ``max_acceleration``:
the top of the emergency reserve (:data:`staghunt.flight.fallback.EMERGENCY_FACTORS`)."""
REFLEX_TOLERANCE = 0.1
"""Metres the reference ahead must come closer than both the required clearance and the
clearance the UAV has now before the reflex brakes (a UAV resting near an obstacle may leave
along its edge)."""
REFLEX_MARGIN_S = 0.3
"""Seconds the reflex looks ahead beyond its latency and its braking time."""


def stopping_time(speed: float, limits: VehicleLimits) -> float:
    """Seconds the reference takes to cover the distance a braking stop at
    :data:`REFLEX_FACTOR` times ``max_acceleration`` needs from ``speed`` (m/s)."""
    a = REFLEX_FACTOR * limits.max_acceleration * (1.0 - BRAKE_RAMP)
    return speed / (2.0 * a)


def hold_piece(track: Track, t: float, limits: VehicleLimits, reason: HoldReason) -> Reference:
    """The stop a UAV makes on its own from ``t`` along ``track``: at ``max_acceleration`` when
    it heard nothing, or braking at :data:`REFLEX_FACTOR` times it (the reflex; a missed plan,
    whose old one may lead into what the new one avoids). The ground station rebuilds the
    same stop from the UAV's telemetry. A UAV already stopping on its own (the segment it flies
    at ``t`` is an earlier hold, or a one-UAV plan, in its stop) keeps that stop: a stop of the
    stop would wrap the whole track once more for every further hold, and evaluating it would
    recurse as deep as the holds go (a team hovering through many re-plans hit Python's
    recursion limit)."""
    _, flown, _ = track.segment_at(t)
    if isinstance(flown, Reference) and flown.n_uavs == 1 and flown.piece_at(t).kind == "stop":
        return flown
    brake = reason is not HoldReason.TIMEOUT
    lim = replace(limits, max_acceleration=REFLEX_FACTOR * limits.max_acceleration) if brake else limits
    return Reference((stop_piece(track, t, lim, brake=brake),))


@dataclass
class Onboard:
    """UAV ``n``'s own decisions (module docstring), with its body ``radius`` and the team's
    separation ``d_s`` and radii."""

    n: int
    track: Track
    limits: VehicleLimits
    plan_timeout: float
    reflex_latency: float
    safe_distance: float
    clearance: float
    radii: np.ndarray
    version: int = 0
    pending: PlanMessage | None = None
    heard: float = 0.0
    newest: tuple[int, float] = (0, 0.0)
    hold: tuple[float, HoldReason] | None = None
    brake_at: float | None = None
    next_reflex: float = 0.0
    seen: dict[str, Cylinder | Prism] = field(default_factory=dict)
    holding_mates: dict[int, np.ndarray] = field(default_factory=dict)
    holds: int = 0
    folded: list[tuple[float, int]] = field(default_factory=list)
    """Plans taken into the track ahead of their start (start, version): a newer plan that starts
    after the pending one was taken, and the pending one is flown until then."""

    def receive(self, t: float, message: Any, pos: np.ndarray, ack: list[Ack]) -> None:
        """Take one message at ``t``, at the UAV's position ``pos``; acknowledgements go to ``ack``."""
        if isinstance(message, Beacon):
            if message.holding:
                self.holding_mates[message.uav] = message.pos
            else:
                self.holding_mates.pop(message.uav, None)
            return
        self.heard = t
        if isinstance(message, Heartbeat):
            self.newest = max(self.newest, (message.version, message.splice))
            return
        if not isinstance(message, PlanMessage) or self.n not in message.uavs:
            return
        self.newest = max(self.newest, (message.version, message.splice))
        have = self.pending.version if self.pending is not None else self.version
        if message.version <= have:
            ack.append(Ack(self.n, message.version, message.version <= self.version
                           or (self.pending is not None and message.version == self.pending.version)))
            return
        if t > message.splice and not message.stop_first:
            ack.append(Ack(self.n, message.version, False, "late"))
            return
        knew = message.holds[self.n] if len(message.holds) > self.n else None
        if self.hold is not None and knew != self.hold[0]:  # made before the station knew it holds
            ack.append(Ack(self.n, message.version, False, "hold"))
            return
        at = max(message.splice, t)
        track, before = self.track, self.pending
        if before is not None and before.splice < at:
            # the pending plan starts first: the station made this one from it, and it is flown
            # until this one starts
            track = track.then(before.splice, before.plan, self.n)
        expect = track.state(np.array([at]))[0][0, 0] + (pos - track.state(np.array([t]))[0][0, 0])
        start = message.plan.state(np.array([at]))[0][self.n, 0]
        if float(np.linalg.norm(start - expect)) > START_TOLERANCE:
            ack.append(Ack(self.n, message.version, False, "start"))
            return
        if track is not self.track:
            self.track = track
            self.folded.append((before.splice, before.version))
        self.pending = message
        ack.append(Ack(self.n, message.version, True))

    def step(self, t: float, dt: float) -> None:
        """Switch to a pending plan that starts, hold when the ground station is silent or a
        plan was missed, brake when the reflex says so."""
        while self.folded and t >= self.folded[0][0] - 1e-9:  # a plan taken ahead starts
            self.version, self.hold, self.brake_at = self.folded.pop(0)[1], None, None
        p = self.pending
        if p is not None and t >= p.splice - 1e-9:
            self.track = self.track.then(p.splice if not p.stop_first else min(p.splice, t), p.plan, self.n)
            self.version, self.pending, self.hold, self.brake_at = p.version, None, None, None
            self.folded.clear()
        if self.hold is None:
            missed = self.newest[0] > max(self.version, self.pending.version if self.pending else 0)
            if missed and t > self.newest[1] + dt:
                self._hold(t, HoldReason.MISSED)
            elif t - self.heard > self.plan_timeout:
                self._hold(t, HoldReason.TIMEOUT)
            elif self.brake_at is not None and t >= self.brake_at - 1e-9:
                self._hold(t, HoldReason.REFLEX)

    def _hold(self, t: float, reason: HoldReason) -> None:
        self.track = self.track.then(t, hold_piece(self.track, t, self.limits, reason), 0)
        self.hold, self.pending, self.brake_at = (t, reason), None, None
        self.folded.clear()
        self.holds += 1

    def reflex(self, t: float) -> None:
        """Every :data:`REFLEX_PERIOD`: schedule a brake if the reference ahead (the pending plan
        included) enters a seen obstacle or a holding team-mate's volume before the UAV could
        stop."""
        if t < self.next_reflex - 1e-9 or self.hold is not None or self.brake_at is not None:
            return
        self.next_reflex = t + REFLEX_PERIOD
        if not self.seen and not self.holding_mates:
            return
        track = self.track
        if self.pending is not None:
            track = track.then(self.pending.splice, self.pending.plan, self.n)
        now = track.state(np.array([t]))[:2, 0, 0]  # position, velocity
        v = float(np.linalg.norm(now[1]))
        ahead = self.reflex_latency + stopping_time(v, self.limits) + REFLEX_MARGIN_S
        times = t + np.arange(0.0, ahead + REFLEX_PERIOD, REFLEX_PERIOD)
        pos = track.state(times)[0]  # (1, T, 3)
        r = self.radii[self.n: self.n + 1]
        danger = False
        if self.seen:
            cyl = tuple(s for s in self.seen.values() if isinstance(s, Cylinder))
            prm = tuple(s for s in self.seen.values() if isinstance(s, Prism))
            clear = static_clearance(cyl, prm, pos, r)[0]
            danger = bool(clear.min() < min(self.clearance, clear[0]) - REFLEX_TOLERANCE) or bool(clear.min() < 0.0)
        for m, where in self.holding_mates.items():
            need = self.safe_distance + self.radii[self.n] + self.radii[m]
            d = np.linalg.norm(pos[0] - where, axis=-1)
            danger = danger or bool(d.min(initial=math.inf) <= need and d.min() < d[0])  # closing in
        if danger:
            self.brake_at = t + self.reflex_latency

    def telemetry(self, t: float, pos: np.ndarray, vel: np.ndarray) -> Telemetry:
        return Telemetry(self.n, t, pos, vel, self.version, self.hold, tuple(self.seen.items()))

    def beacon(self, t: float, pos: np.ndarray) -> Beacon:
        return Beacon(self.n, t, pos, self.hold is not None)


class OnboardTeam:
    """Every UAV's :class:`Onboard`, and the team's reference at a step (UAVs flying the same
    trajectory share its evaluation)."""

    def __init__(self, members: list[Onboard]) -> None:
        self.members = members

    def reference(self, t: float) -> np.ndarray:
        """``(4, N, 3)`` each UAV's reference at ``t``."""
        out = np.zeros((4, len(self.members), 3))
        done: dict[tuple[int, float], np.ndarray] = {}
        for m in self.members:
            start, traj, row = m.track.segment_at(t)
            key = (id(traj), start)
            if key not in done:
                done[key] = traj.state(np.array([t]))[:, :, 0]
            out[:, m.n] = done[key][:, row]
        return out

    def course(self, times: np.ndarray) -> np.ndarray:
        """``(N, G, 3)`` each UAV's reference positions at ``times`` ``(G,)``, as its track
        stands now."""
        return np.concatenate([m.track.state(times)[0] for m in self.members])

    @property
    def holds(self) -> int:
        return sum(m.holds for m in self.members)
