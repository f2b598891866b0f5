"""staghunt: cooperative multi-UAV path planning as a stag hunt game, solved to certified equilibria."""

from typing import Any

from staghunt._version import __version__
from staghunt.api import PlanRequest, PlanRequestError, check_plan, plan
from staghunt.result import PlanResult, Status
from staghunt.scenario import Scenario, ScenarioError, load_scenario
from staghunt.solvers.response import Certificate, CertifyOptions

_FLIGHT = ("FlightResult", "FlyConfig", "fly")
"""Loaded on first use (:mod:`staghunt.flight` imports the simulator and TOPP-RA, which import
Matplotlib: 0.7 s that planning, the CLI's other commands and the compile helpers do not need)."""


def __getattr__(name: str) -> Any:
    if name in _FLIGHT:
        from staghunt import flight

        return getattr(flight, name)
    raise AttributeError(f"module 'staghunt' has no attribute {name!r}")


__all__ = [
    "Certificate", "CertifyOptions", "FlightResult", "FlyConfig", "PlanResult", "Scenario", "ScenarioError",
    "PlanRequest", "PlanRequestError", "Status", "__version__", "check_plan", "fly", "load_scenario", "plan",
]
