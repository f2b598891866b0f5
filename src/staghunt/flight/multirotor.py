"""Batched multirotor dynamics and SE(3) control: every UAV of a team stepped at once, compiled.

The model and the controller are rotorpy's (``rotorpy.vehicles.multirotor.Multirotor`` with
``control_abstraction='cmd_motor_speeds'``, ``aero=True``, no ground, no motor noise, and
``rotorpy.controllers.quadrotor_control.SE3Control``), term for term, for ``N`` vehicles of
one :class:`~staghunt.task.airframes.Airframe`, in one Numba kernel per step (:func:`team_step`,
a loop over the vehicles; compiled once and cached on disk):

- rigid body: position, velocity, attitude quaternion ``[x, y, z, w]`` (its derivative
  ``q' = G(q)^T omega / 2`` without a norm penalty, renormalised after each step, and read
  through a normalised copy, as scipy's ``Rotation.from_quat`` does), body rates;
- forces in the body frame: rotor thrust ``k_eta w^2`` plus translational lift ``k_h`` (local
  horizontal airspeed squared), rotor drag ``-w diag(k_d, k_d, k_z) v_i`` and flapping moment
  ``-k_flap w (v_i x e3)`` at each hub (``v_i`` the hub's airspeed: the body airspeed, wind
  included, plus ``omega x r_i``), parasitic drag ``-|v_a| diag(c_D) v_a``, rotor yaw moments
  ``k_m w^2``;
- motors: first order, ``w' = (w_cmd - w) / tau_m``, the command held over the step and
  clipped to the rotor speed range;
- controller: ``F = m (-k_p e_x - k_v e_v + a_ref + g e3)``, thrust ``F . b3``, desired attitude
  from ``F`` and yaw 0, moment ``J (-k_R e_R - k_w omega) + omega x J omega``, rotor speeds by
  the allocation matrix (rotorpy's gains: ``k_p = (6.5, 6.5, 15)``, ``k_v = (4, 4, 9)``, the
  airframe's ``kp_att``, ``kd_att``); ``a_ref`` includes the drag feed-forward
  (:mod:`~staghunt.flight.vehicles`), computed in the same kernel.

Integration. rotorpy integrates each step with scipy's adaptive ``solve_ivp`` (RK45, relative
tolerance 1e-3, absolute 1e-6), one call per vehicle and step. Here the motor equation, linear
with the command held, is solved exactly (``w(t) = w_cmd + (w_0 - w_cmd) e^(-t/tau_m)``: the
Hummingbird's 5 ms motors are stiff at a 10 ms step) and the rigid body by classic fixed-step
Runge-Kutta 4 with the rotor speeds of each stage taken from that solution, ``substeps`` RK4
steps per control step (1 by default). The tests fly both models 10 s from the same state,
reference and gusts: they agree within 1 cm (0.22 mm on the Hummingbird, 0.7 um on the
``m300``).

Limits (:class:`ControlLimits`; none by default, as in rotorpy). ``max_speed``: the position
loop's velocity command ``v_ref - (k_p / k_v) e_x`` is clamped to it (PX4's ``MPC_XY_VEL_MAX``
in spirit); ``max_tilt``: the commanded force's horizontal part is clamped to ``tan(max_tilt)``
times its vertical part, itself at least a tenth of the weight (PX4's ``MPC_TILTMAX_AIR`` and
minimum thrust). Within the limits the command is rotorpy's exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from staghunt.task.airframes import G, Airframe

KP_POS = (6.5, 6.5, 15.0)
"""Position gains of rotorpy's ``SE3Control``."""
KD_POS = (4.0, 4.0, 9.0)
"""Velocity gains of rotorpy's ``SE3Control``."""

# Scalar parameters of the kernel, in this order (one float64 array).
_PARAMS = ("mass", "k_eta", "k_m", "k_d", "k_z", "k_h", "k_flap", "tau_m", "rotor_speed_min",
           "rotor_speed_max", "kp_att", "kd_att")


