"""Closed-form kinematics of the paper's arm (3R with offsets) and spherical wrist.

The paper robot (Table 1, standard DH ``T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``) has
``alpha = (-pi/2, 0, -pi/2, pi/2, -pi/2, 0)``, ``d2 = d3 = d5 = 0`` and ``a4 = a5 = a6 = 0``:
joints 4-6 intersect at the *wrist centre* (origin of DH frames 4 and 5), which joints 1-3
alone position, and the flange (origin of DH frame 6) lies at ``d6`` from the wrist centre
along ``z5``. With ``theta_i = q_i + offset_i``, ``L = hypot(a3, d4)``,
``gamma = atan2(d4, a3)``:

    u = a2 cos(theta2) + L cos(theta2 + theta3 + gamma)
    v = a2 sin(theta2) + L sin(theta2 + theta3 + gamma)
    p_wc = [cos(theta1) (a1 + u), sin(theta1) (a1 + u), d1 - v]

and the flange direction in DH frame 3 is ``z5 = [-c4 s5, -s4 s5, c5]``.

Inverse kinematics (front shoulder, elbow branch ``e = +-1``):
``theta1 = atan2(y, x)``, ``u = hypot(x, y) - a1``, ``v = d1 - z``,
``cos(theta3 + gamma) = (u^2 + v^2 - a2^2 - L^2) / (2 a2 L)``, ``theta3 + gamma = e acos(.)``,
``theta2 = atan2(v, u) - atan2(L sin(theta3 + gamma), a2 + L cos(theta3 + gamma))``.
Velocities and accelerations follow exactly from the derivatives of these relations (no finite
differences). Unreachable points are clipped to the workspace boundary, so the joint values
stay finite, and reported as a dimensionless excess distance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ident.errors import ModelError
from ident.excitation.family import FloatArray

__all__ = [
    "ArmGeometry",
    "ArmSolution",
    "arm_inverse_kinematics",
    "atan2_derivatives",
    "hypot_derivatives",
    "unwrap_samples",
]

_PAPER_ALPHA = np.array([-np.pi / 2, 0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0])
_SINGULAR = 1e-9


def atan2_derivatives(
    y: FloatArray, dy: FloatArray, ddy: FloatArray, x: FloatArray, dx: FloatArray, ddx: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``theta = atan2(y, x)`` and its first two time derivatives (exact).

    ``theta' = (x y' - y x') / r^2``,
    ``theta'' = (x y'' - y x'') / r^2 - 2 (x y' - y x') (x x' + y y') / r^4``, ``r^2 = x^2 + y^2``
    (clipped away from 0 so the result stays finite).
    """
    r2 = np.maximum(x * x + y * y, _SINGULAR**2)
    cross = x * dy - y * dx
    theta = np.arctan2(y, x)
    dtheta = cross / r2
    ddtheta = (x * ddy - y * ddx) / r2 - 2.0 * cross * (x * dx + y * dy) / (r2 * r2)
    return theta, dtheta, ddtheta


def unwrap_samples(p: FloatArray) -> FloatArray:
    """``np.unwrap(p, axis=1)``, bit for bit, for angles of shape (n_particles, n_samples, ...).

    The same formula, with the wrapping correction (``np.mod``, the slow part) computed only
    at the jumps of at least ``pi`` (elsewhere it is 0): a smooth sampled angle has few.
    """
    p = np.asarray(p, dtype=float)
    dd = np.diff(p, axis=1)
    correction = np.zeros_like(dd)
    jump = ~(np.abs(dd) < np.pi)  # np.unwrap keeps the NaN of a NaN step
    if jump.any():
        d = dd[jump]
        ddmod = np.mod(d + np.pi, 2.0 * np.pi) - np.pi
        ddmod = np.where((ddmod == -np.pi) & (d > 0), np.pi, ddmod)
        correction[jump] = ddmod - d
    out = p.copy()
    out[:, 1:] = p[:, 1:] + np.cumsum(correction, axis=1)
    return out


