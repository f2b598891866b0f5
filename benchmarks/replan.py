"""Closed-loop re-planning benchmark (run on demand, not part of the test suite).

    python benchmarks/replan.py --jobs 2                      # 100 scenario-2 + 20 site_wedge episodes, link 100 ms / 30 ms / 1 %
    python benchmarks/replan.py --jobs 2 --link-delay 0.3 --link-loss 0.05 --tag lossy   # the same episodes, a worse link
    python benchmarks/replan.py --episodes 10 --wedge-episodes 2 --tag smoke             # a smoke run
    python benchmarks/replan.py --summarise results/replan_lossy.json                    # the table of a saved run
    python benchmarks/replan.py --summarise results/replan_before.json --tag before_judged   # ... judged again, saved
    python benchmarks/replan.py --solve-only --episodes 30 --wedge-episodes 10           # first re-plans alone, both cores

The episodes (benchmarks/replan_episodes.py: a site vehicle or the crane's jib, then a pop-up
2-5 s ahead of a random UAV) are built once and saved (``results/replan_episodes.json``), and
every later run flies the same ones (``--rebuild`` builds them again), so that runs of
different code or settings compare episode by episode. A pop-up appears at its time or, sooner,
once any UAV's reference would breach the required clearance to it within the episode's lead
(the trigger's ``lead``): a flight re-timed by the receding horizon and the link meets it as
far ahead of a breach as drawn ahead of contact, whichever UAV comes first. ``--popups
placed`` flies the saved triggers instead (the UAV it was placed for, as close as the plan had
it then: the runs from 2026-11-27 17:00 to 21:00 UTC, which met some pop-ups 0.5 s ahead of
another UAV), ``--popups timed`` none (the runs before, which met some on the UAV itself).

Every episode is a :func:`staghunt.fly` run with the default settings: re-plans take the wall
time they really take while the simulated world goes on (``--latency measured``; a number
fixes it), within the deadline (0.2 s for 3 UAVs, 1 s for 8), the receding horizon at 1 Hz,
the radio link of ``--link-*`` (delay, jitter, loss) between the ground station and the UAVs.
``--jobs 2`` flies two episodes side by side, one per core: each re-plan then has one core,
and its measured latency, and so the flight, depends on how busy the machine is (the load
average is recorded). Reported per set (judged by the one safety judge on the simulated
vehicles, against the true world, every 10 ms): endings, contacts (and of them those where the
pop-up appeared within a UAV's braking reach on the flown timing: each row gives the flown lead,
``popup_flown_lead_s``, beside the built one, ``popup_lead_s``), breaches of each required
margin, episodes that arrived with no stop to hover and no UAV holding on its own, extra time
against the plan without events, the event re-plans' latency (the receding horizon's apart),
overruns of the deadline, plans dropped for being late, the share of plans sent that are
certified 1 %-equilibria, and how fast the simulation ran. Writes ``results/replan[_TAG].json``
and ``.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import provenance

import replan_episodes

HERE = Path(__file__).resolve().parent
EPISODES = HERE / "results" / "replan_episodes.json"


def run_episode(job: dict[str, Any]) -> dict[str, Any]:
    """One flight in a worker process; returns its summary."""
    import warnings

    warnings.simplefilter("ignore")
    from staghunt.costs import to_absolute
    from staghunt.flight import Cause, FlyConfig, fly
    from staghunt.flight.onboard import REFLEX_PERIOD
    from staghunt.world.dynamic import Link

    e = job["episode"]
    wp, dyn = replan_episodes.from_plain(e, job.get("popups", "lead"))
    config = FlyConfig(wind=job.get("wind", 0.0), link=Link(*job["link"]), **job.get("config", {}))
    t0 = time.perf_counter()
    try:
        r = fly(e["kind"], waypoints=wp, events=dyn, seed=e["episode"], config=config, threads=job["threads"])
    except ValueError as exc:
        return {**_meta(job), "error": str(exc)}
    wall = time.perf_counter() - t0
    v = r.verdict
    popup = None
    if e["events"]:  # the pop-up as it happened: at its time, or sooner when its trigger held
        popup = {**e["events"][0], "time": next(x.time for x in r.dynamics.events if x.name == e["events"][0]["name"])}
    return {
        **_meta(job),
        "status": r.status.value, "message": r.message,
        "contact": v.contact,
        "breaches": sorted({b.kind.value for b in v.breaches}),
        "min_clearance_m": float(v.min_clearance.min()),
        "separation_margin_m": float(np.min(v.min_separation - r.separation_limit)),
        "min_ground_m": float(v.min_ground.min()), "min_headroom_m": float(v.min_headroom.min()),
        "stops": r.stops, "holds": r.holds,
        "replans": [{"cause": x.cause.value, "status": x.status.value, "latency_s": x.latency_s,
                     "deadline_s": x.deadline_s, "late": x.late, "overran": x.overran,
                     # certified when sent; a later certificate (of a plan sent without one) apart
                     "certified": x.certified and x.certified_after_s == 0,
                     "certified_later": x.certified and x.certified_after_s > 0,
                     "solved": x.solved, "committed": x.committed, "sent": x.version > 0,
                     "receding": x.cause is Cause.RECEDING, "max_gap": max(x.nash_gaps, default=None),
                     "trigger": x.trigger, "time": x.time, "phases": {k: round(v, 4) for k, v in x.phases},
                     "problems": list(x.problems[:2]) if x.stopped else [],
                     "later": [[w[0], round(w[1], 2)] for w in x.later]}
                    for x in r.replans],
        "backward_m": backward(r.reference, to_absolute(r.scenario.world.terrain, r.scenario.goals()[:, None])[:, 0]),
        "tracking_rms_m": float(np.sqrt(np.mean(r.tracking_rms ** 2))),
        "tracking_max_m": float(r.tracking_max.max()),
        "extra_time_s": None if not math.isfinite(r.extra_time) else float(r.extra_time),
        "flight_s": float(r.times[-1]), "wall_s": wall, "link": r.link,
        "popup_uav": e["popup_uav"], "popup_lead_s": e["popup_lead_s"],
        "popup_appeared_s": popup["time"] if popup else None,
        "popup_triggered": bool(popup and popup["time"] < e["events"][0]["time"]),
        **(popup_reach(r.times, r.actual, r.velocity, popup, [u.radius for u in r.scenario.team],
                       r.scenario.vehicle.max_acceleration,
                       1.0 / r.dynamics.sensing.rate + REFLEX_PERIOD + config.reflex_latency) if popup else {}),
        "popup_swerve_possible": popup_swerve(
            r.times, r.actual, r.velocity, popup, [u.radius for u in r.scenario.team],
            float(r.scenario.costs.min_clearance), r.scenario.vehicle.max_acceleration,
            1.0 / r.dynamics.sensing.rate + config.deadline_for(r.scenario.n_uavs) + 2 * config.link.delay)
        if popup else None,
    }


BACKWARD_M = 2.0
"""An episode flew backwards when a UAV's reference went this far (m) away from its goal after
having been nearer (:func:`backward`)."""


def backward(reference: np.ndarray, goals: np.ndarray) -> float:
    """The most any UAV's reference ``(N, T, 3)`` went away from its goal ``(N, 3)`` after having
    been nearer (m): a timing that overshoots a lead-in and comes back shows here; a detour round
    an obstacle ahead barely moves away from a goal beyond it."""
    d = np.linalg.norm(reference - goals[:, None], axis=-1)  # (N, T)
    return float((d - np.minimum.accumulate(d, axis=1)).max())


def _closing(times: np.ndarray, actual: np.ndarray, velocity: np.ndarray, popup: dict[str, Any],
             radii: list[float]) -> list[tuple[int, float, np.ndarray, np.ndarray]]:
    """At the pop-up's appearance, every UAV closing in on it (``times`` ``(T,)``, ``actual``,
    ``velocity`` ``(N, T, 3)``; ``popup``: the episode's event): ``(n, lead, p, v)`` with
    ``lead`` the seconds until its body would touch it flying on (the first ``s >= 0`` with
    ``|p + s v| = radius + body``; 0 if it already does), ``p`` its horizontal position from
    the pop-up's centre and ``v`` its horizontal velocity then."""
    i = min(int(np.searchsorted(times, popup["time"] - 1e-9)), len(times) - 1)
    c = np.array([popup["x"], popup["y"]])
    out = []
    for n, r in enumerate(radii):
        p, v = actual[n, i, :2] - c, velocity[n, i, :2]
        reach = popup["radius"] + r
        if np.hypot(*p) < reach:
            out.append((n, 0.0, p, v))
            continue
        a, b, q = float(v @ v), float(p @ v), float(p @ p) - reach ** 2
        disc = b * b - a * q
        if a >= 1e-12 and b < 0 and disc >= 0:
            out.append((n, (-b - math.sqrt(disc)) / a, p, v))
    return out


