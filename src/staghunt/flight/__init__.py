"""The closed loop of the paper's Fig. 1 in simulation, made of small parts wired in
:mod:`~staghunt.flight.loop` (:func:`fly`, :func:`check_flight`):

- the vehicles (:mod:`~staghunt.flight.vehicles`) and their sensor (:mod:`~staghunt.flight.sensor`);
- what each UAV decides on its own (:mod:`~staghunt.flight.onboard`: the plan it flies,
  holds, its reflex);
- the radio between them and the ground station (:mod:`~staghunt.flight.link`);
- the ground station, the planner (:mod:`~staghunt.flight.station`, ``tick(t, observations)``),
  which re-solves the game in flight (:mod:`~staghunt.flight.replan`, with the game's own
  loops in :mod:`staghunt.solvers.improve`) and falls back on stops
  (:mod:`~staghunt.flight.fallback`), with what it knows (:mod:`~staghunt.flight.known`);
- the one safety judge (:mod:`staghunt.safety`) for the planner's acceptance, the in-flight
  checks and the flight's verdict (:mod:`~staghunt.flight.result`).

Every curve flown answers :class:`staghunt.trajectory.team.TeamTrajectory`.
"""

from staghunt.flight.config import FlyConfig
from staghunt.flight.link import Outage
from staghunt.flight.loop import FlightRequest, check_flight, fly
from staghunt.flight.offline import FlightInputError
from staghunt.flight.records import Cause, ReplanRecord, ReplanStatus
from staghunt.flight.result import FlightResult, FlightStatus

__all__ = ["Cause", "FlightInputError", "FlightRequest", "FlightResult", "FlightStatus", "FlyConfig", "Outage",
           "ReplanRecord", "ReplanStatus", "check_flight", "fly"]
