"""The one safety judge of the team's positions in time (docs/model.md, section 8).

:mod:`~staghunt.safety.measure` measures: clearances to fixed and moving obstacles, distances
between UAVs, height above the ground. :mod:`~staghunt.safety.judge` judges: one checker with
its margins as named parameters (:class:`Margins`), which serves the planner's acceptance of a
plan, the in-flight checks, the flight's verdict and the exported mission's judge, and tells a
contact (unsafe) from a breach of a required margin (clearance, separation, ground, ceiling).
"""

from staghunt.safety.judge import Breach, BreachKind, Margins, Scene, Severity, Verdict, judge

__all__ = ["Breach", "BreachKind", "Margins", "Scene", "Severity", "Verdict", "judge"]
