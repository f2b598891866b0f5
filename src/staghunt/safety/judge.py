"""One validity checker for the team's positions in time, in OMPL's spirit: what it checks
against (:class:`Scene`), the margins it requires as named parameters (:class:`Margins`), and
what it finds (:class:`Verdict`, a list of :class:`Breach`).

Every place that judges safety uses :func:`judge`: the planner's acceptance of a plan (its
reference sampled in time, margins grown by a tracking allowance), the in-flight check of the
plan being flown against the known motions, the verdict on a simulated flight (the vehicles'
positions at every step against the true world) and the judge of an exported mission.

Four kinds (:class:`BreachKind`), two severities (:class:`Severity`):

- **clearance** between a UAV's body and an obstacle's surface (docs/model.md, section 2: a
  cylinder is infinitely tall, a prism counts within ``(base - r, top + r)``): *contact* below
  0, *breach* below ``Margins.clearance`` (plus ``motion_margin`` for a moving obstacle);
- **separation** between two UAVs' centres: *contact* below ``r_i + r_j`` (the bodies touch),
  *breach* at or below ``Margins.separation + r_i + r_j`` (the scenario's ``d_s + 2 r``);
- **ground**: the body's height above the terrain, ``z - g(x, y) - r``: *contact* below 0,
  *breach* below ``Margins.ground``;
- **ceiling**: the centre's headroom under the ceiling ``z_max - z``: a *breach* below
  ``Margins.ceiling`` (airspace, never a contact).

Shapes: ``N`` UAVs, ``T`` instants.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np

from staghunt.safety.measure import moving_clearance, nearest_mates, static_nearest
from staghunt.world import Cylinder, Prism, Terrain
from staghunt.world.dynamic import Dynamics, motion_names

BLOCK = 2_000_000
"""Largest ``N * N * T`` the pairwise distances are computed on at once (memory)."""


class BreachKind(str, Enum):
    """What a breach is about."""

    CLEARANCE = "clearance"
    SEPARATION = "separation"
    GROUND = "ground"
    CEILING = "ceiling"


class Severity(str, Enum):
    """``CONTACT``: bodies touched (an obstacle, a team-mate, the ground): unsafe. ``BREACH``: a
    required margin was broken without contact."""

    CONTACT = "contact"
    BREACH = "breach"


@dataclass(frozen=True)
class Margins:
    """The distances the judge requires (m): ``clearance`` between a body and an obstacle's
    surface; ``separation`` between two bodies beyond their radii (the scenario's ``d_s``);
    ``ground`` between a body and the terrain; ``ceiling`` between a centre and the ceiling."""

    clearance: float = 0.0
    separation: float = 0.0
    ground: float = 0.0
    ceiling: float = 0.0

    @classmethod
    def required(cls, scenario: Any) -> "Margins":
        """The scenario's requirements: its hard clearance to obstacles and to the ground, its
        ``d_s`` between UAVs, nothing more under the ceiling."""
        c = scenario.costs
        return cls(float(c.min_clearance), float(c.safe_distance), float(c.min_clearance), 0.0)

    def grown(self, allowance: float) -> "Margins":
        """These margins plus ``allowance`` (m) for every body (twice between two bodies): what a
        reference must keep so that vehicles tracking it within ``allowance`` keep these."""
        a = float(allowance)
        return Margins(self.clearance + a, self.separation + 2 * a, self.ground + a, self.ceiling + a)


@dataclass(frozen=True)
class Epoch:
    """The fixed obstacles from ``start`` (s) until the next epoch starts."""

    start: float
    cylinders: tuple[Cylinder, ...]
    prisms: tuple[Prism, ...]


@dataclass(frozen=True, eq=False)
class Scene:
    """What the judge checks against: fixed obstacles by epoch (obstacles appear and disappear),
    the known motions (moving cylinders, jibs), the ground and the ceiling."""

    terrain: Terrain
    ceiling: float
    epochs: tuple[Epoch, ...]
    motions: Dynamics | None = None

    @classmethod
    def fixed(cls, world: Any, cylinders: tuple[Cylinder, ...] | None = None,
              prisms: tuple[Prism, ...] | None = None, motions: Dynamics | None = None) -> "Scene":
        """``world``'s ground and ceiling with these fixed obstacles (default the world's) for
        all time, and ``motions`` (their ``moving`` and ``jibs``; ``None``: none)."""
        cyl = world.cylinders if cylinders is None else cylinders
        prm = world.prisms if prisms is None else prisms
        return cls(world.terrain, float(world.ceiling), (Epoch(-math.inf, tuple(cyl), tuple(prm)),),
                   motions if motions is not None and motions.known_motion else None)

    @classmethod
    def of_arrays(cls, terrain: Terrain, ceiling: float, cylinders: np.ndarray, prisms: np.ndarray,
                  edges: np.ndarray) -> "Scene":
        """The fixed obstacles of a cost model's arrays (``cylinders`` ``(T, 3)`` ``x, y, R``;
        ``prisms`` ``(Q, 8)`` and their ``edges`` ``(E, 4)``, :func:`staghunt.world.prism_arrays`),
        named ``obstacle i`` and ``prism q`` as the plan's checks name them."""
        cyl = tuple(Cylinder(float(x), float(y), float(r), f"obstacle {i + 1}") for i, (x, y, r) in enumerate(cylinders))
        prm = []
        for q, row in enumerate(np.asarray(prisms, dtype=float).reshape(-1, 8)):
            e0, ne = int(row[2]), int(row[3])
            poly = tuple((float(x), float(y)) for x, y in edges[e0:e0 + ne, :2])
            prm.append(Prism(poly, float(row[0]), float(row[1]), f"prism {q + 1}"))
        return cls(terrain, float(ceiling), (Epoch(-math.inf, cyl, tuple(prm)),))

    @classmethod
    def true(cls, world: Any, dyn: Dynamics) -> "Scene":
        """The site as it truly is in flight: the world's obstacles, those that ``dyn``'s events
        add and remove at their times, and its known motions."""
        epochs = []
        for t0 in sorted({-math.inf, *[e.time for e in dyn.events]}):
            gone = {e.name for e in dyn.events if e.kind == "disappear" and e.time <= t0}
            cyl = [c for c in world.cylinders if c.name not in gone]
            prm = [p for p in world.prisms if p.name not in gone]
            for e in dyn.events:
                if e.kind == "appear" and e.time <= t0 and e.name not in gone and e.shape is not None:
                    (cyl if isinstance(e.shape, Cylinder) else prm).append(e.shape)  # type: ignore[arg-type]
            epochs.append(Epoch(t0, tuple(cyl), tuple(prm)))
        return cls(world.terrain, float(world.ceiling), tuple(epochs), dyn if dyn.known_motion else None)


