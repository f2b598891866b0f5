"""The airframes a scenario's team may fly (``[vehicle] airframe``): mass, size, rotors, thrust,
drag and the attitude gains of the simulated multirotor, with their sources.

Each :class:`Airframe` holds a full rotorpy parameter set (:meth:`Airframe.rotorpy_params` gives
it in rotorpy's own dictionary form, so rotorpy's ``Multirotor`` and ``SE3Control`` fly it as
they fly their built-in vehicles), the controller's tilt limit, and the figures a team flown
in simulation is checked against (:meth:`Airframe.misfit`): :attr:`Airframe.body_radius` (arm
plus propeller), :meth:`Airframe.top_speed` (the steady level speed at the tilt limit in still
air, from the model's own drag) and :meth:`Airframe.max_horizontal_acceleration`.

- ``hummingbird``: the AscTec Hummingbird, rotorpy's ``hummingbird_params`` value for value
  (checked by the tests against rotorpy itself): 0.5 kg, 0.17 m arms, 8-inch propellers, thrust
  50 N (thrust-to-weight 10). The tilt limit is PX4's default ``MPC_TILTMAX_AIR`` (45 degrees).
- ``m300``: a DJI Matrice 300 RTK-class inspection quadrotor: DJI's published mass (6.3 kg with
  two TB60 batteries; 9 kg maximum take-off weight), diagonal wheelbase (895 mm), propellers
  (2110, 21 inch), maximum tilt (30 degrees) and maximum speed (23 m/s, S mode). DJI publishes
  no thrust, inertia, motor or drag figures; those are estimates, said so field by field in
  :data:`M300` and in docs/scenario-format.md (``[vehicle]``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

G = 9.81
"""Gravity (m/s^2), rotorpy's value."""

_DIAG = 0.70710678118  # rotorpy's cos(45 deg) for rotors on the diagonals


