"""Joint-space finite Fourier series excitation (Swevers, Ganseman et al. 1997).

Each moving joint ``i`` follows

    q_i(t) = q0_i + sum_{l=1..N} [ a_il / (w l) sin(w l t) - b_il / (w l) cos(w l t) ]
    dq_i(t) = sum_l [ a_il cos(w l t) + b_il sin(w l t) ]
    ddq_i(t) = sum_l w l [ -a_il sin(w l t) + b_il cos(w l t) ]

with fundamental frequency ``w`` [rad/s] and period ``T = 2 pi / w``. It is periodic by
construction. Zero velocity and acceleration at both ends (``t = 0`` and ``t = T``, the same
instant of the periodic motion), so the robot can start from and return to rest, are imposed by
eliminating the first harmonic:

    dq_i(0) = sum_l a_il = 0        =>  a_i1 = -sum_{l>=2} a_il
    ddq_i(0) = w sum_l l b_il = 0   =>  b_i1 = -sum_{l>=2} l b_il

Design variables per moving joint (``2 N - 1`` of them): ``q0[<joint>]`` [rad] (the mean
position), ``a<l>[<joint>]`` and ``b<l>[<joint>]`` for ``l = 2..N`` [rad/s] (velocity
amplitudes).
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.excitation.constraints import JointLimits, evaluate_constraints
from ident.excitation.family import FloatArray, TrajectoryBatch, check_design, sample_times

__all__ = ["JointFourierFamily", "fourier_series", "resolve_joints"]


def resolve_joints(joint_names: Sequence[str], joints: Sequence[int | str]) -> tuple[int, ...]:
    """Joint indices (0-based) from indices or names.

    Raises
    ------
    ValueError
        For an unknown name or an index out of range; the message lists the valid names.
    """
    out = []
    for j in joints:
        if isinstance(j, str):
            if j not in joint_names:
                raise ValueError(f"unknown joint {j!r}; the robot has {', '.join(joint_names)}")
            out.append(list(joint_names).index(j))
        else:
            if not 0 <= int(j) < len(joint_names):
                raise ValueError(f"joint index {j} out of range 0..{len(joint_names) - 1}")
            out.append(int(j))
    if len(set(out)) != len(out):
        raise ValueError(f"moving joints repeat: {list(joints)}")
    return tuple(out)


def fourier_series(
    t: FloatArray, a: FloatArray, b: FloatArray, q0: FloatArray, omega: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Evaluate the finite Fourier series and its derivatives.

    Parameters
    ----------
    t :
        Times [s], shape (n_samples,).
    a, b :
        Velocity amplitudes [rad/s] of harmonics ``1..N``, shape (n_particles, n_joints, N).
    q0 :
        Offsets [rad], shape (n_particles, n_joints).
    omega :
        Fundamental frequency [rad/s].

    Returns
    -------
    :
        ``q, dq, ddq`` [rad, rad/s, rad/s^2], each of shape (n_particles, n_samples, n_joints).
    """
    n_harm = a.shape[-1]
    wl = omega * np.arange(1, n_harm + 1)  # (N,)
    phase = np.outer(t, wl)  # (n_samples, N)
    s, c = np.sin(phase), np.cos(phase)
    q = q0[:, None, :] + np.einsum("sl,pjl->psj", s, a / wl) - np.einsum("sl,pjl->psj", c, b / wl)
    dq = np.einsum("sl,pjl->psj", c, a) + np.einsum("sl,pjl->psj", s, b)
    ddq = np.einsum("sl,pjl->psj", c, b * wl) - np.einsum("sl,pjl->psj", s, a * wl)
    return q, dq, ddq


