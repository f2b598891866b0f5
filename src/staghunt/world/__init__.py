"""The world: site bounds, ground and obstacles. Knows nothing of UAVs or solvers."""

from __future__ import annotations

from dataclasses import dataclass

from staghunt.world.obstacles import Cylinder, Prism, box_polygon, cylinder_array, prism_arrays
from staghunt.world.site import Bounds, GeoOrigin
from staghunt.world.terrain import Terrain, round_half_away

__all__ = [
    "Bounds", "Cylinder", "GeoOrigin", "Prism", "Terrain", "World", "box_polygon", "cylinder_array",
    "prism_arrays", "round_half_away",
]


@dataclass(frozen=True, eq=False)
class World:
    """Site box, ground elevation, cylinder and prism obstacles, and an altitude ceiling
    (absolute site ``z``, m; ``inf`` = none)."""

    bounds: Bounds
    terrain: Terrain
    cylinders: tuple[Cylinder, ...] = ()
    prisms: tuple[Prism, ...] = ()
    ceiling: float = float("inf")
