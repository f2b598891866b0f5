"""The execution layer: every UAV is a simulated multirotor of the scenario's airframe tracking
its reference with an SE(3) geometric controller, in wind.

- Vehicles: :class:`SimulatedTeam` steps the whole team at once
  (:class:`~staghunt.flight.multirotor.Batch`: rotorpy's ``Multirotor`` and ``SE3Control``
  batched in NumPy, rotor dynamics and aerodynamic drag included) at the simulation rate. The
  airframe is the scenario's ``[vehicle] airframe`` (:mod:`staghunt.task.airframes`; the
  Hummingbird, rotorpy's 0.5 kg quadrotor, by default), and the controller's limits are the
  plan's: its velocity command is clamped to ``[vehicle] max_speed``, its tilt to the
  airframe's limit (the scenario is refused when its ``max_acceleration`` is beyond that tilt).
  :class:`RotorpyTeam` flies the same airframe with rotorpy itself, one vehicle after the other
  (scipy's ``solve_ivp`` per vehicle and step; no limits): the reference the tests and
  ``benchmarks/vehicles.py`` compare against.
- Controller input: the reference's position, velocity and acceleration, yaw held at 0, plus a
  drag feed-forward: the acceleration the vehicle's own drag model (parasitic and rotor drag at
  the current rotor speeds) predicts at its measured ground velocity is added to the reference
  acceleration. Without it the Hummingbird lags its reference by about 0.35 m at 5 m/s (the
  controller has no integral term); wind is not known to it.
- Wind: a Dryden gust model (MIL-F-8785C) with the same discrete filter and length scales as
  rotorpy's ``DrydenWind``, driven by the run's own generator, the same gust for the whole
  team. rotorpy's class is not used as is: its module imports torch at load time (a
  multi-gigabyte dependency for one filter) and draws from NumPy's global random state, which
  would make an episode irreproducible from its seed. Turbulence intensity follows the
  MIL-F-8785C low-altitude rule: ``sigma_w = 0.1 W``,
  ``sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h_ft)^0.4`` for a mean wind ``W``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from staghunt.flight.multirotor import Batch, ControlLimits
from staghunt.task import VehicleLimits
from staghunt.task.airframes import AIRFRAMES, Airframe


class DrydenGust:
    """Dryden turbulence on the three axes plus a mean wind (m/s, world frame).

    The gust of each axis is white noise filtered by ``H(s) = alpha (1 + b s) / (1 + c s)^2``
    with ``b = 2 sqrt(3) L / V``, ``c = 2 L / V``, ``alpha = sigma sqrt(2 L / (pi V))``
    (discretised with the bilinear transform, as rotorpy's ``GustModelBase``); ``V`` is the
    mean wind speed (at least 1 m/s) and ``L`` the MIL-F-8785C length scale at ``altitude``.
    The filter is driven by Gaussian white noise of variance ``pi / dt`` (rotorpy drives it with
    ``uniform(-1, 1)`` per step, whose intensity depends on the step and gives gusts about 40
    times too weak at 100 Hz), so that each axis' standard deviation is its ``sigma``
    whatever the step (checked by the tests)."""

    def __init__(self, mean: np.ndarray, altitude: float, dt: float, rng: np.random.Generator) -> None:
        self.mean = np.asarray(mean, dtype=float)
        self.dt, self.rng = dt, rng
        speed = float(np.linalg.norm(self.mean))
        h_ft = 3.281 * max(altitude, 1.0)
        lz = h_ft / 3.281
        lx = h_ft / (0.177 + 0.000823 * h_ft) ** 1.2 / 3.281
        sig_w = 0.1 * speed
        sig_u = sig_w / (0.177 + 0.000823 * h_ft) ** 0.4
        V = max(speed, 1.0)
        coef = []
        for L, sigma in ((lx, sig_u), (lx, sig_u), (lz, sig_w)):
            b, c = 2.0 * math.sqrt(3.0) * L / V, 2.0 * L / V
            alpha = sigma * math.sqrt(2.0 * L / math.pi / V)
            beta, delta, gamma = alpha * b, 2.0 * c, c * c
            C1 = 1.0 + 2 * delta / dt + 4 * gamma / dt**2
            C2 = 2.0 - 8 * gamma / dt**2
            C3 = 1.0 - 2 * delta / dt + 4 * gamma / dt**2
            C4, C5, C6 = alpha + 2 * beta / dt, 2 * alpha, alpha - 2 * beta / dt
            coef.append((C1, C2, C3, C4, C5, C6))
        self.coef = np.array(coef)  # (3, 6)
        self.u = np.zeros((3, 2))  # u_{k-1}, u_{k-2}
        self.y = np.zeros((3, 2))
        self.sigma = np.array([sig_u, sig_u, sig_w])

    def step(self) -> np.ndarray:
        """``(3,)`` the wind for the next step."""
        if not np.any(self.sigma > 0):
            return self.mean.copy()
        C1, C2, C3, C4, C5, C6 = self.coef.T
        u = self.rng.normal(0.0, math.sqrt(math.pi / self.dt), size=3)
        y = (C4 * u + C5 * self.u[:, 0] + C6 * self.u[:, 1] - C2 * self.y[:, 0] - C3 * self.y[:, 1]) / C1
        self.u = np.column_stack([u, self.u[:, 0]])
        self.y = np.column_stack([y, self.y[:, 0]])
        return self.mean + y


def _airframe(vehicle: VehicleLimits | None) -> Airframe:
    name = (vehicle or VehicleLimits()).airframe
    if name not in AIRFRAMES:
        raise ValueError(f"vehicle.airframe: must be one of {', '.join(map(repr, AIRFRAMES))}, got {name!r}")
    return AIRFRAMES[name]


class SimulatedTeam:
    """``N`` multirotors of ``vehicle``'s airframe starting at rest (hovering) at ``starts``
    ``(N, 3)``, stepped together every ``dt`` s (``substeps`` RK4 steps each); ``wind`` gives
    the same gust to every vehicle. ``vehicle``: the scenario's ``[vehicle]`` table (airframe
    and ``max_speed``; default: the Hummingbird, 12 m/s); ``radii``: the UAVs' body radii (m).
    Raises ``ValueError`` (one line naming the key) when the airframe cannot fly the team:
    ``max_speed`` or ``max_acceleration`` beyond its reach, a radius smaller than it
    (:meth:`~staghunt.task.airframes.Airframe.misfit`)."""

    def __init__(self, starts: np.ndarray, dt: float, wind: DrydenGust | None,
                 vehicle: VehicleLimits | None = None, radii: Sequence[float] = (), substeps: int = 1) -> None:
        vehicle = vehicle or VehicleLimits()
        self.dt, self.wind, self.airframe = dt, wind, _airframe(vehicle)
        problem = self.airframe.misfit(vehicle.max_speed, vehicle.max_acceleration, radii)
        if problem:
            raise ValueError(": ".join(problem))
        limits = ControlLimits(max_speed=vehicle.max_speed, max_tilt=math.radians(self.airframe.max_tilt_deg))
        self.batch = Batch(self.airframe, np.asarray(starts, dtype=float), dt, substeps, limits)

    def step(self, t: float, ref: np.ndarray) -> None:
        """Advance every vehicle by ``dt`` tracking ``ref`` ``(4, N, 3)`` (position, velocity,
        acceleration, jerk at ``t``; the jerk is not used, as in rotorpy's controller)."""
        w = self.wind.step() if self.wind is not None else np.zeros(3)
        self.batch.step(ref[0], ref[1], ref[2], w)

    def positions(self) -> np.ndarray:
        """``(N, 3)`` true positions."""
        return self.batch.x.copy()

    def velocities(self) -> np.ndarray:
        """``(N, 3)`` true velocities."""
        return self.batch.v.copy()

    def attitudes(self) -> np.ndarray:
        """``(N, 4)`` attitude quaternions ``[x, y, z, w]`` (body to world)."""
        return self.batch.q.copy()

    def rotor_speeds(self) -> np.ndarray:
        """``(N, n)`` rotor speeds (rad/s)."""
        return self.batch.rotor.copy()

    def saturated(self) -> np.ndarray:
        """``(N,)`` steps so far in which the controller's speed or tilt limit acted."""
        return self.batch.saturated.copy()


class RotorpyTeam:
    """The reference: the team of :class:`SimulatedTeam` flown by rotorpy itself, one
    ``Multirotor`` + ``SE3Control`` per UAV stepped in turn (scipy's ``solve_ivp`` RK45 per
    vehicle and step), with the same drag feed-forward and wind, and no limits (rotorpy's
    controller has none)."""

    def __init__(self, starts: np.ndarray, dt: float, wind: DrydenGust | None,
                 vehicle: VehicleLimits | None = None) -> None:
        from rotorpy.controllers.quadrotor_control import SE3Control
        from rotorpy.vehicles.multirotor import Multirotor

        self.dt, self.wind, self.airframe = dt, wind, _airframe(vehicle)
        params = self.airframe.rotorpy_params()
        hover = self.airframe.hover_rotor_speed
        self.models, self.controllers, self.states = [], [], []
        for p in np.asarray(starts, dtype=float):
            state = {"x": p.copy(), "v": np.zeros(3), "q": np.array([0.0, 0.0, 0.0, 1.0]),
                     "w": np.zeros(3), "wind": np.zeros(3),
                     "rotor_speeds": np.full(self.airframe.num_rotors, hover)}
            self.models.append(Multirotor(params, initial_state=state))
            self.controllers.append(SE3Control(params))
            self.states.append(state)

    def _drag_acceleration(self, n: int) -> np.ndarray:
        from scipy.spatial.transform import Rotation

        m, s = self.models[n], self.states[n]
        R = Rotation.from_quat(s["q"]).as_matrix()
        air = R.T @ s["v"]
        D = -np.linalg.norm(air) * (m.drag_matrix @ air)
        H = -(m.rotor_drag_matrix @ air) * float(np.sum(s["rotor_speeds"]))
        return R @ (D + H) / m.mass

    def step(self, t: float, ref: np.ndarray) -> None:
        """As :meth:`SimulatedTeam.step`."""
        w = self.wind.step() if self.wind is not None else np.zeros(3)
        zero = np.zeros(3)
        for n, (model, controller) in enumerate(zip(self.models, self.controllers)):
            flat = {"x": ref[0, n], "x_dot": ref[1, n], "x_ddot": ref[2, n] - self._drag_acceleration(n),
                    "x_dddot": ref[3, n], "x_ddddot": zero, "yaw": 0.0, "yaw_dot": 0.0, "yaw_ddot": 0.0}
            self.states[n]["wind"] = w
            control = controller.update(t, self.states[n], flat)
            self.states[n] = model.step(self.states[n], control, self.dt)

    def positions(self) -> np.ndarray:
        """``(N, 3)`` true positions."""
        return np.array([s["x"] for s in self.states])

    def velocities(self) -> np.ndarray:
        """``(N, 3)`` true velocities."""
        return np.array([s["v"] for s in self.states])
