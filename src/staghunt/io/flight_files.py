"""The files of a simulated flight (``staghunt fly``): ``flight.csv``, ``replans.json``,
``flight.json`` (the verdict and the metrics), and the plain data the replay page and figures
are drawn from.

Every file is written atomically (complete or absent). ``flight.csv`` has one row per UAV and
logged instant: ``t,uav,x,y,z,vx,vy,vz,ref_x,ref_y,ref_z,error`` (site frame, m, m/s; ``uav``
from 1; ``error`` = |position - reference|).
"""

from __future__ import annotations

import io
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from staghunt.io.atomic import write_text_atomic
from staghunt.io.result_json import encode_number, write_json_atomic

FLIGHT_FORMAT = "staghunt-flight/2"


def _num(v: float) -> float | str:
    return encode_number(float(v))


def log_indices(times: np.ndarray, rate: float) -> np.ndarray:
    """Indices of the simulation steps logged at ``rate`` per second (the last one included)."""
    if len(times) < 2:
        return np.arange(len(times))
    step = max(1, round(1.0 / (rate * float(times[1] - times[0]))))
    idx = np.arange(0, len(times), step)
    return idx if idx[-1] == len(times) - 1 else np.append(idx, len(times) - 1)


def flight_csv(result: Any) -> str:
    """``flight.csv`` text of a :class:`~staghunt.flight.FlightResult`."""
    idx = log_indices(result.times, result.config.log_rate)
    t = result.times[idx]
    out = io.StringIO()
    out.write("t,uav,x,y,z,vx,vy,vz,ref_x,ref_y,ref_z,error\n")
    N = result.actual.shape[0]
    err = np.linalg.norm(result.actual - result.reference, axis=-1)
    for k, i in enumerate(idx):
        for n in range(N):
            x, v, r = result.actual[n, i], result.velocity[n, i], result.reference[n, i]
            out.write(f"{t[k]:.2f},{n + 1},{x[0]:.4f},{x[1]:.4f},{x[2]:.4f},{v[0]:.4f},{v[1]:.4f},"
                      f"{v[2]:.4f},{r[0]:.4f},{r[1]:.4f},{r[2]:.4f},{err[n, i]:.4f}\n")
    return out.getvalue()


def latency_summary(records: Any) -> dict[str, Any]:
    """p50, p95 and max of the measured re-plan latencies (s), the overruns of the deadline, the
    plans dropped for being late, and the share certified of the plans sent."""
    lat = np.array([r.latency_s for r in records])
    if lat.size == 0:
        return {"replans": 0}
    solved = [r for r in records if r.solved]
    return {
        "replans": int(lat.size),
        "latency_p50_s": float(np.percentile(lat, 50)),
        "latency_p95_s": float(np.percentile(lat, 95)),
        "latency_max_s": float(lat.max()),
        "over_deadline": int(sum(r.overran for r in records)),
        "late": int(sum(r.late for r in records)),
        "sent": int(sum(r.version > 0 for r in records)),
        "committed": int(sum(r.committed for r in records)),
        "certified": int(sum(r.certified for r in solved)),
        "solved": len(solved),
    }


def flight_summary(result: Any) -> dict[str, Any]:
    """``flight.json``: status, the verdict (every breach: which margin, which UAV, where and
    when), metrics per UAV and for the team, settings (the latency used), the link, the
    changing world."""
    from dataclasses import asdict

    from staghunt.scenario.dump import scenario_to_dict

    names = result.uav_names
    v = result.verdict
    per_uav = []
    for n, name in enumerate(names):
        per_uav.append({
            "name": name,
            "min_separation_m": _num(v.min_separation[n]),
            "separation_limit_m": _num(result.separation_limit[n]),
            "min_clearance_m": _num(v.min_clearance[n]),
            "min_ground_clearance_m": _num(v.min_ground[n]),
            "min_headroom_m": _num(v.min_headroom[n]),
            "tracking_rms_m": _num(result.tracking_rms[n]),
            "tracking_max_m": _num(result.tracking_max[n]),
            "arrival_s": None if math.isnan(result.arrival[n]) else _num(result.arrival[n]),
        })
    extra = result.extra_time
    config = asdict(result.config)
    return {
        "format": FLIGHT_FORMAT,
        "status": result.status.value,
        "exit_code": result.status.exit_code,
        "message": result.message,
        "seed": result.seed,
        "latency": "measured" if result.config.measured else {"fixed_s": result.config.latency},
        "verdict": {
            "contact": v.contact,
            "margins_m": asdict(v.margins),
            "breaches": [b.to_dict(names) for b in v.breaches],
        },
        "team": {
            "min_separation_m": _num(v.min_separation.min()),
            "min_clearance_m": _num(v.min_clearance.min()),
            "required_clearance_m": result.required_clearance,
            "min_ground_clearance_m": _num(v.min_ground.min()),
            "min_headroom_m": _num(v.min_headroom.min()),
            "tracking_rms_m": _num(math.sqrt(float(np.mean(result.tracking_rms ** 2)))),
            "tracking_max_m": _num(result.tracking_max.max()),
            "baseline_arrival_s": _num(result.baseline_arrival),
            "extra_time_s": None if not math.isfinite(extra) else _num(extra),
            "stops": result.stops,
            "holds": result.holds,
            **latency_summary(result.replans),
        },
        "link": result.link,
        "uavs": per_uav,
        "plan_windows": [{"obstacle": w[0], "from": w[1], "to": w[2]} for w in result.plan_windows],
        "plan_margins": result.plan_margins,
        "config": {k: (_num(x) if isinstance(x, float) else x) for k, x in config.items()},
        "engine": result.details.get("engine"),
        "compile_time_s": result.details.get("compile_time_s"),
        "wall_time_s": result.wall_time_s,
        "scenario": scenario_to_dict(result.scenario),
    }