def popup_reach(times: np.ndarray, actual: np.ndarray, velocity: np.ndarray, popup: dict[str, Any],
                radii: list[float], max_acceleration: float, notice_s: float) -> dict[str, Any]:
    """The pop-up as the flight met it (its ``popup_lead_s`` is on the timing of the plan the
    episode was built on; the receding horizon and the link re-time the flight): at its
    appearance, for the UAV closest to contact along its velocity then (:func:`_closing`), the
    seconds until its body would touch the pop-up flying on (``popup_flown_lead_s``, 0 if it
    already does, ``None`` if no UAV closes in), that UAV (0-based), and whether the pop-up
    appeared within its braking reach (``popup_within_reach``): the distance to contact at most
    what it flies until it notices (``notice_s``: a sensor period, a reflex check and the reflex
    latency) plus a braking stop at three times ``max_acceleration`` (the reflex's)."""
    from staghunt.flight.onboard import REFLEX_FACTOR
    from staghunt.trajectory.quintic import BRAKE_RAMP

    i = min(int(np.searchsorted(times, popup["time"] - 1e-9)), len(times) - 1)
    best: tuple[float, int, bool] | None = None
    for n, lead, _, v in _closing(times, actual, velocity, popup, radii):
        dist = lead * float(np.linalg.norm(v))
        speed = float(np.linalg.norm(velocity[n, i]))
        brake = speed ** 2 / (2 * REFLEX_FACTOR * max_acceleration * (1 - BRAKE_RAMP))
        if best is None or lead < best[0]:
            best = (lead, n, dist <= speed * notice_s + brake)
    if best is None:
        return {"popup_flown_lead_s": None, "popup_flown_uav": None, "popup_within_reach": False}
    return {"popup_flown_lead_s": best[0], "popup_flown_uav": best[1], "popup_within_reach": best[2]}


