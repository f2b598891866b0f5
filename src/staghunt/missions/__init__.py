"""From a plan to the air: timed trajectories and mission files for ground stations.

:func:`export_result` reads a ``result.json``, geo-references the plan (:mod:`staghunt.geo`),
times it (:mod:`staghunt.trajectory`), checks separation and clearance in time, and writes the
mission files of :mod:`staghunt.missions.formats` (docs/missions.md).
"""

from staghunt.missions.export import FORMATS, ExportReport, export_result

__all__ = ["FORMATS", "ExportReport", "export_result"]
