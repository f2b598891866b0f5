"""An exported mission flown open loop by the simulated vehicles (``staghunt export --simulate``).

The in-time check of an export samples the reference trajectories; this module flies them. The
reference is what ``trajectories.csv`` holds (time, position and velocity of every UAV on one
grid): every UAV follows the cubic Hermite curve through its samples (positions and velocities
exactly as written; acceleration and jerk its derivatives) with the simulated multirotor of the
closed loop (:class:`~staghunt.flight.vehicles.SimulatedTeam`: the scenario's airframe and
rotorpy's SE(3) controller at ``sim_rate`` Hz), from rest at the first sample, then holds the
last sample for ``hold`` seconds. Nothing re-plans: the world is the scenario's static one (cylinders, prisms,
no-fly zones, ceiling, terrain), as in the export's in-time check.

The flown states are judged by the one safety judge (:func:`staghunt.safety.judge`), with the
closed loop's margins: separation against ``d_s + 2 r``, clearance to the obstacles and to the
ground against the scenario's hard clearance, headroom under the ceiling; and tracking error
(RMS and maximum) against the reference.
"""

from __future__ import annotations

import csv
import io
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from staghunt.flight.vehicles import SimulatedTeam
from staghunt.safety import Margins, Scene, Verdict, judge
from staghunt.scenario import Scenario
from staghunt.trajectory.hermite import HermiteTeam

SIM_RATE = 100.0
"""Simulation rate (Hz)."""
RECORD_STEP = 5
"""Simulation steps between recorded states (every 0.05 s at 100 Hz)."""
HOLD_S = 2.0
"""Time (s) the vehicles hold the last sample before the flight is judged complete."""


@dataclass(frozen=True, eq=False)
class MissionFlight:
    """The simulated flight of a mission of ``N`` UAVs, recorded at ``T`` instants.

    - ``times``: ``(T,)`` s; ``actual``, ``reference``: ``(N, T, 3)`` site positions.
    - ``tracking_rms``, ``tracking_max``: ``(N,)`` |actual - reference| (m).
    - ``min_separation``: ``(N,)`` least distance to a team-mate at the same instant;
      ``separation_limit``: ``(N,)`` ``d_s + 2 r``.
    - ``min_clearance``: ``(N,)`` least clearance to the obstacles; ``required_clearance``.
    - ``min_height``: ``(N,)`` least height above the ground; ``max_altitude``: ``(N,)``
      highest site ``z`` (against the ceiling).
    - ``problems``: the limits the flight broke (empty: none), from ``verdict``;
      ``seconds``: wall time.
    """

    times: np.ndarray
    actual: np.ndarray
    reference: np.ndarray
    tracking_rms: np.ndarray
    tracking_max: np.ndarray
    min_separation: np.ndarray
    separation_limit: np.ndarray
    min_clearance: np.ndarray
    required_clearance: float
    min_height: np.ndarray
    max_altitude: np.ndarray
    problems: tuple[str, ...]
    sim_rate: float
    seconds: float
    verdict: Verdict | None = None

    @property
    def safe(self) -> bool:
        return not self.problems


