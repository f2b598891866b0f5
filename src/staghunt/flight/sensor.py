"""The team's sensors: every UAV's measured state (with the configured noise) and the obstacles
that appeared within each UAV's sensing range (docs/model.md, section 8)."""

from __future__ import annotations

from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from staghunt.safety.measure import static_clearance
from staghunt.world import Cylinder, Prism
from staghunt.world.dynamic import Dynamics

Course = Callable[[np.ndarray], np.ndarray]
"""The UAVs' references at times ``(G,)``: positions ``(N, G, 3)``."""
LEAD_STEP_S = 0.05
"""Seconds between the samples of a trigger's lead on the UAVs' references."""


def horizontal_distance(shape: Cylinder | Prism, xy: np.ndarray) -> np.ndarray:
    """``(N,)`` horizontal distance from points ``(N, 2)`` to the shape's outline (0 inside)."""
    pos = np.column_stack([xy, np.zeros(len(xy))])[:, None]
    if isinstance(shape, Cylinder):
        return np.maximum(static_clearance((shape,), (), pos, np.zeros(len(xy)))[:, 0], 0.0)
    flat = replace(shape, base=-np.inf, top=np.inf)
    return static_clearance((), (flat,), pos, np.zeros(len(xy)))[:, 0]


class Sensor:
    """What the UAVs sense of ``dyn``: :meth:`measure` their states, :meth:`detect` the obstacles
    that appeared within ``dyn.sensing.range`` of each (remembered once seen, until they are
    gone). Noise is drawn from ``rng``. ``uavs``: the team's names (an appear's trigger may name
    one), ``reach`` ``(N,)``: each UAV's radius plus the required clearance (a trigger's lead
    counts to a UAV coming that close); the events as they happened: :meth:`flown`."""

    def __init__(self, dyn: Dynamics, uavs: Sequence[str], rng: np.random.Generator,
                 reach: Sequence[float] | None = None) -> None:
        self.dyn, self.rng = dyn, rng
        self.index = {name: n for n, name in enumerate(uavs)}
        self.reach = np.zeros(len(uavs)) if reach is None else np.asarray(reach, dtype=float)
        self.seen: list[dict[str, Cylinder | Prism]] = [{} for _ in uavs]
        self.appeared: dict[int, float] = {}  # appear event (its index in dyn.events) -> when it appeared

    def measure(self, pos: np.ndarray, vel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measured positions and velocities ``(N, 3)`` of the true ones."""
        s = self.dyn.sensing
        if s.position_noise > 0:
            pos = pos + self.rng.normal(0.0, s.position_noise, pos.shape)
        if s.velocity_noise > 0:
            vel = vel + self.rng.normal(0.0, s.velocity_noise, vel.shape)
        return pos, vel

    def _appear(self, t: float, pos: np.ndarray, course: Course | None) -> None:
        """The appear events that happen by ``t``: at their time, or sooner at the first tick
        their trigger holds for its UAV, or for any UAV when it names none: true positions
        ``pos`` ``(N, 3)`` within its distance, or ``course`` (the UAVs' references at given
        times) bringing a UAV within its ``reach`` (its radius plus the required clearance) of the
        outline within its lead."""
        for i, e in enumerate(self.dyn.events):
            if e.kind != "appear" or e.shape is None or i in self.appeared:
                continue
            if e.time <= t:
                self.appeared[i] = e.time
            elif e.trigger is not None:
                g = e.trigger
                watch = np.arange(len(self.index)) if g.uav is None else np.array([self.index[g.uav]])
                if g.within > 0 and np.any(horizontal_distance(e.shape, pos[watch, :2]) <= g.within):
                    self.appeared[i] = t
                elif g.lead > 0 and course is not None:
                    ahead = course(t + np.arange(0.0, g.lead + 1e-9, LEAD_STEP_S))[watch, :, :2]  # (M, G, 2)
                    d = horizontal_distance(e.shape, ahead.reshape(-1, 2)).reshape(ahead.shape[:2])
                    if np.any(d < self.reach[watch, None]):
                        self.appeared[i] = t

    def detect(self, t: float, pos: np.ndarray, course: Course | None = None) -> list[dict[str, Cylinder | Prism]]:
        """Per UAV, every appeared obstacle it has seen by ``t`` (its true position ``(N, 3)``
        within the sensing range of it), less those gone. ``course``: the UAVs' references
        ``(N, G, 3)`` at times ``(G,)``, for the triggers with a lead."""
        self._appear(t, pos, course)
        gone = self.dyn.removed(t)
        for i, e in enumerate(self.dyn.events):
            if i not in self.appeared or e.shape is None or e.name in gone:
                continue
            near = horizontal_distance(e.shape, pos[:, :2]) <= self.dyn.sensing.range
            for n in np.flatnonzero(near):
                self.seen[n].setdefault(e.name, e.shape)
        return [{k: v for k, v in s.items() if k not in gone} for s in self.seen]

    def flown(self) -> Dynamics:
        """``dyn`` as it happened: every triggered appear that happened at the time it did, and
        no trigger left (one that never held keeps its time)."""
        events = [replace(e, time=self.appeared.get(i, e.time), trigger=None) if e.trigger is not None else e
                  for i, e in enumerate(self.dyn.events)]
        return replace(self.dyn, events=tuple(sorted(events, key=lambda e: e.time)))
