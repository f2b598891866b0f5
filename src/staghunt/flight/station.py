"""The ground station: the planner's side of the closed loop, ``tick(t, observations)``.

At every planner tick it takes what the radio brought (telemetry, acknowledgements), keeps what
it believes each UAV flies (a :class:`~staghunt.trajectory.team.Track` per UAV: the plans each
took, the holds each reported), and re-plans when a trigger says so (:class:`Trigger`, in
this order): an obstacle a UAV sensed, a UAV holding on its own or refusing a plan, a plan not
taken by every UAV after its start, a predicted conflict with a known motion, a retry while
the team hovers after a stop, and the receding horizon's periodic re-plan with nothing sensed.

A re-plan is a job (:meth:`GroundStation._replan`): it is computed at the tick, but its result
leaves the station only after its latency (measured wall time, or the fixed one) rounded up to
a simulation step; meanwhile the simulated world goes on and the station takes no other job,
but an event pre-empts a receding-horizon job. A plan sent uncertified (no certificate fit
before its deadline) is certified by the next job (:meth:`GroundStation._certify`). The plan starts at the trigger plus the
deadline plus the link's worst delay; a plan that would still start before it reached the
UAVs is dropped for the fallback (the current plan if it stays safe, else a stop). Every plan
goes out twice, is sent again each tick until acknowledged while it can still arrive in time,
and counts as committed once every UAV it concerns acknowledged it; every tick a heartbeat
names the newest plan.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from staghunt.flight.config import FlyConfig
from staghunt.flight.link import Ack, Heartbeat, PlanMessage, Telemetry
from staghunt.flight.onboard import hold_piece
from staghunt.flight.records import Cause, ReplanRecord, ReplanStatus
from staghunt.flight.replan import Replanner, Start
from staghunt.solvers.improve import Deadline
from staghunt.trajectory.quintic import Reference
from staghunt.trajectory.team import RowTeam, Track, end_time
from staghunt.world.dynamic import Dynamics

PLAN_COPIES = 2
"""Copies of every plan message sent at once (a lost plan is the costliest message)."""
STOP_RESERVE = 0.05
"""Seconds a fallback stop needs to be computed and sent after a failed solve."""
SOONER_S = 0.5
"""Seconds sooner a receding-horizon plan must arrive to replace a certified plan."""


@dataclass(frozen=True)
class Trigger:
    """Why the station re-plans now: the ``cause``, in words (``text``), and the known motions'
    conflict ``windows`` to solve around."""

    cause: Cause
    text: str
    windows: tuple[tuple[str, float, float], ...] = ()


@dataclass
class _Job:
    release: float
    message: PlanMessage | None
    record: int
    cause: Cause


class GroundStation:
    """The planner's side of one flight (module docstring). ``ref0``: the plan flown from
    take-off; ``dt``: the simulation step; ``worst_delay``: the link's worst delay (s)."""

    def __init__(self, replanner: Replanner, dyn: Dynamics, config: FlyConfig, ref0: Reference, dt: float,
                 worst_delay: float) -> None:
        self.replanner, self.dyn, self.config, self.dt = replanner, dyn, config, dt
        self.scenario = replanner.scenario
        self.n = self.scenario.n_uavs
        goals = self.scenario.goals()
        goals[:, 2] = self.scenario.world.terrain.absolute(goals[:, 0], goals[:, 1], goals[:, 2])
        self.goals = goals
        self.worst = worst_delay
        self.tracks = [Track(((ref0.pieces[0].t0, ref0, n),)) for n in range(self.n)]
        self.history: list[dict[int, Track]] = [{0: track} for track in self.tracks]
        self.taken = [0] * self.n
        self.held: list[float | None] = [None] * self.n
        self.telemetry: list[Telemetry | None] = [None] * self.n
        self.plans: dict[int, PlanMessage] = {}
        self.acks: dict[int, dict[int, bool]] = {}
        self.refused: list[tuple[int, int, str]] = []
        self.version = 0
        self.released = (0, 0.0)
        self.records: list[ReplanRecord] = []
        self.job: _Job | None = None
        self.last_replan = 0.0
        self.handled_holds: dict[int, float] = {}
        self.verified: set[int] = set()
        self.fresh: list[str] = []
        self.to_certify: tuple[int, Any] | None = None
        self.stops, self.stopped_at, self.retries = 0, -1.0, 0
        self.gave_up: float | None = None
        self.again: Trigger | None = None  # a deferred re-plan, to solve at the next tick
        self.deferred = 0  # deferrals since the last event solved
        self.message = ""

    # ------------------------------------------------------------------ what the station believes

    @property
    def team(self) -> RowTeam:
        """What the station believes every UAV flies, the newest plan sent included from its
        start for every UAV that has not refused it and can take it (it will switch to it before
        anything the station sends now can start): not for a UAV whose hold the plan did not
        know of (it refuses such a plan; built on it, every later plan would start where that
        UAV is not)."""
        p = self.plans.get(self.released[0])
        acks = self.acks.get(self.released[0], {}) if p is not None else {}

        def takes(n: int) -> bool:
            knew = p.holds[n] if len(p.holds) > n else None
            return (self.taken[n] < p.version and acks.get(n) is not False
                    and (self.held[n] is None or knew == self.held[n]))

        tracks = tuple(tr.then(p.splice, p.plan, n) if p is not None and takes(n) else tr
                       for n, tr in enumerate(self.tracks))
        return RowTeam(tracks, (0,) * self.n)

    def _took(self, n: int, version: int) -> None:
        if version > self.taken[n] and version in self.plans:
            p = self.plans[version]
            self.tracks[n] = self.tracks[n].then(p.splice, p.plan, n)
            self.taken[n], self.held[n] = version, None
            self.history[n][version] = self.tracks[n]
        self.acks.setdefault(version, {})[n] = True
        self._commit(version)

    def _commit(self, version: int) -> None:
        p = self.plans.get(version)
        acks = self.acks.get(version, {})
        if p is not None and all(acks.get(n) for n in p.uavs):
            for i, r in enumerate(self.records):
                if r.version == version and not r.committed:
                    self.records[i] = replace(r, committed=True)

    def _observe(self, t: float, inbox: list[Any]) -> None:
        sc = self.scenario
        for m in inbox:
            if isinstance(m, Ack):
                if m.ok:
                    self._took(m.uav, m.version)
                elif m.version == self.released[0]:
                    self.refused.append((m.uav, m.version, m.reason))
                    self.acks.setdefault(m.version, {})[m.uav] = False
            elif isinstance(m, Telemetry):
                old = self.telemetry[m.uav]
                if old is not None and old.time >= m.time:
                    continue
                self.telemetry[m.uav] = m
                if m.version < self.taken[m.uav] and m.version in self.history[m.uav] and self._dropped(m):
                    # it acknowledged a plan, then held before its start: it flies the older one
                    self.tracks[m.uav] = self.history[m.uav][m.version]
                    self.taken[m.uav], self.held[m.uav] = m.version, None
                self._took(m.uav, m.version)
                if m.hold is not None and self.taken[m.uav] == m.version and self.held[m.uav] != m.hold[0]:
                    since, reason = m.hold
                    self.tracks[m.uav] = self.tracks[m.uav].then(
                        since, hold_piece(self.tracks[m.uav], since, sc.vehicle, reason), 0)
                    self.held[m.uav] = since
                for name, shape in m.sensed:
                    if name not in self.replanner.known.sensed:
                        self.replanner.known.sensed[name] = shape
                        self.fresh.append(f"{name} (seen by {sc.team[m.uav].name})")
        for e in self.dyn.events:
            if e.kind == "disappear" and e.time <= t:
                self.replanner.known.removed.add(e.name)

    def _dropped(self, m: Telemetry) -> bool:
        """Whether UAV ``m.uav`` has dropped the plans it acknowledged after the one it flies
        (``m.version``): it holds, on a hold that the newest plan it acknowledged was not made
        knowing of (a UAV drops its pending plan when it holds, and resumes with the next plan
        it takes). Flying the older plan until the acknowledged one starts is no such sign."""
        if m.hold is None:
            return False
        p = self.plans.get(self.taken[m.uav])
        knew = p.holds[m.uav] if p is not None and len(p.holds) > m.uav else None
        return knew != m.hold[0]

    # ------------------------------------------------------------------ the tick

    def tick(self, t: float, inbox: list[Any]) -> list[tuple[int, Any]]:
        """One planner tick at ``t`` with the messages that reached the station; returns the
        messages it sends now (a plan whose latency has just passed, heartbeats, plans sent
        again)."""
        self._observe(t, inbox)
        # a job whose latency has passed leaves first: a re-plan or a certificate started at this
        # tick would replace it, and its plan would never be sent
        released = self.release(t)
        job = self.job
        trigger = None
        if job is None or job.cause is Cause.RECEDING:  # an event pre-empts a receding-horizon job
            trigger = self._trigger(t, job is not None)
        if trigger is not None and job is not None:
            if job.record >= 0:
                self.records[job.record] = replace(self.records[job.record], status=ReplanStatus.KEPT,
                                                   problems=("pre-empted by " + trigger.text,))
            self.job = None
        if trigger is not None:
            self._replan(t, trigger)
        elif job is None and self.to_certify is not None:
            self._certify(t)
        out = released + [(n, Heartbeat(*self.released)) for n in range(self.n)]
        p = self.plans.get(self.released[0])
        if p is not None and not released and (t + self.worst < p.splice or p.stop_first):
            acks = self.acks.get(p.version, {})
            out += [(n, p) for n in p.uavs if n not in acks and t < p.plan.arrival]
        return out

    def release(self, t: float) -> list[tuple[int, Any]]:
        """The messages of a job whose latency has passed by ``t``."""
        job = self.job
        if job is None or t < job.release - 1e-9:
            return []
        self.job = None
        if job.message is None:
            return []
        p = job.message
        self.plans[p.version] = p
        self.released = (p.version, p.splice)
        return [(n, p) for n in p.uavs for _ in range(PLAN_COPIES)]

    def _trigger(self, t: float, busy: bool) -> Trigger | None:
        cfg, names = self.config, [u.name for u in self.scenario.team]
        if self.gave_up is not None:
            return None
        if self.fresh:
            text = "sensed " + ", ".join(self.fresh)
            self.fresh = []
            self.again = None
            return Trigger(Cause.SENSED, text)
        if self.again is not None:
            again, self.again = self.again, None
            return again
        for n, tel in enumerate(self.telemetry):
            if tel is not None and tel.hold is not None and self.handled_holds.get(n) != tel.hold[0]:
                self.handled_holds[n] = tel.hold[0]
                return Trigger(Cause.HOLDING, f"{names[n]} holds ({tel.hold[1].value})")
        if self.refused:
            n, v, why = self.refused.pop(0)
            self.refused.clear()
            return Trigger(Cause.UNCOMMITTED, f"{names[n]} refused plan {v} ({why})")
        p = self.plans.get(self.released[0])
        if p is not None and p.version not in self.verified and t > p.splice + 2 * self.worst + 0.15:
            self.verified.add(p.version)
            missing = [n for n in p.uavs if self.taken[n] < p.version]
            if missing:
                return Trigger(Cause.UNCOMMITTED, f"plan {p.version} not taken by {names[missing[0]]}")
        if busy:
            return None
        team = self.team
        if self.dyn.known_motion:
            found = self.replanner.acceptance.check(team, t, t + cfg.conflict_horizon).windows
            if found:
                pad = cfg.window_pad
                windows = tuple((m, max(t, a - pad), b + pad) for m, a, b in found)
                return Trigger(Cause.PREDICTED, "predicted conflict with " + ", ".join(sorted({w[0] for w in found})),
                               windows)
        if self.stopped_at >= 0 and t >= self.stopped_at + cfg.retry_interval * (self.retries + 1):
            self.retries += 1
            return Trigger(Cause.RETRY, "retry after stop")
        if (cfg.replan_rate > 0 and t - self.last_replan >= 1.0 / cfg.replan_rate - 1e-9 and self.stopped_at < 0
                and all(h is None for h in self.held) and all(v == self.released[0] for v in self.taken)
                and end_time(team) > t + 3.0):
            return Trigger(Cause.RECEDING, "receding horizon")
        return None

    # ------------------------------------------------------------------ a re-plan

    def _step(self, t: float) -> float:
        return math.ceil(t / self.dt - 1e-9) * self.dt

    def _replan(self, t: float, trigger: Trigger) -> None:
        """Compute a re-plan at ``t`` now and hold its result back for its latency."""
        cfg = self.config
        wall0 = time.perf_counter()
        self.last_replan = t
        receding = trigger.cause is Cause.RECEDING
        scale = (cfg.stop_budget_factor if self.stopped_at >= 0
                 else cfg.repair_budget_factor if receding and not self._flying_equilibrium() else 1)
        D = cfg.deadline_for(self.n) * scale
        t_s = self._step(t + D + self.worst)
        base = self.team
        now = base.state(np.array([t]))[:, :, 0]
        tel = self.telemetry
        t_m = np.array([m.time if m is not None else t for m in tel])
        pos = np.array([m.pos if m is not None else now[0][n] for n, m in enumerate(tel)])
        vel = np.array([m.vel if m is not None else now[1][n] for n, m in enumerate(tel)])
        start, error = Start.measured(base, t_s, t_m, pos, vel)

        def soon() -> float:
            spent = time.perf_counter() - wall0 if cfg.measured else float(cfg.latency)
            return self._step(t + spent + STOP_RESERVE) + self.worst

        # the next re-plan starts at most a deadline and two ticks later (one to notice, one of overrun)
        defer = (D + 2.0 / self.dyn.sensing.rate if cfg.defer_stops and self.deferred < cfg.deferrals
                 and trigger.cause is not Cause.RETRY and self.stopped_at < 0 else 0.0)
        before = time.perf_counter() - wall0
        solved = self.replanner.solve(start, soon, scale, list(trigger.windows),
                                      Deadline.after(D) if cfg.measured else Deadline(),
                                      cfg.replan_horizon if receding else 0.0, fallback=not receding, defer=defer)
        plan, status = solved.plan, solved.status
        if receding and plan is not None and not (solved.certified and self._better(plan, base)):
            plan, status = None, ReplanStatus.KEPT
        wall = time.perf_counter() - wall0
        release = self._step(t + (wall if cfg.measured else float(cfg.latency)))
        late = plan is not None and not plan.pieces[0].kind == "stop" and release + self.worst > plan.pieces[0].t0 + 1e-9
        if late:
            keep = receding or self.replanner.acceptance.check(base, release, release + cfg.conflict_horizon).safe
            if keep:
                plan, status = None, ReplanStatus.KEPT
            else:
                at = release + self.worst
                plan, status = self.replanner.fallback.stop(base, at, at)
        message = None
        if plan is not None:
            self.version += 1
            message = PlanMessage(self.version, plan, plan.pieces[0].t0, tuple(range(self.n)), tuple(self.held))
        self.records.append(ReplanRecord(
            t, plan.pieces[0].t0 if plan is not None else t_s, trigger.cause, trigger.text, status, wall, D,
            "measured" if cfg.measured else "fixed", release, solved.evaluations, solved.attempts,
            solved.nash_gaps if status.solved else (), solved.certified and status.solved,
            solved.verdict if status.solved else "", solved.problems, solved.windows, error, late,
            message.version if message is not None else 0, phases=(("start", before), *self.replanner.laps.items()),
            later=solved.later if plan is not None and status.solved else ()))
        self.job = _Job(release, message, len(self.records) - 1, trigger.cause)
        self.to_certify = None
        if message is not None and status.solved and not solved.certified and solved.game is not None:
            self.to_certify = (len(self.records) - 1, solved.game)
        self._after(t, trigger, status)

    def _certify(self, t: float) -> None:
        """The certificate of the plan last sent uncertified (its deadline left no time for
        one), made now as the station's next job: the plan is flying, the record says how it
        stands and how long after it was sent the certificate came."""
        index, game = self.to_certify
        self.to_certify = None
        wall0 = time.perf_counter()
        gaps, certified, verdict, spent = self.replanner.certify(game)
        wall = time.perf_counter() - wall0
        r = self.records[index]
        self.records[index] = replace(r, nash_gaps=gaps, certified=certified, verdict=verdict,
                                      evaluations=r.evaluations + spent, certified_after_s=r.latency_s + wall)
        release = self._step(t + (wall if self.config.measured else float(self.config.latency)))
        self.job = _Job(release, None, -1, Cause.RECEDING)  # busy meanwhile; an event pre-empts it

    def _better(self, plan: Reference, base: RowTeam) -> bool:
        """A receding-horizon plan (certified) is sent only if it arrives at least
        :data:`SOONER_S` sooner, or no later when the plan flown is not an equilibrium (sent at
        its deadline uncertified, and its later certificate found a better reply or has not
        come yet): the team then flies a certified equilibrium again as soon as one is found."""
        return plan.arrival <= end_time(base) - (SOONER_S if self._flying_equilibrium() else 0.0)

    def _flying_equilibrium(self) -> bool:
        """Whether the plan released last is a certified equilibrium (the take-off plan counts as one)."""
        version = self.released[0]  # 0: the take-off plan
        flown = next((r for r in reversed(self.records) if r.version == version), None) if version else None
        return flown is None or flown.certified

    def _after(self, t: float, trigger: Trigger, status: ReplanStatus) -> None:
        """The stop-and-retry bookkeeping of a re-plan's outcome."""
        cfg = self.config
        if status is ReplanStatus.DEFERRED:
            self.deferred += 1
            text = trigger.text if trigger.text.endswith("(deferred)") else trigger.text + " (deferred)"
            self.again = replace(trigger, text=text)
            return
        if trigger.cause is not Cause.RECEDING:
            self.deferred = 0
        # a re-plan that kept the current plan fails too when that plan ends short of the goals
        # (a stop or a sidestep, flown on since no stop replaced it): the team retries from there;
        # so does a yield of such a plan (the same paths, slowed: they end where it ends)
        failed = status in (ReplanStatus.STOP, ReplanStatus.EMERGENCY_STOP) or (
            status is ReplanStatus.KEPT and (trigger.cause is Cause.RETRY
                                             or (trigger.cause is not Cause.RECEDING and self._short()))) or (
            status is ReplanStatus.YIELD and self._short())
        if status is ReplanStatus.STOP_REPLANNED:
            self.stops += 1
        if status is ReplanStatus.SIDESTEP or (status is ReplanStatus.KEPT and not failed):
            return
        if failed:
            if self.stopped_at < 0:
                self.stops += 1
                self.stopped_at = t
            elif self.retries >= cfg.retries_after_stop and not self._passing(t):
                last = self.records[-1]
                self.gave_up = t
                self.message = (f"goal unreachable: after {self.retries} re-plans from the hover no plan "
                                f"passes ({'; '.join(last.problems[:2]) or 'no feasible plan'})")
        else:
            self.stopped_at, self.retries = -1.0, 0

    def _passing(self, t: float) -> bool:
        """Whether the last re-plan solved around a known motion's window that has not ended by
        ``t``: the hovering team waits for it to pass (retrying) before it gives the goal up
        (scenario2 episode 81 of benchmarks/replan.py: a truck crossing where the team hovered
        made every plan infeasible until 36 s; the team gave up at 20 s)."""
        last = self.records[-1] if self.records else None
        return last is not None and any(b > t for _, _, b in last.windows)

    def _short(self) -> bool:
        """Whether what the station believes the team flies ends more than 1 m from a goal."""
        team = self.team
        end = team.state(np.array([end_time(team)]))[0][:, 0]
        return bool(np.any(np.linalg.norm(end - self.goals, axis=-1) > 1.0))

    def waiting(self, t: float) -> float:
        """Until when the flight must go on for the station: a job in progress, the retries of a
        hovering team, or the hold after giving up (``-inf``: nothing)."""
        cfg = self.config
        if self.gave_up is not None:
            return self.gave_up + cfg.hold
        until = -math.inf
        if self.job is not None:
            until = self.job.release
        if self.stopped_at >= 0:
            tries = max(cfg.retries_after_stop, self.retries) + 1
            until = max(until, self.stopped_at + cfg.retry_interval * tries + cfg.hold)
        return until