def hypot_derivatives(
    x: FloatArray, dx: FloatArray, ddx: FloatArray, y: FloatArray, dy: FloatArray, ddy: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``r = hypot(x, y)`` and its first two time derivatives (exact, r clipped away from 0)."""
    r = np.maximum(np.hypot(x, y), _SINGULAR)
    dr = (x * dx + y * dy) / r
    ddr = (dx * dx + dy * dy + x * ddx + y * ddy) / r - dr * dr / r
    return r, dr, ddr


@dataclass(frozen=True)
class ArmGeometry:
    """Lengths [m] and joint offsets [rad] of a paper-type 6R arm (see the module docstring).

    Attributes
    ----------
    a1, d1, a2, a3, d4, d6 :
        DH lengths [m].
    offsets :
        Constant DH joint-angle offsets ``theta_i - q_i`` [rad], shape (6,).
    """

    a1: float
    d1: float
    a2: float
    a3: float
    d4: float
    d6: float
    offsets: tuple[float, ...] = (0.0,) * 6

    @classmethod
    def from_dh(cls, dh: Any) -> ArmGeometry:
        """Geometry from a standard DH table (:class:`ident.robot.dh.DHTable`).

        Raises
        ------
        ModelError
            If the table is not a 6R standard-DH arm of the paper's structure (the message
            names the first mismatch and suggests the joint-space Fourier family).
        """
        if dh is None:
            raise ModelError(
                "the paper's Cartesian excitation needs a DH table (a robot config, not a URDF); "
                "use the joint_fourier family for this robot."
            )
        hint = "; use the joint_fourier family for this robot."
        if dh.convention != "standard" or dh.n_joints != 6:
            raise ModelError(
                f"the paper's arm inverse kinematics needs a 6-joint standard DH table, got "
                f"{dh.n_joints} joints, {dh.convention} convention{hint}"
            )
        if any(kind != "revolute" for kind in dh.joint_types):
            raise ModelError(f"the paper's arm has revolute joints only{hint}")
        alpha = np.asarray(dh.alpha, dtype=float)
        if not np.allclose(alpha, _PAPER_ALPHA, atol=1e-9):
            raise ModelError(
                f"DH alpha = {np.round(np.degrees(alpha), 3).tolist()} deg; the paper's arm has "
                f"(-90, 0, -90, 90, -90, 0){hint}"
            )
        a, d = np.asarray(dh.a, dtype=float), np.asarray(dh.d, dtype=float)
        for name, value in (("d2", d[1]), ("d3", d[2]), ("d5", d[4]), ("a4", a[3]), ("a5", a[4])):
            if abs(value) > 1e-12:
                raise ModelError(f"DH {name} = {value} m must be 0 for a spherical wrist{hint}")
        if abs(a[5]) > 1e-12:
            raise ModelError(f"DH a6 = {a[5]} m must be 0 (flange on the wrist axis){hint}")
        if a[1] <= 0.0 or np.hypot(a[2], d[3]) <= 0.0 or d[5] <= 0.0:
            raise ModelError(f"DH a2, hypot(a3, d4) and d6 must be > 0{hint}")
        return cls(
            a1=float(a[0]),
            d1=float(d[0]),
            a2=float(a[1]),
            a3=float(a[2]),
            d4=float(d[3]),
            d6=float(d[5]),
            offsets=tuple(float(v) for v in dh.theta),
        )

    @property
    def forearm(self) -> float:
        """Distance from elbow (frame 2 origin) to the wrist centre, ``hypot(a3, d4)`` [m]."""
        return float(np.hypot(self.a3, self.d4))

    @property
    def gamma(self) -> float:
        """Angle of the forearm in DH frame 3's x-y plane, ``atan2(d4, a3)`` [rad]."""
        return float(np.arctan2(self.d4, self.a3))

    def wrist_centre(self, q_arm: FloatArray) -> FloatArray:
        """Wrist-centre position [m], shape (..., 3), from ``q_arm`` (..., 3) [rad]."""
        th = np.asarray(q_arm, dtype=float) + np.asarray(self.offsets[:3])
        u = self.a2 * np.cos(th[..., 1]) + self.forearm * np.cos(
            th[..., 1] + th[..., 2] + self.gamma
        )
        v = self.a2 * np.sin(th[..., 1]) + self.forearm * np.sin(
            th[..., 1] + th[..., 2] + self.gamma
        )
        rho = self.a1 + u
        return np.stack([np.cos(th[..., 0]) * rho, np.sin(th[..., 0]) * rho, self.d1 - v], axis=-1)

    def rotation_0_3(self, q_arm: FloatArray) -> FloatArray:
        """Orientation of DH frame 3 in the base, shape (..., 3, 3), from ``q_arm`` (..., 3)."""
        th = np.asarray(q_arm, dtype=float) + np.asarray(self.offsets[:3])
        c1, s1 = np.cos(th[..., 0]), np.sin(th[..., 0])
        c23, s23 = np.cos(th[..., 1] + th[..., 2]), np.sin(th[..., 1] + th[..., 2])
        # Rz(theta1) Rx(-pi/2) Rz(theta2 + theta3) Rx(-pi/2)
        col_x = np.stack([c1 * c23, s1 * c23, -s23], axis=-1)
        col_y = np.stack([s1 * np.ones_like(c23), -c1 * np.ones_like(c23), 0.0 * c23], axis=-1)
        col_z = np.stack([-c1 * s23, -s1 * s23, -c23], axis=-1)
        return np.stack([col_x, col_y, col_z], axis=-1)

    def flange_direction_3(self, q_wrist: FloatArray) -> FloatArray:
        """Unit vector ``z5`` in DH frame 3, shape (..., 3), from ``q_wrist`` (..., 3) [rad]."""
        th = np.asarray(q_wrist, dtype=float) + np.asarray(self.offsets[3:])
        s5 = np.sin(th[..., 1])
        return np.stack(
            [-np.cos(th[..., 0]) * s5, -np.sin(th[..., 0]) * s5, np.cos(th[..., 1])], -1
        )

    def flange(self, q: FloatArray) -> FloatArray:
        """Flange (DH frame 6 origin) position [m], shape (..., 3), from ``q`` (..., 6)."""
        q = np.asarray(q, dtype=float)
        r03 = self.rotation_0_3(q[..., :3])
        z5 = np.einsum("...ij,...j->...i", r03, self.flange_direction_3(q[..., 3:]))
        return self.wrist_centre(q[..., :3]) + self.d6 * z5


