"""Wrist stage of the paper: the flange traces eq. 16-17 + 19 on a sphere, eq. 20-23 give q4-q6.

The arm (joints 1-3) is held at ``arm_hold``, so the wrist centre ``c = (t14, t24, t34)``
(origin of DH frame 4, eq. 10) and the orientation ``R03`` of DH frame 3 are constant. The
traced point is the flange (DH frame 6 origin), which can only move on the sphere of radius
``d6`` about ``c``:

    Qx - t14 = d0 + A cos(P) + F(t),    Qy - t24 = e0 + A sin(P) + F(t)        (eq. 16-17)
    Qz - t34 = + sqrt(d6^2 - (Qx - t14)^2 - (Qy - t24)^2)                       (eq. 19)

``d0, e0`` are offsets from the wrist centre and ``f0 = t34`` (as in Table 2). Eq. 19 as printed
omits the y term; with it the point is exactly on the sphere, which is what eq. 20-22 need.
A point with ``(Qx - t14)^2 + (Qy - t24)^2 > d6^2`` is unreachable: it is clipped to the
equator (finite values) and reported as ``reachability`` relative to ``d6``.

Wrist angles (eq. 20-22): ``vec = c - Q`` (eq. 20) points from the flange to the wrist centre;
the flange direction ``z5 = -vec / d6`` expressed in DH frame 3, ``w = R03^T z5``, equals
``[-c4 s5, -s4 s5, c5]`` for the paper's wrist, so

    q5 = b atan2(hypot(wx, wy), wz),    q4 = atan2(-b wy, -b wx)

with the branch ``b = +-1`` (``s5`` positive or negative) chosen so that the top of the sphere
is reached with ``|q4|`` small. These are eq. 21-22 written in DH frame 3 (for the default hold,
frame 3's axes are the base's z, -y, x: the same atan2 of the same components up to the
frames' signs). Velocities and accelerations are exact derivatives.

Eq. 23 (q6): q6 does not move the flange; the paper sets it to the direction of the last
displacement of the traced point in the plane of ``vec``'s y and z components,
``q6(k) = atan2(vec_z(k) - vec_z(k-1), vec_y(k) - vec_y(k-1))``, and recommends taking the
last sample as the previous one of the first ("initial = last"): the differences are periodic.
The angles are unwrapped along the samples; if they wind (a net turn of ``2 pi m`` per period)
the periodic continuity constraint of joint 6 reports the jump ``2 pi m``. Being a direction,
eq. 23's angle is defined modulo 2 pi: the multiple of 2 pi that centres its range on 0 is
taken.

Taken literally (``theta6="eq23"``; ``dq6``, ``ddq6`` by periodic central differences) eq. 23
is not a motion a robot can follow: the projected displacement reverses whenever the path's y
velocity crosses zero, so q6 jumps by about pi between two samples (0 of 2000 random designs
in the paper's box meet the velocity limits of ``configs/paper6r.yaml``; joint 6 reaches
~4500 deg/s). The default ``theta6="eq23_smooth"`` keeps eq. 23's angle band-limited to the
path's own ``N`` harmonics (the winding trend ``2 pi m t / T`` kept, the rest truncated in the
Fourier domain), with exact spectral derivatives: about 30 % of random designs are then
feasible. ``theta6="hold"`` keeps joint 6 at its held position.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.excitation.family import FloatArray, TrajectoryBatch
from ident.excitation.ik import atan2_derivatives, hypot_derivatives, unwrap_samples
from ident.excitation.mfs import _PAPER_BOX, PAPER_N_HARMONICS, PAPER_PERIOD, _CartesianFamily

__all__ = [
    "THETA6_MODES",
    "PaperWristFamily",
    "band_limited",
    "sphere_point",
    "theta6_eq23",
    "wrist_angles",
]

THETA6_MODES = ("eq23_smooth", "eq23", "hold")

_EQUATOR = 1e-3  # smallest height above the equator, relative to the radius


def sphere_point(
    rel: FloatArray, drel: FloatArray, ddrel: FloatArray, radius: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Complete (x, y) offsets to a point on the upper half of a sphere (eq. 19).

    Parameters
    ----------
    rel, drel, ddrel :
        Offsets from the centre [m], their velocities and accelerations, shape (..., 3); the z
        entries are ignored.
    radius :
        Sphere radius [m].

    Returns
    -------
    :
        Offsets, velocities and accelerations with ``z = +sqrt(r^2 - x^2 - y^2)``, shapes
        (..., 3), and the excess ``max(hypot(x, y) - r, 0) / r``, shape (...).
    """
    x, y = rel[..., 0], rel[..., 1]
    dx, dy, ddx, ddy = drel[..., 0], drel[..., 1], ddrel[..., 0], ddrel[..., 1]
    h = radius**2 - x * x - y * y
    excess = np.where(h < 0.0, np.hypot(x, y) / radius - 1.0, 0.0)
    h = np.maximum(h, (_EQUATOR * radius) ** 2)
    dh = -2.0 * (x * dx + y * dy)
    ddh = -2.0 * (dx * dx + x * ddx + dy * dy + y * ddy)
    z = np.sqrt(h)
    dz = dh / (2.0 * z)
    ddz = ddh / (2.0 * z) - dh * dh / (4.0 * z**3)
    out = []
    for base, zz in ((rel, z), (drel, dz), (ddrel, ddz)):
        v = np.array(base, dtype=float, copy=True)
        v[..., 2] = zz
        out.append(v)
    return out[0], out[1], out[2], excess