def popup_swerve(times: np.ndarray, actual: np.ndarray, velocity: np.ndarray, popup: dict[str, Any],
                 radii: list[float], clearance: float, max_acceleration: float, react_s: float) -> bool | None:
    """Whether every UAV closing in on the pop-up when it appeared (:func:`_closing`) could have
    swerved round it at ``max_acceleration``, flying on at its speed: the sideways offset its
    centre needs (the pop-up's radius, its body and the required ``clearance``, less the
    centre's distance from its line of flight) at most what it moves sideways at that
    acceleration in the time left once the planner has answered (its lead less ``react_s``: a
    sensor period, the deadline and the link's delay both ways), ``a T^2 / 2``. ``False``: only
    slowing down or stopping avoids it, whatever the planner (a lower bound: the way back and
    the tracking allowance are left out); ``None``: no UAV closes in."""
    verdicts = []
    for n, lead, p, v in _closing(times, actual, velocity, popup, radii):
        if lead == 0.0:  # already touching it
            verdicts.append(False)
            continue
        off = abs(float(p[0] * v[1] - p[1] * v[0])) / float(np.linalg.norm(v))  # the centre's distance from the line
        need = popup["radius"] + radii[n] + clearance - off
        left = max(0.0, lead - react_s)
        verdicts.append(need <= 0.5 * max_acceleration * left ** 2)
    return all(verdicts) if verdicts else None


def _meta(job: dict[str, Any]) -> dict[str, Any]:
    e = job["episode"]
    kind = e["kind"] + ("-wind" if job.get("wind", 0.0) else "")
    return {"kind": kind, "episode": e["episode"], "wind": job.get("wind", 0.0)}


def _judged(row: dict[str, Any]) -> dict[str, Any]:
    """A row judged with the required margins: rows of this benchmark as they are; rows of the
    code before the one judge (2026-11-26: a status of arrived, stopped or unsafe, the least
    clearance, separation margin, height and highest z) judged again from those figures."""
    if "breaches" in row or "error" in row:
        return row
    import staghunt

    sc = staghunt.load_scenario(row["kind"].removesuffix("-wind"))
    r = max(u.radius for u in sc.team)
    c, d_s = sc.costs.min_clearance, sc.costs.safe_distance
    kinds = []
    if row["min_clearance_m"] < c:
        kinds.append("clearance")
    if row["separation_margin_m"] <= 0:
        kinds.append("separation")
    if row.get("min_height_m", math.inf) - r < c:
        kinds.append("ground")
    if row.get("max_z_m", -math.inf) > row.get("ceiling_m", math.inf):
        kinds.append("ceiling")
    contact = row["min_clearance_m"] < 0 or row["separation_margin_m"] + d_s < 0
    status = "unsafe" if contact else ("breach" if kinds else row["status"])
    return {**row, "status": status, "contact": contact, "breaches": kinds, "holds": 0,
            "replans": [{**x, "receding": False, "sent": True, "overran": None, "late": None,
                         "solved": "replanned" in x["status"],
                         "cause": "sensed" if x["trigger"].startswith("sensed") else "other"} for x in row["replans"]]}