def read_trajectories_csv(text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``t`` ``(T,)``, positions and velocities ``(N, T, 3)`` from the text of a
    ``trajectories.csv`` (``t,uav,x,y,z,vx,vy,vz``, all UAVs on one grid). Raises
    ``ValueError`` for a file that is not one."""
    rows = list(csv.reader(io.StringIO(text)))
    if not rows or rows[0] != ["t", "uav", "x", "y", "z", "vx", "vy", "vz"]:
        raise ValueError("trajectories.csv: the header must be t,uav,x,y,z,vx,vy,vz")
    try:
        data = np.array(rows[1:], dtype=float)
    except ValueError:
        raise ValueError("trajectories.csv: every field must be a number") from None
    if data.ndim != 2 or data.shape[0] == 0 or not np.all(np.isfinite(data)):
        raise ValueError("trajectories.csv: no rows, or a field that is not finite")
    n = int(data[:, 1].max())
    if data.shape[0] % n or not np.array_equal(data[:, 1], np.tile(np.arange(1, n + 1), data.shape[0] // n)):
        raise ValueError("trajectories.csv: every instant must list UAVs 1..N in order")
    block = data.reshape(-1, n, 8)  # (T, N, 8)
    t = block[:, 0, 0]
    if np.any(np.diff(t) <= 0) or np.any(block[:, :, 0] != t[:, None]):
        raise ValueError("trajectories.csv: the times must rise and be shared by the UAVs")
    return t, np.moveaxis(block[:, :, 2:5], 0, 1), np.moveaxis(block[:, :, 5:8], 0, 1)


def fly_mission(scenario: Scenario, t: np.ndarray, pos: np.ndarray, vel: np.ndarray,
                sim_rate: float = SIM_RATE, hold: float = HOLD_S,
                progress: Callable[[float, float], None] | None = None) -> MissionFlight:
    """Fly the sampled trajectories ``pos``, ``vel`` ``(N, T, 3)`` at times ``t`` ``(T,)``
    (site frame, absolute) with the simulated team and judge the flight (module docstring).
    ``progress(t, t_end)`` is called about once per simulated second."""
    t0 = time.perf_counter()
    curve = HermiteTeam(t, pos, vel)
    dt = 1.0 / sim_rate
    t_end = float(t[-1]) + hold
    steps = math.ceil((t_end - t[0]) / dt)
    team = SimulatedTeam(pos[:, 0], dt, None, scenario.vehicle, [u.radius for u in scenario.team])
    ticks = float(t[0]) + np.arange(steps + 1) * dt  # (S,)
    # The reference at every step, sampled once: (4, N, S, 3) position, velocity, acceleration,
    # jerk; after the last sample, its position at rest.
    ref = curve.state(ticks)
    rec_x: list[np.ndarray] = []
    per_second = max(1, round(sim_rate))
    for k in range(steps + 1):
        if k % RECORD_STEP == 0:
            rec_x.append(team.positions())
        if k < steps:
            team.step(float(ticks[k]), ref[:, :, k])
        if progress is not None and k % per_second == 0:
            progress(float(ticks[k]), t_end)
    recorded = slice(None, None, RECORD_STEP)
    times = ticks[recorded]
    actual = np.stack(rec_x, axis=1)  # (N, T, 3)
    reference = ref[0][:, recorded]
    return judge_mission(scenario, times, actual, reference, sim_rate, time.perf_counter() - t0)


def judge_mission(scenario: Scenario, times: np.ndarray, actual: np.ndarray, reference: np.ndarray,
                  sim_rate: float = SIM_RATE, seconds: float = 0.0) -> MissionFlight:
    """Judge flown positions ``actual`` against ``reference`` ``(N, T, 3)`` (module docstring)."""
    world = scenario.world
    radius = np.array([u.radius for u in scenario.team])
    names = [u.name for u in scenario.team]
    verdict = judge(Scene.fixed(world), radius, times, actual, Margins.required(scenario), names)
    err = np.linalg.norm(actual - reference, axis=-1)
    return MissionFlight(
        times=times, actual=actual, reference=reference,
        tracking_rms=np.sqrt(np.mean(err ** 2, axis=1)), tracking_max=err.max(axis=1),
        min_separation=verdict.min_separation, separation_limit=scenario.costs.safe_distance + 2.0 * radius,
        min_clearance=verdict.min_clearance, required_clearance=float(scenario.costs.min_clearance),
        min_height=verdict.min_ground + radius, max_altitude=actual[..., 2].max(axis=1),
        problems=tuple(f"in flight: {p}" for p in verdict.problems(names)), sim_rate=float(sim_rate),
        seconds=float(seconds), verdict=verdict)
