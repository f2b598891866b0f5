"""staghunt: cooperative multi-UAV path planning as a stag hunt game (game-based SPSO)."""

from staghunt.api import plan
from staghunt.result import PlanResult, Status
from staghunt.scenario import Scenario, ScenarioError, load_scenario

__version__ = "0.1.0"

__all__ = ["PlanResult", "Scenario", "ScenarioError", "Status", "__version__", "load_scenario", "plan"]
