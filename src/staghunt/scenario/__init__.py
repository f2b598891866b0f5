"""Scenarios: the immutable planning problem and its TOML file format (validated at load time)."""

from staghunt.scenario.loader import (
    ScenarioError,
    builtin_names,
    builtin_path,
    load_scenario,
    scenario_from_dict,
)
from staghunt.scenario.dump import scenario_to_dict
from staghunt.scenario.model import CostParams, Scenario, SolverSettings

__all__ = [
    "CostParams",
    "Scenario",
    "ScenarioError",
    "SolverSettings",
    "builtin_names",
    "builtin_path",
    "load_scenario",
    "scenario_from_dict",
    "scenario_to_dict",
]