@dataclass(frozen=True)
class ControlLimits:
    """The controller's limits: ``max_speed`` (m/s) of its velocity command, ``max_tilt`` (rad)
    of the commanded thrust from the vertical. ``inf`` / ``pi / 2``: no limit."""

    max_speed: float = math.inf
    max_tilt: float = math.pi / 2


@njit(cache=True)
def _rotation(q: np.ndarray, R: np.ndarray) -> None:
    """``R`` ``(3, 3)`` (body to world) of the quaternion ``q`` ``[x, y, z, w]``, normalised."""
    s = 1.0 / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    x, y, z, w = q[0] * s, q[1] * s, q[2] * s, q[3] * s
    R[0, 0], R[0, 1], R[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
    R[1, 0], R[1, 1], R[1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    R[2, 0], R[2, 1], R[2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)


@njit(cache=True)
def _derivative(y: np.ndarray, rotor: np.ndarray, wind: np.ndarray, P: np.ndarray, r: np.ndarray,
                dirs: np.ndarray, cd: np.ndarray, J: np.ndarray, J_inv: np.ndarray, R: np.ndarray,
                out: np.ndarray) -> None:
    """``out`` = the derivative of ``y`` = (x, v, q, omega) ``(13,)`` at rotor speeds ``rotor``."""
    mass, k_eta, k_m, k_d, k_z, k_h, k_flap = P[0], P[1], P[2], P[3], P[4], P[5], P[6]
    _rotation(y[6:10], R)
    rx, ry, rz = y[3] - wind[0], y[4] - wind[1], y[5] - wind[2]
    va0 = R[0, 0] * rx + R[1, 0] * ry + R[2, 0] * rz  # body airspeed R^T (v - wind)
    va1 = R[0, 1] * rx + R[1, 1] * ry + R[2, 1] * rz
    va2 = R[0, 2] * rx + R[1, 2] * ry + R[2, 2] * rz
    w0, w1, w2 = y[10], y[11], y[12]
    f0 = f1 = f2 = m0 = m1 = m2 = 0.0
    for k in range(r.shape[0]):
        px, py, pz = r[k, 0], r[k, 1], r[k, 2]
        lx, ly, lz = va0 + w1 * pz - w2 * py, va1 + w2 * px - w0 * pz, va2 + w0 * py - w1 * px
        om = rotor[k]
        hx, hy = -om * k_d * lx, -om * k_d * ly
        hz = -om * k_z * lz + k_eta * om * om + k_h * (lx * lx + ly * ly)
        f0 += hx
        f1 += hy
        f2 += hz
        m0 += py * hz - pz * hy - k_flap * om * ly
        m1 += pz * hx - px * hz + k_flap * om * lx
        m2 += px * hy - py * hx + dirs[k] * k_m * om * om
    speed = math.sqrt(va0 * va0 + va1 * va1 + va2 * va2)
    f0 -= speed * cd[0] * va0
    f1 -= speed * cd[1] * va1
    f2 -= speed * cd[2] * va2
    out[0], out[1], out[2] = y[3], y[4], y[5]
    out[3] = (R[0, 0] * f0 + R[0, 1] * f1 + R[0, 2] * f2) / mass
    out[4] = (R[1, 0] * f0 + R[1, 1] * f1 + R[1, 2] * f2) / mass
    out[5] = (R[2, 0] * f0 + R[2, 1] * f1 + R[2, 2] * f2) / mass - G
    q0, q1, q2, q3 = y[6], y[7], y[8], y[9]
    out[6] = 0.5 * (q3 * w0 - q2 * w1 + q1 * w2)
    out[7] = 0.5 * (q2 * w0 + q3 * w1 - q0 * w2)
    out[8] = 0.5 * (-q1 * w0 + q0 * w1 + q3 * w2)
    out[9] = 0.5 * (-q0 * w0 - q1 * w1 - q2 * w2)
    j0 = J[0, 0] * w0 + J[0, 1] * w1 + J[0, 2] * w2
    j1 = J[1, 0] * w0 + J[1, 1] * w1 + J[1, 2] * w2
    j2 = J[2, 0] * w0 + J[2, 1] * w1 + J[2, 2] * w2
    g0, g1, g2 = m0 - (w1 * j2 - w2 * j1), m1 - (w2 * j0 - w0 * j2), m2 - (w0 * j1 - w1 * j0)
    for i in range(3):
        out[10 + i] = J_inv[i, 0] * g0 + J_inv[i, 1] * g1 + J_inv[i, 2] * g2


@njit(cache=True)
def _command(y: np.ndarray, rotor: np.ndarray, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray,
             P: np.ndarray, kh: np.ndarray, cd: np.ndarray, J: np.ndarray, tm_to_f: np.ndarray,
             max_speed: float, max_tilt: float, R: np.ndarray, cmd: np.ndarray) -> bool:
    """``cmd`` = rotor speed commands (clipped) tracking ``pos``, ``vel``, ``acc`` ``(3,)`` plus
    the drag feed-forward, yaw 0. Returns whether a limit changed the command."""
    mass, k_eta, kp_att, kd_att = P[0], P[1], P[10], P[11]
    _rotation(y[6:10], R)
    # Drag feed-forward: minus the drag acceleration at the ground velocity (no wind).
    a0 = R[0, 0] * y[3] + R[1, 0] * y[4] + R[2, 0] * y[5]
    a1 = R[0, 1] * y[3] + R[1, 1] * y[4] + R[2, 1] * y[5]
    a2 = R[0, 2] * y[3] + R[1, 2] * y[4] + R[2, 2] * y[5]
    speed, total = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2), rotor.sum()
    d0 = -speed * cd[0] * a0 - kh[0] * a0 * total
    d1 = -speed * cd[1] * a1 - kh[1] * a1 * total
    d2 = -speed * cd[2] * a2 - kh[2] * a2 * total
    vc = np.empty(3)
    for i in range(3):
        vc[i] = vel[i] - KP_POS[i] / KD_POS[i] * (y[i] - pos[i])  # the velocity command
    norm = math.sqrt(vc[0] * vc[0] + vc[1] * vc[1] + vc[2] * vc[2])
    limited = norm > max_speed
    F = np.empty(3)
    for i in range(3):
        drag = (R[i, 0] * d0 + R[i, 1] * d1 + R[i, 2] * d2) / mass
        if limited:
            feedback = KD_POS[i] * (vc[i] * (max_speed / norm) - y[3 + i])
        else:
            feedback = -KP_POS[i] * (y[i] - pos[i]) - KD_POS[i] * (y[3 + i] - vel[i])
        F[i] = feedback + acc[i] - drag
    for i in range(3):
        F[i] *= mass
    F[2] += mass * G
    if max_tilt < 0.5 * math.pi:
        fz = max(F[2], 0.1 * mass * G)
        fh, cap = math.hypot(F[0], F[1]), fz * math.tan(max_tilt)
        if fh > cap or fz > F[2]:
            limited = True
            scale = cap / fh if fh > cap else 1.0
            F[0], F[1], F[2] = F[0] * scale, F[1] * scale, fz
    u1 = F[0] * R[0, 2] + F[1] * R[1, 2] + F[2] * R[2, 2]
    n = math.sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2])
    b30, b31, b32 = F[0] / n, F[1] / n, F[2] / n
    n = math.sqrt(b32 * b32 + b31 * b31)  # b2 = normalize(b3 x (1, 0, 0)) = (0, b3z, -b3y) / n
    b20, b21, b22 = 0.0, b32 / n, -b31 / n
    b10, b11, b12 = b21 * b32 - b22 * b31, b22 * b30 - b20 * b32, b20 * b31 - b21 * b30
    M = np.empty((3, 3))  # R_des^T R, R_des = [b1 b2 b3] as columns
    for j in range(3):
        M[0, j] = b10 * R[0, j] + b11 * R[1, j] + b12 * R[2, j]
        M[1, j] = b20 * R[0, j] + b21 * R[1, j] + b22 * R[2, j]
        M[2, j] = b30 * R[0, j] + b31 * R[1, j] + b32 * R[2, j]
    e0, e1, e2 = 0.5 * (M[2, 1] - M[1, 2]), 0.5 * (M[0, 2] - M[2, 0]), 0.5 * (M[1, 0] - M[0, 1])
    w0, w1, w2 = y[10], y[11], y[12]
    t0, t1, t2 = -kp_att * e0 - kd_att * w0, -kp_att * e1 - kd_att * w1, -kp_att * e2 - kd_att * w2
    j0 = J[0, 0] * w0 + J[0, 1] * w1 + J[0, 2] * w2
    j1 = J[1, 0] * w0 + J[1, 1] * w1 + J[1, 2] * w2
    j2 = J[2, 0] * w0 + J[2, 1] * w1 + J[2, 2] * w2
    tm = np.empty(4)
    tm[0] = u1
    tm[1] = J[0, 0] * t0 + J[0, 1] * t1 + J[0, 2] * t2 + (w1 * j2 - w2 * j1)
    tm[2] = J[1, 0] * t0 + J[1, 1] * t1 + J[1, 2] * t2 + (w2 * j0 - w0 * j2)
    tm[3] = J[2, 0] * t0 + J[2, 1] * t1 + J[2, 2] * t2 + (w0 * j1 - w1 * j0)
    for k in range(cmd.shape[0]):
        f = (tm_to_f[k, 0] * tm[0] + tm_to_f[k, 1] * tm[1] + tm_to_f[k, 2] * tm[2] + tm_to_f[k, 3] * tm[3]) / k_eta
        s = math.copysign(math.sqrt(abs(f)), f) if f != 0.0 else 0.0
        cmd[k] = min(max(s, P[8]), P[9])
    return limited


