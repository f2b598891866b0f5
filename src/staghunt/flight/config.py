"""The settings of a closed-loop flight (:class:`FlyConfig`), checked once before it starts."""

from __future__ import annotations

import math
from dataclasses import dataclass

from staghunt.flight.link import Outage
from staghunt.scenario import Scenario, SolverSettings
from staghunt.solvers.response import CertifyOptions, check_search
from staghunt.world.dynamic import Link

MEASURED = "measured"
"""``FlyConfig.latency``: every re-plan takes effect after the wall time it really took."""


def auto_deadline(n_uavs: int) -> float:
    """The default re-plan deadline (s) of a team of ``n_uavs``: 0.215 s for up to three UAVs,
    0.16 s more per further UAV, at most 1 s from eight UAVs on (a re-plan's work grows with
    the team). The latency targets are a p95 of 0.2 s for 3 UAVs and 1 s for 8. A re-plan
    starts no step whose estimate ends in the deadline's last
    :data:`~staghunt.flight.replan.RESERVE_SHARE`, so a deadline equal to the target left its
    last tenth unused and event plans uncertified for lack of time; three UAVs get 0.215 s, whose
    p95 stays within 0.2 s (the figures: benchmarks/README.md and JOURNAL.md, "Closed loop: the
    deadline the latency target allows")."""
    return min(1.0, 0.215 + 0.16 * max(0, n_uavs - 3))