@dataclass(frozen=True)
class Breach:
    """One UAV's breach of one kind: the first instant a margin was broken (``since``), and the
    worst one (``time``, ``position`` ``(x, y, z)``, ``value`` the clearance, distance, height
    or headroom there, against ``required``); ``other``: the obstacle, team-mate, ``ground``
    or ``ceiling``."""

    kind: BreachKind
    severity: Severity
    uav: int
    other: str
    since: float
    time: float
    position: tuple[float, float, float]
    value: float
    required: float

    def describe(self, names: list[str]) -> str:
        who = names[self.uav] if self.uav < len(names) else f"UAV {self.uav + 1}"
        at = f"at t = {self.time:.2f} s, ({self.position[0]:.1f}, {self.position[1]:.1f}, {self.position[2]:.1f})"
        what = {BreachKind.CLEARANCE: f"clearance to {self.other or 'an obstacle'}",
                BreachKind.SEPARATION: f"distance to team-mate {self.other}",
                BreachKind.GROUND: "height of its body above the ground",
                BreachKind.CEILING: "headroom under the ceiling"}[self.kind]
        word = "contact" if self.severity is Severity.CONTACT else "breach"
        return f"{word}: {who}'s {what} fell to {self.value:.2f} m (required {self.required:.2f} m) {at}"

    def to_dict(self, names: list[str]) -> dict[str, Any]:
        return {"kind": self.kind.value, "severity": self.severity.value,
                "uav": names[self.uav] if self.uav < len(names) else self.uav + 1, "other": self.other,
                "since_s": round(self.since, 3), "time_s": round(self.time, 3),
                "position": [round(v, 3) for v in self.position], "value_m": round(self.value, 4),
                "required_m": round(self.required, 4)}