def flight_dict(result: Any, max_samples: int = 1500) -> dict[str, Any]:
    """The plain data of the replay page, the animation and the figures (site frame, m, s;
    at most ``max_samples`` instants)."""
    from staghunt.world import Cylinder

    sc = result.scenario
    idx = log_indices(result.times, result.config.log_rate)
    if len(idx) > max_samples:
        idx = idx[np.linspace(0, len(idx) - 1, max_samples).round().astype(int)]
    t = result.times[idx]
    b = sc.world.bounds
    ground = sc.world.terrain
    zmax = float(np.max(result.actual[..., 2])) + 5.0
    dyn = result.dynamics
    moving: list[dict[str, Any]] = []
    gone = {e.name: e.time for e in dyn.events if e.kind == "disappear"}
    for m in dyn.moving:
        moving.append({"name": m.name, "kind": "cylinder", "radius": m.radius,
                       "xy": np.round(m.xy(t), 2).tolist(),
                       "visible": (t < gone.get(m.name, np.inf)).tolist()})
    for j in dyn.jibs:
        moving.append({"name": j.name, "kind": "polygon", "base": j.base, "top": j.top,
                       "polygons": np.round(j.polygons(t), 2).tolist(),
                       "visible": (t < gone.get(j.name, np.inf)).tolist()})
    for e in dyn.events:
        if e.kind != "appear" or e.shape is None:
            continue
        visible = ((t >= e.time) & (t < gone.get(e.name, np.inf))).tolist()
        if isinstance(e.shape, Cylinder):
            xy = [[e.shape.x, e.shape.y]] * len(t)
            moving.append({"name": e.name, "kind": "cylinder", "radius": e.shape.radius,
                           "xy": xy, "visible": visible})
        else:
            poly = [list(v) for v in e.shape.polygon]
            moving.append({"name": e.name, "kind": "polygon", "base": max(e.shape.base, -1e9),
                           "top": min(e.shape.top, 1e9), "polygons": [poly] * len(t),
                           "visible": visible})
    terrain = None
    if not ground.is_flat:
        xs = np.linspace(b.xmin, b.xmax, 25)
        ys = np.linspace(b.ymin, b.ymax, 25)
        X, Y = np.meshgrid(xs, ys)
        terrain = {"x": xs.round(2).tolist(), "y": ys.round(2).tolist(),
                   "z": np.round(ground.height(X, Y), 2).tolist()}
    return {
        "title": f"{sc.name} · seed {result.seed} · {result.status.value}",
        "site": {"xmin": b.xmin, "xmax": b.xmax, "ymin": b.ymin, "ymax": b.ymax,
                 "zmin": float(min(0.0, np.min(result.actual[..., 2]) - 1.0)), "zmax": zmax},
        "times": np.round(t, 3).tolist(),
        "uavs": [{"name": u.name, "radius": u.radius,
                  "actual": np.round(result.actual[n, idx], 2).tolist(),
                  "reference": np.round(result.reference[n, idx], 2).tolist()}
                 for n, u in enumerate(sc.team)],
        "cylinders": [[c.x, c.y, c.radius] for c in sc.world.cylinders],
        "prisms": [{"polygon": [list(v) for v in p.polygon], "base": max(p.base, -1e9),
                    "top": min(p.top, 1e9), "nofly": p.is_nofly} for p in sc.world.prisms],
        "moving": moving,
        "replans": [{"time": r.time, "trigger": r.trigger, "verdict": r.status.value if not r.solved
                     else ("epsilon-equilibrium" if r.certified else "not certified")}
                    for r in result.replans if r.version > 0],
        "terrain": terrain,
        "separation_limit": float(result.separation_limit.max()),
    }


def write_flight(result: Any, out_dir: str | os.PathLike[str]) -> list[Path]:
    """Write ``flight.csv``, ``replans.json`` and ``flight.json`` into ``out_dir`` (which must
    exist); returns the paths written. The figures, ``flight.gif`` and ``replay.html``:
    :func:`staghunt.plots.flight_files.write_flight_figures`."""
    out = Path(out_dir)
    files = [
        write_text_atomic(flight_csv(result), out / "flight.csv"),
        write_json_atomic({"format": FLIGHT_FORMAT, "replans": [r.to_dict() for r in result.replans]},
                          out / "replans.json"),
        write_json_atomic(flight_summary(result), out / "flight.json"),
    ]
    return files
