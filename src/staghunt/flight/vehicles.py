"""The execution layer: every UAV is a simulated multirotor (rotorpy) tracking its reference
with rotorpy's SE(3) geometric controller, in wind.

- Vehicle: :class:`rotorpy.vehicles.multirotor.Multirotor` with the Hummingbird parameter set
  (0.5 kg quadrotor), rotor dynamics and aerodynamic drag, integrated by rotorpy (scipy's
  ``solve_ivp``) at the simulation rate.
- Controller: :class:`rotorpy.controllers.quadrotor_control.SE3Control` (Lee et al.), fed the
  reference's position, velocity and acceleration (and jerk), yaw held at 0, plus a drag
  feed-forward: the acceleration the vehicle's own drag model (rotorpy's parasitic and rotor
  drag at the current rotor speeds) predicts at its measured ground velocity is added to the
  reference acceleration. Without it the Hummingbird lags its reference by about 0.35 m at
  5 m/s (the controller has no integral term); wind is not known to it.
- Wind: a Dryden gust model (MIL-F-8785C) with the same discrete filter and length scales as
  rotorpy's ``DrydenWind``, driven by the run's own generator. rotorpy's class is not used as is:
  its module imports torch at load time (a multi-gigabyte dependency for one filter) and draws
  from NumPy's global random state, which would make an episode irreproducible from its seed.
  Turbulence intensity follows the MIL-F-8785C low-altitude rule: ``sigma_w = 0.1 W``,
  ``sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h_ft)^0.4`` for a mean wind ``W``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

G = 9.81


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


@dataclass
class _Vehicle:
    model: object
    controller: object
    state: dict


class SimulatedTeam:
    """``N`` rotorpy multirotors starting at rest (hovering) at ``starts`` ``(N, 3)``."""

    def __init__(self, starts: np.ndarray, dt: float, wind: DrydenGust | None) -> None:
        from rotorpy.controllers.quadrotor_control import SE3Control
        from rotorpy.vehicles.hummingbird_params import quad_params
        from rotorpy.vehicles.multirotor import Multirotor

        self.dt, self.wind = dt, wind
        self.vehicles: list[_Vehicle] = []
        hover = math.sqrt(quad_params["mass"] * G / (quad_params["num_rotors"] * quad_params["k_eta"]))
        for p in np.asarray(starts, dtype=float):
            state = {"x": p.copy(), "v": np.zeros(3), "q": np.array([0.0, 0.0, 0.0, 1.0]),
                     "w": np.zeros(3), "wind": np.zeros(3), "rotor_speeds": np.full(4, hover)}
            model = Multirotor(quad_params, initial_state=state)
            self.vehicles.append(_Vehicle(model, SE3Control(quad_params), state))

    @staticmethod
    def drag_acceleration(v: _Vehicle) -> np.ndarray:
        """``(3,)`` world-frame acceleration of the vehicle's drag at its ground velocity (no wind)."""
        from scipy.spatial.transform import Rotation

        m = v.model
        R = Rotation.from_quat(v.state["q"]).as_matrix()
        air = R.T @ v.state["v"]
        D = -np.linalg.norm(air) * (m.drag_matrix @ air)
        H = -(m.rotor_drag_matrix @ air) * float(np.sum(v.state["rotor_speeds"]))
        return R @ (D + H) / m.mass

    def step(self, t: float, ref: np.ndarray) -> None:
        """Advance every vehicle by ``dt`` tracking ``ref`` ``(4, N, 3)`` (position, velocity,
        acceleration, jerk at ``t``)."""
        w = self.wind.step() if self.wind is not None else np.zeros(3)
        zero = np.zeros(3)
        for n, v in enumerate(self.vehicles):
            ff = ref[2, n] - self.drag_acceleration(v)
            flat = {"x": ref[0, n], "x_dot": ref[1, n], "x_ddot": ff, "x_dddot": ref[3, n],
                    "x_ddddot": zero, "yaw": 0.0, "yaw_dot": 0.0, "yaw_ddot": 0.0}
            v.state["wind"] = w
            control = v.controller.update(t, v.state, flat)
            v.state = v.model.step(v.state, control, self.dt)

    def positions(self) -> np.ndarray:
        """``(N, 3)`` true positions."""
        return np.array([v.state["x"] for v in self.vehicles])

    def velocities(self) -> np.ndarray:
        """``(N, 3)`` true velocities."""
        return np.array([v.state["v"] for v in self.vehicles])