@dataclass(frozen=True, eq=False)
class ArmSolution:
    """Joint motion of joints 1-3 for a wrist-centre path.

    Attributes
    ----------
    q, dq, ddq :
        [rad, rad/s, rad/s^2], shape (..., 3).
    excess :
        Distance of each point outside the reachable shell, relative to ``a2 + L``, shape
        (...,); 0 where reachable.
    """

    q: FloatArray
    dq: FloatArray
    ddq: FloatArray
    excess: FloatArray


def arm_inverse_kinematics(
    geometry: ArmGeometry,
    p: FloatArray,
    dp: FloatArray | None = None,
    ddp: FloatArray | None = None,
    *,
    elbow: int = 1,
) -> ArmSolution:
    """Joints 1-3 placing the wrist centre on ``p``, with exact velocities and accelerations.

    Parameters
    ----------
    geometry :
        Arm geometry.
    p, dp, ddp :
        Wrist-centre position [m], velocity [m/s] and acceleration [m/s^2] in the base frame,
        shape (..., 3); ``dp``, ``ddp`` default to 0.
    elbow :
        Elbow branch: ``+1`` gives ``theta3 + gamma`` in ``[0, pi]`` (for the paper robot,
        ``q3`` in [-90, 90] deg, inside its range [-110, 70] deg for most points), ``-1`` the
        other one.

    Returns
    -------
    :
        The joint motion (``atan2`` results are in ``(-pi, pi]``: unwrap along the samples) and
        the reachability excess.
    """
    if elbow not in (1, -1):
        raise ValueError(f"elbow must be +1 or -1, got {elbow}")
    p = np.asarray(p, dtype=float)
    dp = np.zeros_like(p) if dp is None else np.asarray(dp, dtype=float)
    ddp = np.zeros_like(p) if ddp is None else np.asarray(ddp, dtype=float)
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    th1, dth1, ddth1 = atan2_derivatives(y, dp[..., 1], ddp[..., 1], x, dp[..., 0], ddp[..., 0])
    r, dr, ddr = hypot_derivatives(x, dp[..., 0], ddp[..., 0], y, dp[..., 1], ddp[..., 1])
    u, du, ddu = r - geometry.a1, dr, ddr
    v, dv, ddv = geometry.d1 - z, -dp[..., 2], -ddp[..., 2]
    a2, length = geometry.a2, geometry.forearm
    th2, dth2, ddth2, beta, dphi, ddphi, excess = _shoulder_elbow(
        (u, du, ddu), (v, dv, ddv), a2, length, elbow
    )
    th3 = beta - geometry.gamma
    offsets = np.asarray(geometry.offsets[:3])
    q = np.stack([th1, th2, th3], axis=-1) - offsets
    q = (q + np.pi) % (2.0 * np.pi) - np.pi
    dq = np.stack([dth1, dth2, dphi - dth2], axis=-1)
    ddq = np.stack([ddth1, ddth2, ddphi - ddth2], axis=-1)
    return ArmSolution(q=q, dq=dq, ddq=ddq, excess=excess / (a2 + length))