@dataclass(frozen=True, eq=False)
class Verdict:
    """What :func:`judge` found: the breaches (one per UAV and kind, contacts first), per UAV
    ``(N,)`` the least ``min_clearance`` (to any obstacle), ``min_separation`` (centre
    distance to the nearest team-mate), ``min_ground`` (body above the terrain),
    ``min_headroom`` (centre under the ceiling), the known motions' conflict ``windows``
    ``(name, first, last)`` (instants where their clearance breaks its margin) and, if asked,
    ``clearance`` ``(N, T)``."""

    margins: Margins
    breaches: tuple[Breach, ...]
    min_clearance: np.ndarray
    min_separation: np.ndarray
    min_ground: np.ndarray
    min_headroom: np.ndarray
    windows: tuple[tuple[str, float, float], ...] = ()
    clearance: np.ndarray | None = None

    @property
    def contact(self) -> bool:
        return any(b.severity is Severity.CONTACT for b in self.breaches)

    @property
    def safe(self) -> bool:
        """No margin broken."""
        return not self.breaches

    @property
    def least_clearance(self) -> float:
        return float(self.min_clearance.min(initial=math.inf))

    def problems(self, names: list[str]) -> list[str]:
        return [b.describe(names) for b in self.breaches]


def _worst(kind: BreachKind, excess: np.ndarray, contact: np.ndarray, value: np.ndarray,
           required: np.ndarray, times: np.ndarray, pos: np.ndarray, other: Any) -> list[Breach]:
    """One :class:`Breach` per UAV with ``excess`` ``(N, T)`` (value minus required) below 0
    (``<= 0`` counts for separation, passed as a tiny negative shift by the caller)."""
    out = []
    for n in np.flatnonzero((excess < 0).any(axis=1)):
        k = int(np.argmin(excess[n]))
        first = int(np.argmax(excess[n] < 0))
        out.append(Breach(kind, Severity.CONTACT if contact[n].any() else Severity.BREACH, int(n),
                          other(n, k), float(times[first]), float(times[k]),
                          tuple(float(v) for v in pos[n, k]), float(value[n, k]),
                          float(np.broadcast_to(required, value.shape)[n, k])))
    return out


