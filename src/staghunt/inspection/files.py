"""``inspection.json``: a planned inspection as strict JSON, and back to a flyable timeline.

Layout::

    format "staghunt-inspection", version 1, status, message, seed, makespan,
    scenario (staghunt.scenario.scenario_to_dict, objectives and payloads included),
    config {allocation, solutions, rounds, time_cap_s},
    allocation {method, status, makespan, lower_bound, ratio, solve_time_s, dropped,
                baseline {method, makespan}, uavs [N x {name, tasks, end, work, transit, wait}]},
    objectives [per objective: {name, kind, segments, photos, qgc_photos, distance_m, gsd_cm,
                work_s, moved, unreached, details}],
    outbound {feasible, message, certificate {verdict, is_equilibrium, gaps}} or null,
    safety {safe, problems, min_separation, min_clearance, ...},
    coverage [planned coverage per objective], times {captures_s, allocation_s, legs_s, ...},
    uavs [N x {name, pieces [{kind, t0, t1, label, points [[x, y, z], ...], task,
                              segment {objective, kind, index, trigger, trigger_distance, speed,
                                       gsd_cm, camera, dwell_s, reversible, window, yaw, pitch}}]}]

:func:`read_timeline` rebuilds every UAV's timeline from the stored pieces: the team's outbound
leg timed together again, the other legs and the captures timed again from their points (the
same TOPP-RA timing, so the same times), the hovers as stored.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from staghunt.acquisition.segments import CaptureSegment
from staghunt.inspection.planner import InspectionPlan
from staghunt.inspection.timeline import Piece, Timeline, capture_piece, hover_piece, path_piece, team_pieces
from staghunt.io.result_json import encode_array, load_json_strict, write_json_atomic
from staghunt.scenario import Scenario, scenario_from_dict, scenario_to_dict

__all__ = ["FORMAT", "allocation_dict", "inspection_to_dict", "read_inspection", "read_timeline", "write_inspection"]

FORMAT = "staghunt-inspection"


def _segment(seg: CaptureSegment) -> dict[str, Any]:
    return {"objective": seg.objective, "kind": seg.kind, "index": seg.index, "trigger": seg.trigger,
            "trigger_distance": seg.trigger_distance, "speed": seg.speed, "gsd_cm": seg.gsd_cm, "camera": seg.camera,
            "dwell_s": seg.dwell_s, "reversible": seg.reversible,
            "window": None if seg.window is None else list(seg.window),
            "yaw": encode_array(seg.yaw, "segment.yaw"), "pitch": encode_array(seg.pitch, "segment.pitch")}


def _piece(p: Piece) -> dict[str, Any]:
    return {"kind": p.kind, "t0": p.t0, "t1": p.t1, "label": p.label, "points": encode_array(p.points, "points"),
            "task": p.task, "segment": None if p.segment is None else _segment(p.segment)}


def inspection_to_dict(plan: InspectionPlan) -> dict[str, Any]:
    """The plan as plain JSON-able data (the module's layout)."""
    a, b = plan.allocation, plan.baseline
    names = plan.timeline.names
    out = plan.outbound
    cert = None if out is None or out.certificate is None else {
        "verdict": out.certificate.verdict, "is_equilibrium": bool(out.certificate.is_equilibrium),
        "max_relative_gap": float(out.certificate.max_relative_gap),
        "relative_gaps": [float(u.relative) for u in out.certificate.uavs]}
    s = plan.safety
    return {
        "format": FORMAT, "version": 1, "status": plan.status.value, "message": plan.message, "seed": plan.seed,
        "makespan": plan.makespan,
        "config": {"allocation": plan.config.allocation, "solutions": plan.config.solutions,
                   "rounds": plan.config.rounds, "time_cap_s": plan.config.time_cap_s},
        "allocation": {
            "method": a.method, "status": a.status, "makespan": a.makespan, "lower_bound": a.lower_bound,
            "ratio": a.makespan / a.lower_bound if a.lower_bound > 0 else None, "solve_time_s": a.solve_time_s,
            "dropped": [plan.tasks[i].objective for i in a.dropped],
            "baseline": {"method": b.method, "makespan": b.makespan},
            "flown_makespan_over_lower_bound": plan.makespan / a.lower_bound if a.lower_bound > 0 else None,
            "uavs": [{"name": names[r.uav], "tasks": [[v.task, v.way] for v in r.visits], "end": r.end,
                      "work": r.work, "transit": r.transit, "wait": r.wait} for r in a.routes]},
        "objectives": [{"name": o.name, "kind": o.kind, "segments": len(o.segments), "photos": o.photos,
                        "qgc_photos": o.qgc_photos, "distance_m": o.distance_m, "gsd_cm": o.gsd_cm, "work_s": o.work_s,
                        "moved": list(o.moved), "unreached": list(o.unreached), "details": o.details}
                       for o in plan.captures.objectives],
        "outbound": None if out is None else {"feasible": out.feasible, "message": out.message, "certificate": cert},
        "safety": {"safe": s.safe, "problems": list(s.problems), "min_separation": list(s.min_separation),
                   "separation_limit": list(s.separation_limit), "min_clearance": list(s.min_clearance),
                   "required_clearance": s.required_clearance, "min_height": list(s.min_height)},
        "coverage": list(plan.coverage),
        "times": plan.times,
        "scenario": scenario_to_dict(plan.scenario),
        "uavs": [{"name": names[n], "pieces": [_piece(p) for p in pieces]} for n, pieces in enumerate(plan.timeline.pieces)],
    }


def clean(value: Any) -> Any:
    """Plain JSON data: NumPy scalars and arrays as Python numbers and lists, an infinity as the
    string ``"inf"`` (as in ``result.json``), ``NaN`` as ``null``."""
    if isinstance(value, dict):
        return {str(k): clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return clean(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    return value


def write_inspection(plan: InspectionPlan, path: str | os.PathLike[str]) -> Path:
    """Write ``inspection.json`` atomically."""
    return write_json_atomic(clean(inspection_to_dict(plan)), path)


def allocation_dict(scenario: Scenario, captures: Any, tasks: list[Any], alloc: Any, greedy: Any) -> dict[str, Any]:
    """``allocation.json`` of ``staghunt inspect``: the capture plans and the allocation."""
    names = [u.name for u in scenario.team]
    return clean({
        "format": "staghunt-allocation", "version": 1, "scenario": scenario.name,
        "objectives": [{"name": o.name, "kind": o.kind, "segments": len(o.segments), "photos": o.photos,
                        "qgc_photos": o.qgc_photos, "distance_m": o.distance_m, "gsd_cm": o.gsd_cm, "work_s": o.work_s,
                        "moved": list(o.moved), "unreached": list(o.unreached), "details": o.details}
                       for o in captures.objectives],
        "tasks": [{"index": t.index, "objective": t.objective, "duration_s": t.duration, "window": t.window,
                   "uavs": [names[k] for k in t.uavs]} for t in tasks],
        "allocation": {"method": alloc.method, "status": alloc.status, "message": alloc.message,
                       "makespan": alloc.makespan, "lower_bound": alloc.lower_bound, "solve_time_s": alloc.solve_time_s,
                       "dropped": [tasks[i].objective for i in alloc.dropped], "details": alloc.details,
                       "uavs": [{"name": names[r.uav], "tasks": [[v.task, v.way, v.start, v.end] for v in r.visits],
                                 "end": r.end, "work": r.work, "transit": r.transit, "wait": r.wait}
                                for r in alloc.routes]},
        "baseline": {"method": greedy.method, "makespan": greedy.makespan}})


def read_inspection(path: str | os.PathLike[str]) -> dict[str, Any]:
    """An ``inspection.json`` read and checked for its format (``ValueError`` naming the file)."""
    data = load_json_strict(path)
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{os.fspath(path)}: not a staghunt inspection file (format {FORMAT!r})")
    return data


def _segment_from(d: dict[str, Any], points: np.ndarray) -> CaptureSegment:
    return CaptureSegment(
        objective=d["objective"], kind=d["kind"], index=int(d["index"]), points=points,
        yaw=np.asarray(d["yaw"], dtype=float), pitch=np.asarray(d["pitch"], dtype=float), trigger=d["trigger"],
        trigger_distance=float(d["trigger_distance"]), speed=float(d["speed"]), gsd_cm=float(d["gsd_cm"]),
        camera=d["camera"], dwell_s=float(d["dwell_s"]), reversible=bool(d["reversible"]),
        window=None if d["window"] is None else (float(d["window"][0]), float(d["window"][1])))


def read_timeline(data: dict[str, Any], source: str = "inspection.json") -> tuple[Scenario, Timeline]:
    """The scenario and the timeline of a read ``inspection.json``."""
    scenario = scenario_from_dict(data["scenario"], name="inspection")
    limits = scenario.vehicle
    uavs = data["uavs"]
    outbound = [(n, u["pieces"][0]) for n, u in enumerate(uavs) if u["pieces"] and u["pieces"][0]["label"] == "outbound"]
    team: dict[int, Piece] = {}
    if outbound:
        from staghunt.costs import CostModel
        from staghunt.inspection.legs import leg_scenario

        pts = np.array([np.asarray(p["points"], dtype=float) for _, p in outbound])
        flying = [n for n, _ in outbound]
        model = CostModel.from_scenario(leg_scenario(scenario, flying, pts[:, 0], pts[:, -1], "outbound"))
        for (n, _), piece in zip(outbound, team_pieces(0.0, pts, limits, "outbound", model)):
            team[n] = piece
    out: list[tuple[Piece, ...]] = []
    for n, u in enumerate(uavs):
        pieces: list[Piece] = []
        for i, p in enumerate(u["pieces"]):
            pts = np.asarray(p["points"], dtype=float).reshape(-1, 3)
            t0 = float(p["t0"])
            if i == 0 and n in team:
                pieces.append(team[n])
            elif p["kind"] == "capture":
                pieces.append(capture_piece(t0, _segment_from(p["segment"], pts), limits, int(p["task"])))
            elif p["kind"] == "hover":
                pieces.append(hover_piece(t0, float(p["t1"]), pts[0], label=p["label"]))
            else:
                pieces.append(path_piece(p["kind"], t0, pts, limits, label=p["label"]))
        out.append(tuple(pieces))
    return scenario, Timeline(tuple(out), tuple(u["name"] for u in uavs))