def _shoulder_elbow(
    u_motion: tuple[FloatArray, FloatArray, FloatArray],
    v_motion: tuple[FloatArray, FloatArray, FloatArray],
    a2: float,
    length: float,
    elbow: int,
) -> tuple[FloatArray, ...]:
    """Planar two-link inverse kinematics of the wrist centre (u, v) [m] with its first and
    second derivatives, links ``a2`` and ``length`` [m]: theta2, its derivatives, beta =
    theta3 + gamma, the forearm angle phi's derivatives, and the reachability excess [m]."""
    u, du, ddu = u_motion
    v, dv, ddv = v_motion
    rho = np.hypot(u, v)
    excess = np.maximum(np.maximum(rho - (a2 + length), abs(a2 - length) - rho), 0.0)
    cos_beta = np.clip((rho * rho - a2 * a2 - length * length) / (2.0 * a2 * length), -1.0, 1.0)
    beta = elbow * np.arccos(cos_beta)  # theta3 + gamma
    sin_beta = np.sin(beta)
    th2 = np.arctan2(v, u) - np.arctan2(length * sin_beta, a2 + length * np.cos(beta))
    phi = th2 + beta  # absolute angle of the forearm in the (u, v) plane
    c2, s2, cp, sp = np.cos(th2), np.sin(th2), np.cos(phi), np.sin(phi)
    det = a2 * length * sin_beta
    det = np.where(np.abs(det) < _SINGULAR, np.where(det < 0.0, -_SINGULAR, _SINGULAR), det)
    # J = [[-a2 s2, -L sp], [a2 c2, L cp]] maps (dtheta2, dphi) to (du, dv)
    dth2 = (length * cp * du + length * sp * dv) / det
    dphi = (-a2 * c2 * du - a2 * s2 * dv) / det
    rhs_u = ddu + a2 * c2 * dth2**2 + length * cp * dphi**2
    rhs_v = ddv + a2 * s2 * dth2**2 + length * sp * dphi**2
    ddth2 = (length * cp * rhs_u + length * sp * rhs_v) / det
    ddphi = (-a2 * c2 * rhs_u - a2 * s2 * rhs_v) / det
    return th2, dth2, ddth2, beta, dphi, ddphi, excess