@dataclass(frozen=True)
class Airframe:
    """A multirotor's physical and control parameters (SI units, rotorpy's names and meaning).

    ``rotor_pos``: ``(n, 3)`` rotor hubs from the centre of mass (body frame, x forward, z up);
    ``rotor_directions``: ``(n,)`` +1/-1, the sign of each rotor's yaw moment. ``inertia``:
    ``(Ixx, Iyy, Izz, Ixy, Iyz, Ixz)`` kg m^2. ``drag``: parasitic ``(c_Dx, c_Dy, c_Dz)``
    N/(m/s)^2. ``k_eta`` thrust and ``k_m`` yaw-moment coefficients per (rad/s)^2; ``k_d``,
    ``k_z`` rotor drag (H-force) and induced inflow, ``k_h`` translational lift, ``k_flap``
    flapping moment; ``tau_m`` motor time constant (s); rotor speeds in rad/s. ``kp_att``,
    ``kd_att``: the SE(3) controller's attitude gains (1/s^2, 1/s). ``max_tilt_deg``: the
    controller's tilt limit. ``sources``: where the values come from."""

    name: str
    title: str
    mass: float
    inertia: tuple[float, float, float, float, float, float]
    arm_length: float
    rotor_radius: float
    rotor_pos: tuple[tuple[float, float, float], ...]
    rotor_directions: tuple[int, ...]
    drag: tuple[float, float, float]
    k_eta: float
    k_m: float
    k_d: float
    k_z: float
    k_h: float
    k_flap: float
    tau_m: float
    rotor_speed_min: float
    rotor_speed_max: float
    kp_att: float
    kd_att: float
    max_tilt_deg: float
    sources: tuple[str, ...]

    @property
    def num_rotors(self) -> int:
        return len(self.rotor_pos)

    @property
    def body_radius(self) -> float:
        """Arm plus propeller radius (m): the smallest sphere around the centre that holds the
        rotor discs (a UAV's ``radius`` in the scenario must be at least this)."""
        return self.arm_length + self.rotor_radius

    @property
    def max_thrust(self) -> float:
        """All rotors at full speed (N)."""
        return self.num_rotors * self.k_eta * self.rotor_speed_max**2

    @property
    def thrust_to_weight(self) -> float:
        return self.max_thrust / (self.mass * G)

    @property
    def hover_rotor_speed(self) -> float:
        """Rotor speed (rad/s) that holds the weight, level, in still air."""
        return math.sqrt(self.mass * G / (self.num_rotors * self.k_eta))

    def max_horizontal_acceleration(self) -> float:
        """Largest level horizontal acceleration (m/s^2) at rest: ``g tan(tilt)`` at the tilt
        limit, or less when full thrust cannot hold the weight at that tilt."""
        tilt = math.radians(self.max_tilt_deg)
        tilt = min(tilt, math.acos(min(1.0, 1.0 / self.thrust_to_weight)))
        return G * math.tan(tilt)

    def level_flight(self, speed: float) -> tuple[float, float] | None:
        """Forward flight at ``speed`` (m/s, along body x) at the tilt limit in still air, all
        rotors at one speed ``w`` holding the weight: ``(net forward force (N), w)``, or
        ``None`` when no rotor speed in range holds it. Thrust, rotor drag, induced inflow,
        translational lift and parasitic drag of the model (rotorpy's), no body rates."""
        c, s = math.cos(math.radians(self.max_tilt_deg)), math.sin(math.radians(self.max_tilt_deg))
        n, v = self.num_rotors, speed
        cdx, _, cdz = self.drag
        # Body airspeed (c v, 0, s v); the world vertical balance is a quadratic in w.
        qa = n * c * self.k_eta
        qb = n * s * c * v * (self.k_d - self.k_z)
        qc = (s * c * cdx + n * c**3 * self.k_h - c * s * cdz) * v * v - self.mass * G
        disc = qb * qb - 4 * qa * qc
        if disc < 0:
            return None
        w = (-qb + math.sqrt(disc)) / (2 * qa)
        if not self.rotor_speed_min <= w <= self.rotor_speed_max:
            return None
        fx = -n * self.k_d * c * v * w - cdx * c * v * v
        fz = n * self.k_eta * w * w + n * self.k_h * (c * v) ** 2 - n * self.k_z * s * v * w - cdz * s * v * v
        return c * fx + s * fz, w

    def top_speed(self) -> float:
        """The steady level speed (m/s) at the tilt limit in still air (:meth:`level_flight`
        balanced, by bisection); 0 if the weight cannot be held there."""
        if self.level_flight(0.0) is None:
            return 0.0
        lo, hi = 0.0, 200.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            f = self.level_flight(mid)
            if f is not None and f[0] > 0:
                lo = mid
            else:
                hi = mid
        return lo

    def misfit(self, max_speed: float, max_acceleration: float, radii: Sequence[float] = ()
               ) -> tuple[str, str] | None:
        """``(key, message)`` when a team cannot be flown by this airframe: a ``max_speed``
        (m/s) above :meth:`top_speed`, a ``max_acceleration`` (m/s^2) above
        :meth:`max_horizontal_acceleration`, or a UAV's radius (m, ``radii[i]``) smaller than
        :attr:`body_radius`; ``None`` when it can."""
        tilt = f"{self.max_tilt_deg:g} degree tilt limit"
        for i, r in enumerate(radii):
            if r < self.body_radius:
                return f"team[{i}].radius", (
                    f"{r:.12g} m is smaller than airframe {self.name!r} (vehicle.airframe): arm "
                    f"{self.arm_length:.3f} m plus propeller {self.rotor_radius:.3f} m = {self.body_radius:.3f} m")
        top, reach = self.top_speed(), self.max_horizontal_acceleration()
        if max_speed > top:
            return "vehicle.max_speed", (f"{max_speed:.12g} m/s is above the top speed of airframe "
                                         f"{self.name!r} ({top:.2f} m/s at its {tilt})")
        if max_acceleration > reach:
            return "vehicle.max_acceleration", (f"{max_acceleration:.12g} m/s^2 is above what airframe "
                                                f"{self.name!r} reaches at its {tilt} ({reach:.2f} m/s^2)")
        return None

    def rotorpy_params(self) -> dict[str, object]:
        """The parameter set in rotorpy's ``quad_params`` form (``rotorpy.vehicles.*_params``)."""
        import numpy as np

        ixx, iyy, izz, ixy, iyz, ixz = self.inertia
        return {
            "mass": self.mass, "Ixx": ixx, "Iyy": iyy, "Izz": izz, "Ixy": ixy, "Iyz": iyz, "Ixz": ixz,
            "num_rotors": self.num_rotors, "rotor_radius": self.rotor_radius,
            "rotor_pos": {f"r{i + 1}": np.array(p) for i, p in enumerate(self.rotor_pos)},
            "rotor_directions": np.array(self.rotor_directions), "rI": np.array([0, 0, 0]),
            "c_Dx": self.drag[0], "c_Dy": self.drag[1], "c_Dz": self.drag[2],
            "k_eta": self.k_eta, "k_m": self.k_m, "k_d": self.k_d, "k_z": self.k_z, "k_h": self.k_h,
            "k_flap": self.k_flap, "tau_m": self.tau_m, "rotor_speed_min": self.rotor_speed_min,
            "rotor_speed_max": self.rotor_speed_max, "motor_noise_std": 0.0,
            "k_w": 1, "k_v": 10, "kp_att": self.kp_att, "kd_att": self.kd_att,
        }


def _x_rotors(arm: float) -> tuple[tuple[float, float, float], ...]:
    """Four rotors on the diagonals at ``arm`` m, in rotorpy's order (front right first)."""
    d = arm
    return ((d * _DIAG, d * _DIAG, 0.0), (d * _DIAG, -d * _DIAG, 0.0),
            (-d * _DIAG, -d * _DIAG, 0.0), (-d * _DIAG, d * _DIAG, 0.0))