@njit(cache=True)
def team_step(Y: np.ndarray, rotors: np.ndarray, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray,
              wind: np.ndarray, P: np.ndarray, r: np.ndarray, dirs: np.ndarray, cd: np.ndarray,
              kh: np.ndarray, J: np.ndarray, J_inv: np.ndarray, tm_to_f: np.ndarray, max_speed: float,
              max_tilt: float, dt: float, substeps: int, saturated: np.ndarray) -> None:
    """One control step of ``dt`` for every vehicle, in place: states ``Y`` ``(N, 13)`` (x, v,
    q, omega), rotor speeds ``rotors`` ``(N, n)``, references ``pos``, ``vel``, ``acc``
    ``(N, 3)``, ``wind`` ``(3,)``; ``saturated`` ``(N,)`` counts the steps a limit acted."""
    n_rot = rotors.shape[1]
    R = np.empty((3, 3))
    cmd, gap, om = np.empty(n_rot), np.empty(n_rot), np.empty(n_rot)
    k1, k2, k3, k4, s = np.empty(13), np.empty(13), np.empty(13), np.empty(13), np.empty(13)
    tau, h = P[7], dt / substeps
    for u in range(Y.shape[0]):
        y = Y[u]
        if _command(y, rotors[u], pos[u], vel[u], acc[u], P, kh, cd, J, tm_to_f, max_speed, max_tilt, R, cmd):
            saturated[u] += 1
        for k in range(n_rot):
            gap[k] = rotors[u, k] - cmd[k]
        for sub in range(substeps):
            t0 = sub * h
            for k in range(n_rot):
                om[k] = cmd[k] + gap[k] * math.exp(-t0 / tau)
            _derivative(y, om, wind, P, r, dirs, cd, J, J_inv, R, k1)
            for k in range(n_rot):
                om[k] = cmd[k] + gap[k] * math.exp(-(t0 + 0.5 * h) / tau)
            for i in range(13):
                s[i] = y[i] + 0.5 * h * k1[i]
            _derivative(s, om, wind, P, r, dirs, cd, J, J_inv, R, k2)
            for i in range(13):
                s[i] = y[i] + 0.5 * h * k2[i]
            _derivative(s, om, wind, P, r, dirs, cd, J, J_inv, R, k3)
            for k in range(n_rot):
                om[k] = cmd[k] + gap[k] * math.exp(-(t0 + h) / tau)
            for i in range(13):
                s[i] = y[i] + h * k3[i]
            _derivative(s, om, wind, P, r, dirs, cd, J, J_inv, R, k4)
            for i in range(13):
                y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        qn = math.sqrt(y[6] * y[6] + y[7] * y[7] + y[8] * y[8] + y[9] * y[9])
        for i in range(6, 10):
            y[i] /= qn
        for k in range(n_rot):
            rotors[u, k] = min(max(cmd[k] + gap[k] * math.exp(-dt / tau), P[8]), P[9])


