"""Tasks: the units of capture work the task layer allocates, and who may fly them.

A :class:`Task` is one capture segment (a survey line, one wall of a facade layer, a viewpoint),
so that a large area or a facade is split among UAVs line by line and wall by wall, with no
photo taken twice. It may be flown in several **ways** (:class:`Way`): a survey line or a wall
in either direction; the allocation picks one. A task's ``uavs`` are the UAVs whose camera it was planned
for and whose gimbal reaches its pitch.

:class:`Fleet` is what the allocation knows of the UAVs: where each starts and must end, when
it is free, how long it may still fly, at which speed it transits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from staghunt.acquisition.segments import CapturePlan, CaptureSegment
from staghunt.task.objectives import Inspection, Objective

__all__ = ["Fleet", "Task", "Way", "check_capable", "make_tasks", "window_of"]

@dataclass(frozen=True, eq=False)
class Way:
    """One way to fly a task: the segment as flown (points in flying order)."""

    segment: CaptureSegment

    @property
    def entry(self) -> np.ndarray:
        return self.segment.entry

    @property
    def exit(self) -> np.ndarray:
        return self.segment.exit


@dataclass(frozen=True, eq=False)
class Task:
    """A unit of capture work of objective ``objective`` (``priority``, ``required`` from it):
    its ``ways``, its duration (s, the same every way), its time ``window`` (``None``: any time)
    and the indices of the UAVs that may fly it."""

    index: int
    objective: str
    ways: tuple[Way, ...]
    duration: float
    window: tuple[float, float] | None
    uavs: tuple[int, ...]
    priority: int = 1
    required: bool = True

    @property
    def segment(self) -> CaptureSegment:
        return self.ways[0].segment


@dataclass(frozen=True, eq=False)
class Fleet:
    """What the allocation knows of ``N`` UAVs: ``starts``/``goals`` ``(N, 3)`` absolute, the
    time each is free to start (``ready (N,)``, s after take-off), the flight time it has left
    from then (``endurance (N,)``, s), its transit speed (``speed (N,)``, m/s), its name, and
    which UAVs take part at all (``active (N,)``: a lost UAV does not)."""

    starts: np.ndarray
    goals: np.ndarray
    ready: np.ndarray
    endurance: np.ndarray
    speed: np.ndarray
    names: tuple[str, ...]
    active: np.ndarray

    @property
    def n(self) -> int:
        return len(self.names)

    def travel(self, k: int, a: np.ndarray, b: np.ndarray) -> float:
        """Transit time (s) of UAV ``k`` from ``a`` to ``b``: the straight line at its speed (a
        lower bound of the planned leg, which may go round obstacles)."""
        return float(np.linalg.norm(np.asarray(b) - np.asarray(a))) / float(self.speed[k])


def _ways(seg: CaptureSegment) -> tuple[Way, ...]:
    if not seg.reversible or len(seg.points) < 2:
        return (Way(seg),)
    return (Way(seg), Way(seg.reversed()))


def _capable(inspection: Inspection, seg: CaptureSegment) -> tuple[int, ...]:
    lo, hi = float(np.degrees(seg.pitch.min())), float(np.degrees(seg.pitch.max()))
    return tuple(k for k, p in enumerate(inspection.payloads)
                 if p.camera.name == seg.camera and p.gimbal_pitch_min_deg - 1e-6 <= lo and hi <= p.gimbal_pitch_max_deg + 1e-6)


def make_tasks(inspection: Inspection, captures: CapturePlan) -> list[Task]:
    """Every capture segment of ``captures`` as a task, in the objectives' order."""
    tasks: list[Task] = []
    for plan in captures.objectives:
        obj: Objective = inspection.objective(plan.name)
        for seg in plan.segments:
            tasks.append(Task(index=len(tasks), objective=obj.name, ways=_ways(seg), duration=seg.duration,
                              window=seg.window, uavs=_capable(inspection, seg), priority=obj.priority,
                              required=obj.required))
    return tasks


def window_of(task: Task) -> tuple[float, float]:
    """``(earliest start, latest start)`` of ``task`` (s)."""
    if task.window is None:
        return 0.0, math.inf
    return task.window[0], task.window[1] - task.duration


def check_capable(tasks: list[Task]) -> None:
    """Every task has a UAV that can fly it, else a :class:`~staghunt.errors.FieldError`."""
    from staghunt.errors import FieldError

    for t in tasks:
        if not t.uavs:
            raise FieldError(f"objectives: {t.objective}: no UAV carries camera {t.segment.camera!r} with a gimbal "
                             "that reaches its pitch", "objectives")