@dataclass(frozen=True)
class FlyConfig:
    """Settings of a closed-loop flight.

    Time (docs/model.md, section 8):

    - ``sim_rate``: simulation steps per second (Hz, >= 100).
    - ``latency``: ``"measured"`` (default): a re-plan takes effect after the wall time it
      really took, rounded up to the next step, while the simulated world goes on; a number:
      every re-plan takes exactly that long (s), whatever it took (reproducible: tests, golden
      files).
    - ``deadline``: the re-plan's time budget (s; ``None``: the fixed latency, or with
      measured latency :func:`auto_deadline`). A new plan starts ``deadline`` plus the link's
      worst delay after its trigger; with measured latency the solve returns the best plan it
      has by the deadline; a plan that would start before it reaches the UAVs is dropped for
      the safety fallback.
    - ``allowance``: metres a plan must keep beyond every required margin (the tracking
      error it leaves to the vehicles; :meth:`staghunt.safety.Margins.grown`).
    - ``conflict_horizon``: seconds ahead in which a predicted conflict with a known motion
      triggers a re-plan.
    - ``replan_rate``: receding horizon: re-plans per second with nothing sensed (Hz; 0: only
      on events), each over ``replan_horizon`` seconds of the route ahead (0: to the goals).
    - ``replan_particles``, ``replan_iterations``: the game's budget per re-plan
      (``particles x (iterations + 1) x N`` path evaluations, as for ``plan``).
    - ``certify_particles``, ``certify_iterations``, ``epsilon``: each re-plan's certificate;
      ``certify_rounds``: better replies the certificate finds adopted and certified again,
      up to this many times (:func:`staghunt.solvers.improve.certify_and_improve`).
    - ``reply_start``: the first reply's share of a re-plan's budget.
    - ``attempts``: solves per re-plan (each new predicted conflict with a motion adds its
      swept window and solves again); ``window_pad``: seconds added on both sides of a window.
    - ``later_conflicts``: a new plan whose only problems are conflicts with known motions
      that begin more than ``conflict_horizon`` after it starts is accepted; the station's
      predicted-conflict re-plan meets them when they come within the horizon, as it meets
      any plan's (``False``: such a plan is refused and the team solves around the motion's
      window within the same re-plan, or stops).
    - ``defer_stops``: a re-plan of a moving team that finds no plan keeps the current plan and
      solves again (warm-started from its best try) while a stop decided then would still pass
      the acceptance, up to ``deferrals`` times per event, instead of stopping at once.
    - ``stop_budget_factor``: after a stop to hover, the next re-plan gets this many times the
      budget and the deadline; ``retries_after_stop``, ``retry_interval``: re-plans tried while
      hovering (then the goal is reported unreachable), each going on from the best try of the
      one before. The defaults give a hovering team the flight's deadline per re-plan and a
      re-plan every half second, sixteen in all: as much search as four re-plans of four
      times the deadline, two seconds apart (the defaults before), in slices that keep every
      re-plan's latency within the deadline.
    - ``repair_budget_factor``: a receding-horizon re-plan while the plan flown is not a
      certified equilibrium (an event's plan sent uncertified) gets this many times the budget
      and the deadline; an event pre-empts it as it does any receding-horizon re-plan. Off
      (1) by default: with 3, scenario 2's plans sent uncertified gave way to a certified one
      sooner in one run and no sooner in a later one, and one run had a re-plan that overran
      its deadline by over a minute, not explained (benchmarks/JOURNAL.md, "Closed loop: where
      the extra time goes" and "Closed loop: where a re-plan's wall time goes").
    - ``link``: the radio (delay, jitter, loss; ``None``: the scenario's or events file's
      ``[link]``); ``outages``: radio shadows, every message to or from a UAV lost for a while
      (:class:`~staghunt.flight.link.Outage`); ``plan_timeout``: a UAV that hears nothing from
      the ground station for this long holds where it is (s); ``straggler_check``: a new plan
      is sent only if a UAV that missed it, flying on and then holding, keeps apart from its
      team-mates flying it (:meth:`staghunt.flight.known.Acceptance.stragglers`).
    - ``reflex_latency``: the onboard reflex brakes this long after its check finds its
      reference entering a sensed obstacle or a holding neighbour's volume (s).
    - ``wind``: mean wind speed (m/s, Dryden turbulence on top), blowing towards
      ``wind_heading_deg`` (counter-clockwise from east).
    - ``log_rate``: rows per second and UAV in ``flight.csv``.
    - ``hold``: seconds simulated after arrival or after giving up, hovering.
    """

    sim_rate: float = 100.0
    latency: float | str = MEASURED
    deadline: float | None = None
    allowance: float = 0.25
    conflict_horizon: float = 10.0
    replan_rate: float = 1.0
    replan_horizon: float = 20.0
    replan_particles: int = 100
    replan_iterations: int = 100
    certify_particles: int = 200
    certify_iterations: int = 100
    epsilon: float = 0.01
    certify_rounds: int = 4
    reply_start: float = 0.1
    attempts: int = 3
    window_pad: float = 3.0
    later_conflicts: bool = True
    defer_stops: bool = True
    deferrals: int = 8
    stop_budget_factor: int = 1
    repair_budget_factor: int = 1
    retries_after_stop: int = 15
    retry_interval: float = 0.5
    link: Link | None = None
    outages: tuple[Outage, ...] = ()
    straggler_check: bool = True
    plan_timeout: float = 1.0
    reflex_latency: float = 0.05
    wind: float = 0.0
    wind_heading_deg: float = 0.0
    log_rate: float = 20.0
    hold: float = 2.0

    @property
    def measured(self) -> bool:
        """Whether re-plans take their measured wall time (else the fixed ``latency``)."""
        return self.latency == MEASURED

    def deadline_for(self, n_uavs: int) -> float:
        """The re-plan deadline of a team of ``n_uavs`` (s): the one given, else with a fixed
        latency that latency, else :func:`auto_deadline`."""
        if self.deadline is not None:
            return self.deadline
        return auto_deadline(n_uavs) if self.measured else float(self.latency)

    def check(self) -> None:
        """Raise ``ValueError`` (one line naming the setting) for unusable settings."""
        def real(v: object) -> bool:
            return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

        def integer(v: object) -> bool:
            return isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 1_000_000

        link = self.link
        rules = [
            ("sim_rate", real(self.sim_rate) and 100 <= self.sim_rate <= 2000, "a number in [100, 2000] Hz"),
            ("latency", self.latency == MEASURED or (real(self.latency) and 0 < self.latency <= 10),
             f"{MEASURED!r} or a number in (0, 10] s"),
            ("deadline", self.deadline is None or (real(self.deadline) and 0.01 <= self.deadline <= 10),
             "None or a number in [0.01, 10] s"),
            ("allowance", real(self.allowance) and 0 <= self.allowance <= 10, "a number in [0, 10] m"),
            ("conflict_horizon", real(self.conflict_horizon) and 0 < self.conflict_horizon <= 600,
             "a number in (0, 600] s"),
            ("replan_rate", real(self.replan_rate) and 0 <= self.replan_rate <= 10, "a number in [0, 10] Hz"),
            ("replan_horizon", real(self.replan_horizon) and 0 <= self.replan_horizon <= 3600, "a number in [0, 3600] s"),
            ("replan_particles", integer(self.replan_particles), "an integer in [1, 1e6]"),
            ("replan_iterations", integer(self.replan_iterations), "an integer in [1, 1e6]"),
            ("certify_particles", integer(self.certify_particles), "an integer in [1, 1e6]"),
            ("certify_iterations", integer(self.certify_iterations), "an integer in [1, 1e6]"),
            ("epsilon", real(self.epsilon) and self.epsilon >= 0, "a finite number >= 0"),
            ("certify_rounds", isinstance(self.certify_rounds, int) and not isinstance(self.certify_rounds, bool)
             and 0 <= self.certify_rounds <= 20, "an integer in [0, 20]"),
            ("reply_start", real(self.reply_start) and 0 < self.reply_start <= 1, "a number in (0, 1]"),
            ("attempts", integer(self.attempts) and self.attempts <= 20, "an integer in [1, 20]"),
            ("window_pad", real(self.window_pad) and 0 <= self.window_pad <= 60, "a number in [0, 60] s"),
            ("later_conflicts", isinstance(self.later_conflicts, bool), "True or False"),
            ("defer_stops", isinstance(self.defer_stops, bool), "True or False"),
            ("deferrals", integer(self.deferrals) and self.deferrals <= 100, "an integer in [1, 100]"),
            ("stop_budget_factor", integer(self.stop_budget_factor) and self.stop_budget_factor <= 100,
             "an integer in [1, 100]"),
            ("repair_budget_factor", integer(self.repair_budget_factor) and self.repair_budget_factor <= 100,
             "an integer in [1, 100]"),
            ("retries_after_stop", integer(self.retries_after_stop) and self.retries_after_stop <= 100,
             "an integer in [1, 100]"),
            ("retry_interval", real(self.retry_interval) and 0 < self.retry_interval <= 60, "a number in (0, 60] s"),
            ("link", link is None or (isinstance(link, Link) and real(link.delay) and 0 <= link.delay <= 10
                                      and real(link.jitter) and 0 <= link.jitter <= 10
                                      and real(link.loss) and 0 <= link.loss < 1),
             "None or a Link with delay and jitter in [0, 10] s and loss in [0, 1)"),
            ("outages", isinstance(self.outages, tuple) and all(
                isinstance(o, Outage) and isinstance(o.uav, int) and real(o.start) and real(o.end) and o.start <= o.end
                for o in self.outages), "a tuple of Outage(uav, start, end)"),
            ("straggler_check", isinstance(self.straggler_check, bool), "True or False"),
            ("plan_timeout", real(self.plan_timeout) and 0.1 <= self.plan_timeout <= 60, "a number in [0.1, 60] s"),
            ("reflex_latency", real(self.reflex_latency) and 0 <= self.reflex_latency <= 1, "a number in [0, 1] s"),
            ("wind", real(self.wind) and 0 <= self.wind <= 30, "a number in [0, 30] m/s"),
            ("wind_heading_deg", real(self.wind_heading_deg), "a finite number of degrees"),
            ("log_rate", real(self.log_rate) and 1 <= self.log_rate <= self.sim_rate, "a number in [1, sim_rate] Hz"),
            ("hold", real(self.hold) and 0 <= self.hold <= 600, "a number in [0, 600] s"),
        ]
        for name, ok, what in rules:
            if not ok:
                raise ValueError(f"flight setting {name} must be {what}, got {getattr(self, name)!r}")

    def certify_options(self) -> CertifyOptions:
        """The re-plans' certificate: its budget and tolerance."""
        return CertifyOptions(self.certify_particles, self.certify_iterations, self.epsilon)

    def certify_search(self, scenario: Scenario) -> SolverSettings:
        """The settings of the re-plans' certificate searches in ``scenario`` (its solver's, with
        the certificate's budget), checked (:func:`~staghunt.solvers.response.check_search`): once
        per flight, before it starts. Raises a :class:`~staghunt.errors.FieldError`."""
        search = check_search(scenario.solver, self.certify_options(), "re-plan settings")
        assert search is not None
        return search