class JointFourierFamily:
    """Joint-space Fourier-series trajectories of some joints, the others held.

    Parameters
    ----------
    robot :
        An :class:`ident.Robot` (uses ``joint_names``, ``q_lower``, ``q_upper``, ``dq_max``,
        ``ddq_max``).
    moving_joints :
        Joints that move (indices or names).
    n_harmonics :
        Number of harmonics ``N`` (>= 2; the first one is eliminated by the rest conditions).
    base_frequency :
        Fundamental frequency ``w`` [rad/s]; period ``T = 2 pi / w``. Default 2 pi / 10 s (the
        paper's 0.6283 rad/s).
    n_samples :
        Samples per period; sample times ``t_k = k T / n_samples``, ``k = 0..n_samples-1``.
    held_positions :
        Positions of all joints [rad], shape (nq,); entries of the held joints are used.
        Default: 0 clipped into the position limits.
    amplitude_bound :
        Bound of the ``a``, ``b`` coefficients [rad/s], scalar or one per moving joint.
        Default: half the velocity limit of each joint (1 rad/s where unknown).

    Notes
    -----
    Bounds of ``q0`` are the joint's position limits (``[-pi, pi]`` where unknown).
    """

    traced_frame: str | None = None

    def __init__(
        self,
        robot: Any,
        moving_joints: Sequence[int | str],
        n_harmonics: int = 5,
        base_frequency: float = 2.0 * np.pi / 10.0,
        *,
        n_samples: int = 500,
        held_positions: npt.ArrayLike | None = None,
        amplitude_bound: float | npt.ArrayLike | None = None,
    ) -> None:
        if n_harmonics < 2:
            raise ValueError(f"n_harmonics must be >= 2 (rest conditions), got {n_harmonics}")
        if not base_frequency > 0.0:
            raise ValueError(f"base_frequency must be > 0 rad/s, got {base_frequency}")
        if n_samples < 2 * n_harmonics + 1:
            raise ValueError(f"n_samples must be >= {2 * n_harmonics + 1}, got {n_samples}")
        self.limits = JointLimits.from_robot(robot)
        self.joint_names = self.limits.joint_names
        self.moving_joints = resolve_joints(self.joint_names, moving_joints)
        self.n_harmonics = int(n_harmonics)
        self.base_frequency = float(base_frequency)
        self.period = 2.0 * np.pi / self.base_frequency
        self.n_samples = int(n_samples)
        self.t = sample_times(self.n_samples, self.period)
        lower, upper = self.limits.finite_position_box()
        if held_positions is None:
            held = np.clip(np.zeros(self.limits.nq), lower, upper)
        else:
            held = np.asarray(held_positions, dtype=float).copy()
            if held.shape != (self.limits.nq,):
                raise ValueError(
                    f"held_positions must have shape ({self.limits.nq},), got {held.shape}"
                )
        held.setflags(write=False)
        self.held_positions = held
        moving = list(self.moving_joints)
        if amplitude_bound is None:
            dq_max = self.limits.dq_max[moving]
            amp = np.where(np.isfinite(dq_max), 0.5 * dq_max, 1.0)
        else:
            amp = np.broadcast_to(np.asarray(amplitude_bound, dtype=float), (len(moving),))
        names: list[str] = []
        rows: list[tuple[float, float]] = []
        for k, j in enumerate(moving):
            joint = self.joint_names[j]
            names.append(f"q0[{joint}]")
            rows.append((lower[j], upper[j]))
            for kind in ("a", "b"):
                for h in range(2, self.n_harmonics + 1):
                    names.append(f"{kind}{h}[{joint}]")
                    rows.append((-amp[k], amp[k]))
        self.variable_names = tuple(names)
        self.bounds = np.array(rows, dtype=float)

    def with_samples(self, n_samples: int) -> JointFourierFamily:
        """The same family (bounds, held joints, variables) sampled ``n_samples`` times per period.

        Used to evaluate a design at a controller's rate in closed form.
        """
        if n_samples < 2 * self.n_harmonics + 1:
            raise ValueError(f"n_samples must be >= {2 * self.n_harmonics + 1}, got {n_samples}")
        clone = copy.copy(self)
        clone.n_samples = int(n_samples)
        clone.t = sample_times(clone.n_samples, self.period)
        return clone

    def coefficients(self, x: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Full coefficient arrays from design vectors.

        Parameters
        ----------
        x :
            Design, shape (n_particles, n_vars).

        Returns
        -------
        :
            ``a, b`` [rad/s] of shape (n_particles, n_moving, N) (first harmonic from the rest
            conditions) and ``q0`` [rad] of shape (n_particles, n_moving).
        """
        x = check_design(x, len(self.variable_names))
        n_h = self.n_harmonics
        per_joint = x.reshape(x.shape[0], len(self.moving_joints), 2 * n_h - 1)
        q0 = per_joint[:, :, 0]
        a_free = per_joint[:, :, 1:n_h]
        b_free = per_joint[:, :, n_h:]
        harmonics = np.arange(2, n_h + 1)
        a1 = -a_free.sum(axis=2, keepdims=True)
        b1 = -(b_free * harmonics).sum(axis=2, keepdims=True)
        return np.concatenate([a1, a_free], axis=2), np.concatenate([b1, b_free], axis=2), q0

    def _states(self, x: FloatArray, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        a, b, q0 = self.coefficients(x)
        qm, dqm, ddqm = fourier_series(t, a, b, q0, self.base_frequency)
        shape = (x.shape[0], t.shape[0], self.limits.nq)
        q = np.broadcast_to(self.held_positions, shape).copy()
        dq = np.zeros(shape)
        ddq = np.zeros(shape)
        moving = list(self.moving_joints)
        q[:, :, moving] = qm
        dq[:, :, moving] = dqm
        ddq[:, :, moving] = ddqm
        return q, dq, ddq

    def trajectories(self, x: npt.ArrayLike) -> TrajectoryBatch:
        """Trajectories of a swarm.

        Parameters
        ----------
        x :
            Design, shape (n_particles, n_vars) or (n_vars,).

        Returns
        -------
        :
            Joint states over one period and the constraint report (limits and continuity).
        """
        x = check_design(x, len(self.variable_names))
        q, dq, ddq = self._states(x, self.t)
        ends = self._states(x, np.array([0.0, self.period]))
        violations = evaluate_constraints(
            q,
            dq,
            ddq,
            self.limits,
            start=tuple(s[:, 0] for s in ends),
            end=tuple(s[:, 1] for s in ends),
        )
        return TrajectoryBatch(
            t=self.t.copy(),
            q=q,
            dq=dq,
            ddq=ddq,
            traced_points=None,
            violations=violations,
            joint_names=self.joint_names,
        )
