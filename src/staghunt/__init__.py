"""staghunt: cooperative multi-UAV path planning as a stag hunt game, solved to certified equilibria."""

from staghunt._version import __version__
from staghunt.api import PlanRequest, PlanRequestError, check_plan, plan
from staghunt.flight import FlightResult, FlyConfig, fly
from staghunt.result import PlanResult, Status
from staghunt.scenario import Scenario, ScenarioError, load_scenario
from staghunt.solvers.response import Certificate, CertifyOptions


__all__ = [
    "Certificate", "CertifyOptions", "FlightResult", "FlyConfig", "PlanResult", "Scenario", "ScenarioError",
    "PlanRequest", "PlanRequestError", "Status", "__version__", "check_plan", "fly", "load_scenario", "plan",
]