def _replaced(replans: list[dict[str, Any]]) -> list[float | None]:
    """For each event plan of one episode sent uncertified: the seconds (flight time) until a
    certified receding-horizon plan replaced it (``None``: the next plan sent was not one, or
    none was)."""
    sent = [x for x in replans if x["sent"]]
    out: list[float | None] = []
    for x, nxt in zip(sent, sent[1:] + [None]):
        if not x["receding"] and x["solved"] and not x["certified"]:
            out.append(nxt["time"] - x["time"] if nxt is not None and nxt["receding"] and nxt["certified"] else None)
    return out


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    ok = [_judged(r) for r in rows if "error" not in r]
    events = [x for r in ok for x in r["replans"] if not x["receding"]]
    timed = [x for x in events if x.get("deadline_s") is not None]
    least = min((x["deadline_s"] for x in timed), default=0.0)
    lat = np.array([x["latency_s"] for x in events]) * 1000
    solved = [x for r in ok for x in r["replans"] if x["solved"] and x["sent"]]
    receding = [x for r in ok for x in r["replans"] if x["receding"]]
    extra = [r["extra_time_s"] for r in ok if r["extra_time_s"] is not None and r["status"] != "stopped"]
    clean = [r for r in ok if r["status"] == "arrived" and r["stops"] == 0 and r["holds"] == 0]
    speed = [r["flight_s"] / r["wall_s"] for r in ok if r.get("wall_s")]
    count = (lambda key: sum(bool(x[key]) for x in events)) if events and events[0].get("late") is not None else None
    replaced = [a for r in ok for a in _replaced(r["replans"])]
    worst = max((x for r in ok for x in r["replans"] if x.get("phases")), key=lambda x: x["latency_s"] / x["deadline_s"],
                default=None)
    after = [a for a in replaced if a is not None]
    return {
        "episodes": len(rows), "refused": len(rows) - len(ok),
        **{s: sum(r["status"] == s for r in ok) for s in ("arrived", "stopped", "breach", "unsafe")},
        "contacts": sum(r["contact"] for r in ok),
        "contacts_popup_within_reach": sum(r["contact"] and bool(r.get("popup_within_reach")) for r in ok),
        "popups_within_reach": sum(bool(r.get("popup_within_reach")) for r in ok),
        "popups_triggered": sum(bool(r.get("popup_triggered")) for r in ok),
        "popup_flown_lead_s_median": _median([r.get("popup_flown_lead_s") for r in ok]),
        **_lead_drift(ok),
        **{f"{k}_breaches": sum(k in r["breaches"] for r in ok) for k in ("clearance", "separation", "ground", "ceiling")},
        "arrived_without_stop": len(clean), "episodes_with_stop": sum(r["stops"] > 0 for r in ok),
        # episodes where a UAV flew backwards (BACKWARD_M or more away from its goal after being nearer)
        "episodes_backward": sum(r.get("backward_m", 0.0) >= BACKWARD_M for r in ok) if ok and "backward_m" in ok[0] else None,
        "episodes_with_hold": sum(r["holds"] > 0 for r in ok),
        "least_clearance_m": min((r["min_clearance_m"] for r in ok), default=None),
        "median_least_clearance_m": float(np.median([r["min_clearance_m"] for r in ok])) if ok else None,
        "extra_time_s_median": float(np.median(extra)) if extra else None,
        "extra_time_s_range": [float(min(extra)), float(max(extra))] if extra else None,
        "event_replans": len(events),
        **_percentiles("latency", lat),
        "latency_max_ms": float(lat.max()) if lat.size else None,
        **_percentiles("sensed_latency", np.array([x["latency_s"] for x in events if x["cause"] == "sensed"]) * 1000),
        "over_deadline": count("overran") if count else None, "late": count("late") if count else None,
        "solved": len(solved), "certified": sum(x["certified"] for x in solved),
        "event_solved": sum(not x["receding"] for x in solved),
        "event_certified": sum(x["certified"] for x in solved if not x["receding"]),
        "certified_later": sum(x.get("certified_later", False) for x in solved),
        "sensed_solved": sum(x["cause"] == "sensed" for x in solved),
        "sensed_certified": sum(x["certified"] for x in solved if x["cause"] == "sensed"),
        "episodes_with_emergency_stop": sum(any(x["status"] == "emergency stop" for x in r["replans"]) for r in ok),
        "first_stop_causes": stop_causes(ok),
        "popups_no_swerve": sum(r.get("popup_swerve_possible") is False for r in ok),
        "arrived_without_stop_swerve_possible": sum(r.get("popup_swerve_possible") is not False for r in clean),
        "episodes_swerve_possible": sum(r.get("popup_swerve_possible") is not False for r in ok),
        # event plans sent with a conflict with a known motion left beyond the conflict horizon
        "later_conflicts": sum(bool(x.get("later")) for x in events),
        "episodes_later_conflicts": sum(any(x.get("later") for x in r["replans"]) for r in ok),
        # event re-plans that slowed the team on its paths to let a known motion pass first
        "yields": sum(x["status"] == "yield" for x in events),
        "episodes_yield": sum(any(x["status"] == "yield" for x in r["replans"]) for r in ok),
        "deferred_replans": sum(x["status"] == "deferred" for x in events),
        "episodes_deferred": sum(any(x["status"] == "deferred" for x in r["replans"]) for r in ok),
        "episodes_deferred_without_stop": sum(any(x["status"] == "deferred" for x in r["replans"]) and r["stops"] == 0
                                              for r in ok),
        # the re-plans of a flying team (the flight's deadline; a hovering team's has the stop budget factor)
        **_percentiles("flying_latency", np.array([x["latency_s"] for x in timed if x["deadline_s"] <= least + 1e-9])
                       * 1000),
        "receding": len(receding), "receding_sent": sum(x["sent"] for x in receding),
        "event_uncertified": len(replaced), "event_replaced": len(after),
        "event_replaced_after_s_median": float(np.median(after)) if after else None,
        "sim_speed_median": float(np.median(speed)) if speed else None,
        # the re-plan furthest over its deadline, and where its wall time went
        "worst_overrun": None if worst is None else {k: worst[k] for k in ("time", "cause", "trigger", "status",
                                                                             "latency_s", "deadline_s", "phases")},
    }