HUMMINGBIRD = Airframe(
    name="hummingbird",
    title="AscTec Hummingbird (rotorpy's parameter set)",
    mass=0.500, inertia=(3.65e-3, 3.68e-3, 7.03e-3, 0.0, 0.0, 0.0),
    arm_length=0.17, rotor_radius=0.10, rotor_pos=_x_rotors(0.17), rotor_directions=(1, -1, 1, -1),
    drag=(0.5e-2, 0.5e-2, 1e-2),
    k_eta=5.57e-06, k_m=1.36e-07, k_d=1.19e-04, k_z=2.32e-04, k_h=3.39e-3, k_flap=0.0,
    tau_m=0.005, rotor_speed_min=0.0, rotor_speed_max=1500.0,
    kp_att=544.0, kd_att=46.64,
    max_tilt_deg=45.0,
    sources=(
        "rotorpy 3.0 rotorpy/vehicles/hummingbird_params.py (all physical values and the attitude gains; "
        "its own sources: digitalrepository.unm.edu ece_etds 1189, IEEE Xplore 7991501)",
        "tilt limit: PX4 parameter MPC_TILTMAX_AIR, default 45 degrees",
    ),
)

_M300_ARM = 0.895 / 2  # half the published diagonal wheelbase
_M300_D = 21 * 0.0254  # 2110 propeller: 21 inch diameter
_M300_SCALE = _M300_D / 0.2  # propeller diameter against the Hummingbird's 8 inch

M300 = Airframe(
    name="m300",
    title="DJI Matrice 300 RTK-class inspection quadrotor",
    # Published: 6.3 kg with two TB60 batteries (maximum take-off weight 9 kg).
    mass=6.3,
    # Estimated: a 4.7 kg central box 0.35 x 0.25 x 0.20 m plus 0.4 kg (motor, propeller,
    # arm) at each rotor hub.
    inertia=(0.200, 0.224, 0.393, 0.0, 0.0, 0.0),
    arm_length=_M300_ARM, rotor_radius=_M300_D / 2, rotor_pos=_x_rotors(_M300_ARM),
    rotor_directions=(1, -1, 1, -1),
    # Parasitic drag: the Hummingbird's scaled by the propeller diameter squared (frontal area).
    drag=(0.5e-2 * _M300_SCALE**2, 0.5e-2 * _M300_SCALE**2, 1e-2 * _M300_SCALE**2),
    # Thrust: 2 x the maximum take-off weight (9 kg) at 5000 rpm (524 rad/s), the usual 2:1
    # design rule at the maximum take-off weight; DJI publishes none. Yaw moment: the
    # Hummingbird's k_m/k_eta scaled by the propeller diameter (Q/T ~ D at equal blade
    # coefficients).
    k_eta=2 * 9.0 * G / (4 * 523.6**2),
    k_m=2 * 9.0 * G / (4 * 523.6**2) * (1.36e-07 / 5.57e-06) * _M300_SCALE,
    # Rotor drag: chosen so that the model's top speed at the 30 degree tilt limit is the
    # published 23 m/s (Airframe.top_speed); induced inflow and translational lift keep the
    # Hummingbird's ratios to it and to the diameter squared.
    k_d=6.55e-04, k_z=6.55e-04 * (2.32e-04 / 1.19e-04), k_h=3.39e-3 * _M300_SCALE**2, k_flap=0.0,
    # Motor time constant: PX4 SIH's default SIH_T_TAU (0.05 s), for lack of a published one.
    tau_m=0.05, rotor_speed_min=0.0, rotor_speed_max=523.6,
    # Attitude gains: poles at -14 +- 2j rad/s, below the 20 rad/s of the motors. rotorpy
    # SE3Control's defaults (310, 57) leave a slow pole at -6 rad/s (tracking 10-30 % worse);
    # (900, 60) is unstable with 50 ms motors.
    kp_att=200.0, kd_att=28.0,
    max_tilt_deg=30.0,
    sources=(
        "DJI Matrice 300 RTK specifications (dji.com/matrice-300/specs): weight with two TB60 batteries "
        "approx. 6.3 kg, max takeoff weight 9 kg, diagonal wheelbase 895 mm, max speed 23 m/s (S mode), "
        "max pitch angle 30 degrees, propeller 2110",
        "estimates (no published figure): inertia, thrust and rotor speeds, drag, motor time constant; "
        "see the comments of staghunt.task.airframes.M300",
    ),
)

AIRFRAMES: dict[str, Airframe] = {a.name: a for a in (HUMMINGBIRD, M300)}
"""The airframes by name; the first is the default."""

AIRFRAME_NAMES: tuple[str, ...] = tuple(AIRFRAMES)
DEFAULT_AIRFRAME = HUMMINGBIRD.name