class Batch:
    """``N`` multirotors of one airframe starting at rest (hovering) at ``x`` ``(N, 3)``.

    State (read-only views): ``x``, ``v`` ``(N, 3)`` world position and velocity (m, m/s),
    ``q`` ``(N, 4)`` attitude ``[x, y, z, w]`` (body to world), ``w`` ``(N, 3)`` body rates
    (rad/s), ``rotor`` ``(N, n)`` rotor speeds (rad/s); ``saturated`` ``(N,)`` control steps in
    which a limit changed the command."""

    def __init__(self, airframe: Airframe, x: np.ndarray, dt: float, substeps: int = 1,
                 limits: ControlLimits = ControlLimits()) -> None:
        a = airframe
        self.airframe, self.dt, self.substeps, self.limits = a, float(dt), int(substeps), limits
        x = np.array(x, dtype=float).reshape(-1, 3)
        self.Y = np.zeros((len(x), 13))
        self.Y[:, 0:3], self.Y[:, 9] = x, 1.0
        self.rotor = np.full((len(x), a.num_rotors), a.hover_rotor_speed)
        self.saturated = np.zeros(len(x), dtype=np.int64)
        ixx, iyy, izz, ixy, iyz, ixz = a.inertia
        self.J = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        self.J_inv = np.linalg.inv(self.J)
        self.r = np.array(a.rotor_pos, dtype=float)  # (n, 3)
        self.dirs = np.array(a.rotor_directions, dtype=float)
        self.cd = np.array(a.drag, dtype=float)
        self.kh = np.array([a.k_d, a.k_d, a.k_z])
        # rotorpy's allocation: rows thrust, x and y moments (r x e3), yaw moment (k_m / k_eta).
        f_to_tm = np.vstack([np.ones(a.num_rotors), self.r[:, 1], -self.r[:, 0], (a.k_m / a.k_eta) * self.dirs])
        self.tm_to_f = np.linalg.inv(f_to_tm)  # (n, 4)
        self.P = np.array([float(getattr(a, k)) for k in _PARAMS])

    @property
    def x(self) -> np.ndarray:
        return self.Y[:, 0:3]

    @property
    def v(self) -> np.ndarray:
        return self.Y[:, 3:6]

    @property
    def q(self) -> np.ndarray:
        return self.Y[:, 6:10]

    @property
    def w(self) -> np.ndarray:
        return self.Y[:, 10:13]

    def step(self, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray, wind: np.ndarray) -> None:
        """Control and advance every vehicle by ``dt`` tracking ``pos``, ``vel``, ``acc``
        ``(N, 3)`` (the drag feed-forward added) in ``wind`` ``(3,)`` (world m/s)."""
        f = np.ascontiguousarray
        team_step(self.Y, self.rotor, f(pos, dtype=float), f(vel, dtype=float), f(acc, dtype=float),
                  f(wind, dtype=float), self.P, self.r, self.dirs, self.cd, self.kh, self.J, self.J_inv,
                  self.tm_to_f, float(self.limits.max_speed), float(self.limits.max_tilt), self.dt,
                  self.substeps, self.saturated)