INSIDE_LEAD_S = 0.5
"""A pop-up counts as met inside its drawn lead when the flight met it this much sooner."""


def _lead_drift(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """How far ahead the flights met their pop-ups against how far ahead they were drawn, over
    the episodes where a UAV closed in: the median drawn lead, the median of the flown lead
    less the drawn one, and how many pop-ups were met :data:`INSIDE_LEAD_S` or more inside it."""
    pairs = [(r["popup_lead_s"], r["popup_flown_lead_s"]) for r in rows
             if r.get("popup_lead_s") is not None and r.get("popup_flown_lead_s") is not None]
    drift = [flown - drawn for drawn, flown in pairs]
    return {"popup_lead_s_median": _median([drawn for drawn, _ in pairs]),
            "popup_lead_drift_s_median": _median(drift),
            "popups_met_inside_lead": sum(d <= -INSIDE_LEAD_S for d in drift)}


def stop_cause(problems: list[str]) -> str:
    """Why a re-plan stopped the team, from its first problem (rows of code before 2026-11-27 19:40
    UTC record none): the game found no feasible plan from the moving state; it did, but the
    timed plan broke a margin (``contact:`` or ``breach:``, the one judge's words) at the pop-up
    (the episodes' pop-ups are all named ``pop-up...``, :mod:`replan_episodes`) or elsewhere (a
    known motion's conflict found after the last try, a team-mate, a static obstacle); no timing
    met the limits; or another reason."""
    if not problems:
        return "not recorded"
    first = problems[0]
    if first.startswith("no feasible plan"):
        return "no feasible plan"
    if first.startswith(("contact:", "breach:")):
        return "timed plan broke a margin at the pop-up" if "clearance to pop-up" in first else \
            "timed plan broke a margin elsewhere"
    return "timing over the limits" if first.startswith("no timing") else "other"


def stop_causes(rows: list[dict[str, Any]]) -> dict[str, int]:
    """Per :func:`stop_cause`, the episodes whose first stop (a re-plan whose status brings the
    team to rest, ``ReplanStatus.stopped``) had that cause."""
    from staghunt.flight import ReplanStatus

    stops = {s.value for s in ReplanStatus if s.stopped}
    firsts = [next((x for x in r["replans"] if x["status"] in stops), None) for r in rows]
    causes = [stop_cause(x.get("problems", [])) for x in firsts if x is not None]
    return {c: causes.count(c) for c in sorted(set(causes))}


def _median(values: list[float | None]) -> float | None:
    known = [v for v in values if v is not None]
    return float(np.median(known)) if known else None


def _percentiles(name: str, ms: np.ndarray) -> dict[str, float | None]:
    """``{name_p50_ms, name_p95_ms}`` of the latencies ``ms`` ``(R,)`` (``None`` if there are none)."""
    return {f"{name}_p{q}_ms": float(np.percentile(ms, q)) if ms.size else None for q in (50, 95)}


def table(summary: dict[str, dict[str, Any]], title: str = "set") -> str:
    """The markdown table of :func:`summarise` per set."""
    lines = [f"| {title} | arrived / stopped / breach / unsafe | contacts | breaches: clearance / separation / ground / "
             "ceiling | arrived without stop or hold | stops / holds (episodes) | extra time median [range] (s) | "
             "event re-plans | latency p50 / p95 / max (ms) | sensed obstacle: p50 / p95 (ms) | over deadline / late | "
             "plans certified | receding: sent / made | simulation (x real time) |", "|" + "---|" * 15]
    for k, s in summary.items():
        ex, n = s["extra_time_s_range"], s["episodes"] - s["refused"]
        na = "-"
        lines.append(
            f"| {k}: {s['episodes']}" + (f" ({s['refused']} refused)" if s["refused"] else "") + " | "
            f"{s['arrived']} / {s['stopped']} / {s['breach']} / {s['unsafe']} | {s['contacts']} | "
            f"{s['clearance_breaches']} / {s['separation_breaches']} / {s['ground_breaches']} / {s['ceiling_breaches']} | "
            f"{s['arrived_without_stop']}/{n} ({100 * s['arrived_without_stop'] / max(n, 1):.0f} %)"
            + (f"; of those a swerve could avoid, {s['arrived_without_stop_swerve_possible']}/{s['episodes_swerve_possible']}"
               if s.get("episodes_swerve_possible") is not None else "") + " | "
            f"{s['episodes_with_stop']} / {s['episodes_with_hold']} | "
            + (f"{s['extra_time_s_median']:.1f} [{ex[0]:.1f}, {ex[1]:.1f}]" if ex else na) + " | "
            f"{s['event_replans']} | "
            + (f"{s['latency_p50_ms']:.0f} / {s['latency_p95_ms']:.0f} / {s['latency_max_ms']:.0f}" if s["event_replans"] else na)
            + " | " + (f"{s['sensed_latency_p50_ms']:.0f} / {s['sensed_latency_p95_ms']:.0f}"
                       if s.get("sensed_latency_p50_ms") is not None else na)
            + " | " + (f"{s['over_deadline']} / {s['late']}" if s["over_deadline"] is not None else na) + " | "
            f"{s['certified']}/{s['solved']}"
            + (f"; uncertified event plans replaced by a certified one {s['event_replaced']}/{s['event_uncertified']}"
               if s.get("event_uncertified") else "") + " | "
            + (f"{s['receding_sent']} / {s['receding']}" if s["receding"] else na) + " | "
            + (f"{s['sim_speed_median']:.2f}" if s["sim_speed_median"] else na) + " |")
    return "\n".join(lines) + "\n"


def solve_only(e: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """The first re-plan of an episode on its plan alone (no vehicle simulated), with the
    engine's adaptive threads and its deadline: the solve latency on the whole machine,
    certificate included."""
    from dataclasses import replace

    import staghunt
    from staghunt.engine import get_engine
    from staghunt.flight import FlyConfig, aside
    from staghunt.flight.offline import plan_around
    from staghunt.flight.replan import PRELOAD, Replanner, Start
    from staghunt.api import check_plan
    from staghunt.solvers.improve import Deadline

    engine = get_engine("auto")
    aside.rest_worker(wait=PRELOAD)  # the plans from rest's process, started once (as a flight does)
    wp, dyn = replan_episodes.from_plain(e)
    sc = replace(staghunt.load_scenario(e["kind"]), dynamics=dyn)
    config = FlyConfig(**overrides)
    _, ref, _, _ = plan_around(check_plan(sc, "game", 1, sc.solver, engine), dyn, wp, config)
    popup = dyn.events[0]
    planner = Replanner(sc, dyn, config, engine, np.random.default_rng(e["episode"]))
    planner.known.sensed[popup.name] = popup.shape
    t = math.ceil(popup.time * 10.0) / 10.0  # the first planner tick after it appears
    D = config.deadline_for(sc.n_uavs)
    s = ref.state(np.array([t + D + dyn.link.worst_delay]))[:, :, 0]
    start = Start(t + D + dyn.link.worst_delay, ref, s[0], s[1], s[2])
    t0 = time.perf_counter()
    out = planner.solve(start, lambda: t + (time.perf_counter() - t0) + dyn.link.worst_delay, 1, [],
                        Deadline.after(D) if config.measured else Deadline())
    return {"kind": e["kind"], "episode": e["episode"], "status": out.status.value,
            "latency_s": time.perf_counter() - t0, "deadline_s": D, "certified": out.certified,
            "max_gap": max(out.nash_gaps, default=None), "evaluations": out.evaluations}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=100, help="scenario-2 episodes (default 100)")
    ap.add_argument("--wedge-episodes", type=int, default=20, help="site_wedge episodes (default 20)")
    ap.add_argument("--wind-episodes", type=int, default=0, help="of the scenario-2 episodes, fly these again in 5 m/s wind")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--link-delay", type=float, default=0.1)
    ap.add_argument("--link-jitter", type=float, default=0.03)
    ap.add_argument("--link-loss", type=float, default=0.01)
    ap.add_argument("--latency", default="measured", help="'measured' (default) or a fixed number of seconds")
    ap.add_argument("--tag", default="", help="results/replan_TAG.json and .md")
    ap.add_argument("--rebuild", action="store_true", help="build the episodes again")
    ap.add_argument("--episodes-file", type=Path, default=EPISODES, help="the saved episodes (default "
                    "results/replan_episodes.json; built there if missing)")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--summarise", type=Path, metavar="JSON", help="only print the table of a saved run (judged by "
                    "this script's rules; with --tag, also write its summary to results/replan_TAG.json)")
    ap.add_argument("--solve-only", action="store_true",
                    help="only each episode's first re-plan, on the plan, one at a time with the engine's adaptive "
                    "threads (the latency on the whole machine); writes replan_solve.json")
    ap.add_argument("--popups", choices=replan_episodes.POPUPS, default="lead",
                    help="lead (default): a pop-up appears at its time or once any UAV would breach its clearance "
                    "within its drawn lead; "
                    "placed: the saved trigger, on the UAV it was placed for; timed: at its time only")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a FlyConfig setting for every episode, e.g. --set replan_rate=0 (repeatable)")
    args = ap.parse_args()
    started = provenance.start()
    if args.summarise is not None:
        saved = json.loads(args.summarise.read_text())
        rows = saved["episodes"]
        summary = {k: summarise([r for r in rows if r["kind"] == k]) for k in sorted({r["kind"] for r in rows})}
        print(table(summary))
        if args.tag:  # the saved run judged by this script's rules, with the saved run's date, code and machine
            out = {k: saved[k] for k in ("date", "code", "machine") if k in saved}
            out.update(judged_from=args.summarise.name, summary=summary)
            (args.out / f"replan_{args.tag}.json").write_text(json.dumps(out, indent=1, default=str) + "\n")
        return 0
    overrides = _overrides(args.set)
    if args.latency != "measured":
        overrides["latency"] = float(args.latency)
    counts = {"scenario2": max(args.episodes, args.wind_episodes), "site_wedge": args.wedge_episodes}
    have: list[dict[str, Any]] = []
    plans: dict[str, Any] = {}
    if args.episodes_file.exists() and not args.rebuild:
        added = replan_episodes.add_triggers_to_file(args.episodes_file, started)
        if added:
            print(f"gave {added} saved pop-ups their trigger", file=sys.stderr)
        have, plans = replan_episodes.load(args.episodes_file)
    if any(sum(e["kind"] == k for e in have) < n for k, n in counts.items()):
        print("building the episodes", file=sys.stderr)
        have, plans = replan_episodes.build({k: max(n, sum(e["kind"] == k for e in have)) for k, n in counts.items()})
        replan_episodes.save(args.episodes_file, have, plans, started)
    pick = [e for e in have if (e["kind"] == "scenario2" and e["episode"] < counts["scenario2"])
            or (e["kind"] == "site_wedge" and e["episode"] < args.wedge_episodes)]
    if args.solve_only:
        first = [e for e in pick if e["kind"] != "scenario2" or e["episode"] < args.episodes]
        return _solve_only(first, args.out, overrides, started)
    threads = 1 if args.jobs > 1 else None
    link = (args.link_delay, args.link_jitter, args.link_loss)
    jobs: list[dict[str, Any]] = []
    for e in pick:
        base = {"episode": e, "threads": threads, "config": overrides, "link": link, "popups": args.popups}
        if e["kind"] != "scenario2" or e["episode"] < args.episodes:
            jobs.append(base)
        if e["kind"] == "scenario2" and e["episode"] < args.wind_episodes:
            jobs.append({**base, "wind": 5.0})
    print(f"{len(jobs)} episodes, {args.jobs} at a time", file=sys.stderr)
    t0 = time.perf_counter()
    rows: list[dict[str, Any]] = []
    loads: list[float] = []
    # spawned workers: a forked child of a process that has run OpenMP threads (the plans above)
    # is killed by GNU OpenMP as soon as it starts a parallel loop of its own
    with ProcessPoolExecutor(max_workers=args.jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
        for i, row in enumerate(pool.map(run_episode, jobs)):
            rows.append(row)
            loads.append(os.getloadavg()[0])
            print(f"[{i + 1}/{len(jobs)}] {row['kind']} #{row['episode']}: {row.get('status', row.get('error'))} "
                  f"stops {row.get('stops')} holds {row.get('holds')} extra {row.get('extra_time_s')} "
                  f"clear {row.get('min_clearance_m', float('nan')):.2f} m load {loads[-1]:.1f}", file=sys.stderr)
    wall = time.perf_counter() - t0
    kinds = sorted({r["kind"] for r in rows})
    summary = {k: summarise([r for r in rows if r["kind"] == k]) for k in kinds}
    meta = {"jobs": args.jobs, "threads_per_solve": threads or "adaptive", "wall_s": wall, "link": link,
            "popups": args.popups,
            "latency": args.latency, "settings": overrides, "loadavg_median": float(np.median(loads)) if loads else None,
            "loadavg_range": [min(loads), max(loads)] if loads else None, "cpus": os.cpu_count(), "plans": plans}
    name = "replan" + (f"_{args.tag}" if args.tag else "")
    args.out.mkdir(parents=True, exist_ok=True)
    report = provenance.stamped(started, {"meta": meta, "summary": summary, "episodes": rows})
    (args.out / f"{name}.json").write_text(json.dumps(report, indent=1, default=str) + "\n")
    md = table(summary) + (f"\n{args.jobs} episode(s) at a time, {threads or 'adaptive'} thread(s) per solve, link "
                           f"{link[0] * 1000:.0f} ms / {link[1] * 1000:.0f} ms / {link[2] * 100:.0f} %, latency "
                           f"{args.latency}, {wall / 60:.1f} min, load average median {meta['loadavg_median']:.2f} "
                           f"(range {meta['loadavg_range'][0]:.2f}-{meta['loadavg_range'][1]:.2f}).\n")
    for k in kinds:
        w = summary[k]["worst_overrun"]
        if w is not None:
            md += (f"\n{k}: the re-plan furthest over its deadline took {w['latency_s'] * 1000:.0f} ms of "
                   f"{w['deadline_s'] * 1000:.0f} ({w['cause']}, {w['status']}): "
                   + ", ".join(f"{p} {1000 * v:.0f}" for p, v in w["phases"].items()) + " ms.\n")
    (args.out / f"{name}.md").write_text(md)
    print(md)
    return 0


def _overrides(items: list[str]) -> dict[str, Any]:
    """``NAME=VALUE`` strings -> FlyConfig keyword arguments (numbers as int or float)."""
    from dataclasses import fields

    from staghunt.flight import FlyConfig

    known = {f.name: f.type for f in fields(FlyConfig)}
    out: dict[str, Any] = {}
    for item in items:
        name, _, value = item.partition("=")
        if name not in known:
            raise SystemExit(f"--set: unknown FlyConfig setting {name!r}; one of {', '.join(known)}")
        out[name] = int(value) if known[name] in (int, "int") else float(value)
    FlyConfig(**out).check()
    return out


def _solve_only(jobs: list[dict[str, Any]], out: Path, overrides: dict[str, Any], started: provenance.Started) -> int:
    rows = []
    for i, job in enumerate(jobs):
        rows.append(solve_only(job, overrides))
        r = rows[-1]
        print(f"[{i + 1}/{len(jobs)}] {r['kind']} #{r['episode']}: {r['status']} {1000 * r['latency_s']:.0f} ms "
              f"certified {r['certified']}", file=sys.stderr)
    lines = ["| episodes | first re-plans solved | latency p50 / p95 / max (ms) | certified |", "|---|---|---|---|"]
    for k in sorted({r["kind"] for r in rows}):
        sel = [r for r in rows if r["kind"] == k]
        lat = np.array([r["latency_s"] for r in sel]) * 1000
        solved = [r for r in sel if r["status"] in ("replanned", "stop, replanned")]
        lines.append(f"| {k}: {len(sel)} | {len(solved)} | {np.percentile(lat, 50):.0f} / "
                     f"{np.percentile(lat, 95):.0f} / {lat.max():.0f} | {sum(r['certified'] for r in solved)}/{len(solved)} |")
    settings = ", ".join(f"{k} = {v}" for k, v in overrides.items()) or "default settings"
    md = "\n".join(lines) + (f"\n\none re-plan at a time, adaptive threads, {settings}, load average "
                             f"{os.getloadavg()[0]:.2f} at the end.\n")
    out.mkdir(parents=True, exist_ok=True)
    (out / "replan_solve.json").write_text(json.dumps(provenance.stamped(started, {"episodes": rows}), indent=1) + "\n")
    (out / "replan_solve.md").write_text(md)
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
