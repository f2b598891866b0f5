"""From a plan to the air: timed trajectories and mission files for ground stations.

:func:`export_result` reads a ``result.json``, geo-references the plan (:mod:`staghunt.geo`),
times it (:mod:`staghunt.trajectory`), checks separation and clearance in time, and writes the
mission files of :mod:`staghunt.missions.formats` (docs/missions.md).
"""

from typing import Any

from staghunt.missions.formats import FORMATS

__all__ = ["FORMATS", "ExportReport", "export_result"]


def __getattr__(name: str) -> Any:
    """:mod:`staghunt.missions.export` on first use: it imports the simulator (the flown check),
    0.7 s that the CLI's parser, which lists :data:`FORMATS`, does not need."""
    if name in ("ExportReport", "export_result"):
        from staghunt.missions import export

        return getattr(export, name)
    raise AttributeError(f"module 'staghunt.missions' has no attribute {name!r}")
