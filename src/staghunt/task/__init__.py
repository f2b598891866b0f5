"""The task: who flies (team), how they keep together (formation), what they minimise (weights)."""

from staghunt.task.formation import (
    Formation,
    formation_error_edges,
    formation_error_quadratic,
    is_connected,
)
from staghunt.task.team import UAV, WEIGHT_NAMES, Team, VehicleLimits, Weights

__all__ = [
    "Formation",
    "Team",
    "UAV",
    "VehicleLimits",
    "WEIGHT_NAMES",
    "Weights",
    "formation_error_edges",
    "formation_error_quadratic",
    "is_connected",
]