def judge(scene: Scene, radius: np.ndarray, times: np.ndarray, pos: np.ndarray, margins: Margins,
          names: list[str] | None = None, motion_margin: float = 0.0, keep: bool = False,
          active: np.ndarray | None = None) -> Verdict:
    """Judge positions ``pos`` ``(N, T, 3)`` (absolute site) at ``times`` ``(T,)`` of UAVs of
    body ``radius`` ``(N,)`` against ``scene`` with ``margins`` (module docstring).
    ``motion_margin`` (m) is added to the clearance required from a moving obstacle (the
    distance it and a UAV can close between two samples); ``names`` name the UAVs in the
    breaches (default ``UAV 1``...); ``keep``: keep the clearances ``(N, T)`` in the verdict;
    ``active`` ``(N, T)``: the instants each UAV counts (``False``: it has left the team, landed
    where it was lost; it is then judged against nothing and nobody against it)."""
    times = np.asarray(times, dtype=float)
    pos = np.asarray(pos, dtype=float)
    N, T = pos.shape[:2]
    on = np.ones((N, T), dtype=bool) if active is None else np.asarray(active, dtype=bool)
    r = np.asarray(radius, dtype=float)
    names = names or [f"UAV {n + 1}" for n in range(N)]
    # clearance to fixed obstacles, epoch by epoch
    clear = np.full((N, T), np.inf)
    label = np.full((N, T), -1, dtype=int)
    labels: list[str] = []
    starts = [e.start for e in scene.epochs]
    idx = np.clip(np.searchsorted(starts, times, side="right") - 1, 0, len(starts) - 1)
    for i in np.unique(idx):
        e = scene.epochs[i]
        sel = idx == i
        c, w = static_nearest(e.cylinders, e.prisms, pos[:, sel], r)
        clear[:, sel] = np.where(on[:, sel], c, np.inf)
        label[:, sel] = np.where(w >= 0, w + len(labels), -1)
        labels += [s.name for s in e.cylinders] + [s.name for s in e.prisms]
    breaches = _worst(BreachKind.CLEARANCE, clear - margins.clearance, clear < 0, clear, np.array(margins.clearance),
                      times, pos, lambda n, k: labels[label[n, k]] if label[n, k] >= 0 else "")
    windows: list[tuple[str, float, float]] = []
    if scene.motions is not None:
        mc, which = moving_clearance(scene.motions, pos, times, r)
        mc = np.where(on, mc, np.inf)
        need = margins.clearance + motion_margin
        moving = motion_names(scene.motions)
        bad = mc < need
        for i in np.unique(which[bad]):
            ks = np.flatnonzero((bad & (which == i)).any(axis=0))
            windows.append((moving[i], float(times[ks[0]]), float(times[ks[-1]])))
        more = _worst(BreachKind.CLEARANCE, mc - need, mc < 0, mc, np.array(need), times, pos,
                      lambda n, k: moving[which[n, k]])
        # one clearance breach per UAV: the worse of the fixed and the moving obstacles'
        for b in more:
            old = next((x for x in breaches if x.uav == b.uav), None)
            if old is None or b.value - b.required < old.value - old.required:
                if old is not None:
                    b = Breach(b.kind, Severity.CONTACT if Severity.CONTACT in (b.severity, old.severity)
                               else b.severity, b.uav, b.other, min(b.since, old.since), b.time, b.position,
                               b.value, b.required)
                    breaches.remove(old)
                breaches.append(b)
            elif b.severity is Severity.CONTACT and old.severity is not Severity.CONTACT:
                breaches[breaches.index(old)] = Breach(old.kind, Severity.CONTACT, old.uav, old.other,
                                                       min(b.since, old.since), old.time, old.position,
                                                       old.value, old.required)
        clear = np.minimum(clear, mc)
    # separation, in blocks of instants
    dist = np.full((N, T), np.inf)
    mate = np.full((N, T), -1, dtype=int)
    step = max(1, BLOCK // max(1, N * N))
    for a in range(0, T, step):
        dist[:, a:a + step], mate[:, a:a + step] = nearest_mates(pos[:, a:a + step], r, on[:, a:a + step])
    touch = r[:, None] + np.where(mate >= 0, r[np.maximum(mate, 0)], 0.0)
    need_sep = margins.separation + touch
    breaches += _worst(BreachKind.SEPARATION, np.nextafter(dist - need_sep, -np.inf), dist < touch, dist, need_sep,
                       times, pos, lambda n, k: names[mate[n, k]])
    # ground and ceiling
    ground = np.where(on, pos[..., 2] - scene.terrain.height(pos[..., 0], pos[..., 1]) - r[:, None], np.inf)
    breaches += _worst(BreachKind.GROUND, ground - margins.ground, ground < 0, ground, np.array(margins.ground),
                       times, pos, lambda n, k: "ground")
    head = np.where(on, scene.ceiling - pos[..., 2], np.inf)
    breaches += _worst(BreachKind.CEILING, head - margins.ceiling, np.zeros_like(head, dtype=bool), head,
                       np.array(margins.ceiling), times, pos, lambda n, k: "ceiling")
    order = sorted(breaches, key=lambda b: (b.severity is not Severity.CONTACT, b.since, b.uav))
    return Verdict(margins, tuple(order), clear.min(axis=1, initial=np.inf), dist.min(axis=1, initial=np.inf),
                   ground.min(axis=1, initial=np.inf), head.min(axis=1, initial=np.inf), tuple(windows),
                   clear if keep else None)
