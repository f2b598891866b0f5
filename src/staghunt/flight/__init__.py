"""The closed loop of the paper's Fig. 1 in simulation: simulated multirotors fly the plan
(:mod:`~staghunt.flight.vehicles`), the planner senses the changing site and re-solves the game
in flight (:mod:`~staghunt.flight.replan`) along a spliced reference
(:mod:`~staghunt.trajectory.quintic`); :mod:`~staghunt.safety.measure` judges separations and
clearances at the same instant; :func:`check_flight` checks an episode once, :func:`fly` runs it
(:mod:`~staghunt.flight.loop`)."""

from staghunt.flight.loop import FlightInputError, FlightRequest, FlightResult, FlightStatus, check_flight, fly
from staghunt.flight.replan import FlyConfig, ReplanRecord

__all__ = ["FlightInputError", "FlightRequest", "FlightResult", "FlightStatus", "FlyConfig", "ReplanRecord",
           "check_flight", "fly"]
