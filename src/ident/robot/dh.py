"""Denavit-Hartenberg tables, both conventions, and their vectorized forward kinematics.

Two conventions are supported; row ``i`` (1-based joint ``i``) of a table holds ``a``, ``d``,
``alpha``, ``theta`` and the joint moves ``theta`` (revolute) or ``d`` (prismatic):

- ``standard`` (distal, Denavit-Hartenberg 1955 as in Spong):
  ``T_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``; DH frame ``i`` sits at the distal end of
  link ``i``, on the axis of joint ``i + 1``.
- ``modified`` (proximal, Craig): ``T_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i + q_i) Tz(d_i)``;
  row ``i`` stores ``a_{i-1}`` and ``alpha_{i-1}`` in its ``a`` and ``alpha`` columns, and DH frame
  ``i`` sits on the axis of joint ``i``.

In both, the joint motion ``J_i(q) = Rz(q)`` or ``Tz(q)`` commutes with ``Rz(theta_i) Tz(d_i)``, so
``T_i = J_i(q_i) F_i`` (standard) or ``T_i = G_i J_i(q_i)`` (modified) with fixed transforms
``F_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`` and ``G_i = Rx(alpha_{i-1}) Tx(a_{i-1})
Rz(theta_i) Tz(d_i)``. :func:`DHTable.elementary_steps` exposes these factors; the URDF writer
builds joint origins from them.

All lengths are in metres and angles in radians (configs are converted on load).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from ident.errors import ModelError

__all__ = [
    "CONVENTIONS",
    "JOINT_TYPES",
    "DHTable",
    "elementary_transform",
    "rot_x",
    "rot_z",
    "trans_x",
    "trans_z",
]

FloatArray = npt.NDArray[np.float64]
Convention = Literal["standard", "modified"]
JointType = Literal["revolute", "prismatic"]
Step = tuple[Literal["rz", "tz", "tx", "rx"], float]

CONVENTIONS: tuple[str, ...] = ("standard", "modified")
JOINT_TYPES: tuple[str, ...] = ("revolute", "prismatic")


def _rotation(angle: npt.ArrayLike, i: int, j: int) -> FloatArray:
    """Homogeneous rotations by ``angle`` [rad] turning axis ``i`` toward axis ``j``."""
    angle = np.atleast_1d(np.asarray(angle, dtype=float))
    c, s = np.cos(angle), np.sin(angle)
    out = np.broadcast_to(np.eye(4), (angle.shape[0], 4, 4)).copy()
    out[:, i, i], out[:, i, j] = c, -s
    out[:, j, i], out[:, j, j] = s, c
    return out


def _translation(distance: npt.ArrayLike, axis: int) -> FloatArray:
    """Homogeneous translations by ``distance`` [m] along ``axis``."""
    distance = np.atleast_1d(np.asarray(distance, dtype=float))
    out = np.broadcast_to(np.eye(4), (distance.shape[0], 4, 4)).copy()
    out[:, axis, 3] = distance
    return out


def rot_z(angle: npt.ArrayLike) -> FloatArray:
    """Homogeneous rotations about z.

    Parameters
    ----------
    angle :
        Angles [rad], shape (n_samples,) or scalar.

    Returns
    -------
    :
        Transforms of shape (n_samples, 4, 4) (a scalar gives n_samples = 1).
    """
    return _rotation(angle, 0, 1)


def rot_x(angle: npt.ArrayLike) -> FloatArray:
    """Homogeneous rotations about x, angles [rad] -> shape (n_samples, 4, 4)."""
    return _rotation(angle, 1, 2)


def trans_z(distance: npt.ArrayLike) -> FloatArray:
    """Homogeneous translations along z, distances [m] -> shape (n_samples, 4, 4)."""
    return _translation(distance, 2)


def trans_x(distance: npt.ArrayLike) -> FloatArray:
    """Homogeneous translations along x, distances [m] -> shape (n_samples, 4, 4)."""
    return _translation(distance, 0)


_ELEMENTARY = {"rz": rot_z, "rx": rot_x, "tz": trans_z, "tx": trans_x}


def elementary_transform(steps: list[Step] | tuple[Step, ...]) -> FloatArray:
    """Product of elementary steps ``[("rz", angle), ("tz", d), ...]`` as one (4, 4) transform."""
    out = np.eye(4)
    for kind, value in steps:
        out = out @ _ELEMENTARY[kind](value)[0]
    return out


@dataclass(frozen=True, eq=False)
class DHTable:
    """A Denavit-Hartenberg table in SI units.

    Attributes
    ----------
    convention :
        ``"standard"`` or ``"modified"`` (see the module docstring for the row semantics).
    a, d, alpha, theta :
        Columns of shape (n_joints,): lengths [m], angles [rad]. ``theta`` (revolute) or ``d``
        (prismatic) is the constant offset added to the joint variable.
    joint_types :
        ``"revolute"`` or ``"prismatic"`` per joint.
    """

    convention: Convention
    a: FloatArray
    d: FloatArray
    alpha: FloatArray
    theta: FloatArray
    joint_types: tuple[JointType, ...]

    def __post_init__(self) -> None:
        if self.convention not in CONVENTIONS:
            raise ModelError(
                f"DH convention {self.convention!r} is unknown; "
                f"use one of {', '.join(CONVENTIONS)}."
            )
        columns = {}
        for name in ("a", "d", "alpha", "theta"):
            value = np.array(getattr(self, name), dtype=float)
            if value.ndim != 1:
                raise ModelError(f"DH column {name!r} must be one-dimensional, got {value.shape}.")
            if not np.all(np.isfinite(value)):
                raise ModelError(f"DH column {name!r} has non-finite entries: {value.tolist()}.")
            value.setflags(write=False)
            columns[name] = value
            object.__setattr__(self, name, value)
        n_joints = len(self.joint_types)
        for name, value in columns.items():
            if value.shape[0] != n_joints:
                raise ModelError(
                    f"DH column {name!r} has {value.shape[0]} rows for {n_joints} joints; "
                    "give one row per joint."
                )
        for i, kind in enumerate(self.joint_types):
            if kind not in JOINT_TYPES:
                raise ModelError(
                    f"joint {i + 1} has type {kind!r}; use one of {', '.join(JOINT_TYPES)}."
                )
        if n_joints == 0:
            raise ModelError("a DH table needs at least one joint.")

    @property
    def n_joints(self) -> int:
        """Number of joints (rows)."""
        return len(self.joint_types)

    def fixed_steps(self, i: int) -> tuple[Step, ...]:
        """Elementary factors of the fixed part of link transform ``i`` (0-based).

        Standard: ``F_i = Rz(theta) Tz(d) Tx(a) Rx(alpha)`` (applied after the joint motion).
        Modified: ``G_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta) Tz(d)`` (applied before it).
        """
        a, d, alpha, theta = self.a[i], self.d[i], self.alpha[i], self.theta[i]
        if self.convention == "standard":
            return (("rz", theta), ("tz", d), ("tx", a), ("rx", alpha))
        return (("rx", alpha), ("tx", a), ("rz", theta), ("tz", d))

    def fixed_transform(self, i: int) -> FloatArray:
        """``F_i`` (standard) or ``G_i`` (modified) as a (4, 4) transform, ``i`` 0-based."""
        return elementary_transform(self.fixed_steps(i))

    def _joint_motion(self, i: int, qi: FloatArray) -> FloatArray:
        return rot_z(qi) if self.joint_types[i] == "revolute" else trans_z(qi)

    def link_transforms(self, q: npt.ArrayLike) -> FloatArray:
        """Transforms ``T_i`` from DH frame ``i - 1`` to DH frame ``i``.

        Parameters
        ----------
        q :
            Joint positions [rad or m], shape (n_samples, n_joints) or (n_joints,).

        Returns
        -------
        :
            Shape (n_samples, n_joints, 4, 4).
        """
        q = self._check_q(q)
        out = np.empty((q.shape[0], self.n_joints, 4, 4))
        for i in range(self.n_joints):
            fixed = self.fixed_transform(i)
            motion = self._joint_motion(i, q[:, i])
            if self.convention == "standard":
                out[:, i] = motion @ fixed
            else:
                out[:, i] = fixed @ motion
        return out

    def forward_kinematics(self, q: npt.ArrayLike) -> FloatArray:
        """Poses of DH frames ``0..n`` in the base frame (frame 0).

        Parameters
        ----------
        q :
            Joint positions [rad or m], shape (n_samples, n_joints) or (n_joints,).

        Returns
        -------
        :
            Shape (n_samples, n_joints + 1, 4, 4); index 0 is the identity and index ``n`` is the
            flange (DH frame n).
        """
        links = self.link_transforms(q)
        out = np.empty((links.shape[0], self.n_joints + 1, 4, 4))
        out[:, 0] = np.eye(4)
        for i in range(self.n_joints):
            out[:, i + 1] = out[:, i] @ links[:, i]
        return out

    def _check_q(self, q: npt.ArrayLike) -> FloatArray:
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != self.n_joints:
            raise ModelError(
                f"q must have shape (n_samples, {self.n_joints}) for this DH table, got {q.shape}."
            )
        return q
