"""The world: site bounds, ground and obstacles. Knows nothing of UAVs or solvers."""

from __future__ import annotations

from dataclasses import dataclass

from staghunt.world.obstacles import Cylinder, cylinder_array
from staghunt.world.site import Bounds, GeoOrigin
from staghunt.world.terrain import Terrain, round_half_away

__all__ = ["Bounds", "Cylinder", "GeoOrigin", "Terrain", "World", "cylinder_array", "round_half_away"]


@dataclass(frozen=True, eq=False)
class World:
    """Site box, ground elevation and cylinder obstacles."""

    bounds: Bounds
    terrain: Terrain
    cylinders: tuple[Cylinder, ...] = ()