def wrist_angles(
    w: FloatArray, dw: FloatArray, ddw: FloatArray, branch: int = 1
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """q4, q5 placing ``z5 = [-c4 s5, -s4 s5, c5]`` (DH frame 3) on the unit vector ``w``.

    Parameters
    ----------
    w, dw, ddw :
        Flange direction in DH frame 3 and its derivatives, shape (..., 3).
    branch :
        +1: ``sin(q5) >= 0``; -1: ``sin(q5) <= 0``.

    Returns
    -------
    :
        ``q, dq, ddq`` of joints 4 and 5 (DH angles, without offsets), each (..., 2).
    """
    if branch not in (1, -1):
        raise ValueError(f"branch must be +1 or -1, got {branch}")
    b = float(branch)
    q4 = atan2_derivatives(-b * w[..., 1], -b * dw[..., 1], -b * ddw[..., 1],
                           -b * w[..., 0], -b * dw[..., 0], -b * ddw[..., 0])  # fmt: skip
    rho = hypot_derivatives(w[..., 0], dw[..., 0], ddw[..., 0], w[..., 1], dw[..., 1], ddw[..., 1])
    q5 = atan2_derivatives(*rho, w[..., 2], dw[..., 2], ddw[..., 2])
    q45, dq45, ddq45 = (np.stack([a4, b * a5], axis=-1) for a4, a5 in zip(q4, q5, strict=True))
    return q45, dq45, ddq45


def theta6_eq23(
    vec: FloatArray, period: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Joint 6 from eq. 23 on a periodic sample grid, with the paper's "initial = last".

    Parameters
    ----------
    vec :
        ``vec = c - Q`` of eq. 20 at the samples ``t_k = k T / n``, shape (n_particles, n, 3).
    period :
        Period ``T`` [s].

    Returns
    -------
    :
        ``q6`` (unwrapped) [rad], ``dq6`` [rad/s], ``ddq6`` [rad/s^2], shape (n_particles, n),
        and the winding ``q6(T) - q6(0) = 2 pi m`` [rad], shape (n_particles,).
    """
    n = vec.shape[1]
    dt = period / n
    delta = vec - np.roll(vec, 1, axis=1)  # sample 0 uses the last sample (initial = last)
    angle = np.arctan2(delta[..., 2], delta[..., 1])
    closed = unwrap_samples(np.concatenate([angle, angle[:, :1]], axis=1))
    winding = closed[:, -1] - closed[:, 0]
    q6 = closed[:, :-1]
    trend = winding[:, None] * (np.arange(n) / n)
    periodic = q6 - trend
    dq6 = (np.roll(periodic, -1, axis=1) - np.roll(periodic, 1, axis=1)) / (2 * dt)
    dq6 = dq6 + winding[:, None] / period
    ddq6 = (np.roll(periodic, -1, axis=1) - 2 * periodic + np.roll(periodic, 1, axis=1)) / dt**2
    return q6, dq6, ddq6, winding


def band_limited(
    q: FloatArray, winding: FloatArray, period: float, n_harmonics: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Truncate a periodic-plus-trend signal to its first harmonics; exact derivatives.

    Parameters
    ----------
    q :
        Samples at ``t_k = k T / n``, shape (n_particles, n).
    winding :
        ``q(T) - q(0)`` [rad], shape (n_particles,): the linear trend ``winding * t / T`` is
        kept, the periodic rest is truncated to harmonics ``0..n_harmonics``.
    period :
        ``T`` [s].
    n_harmonics :
        Highest harmonic kept.

    Returns
    -------
    :
        ``q, dq, ddq`` of the band-limited signal, each (n_particles, n).
    """
    n = q.shape[1]
    trend = winding[:, None] * (np.arange(n) / n)
    spectrum = np.fft.rfft(q - trend, axis=1)
    spectrum[:, n_harmonics + 1 :] = 0.0
    k = np.arange(spectrum.shape[1]) * (2.0 * np.pi / period)
    smooth = np.fft.irfft(spectrum, n, axis=1) + trend
    dsmooth = np.fft.irfft(1j * k * spectrum, n, axis=1) + winding[:, None] / period
    ddsmooth = np.fft.irfft(-(k**2) * spectrum, n, axis=1)
    return smooth, dsmooth, ddsmooth


class PaperWristFamily(_CartesianFamily):
    """Wrist stage of the paper: the flange moves on the sphere about the held wrist centre.

    Parameters
    ----------
    robot :
        An :class:`ident.Robot` built from a DH config of the paper's structure.
    n_samples :
        Samples per period (default 500: 50 Hz over 10 s).
    period :
        Period ``T`` [s] (default 10 s; fundamental frequency 0.6283 rad/s).
    n_harmonics :
        ``N`` (default 3).
    length_unit :
        Metres per unit of the design variables (default 1e-3: millimetres, Table 2).
    arm_hold :
        Positions [rad] at which joints 1-3 are held. Default ``(0, 0, -pi/2)``: the forearm
        horizontal along the base x axis, so that eq. 21-23 (atan2 of the y and z components)
        are angles about the forearm, as in the paper.
    wrist_branch :
        Branch of q5's sign (+1 or -1); default: the one reaching the top of the sphere with
        the smaller ``|q4|`` (-1 for the default hold).
    theta6 :
        How joint 6 moves: ``"eq23_smooth"`` (default), ``"eq23"`` (literal) or ``"hold"``
        (see the module docstring).
    bounds :
        Search box (n_vars, 2) in ``length_unit``; default ``a0``, ``b0`` in [-10, 10] and
        ``c0``, ``d0``, ``e0`` in [0, 10] (the paper's +-10 box, "a and b span negative and
        positive limits, others positive").

    Notes
    -----
    Variables: ``a0(1..N)``, ``b0(1..N)``, ``c0``, ``d0``, ``e0`` (Table 2; ``f0 = t34``).
    """

    traced_frame = "flange"
    moving_joints = (3, 4, 5)
    with_f0 = False
    fourier_z = False

    def __init__(
        self,
        robot: Any,
        *,
        n_samples: int = 500,
        period: float = PAPER_PERIOD,
        n_harmonics: int = PAPER_N_HARMONICS,
        length_unit: float = 1e-3,
        arm_hold: npt.ArrayLike = (0.0, 0.0, -np.pi / 2),
        wrist_branch: int | None = None,
        theta6: str = "eq23_smooth",
        bounds: npt.ArrayLike | None = None,
    ) -> None:
        super().__init__(
            robot,
            n_samples=n_samples,
            period=period,
            n_harmonics=n_harmonics,
            length_unit=length_unit,
            default_bounds=_PAPER_BOX,
            bounds=bounds,
            hold=arm_hold,
            hold_name="arm_hold",
        )
        if theta6 not in THETA6_MODES:
            raise ValueError(f"theta6 must be one of {', '.join(THETA6_MODES)}, got {theta6!r}")
        self.theta6 = theta6
        hold = self.held_positions[:3]
        self.wrist_centre = self.geometry.wrist_centre(hold)
        self.rotation_0_3 = self.geometry.rotation_0_3(hold)
        if wrist_branch is None:
            top = self.rotation_0_3.T @ np.array([0.0, 0.0, 1.0])
            q4 = [np.arctan2(-b * top[1], -b * top[0]) for b in (1, -1)]
            wrist_branch = 1 if abs(q4[0]) <= abs(q4[1]) else -1
        if wrist_branch not in (1, -1):
            raise ValueError(f"wrist_branch must be +1 or -1, got {wrist_branch}")
        self.wrist_branch = int(wrist_branch)

    def path(self, x: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Flange offsets from the wrist centre on the extended grid (n_particles, n + 1, 3).

        Returns
        -------
        :
            Offsets [m], velocities [m/s], accelerations [m/s^2] and the reachability excess
            per sample, shape (n_particles, n + 1).
        """
        return sphere_point(*self._cartesian_path(x), self.geometry.d6)

    def trajectories(self, x: npt.ArrayLike) -> TrajectoryBatch:
        """Trajectories of a swarm; ``x`` of shape (n_particles, n_vars) in ``length_unit``."""
        rel, drel, ddrel, excess = self.path(x)
        d6 = self.geometry.d6
        rot = self.rotation_0_3
        w, dw, ddw = (v @ rot / d6 for v in (rel, drel, ddrel))  # R^T v per sample
        q45, dq45, ddq45 = wrist_angles(w, dw, ddw, self.wrist_branch)
        q45 = unwrap_samples(q45 - np.asarray(self.geometry.offsets[3:5]))
        n = self.n_samples
        q6, dq6, ddq6, winding = theta6_eq23(-rel[:, :n], self.period)
        if self.theta6 == "eq23_smooth":
            q6, dq6, ddq6 = band_limited(q6, winding, self.period, self.n_harmonics)
        elif self.theta6 == "hold":
            q6 = np.full_like(q6, self.held_positions[5] + self.geometry.offsets[5])
            dq6, ddq6, winding = np.zeros_like(q6), np.zeros_like(q6), np.zeros_like(winding)
        q6 = q6 - self.geometry.offsets[5]
        if self.theta6 != "hold":  # eq. 23 is an angle modulo 2 pi: centre its range on 0
            mid = 0.5 * (q6.max(axis=1) + q6.min(axis=1))
            q6 = q6 - 2.0 * np.pi * np.round(mid / (2.0 * np.pi))[:, None]
        q_ext = np.concatenate(
            [q45, np.append(q6, q6[:, :1] + winding[:, None], axis=1)[..., None]], -1
        )
        dq_ext = np.concatenate([dq45, np.append(dq6, dq6[:, :1], axis=1)[..., None]], -1)
        ddq_ext = np.concatenate([ddq45, np.append(ddq6, ddq6[:, :1], axis=1)[..., None]], -1)
        traced = self.wrist_centre + rel
        return self._assemble(q_ext, dq_ext, ddq_ext, q_ext[:, -1], traced, excess.max(axis=1))
