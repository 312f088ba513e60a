"""The paper's Cartesian modified Fourier series (eq. 16-18) and its arm-stage family.

Eq. 16-18 (N harmonics, fundamental frequency ``w = 2 pi / T``, the circle parameter
``P = w t`` running from 0 to 2 pi over the period ``T``):

    Qx(t) = d0 + A cos(P) + F(t)
    Qy(t) = e0 + A sin(P) + F(t)
    Qz(t) = f0 + F(t)                                     (eq. 18, arm stage)
    F(t)  = sum_{j=1..N} [ b0_j / (w j) sin(w j t) - c0 / (w j) cos(w j t) ]

with ``A = sum_j a0_j`` (eq. 16-17 multiply every harmonic's ``a0_j`` by the same ``cos(P)``,
so only the sum, the circle radius, matters) and one ``c0`` for all harmonics (Tables 2-3 list
a single ``c0``). The same Fourier term ``F`` is added to the three coordinates, as printed.
Everything is periodic with period ``T``: position, velocity and acceleration are continuous
when the motion repeats (eq. 24).

Units: the design variables are lengths (``a0``, ``d0``, ``e0``, ``f0``) and velocities
(``b0``, ``c0``) in ``length_unit`` metres (default 1e-3: the paper's millimetres, so the
numbers of Tables 2-3 can be entered as printed); they are converted to SI once, here.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.excitation.constraints import JointLimits, evaluate_constraints
from ident.excitation.family import FloatArray, TrajectoryBatch, check_design, sample_times
from ident.excitation.ik import ArmGeometry, arm_inverse_kinematics, unwrap_samples

__all__ = [
    "PAPER_N_HARMONICS",
    "PAPER_PERIOD",
    "PaperArmFamily",
    "mfs_path",
    "mfs_variable_names",
]

PAPER_PERIOD = 10.0  # [s]; fundamental frequency 2 pi / 10 = 0.6283 rad/s
PAPER_N_HARMONICS = 3


def mfs_variable_names(n_harmonics: int, *, with_f0: bool) -> tuple[str, ...]:
    """``("a0(1)", ..., "a0(N)", "b0(1)", ..., "b0(N)", "c0", "d0", "e0"[, "f0"])``."""
    names = [f"a0({j})" for j in range(1, n_harmonics + 1)]
    names += [f"b0({j})" for j in range(1, n_harmonics + 1)]
    names += ["c0", "d0", "e0"] + (["f0"] if with_f0 else [])
    return tuple(names)


def mfs_path(
    t: FloatArray,
    a: FloatArray,
    b: FloatArray,
    c: FloatArray,
    centre: FloatArray,
    omega: float,
    *,
    fourier_z: bool = True,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Cartesian path of eq. 16-18 and its exact time derivatives.

    Parameters
    ----------
    t :
        Times [s], shape (n_samples,).
    a :
        Circle coefficients ``a0_j`` [m], shape (n_particles, N) (only their sum matters).
    b :
        Sine coefficients ``b0_j`` [m/s], shape (n_particles, N).
    c :
        Cosine coefficient ``c0`` [m/s], shape (n_particles,) (the same for every harmonic).
    centre :
        ``(d0, e0, f0)`` [m], shape (n_particles, 3).
    omega :
        Fundamental frequency [rad/s]; the circle parameter is ``P = omega t``.
    fourier_z :
        Add the Fourier term to z (eq. 18); False keeps ``Qz = f0``.

    Returns
    -------
    :
        ``Q, dQ, ddQ`` [m, m/s, m/s^2], each of shape (n_particles, n_samples, 3).
    """
    n_harm = b.shape[1]
    wj = omega * np.arange(1, n_harm + 1)  # (N,)
    phase = np.outer(t, wj)  # (n_samples, N)
    s, co = np.sin(phase), np.cos(phase)
    cj = np.broadcast_to(np.asarray(c)[:, None], b.shape)
    # (n_particles, n_samples), C-contiguous: the assembly below runs on contiguous rows
    f = (b / wj) @ s.T - (cj / wj) @ co.T
    df = b @ co.T + cj @ s.T
    ddf = (cj * wj) @ co.T - (b * wj) @ s.T
    radius = a.sum(axis=1)[:, None]  # (n_particles, 1)
    cp, sp = np.cos(omega * t), np.sin(omega * t)
    circle = (cp, sp, np.zeros_like(t))  # (n_samples,) each
    dcircle = (omega * -sp, omega * cp, omega * np.zeros_like(t))
    fourier_axes = (1.0, 1.0, 1.0 if fourier_z else 0.0)
    shape = (b.shape[0], t.shape[0], 3)
    q, dq, ddq = np.empty(shape), np.empty(shape), np.empty(shape)
    for i in range(3):  # coordinate by coordinate: no (n_particles, n_samples, 3) temporaries
        q[..., i] = centre[:, i, None] + radius * circle[i] + f * fourier_axes[i]
        dq[..., i] = radius * dcircle[i] + df * fourier_axes[i]
        ddq[..., i] = -(omega**2) * radius * circle[i] + ddf * fourier_axes[i]
    return q, dq, ddq


# The paper's search box in ``length_unit`` ("limits +-10 ... a and b span negative and positive,
# others positive"); a family overrides entries (the arm's ``e0``).
_PAPER_BOX: dict[str, tuple[float, float]] = {
    "a0": (-10.0, 10.0),
    "b0": (-10.0, 10.0),
    "c0": (0.0, 10.0),
    "d0": (0.0, 10.0),
    "e0": (0.0, 10.0),
    "f0": (0.0, 10.0),
}


class _CartesianFamily:
    """Sampling grid, variables, bounds, units, held joints and the eq. 16-18 path shared by
    the paper's two families (the moving joints are 0-2 or 3-5 of a 6-joint arm)."""

    traced_frame: str | None = None
    moving_joints: tuple[int, ...]
    with_f0: bool  # f0 is a design variable (the arm); else the centre's z is 0 (the wrist)
    fourier_z: bool  # eq. 18 adds F(t) to z (the arm); the wrist completes z by eq. 19

    def __init__(
        self,
        robot: Any,
        *,
        n_samples: int,
        period: float,
        n_harmonics: int,
        length_unit: float,
        default_bounds: dict[str, tuple[float, float]],
        bounds: npt.ArrayLike | None,
        hold: npt.ArrayLike,
        hold_name: str,
    ) -> None:
        if n_samples < 8:
            raise ValueError(f"n_samples must be >= 8, got {n_samples}")
        if not period > 0.0:
            raise ValueError(f"period must be > 0 s, got {period}")
        if n_harmonics < 1:
            raise ValueError(f"n_harmonics must be >= 1, got {n_harmonics}")
        if not length_unit > 0.0:
            raise ValueError(f"length_unit must be > 0 m, got {length_unit}")
        self.robot = robot
        self.geometry = ArmGeometry.from_dh(getattr(robot, "dh", None))
        self.limits = JointLimits.from_robot(robot)
        self.joint_names = self.limits.joint_names
        self.n_samples = int(n_samples)
        self.period = float(period)
        self.base_frequency = 2.0 * np.pi / self.period
        self.n_harmonics = int(n_harmonics)
        self.length_unit = float(length_unit)
        self.t = sample_times(self.n_samples, self.period)
        self._t_ext = np.append(self.t, self.period)  # one more sample at t = T for continuity
        self.variable_names = mfs_variable_names(self.n_harmonics, with_f0=self.with_f0)
        if bounds is None:
            rows = [default_bounds[name.split("(")[0]] for name in self.variable_names]
            self.bounds = np.array(rows, dtype=float)
        else:
            self.bounds = np.array(bounds, dtype=float)
            if self.bounds.shape != (len(self.variable_names), 2):
                raise ValueError(
                    f"bounds must have shape ({len(self.variable_names)}, 2) for "
                    f"{', '.join(self.variable_names)}; got {self.bounds.shape}"
                )
        if np.any(self.bounds[:, 0] > self.bounds[:, 1]):
            raise ValueError("every lower bound must be <= its upper bound")
        held_joints = [j for j in range(6) if j not in self.moving_joints]
        hold_array = np.asarray(hold, dtype=float)
        if hold_array.shape != (3,):
            raise ValueError(
                f"{hold_name} must have 3 entries (joints {held_joints[0] + 1}-"
                f"{held_joints[-1] + 1}), got {hold_array.shape}"
            )
        held = np.zeros(6)
        held[held_joints] = hold_array
        held.setflags(write=False)
        self.held_positions = held

    def feasibility_advice(self, violated: Sequence[str] = ()) -> str:
        """What to change in this family's settings when no design meets the constraints."""
        return (
            "check that the Cartesian circle is reachable (its centre and radius in "
            "excitation.bounds), narrow excitation.bounds, or relax the joint limits of the "
            "robot config"
        )

    def with_samples(self, n_samples: int) -> Any:
        """The same family (bounds, holds, variables) sampled ``n_samples`` times per period.

        Used to evaluate a design at a controller's rate in closed form (eq. 16-22 are
        formulas of ``t``; the paper wrist's joint 6, eq. 23, is built from the samples, so its
        dense version is the same construction on the finer grid).
        """
        if n_samples < 8:
            raise ValueError(f"n_samples must be >= 8, got {n_samples}")
        clone = copy.copy(self)
        clone.n_samples = int(n_samples)
        clone.t = sample_times(clone.n_samples, self.period)
        clone._t_ext = np.append(clone.t, self.period)
        return clone

    def _cartesian_path(self, x: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Eq. 16-18 on the extended grid [m, m/s, m/s^2], (n_particles, n + 1, 3)."""
        x = check_design(x, len(self.variable_names))
        a, b, c, centre = self._split(x)
        return mfs_path(self._t_ext, a, b, c, centre, self.base_frequency, fourier_z=self.fourier_z)

    def _split(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``a, b, c, centre`` in SI from design vectors (n_particles, n_vars)."""
        n = self.n_harmonics
        x = x * self.length_unit
        a, b, c = x[:, :n], x[:, n : 2 * n], x[:, 2 * n]
        centre = np.zeros((x.shape[0], 3))
        rest = x[:, 2 * n + 1 :]
        centre[:, : rest.shape[1]] = rest
        return a, b, c, centre

    def _assemble(
        self,
        q_ext: FloatArray,
        dq_ext: FloatArray,
        ddq_ext: FloatArray,
        q_end: FloatArray,
        traced: FloatArray,
        reach: FloatArray,
    ) -> TrajectoryBatch:
        """Full-robot batch from the moving joints' motion on the extended grid."""
        held = self.held_positions
        n_p, n = q_ext.shape[0], self.n_samples
        shape = (n_p, n, self.limits.nq)
        q = np.broadcast_to(held, shape).copy()
        dq, ddq = np.zeros(shape), np.zeros(shape)
        cols = list(self.moving_joints)
        q[:, :, cols] = q_ext[:, :n]
        dq[:, :, cols] = dq_ext[:, :n]
        ddq[:, :, cols] = ddq_ext[:, :n]
        start = [np.broadcast_to(held, (n_p, self.limits.nq)).copy() for _ in range(3)]
        start[1][:], start[2][:] = 0.0, 0.0
        end = [s.copy() for s in start]
        for s, e, ext, last in zip(
            start, end, (q_ext, dq_ext, ddq_ext), (q_end, dq_ext[:, n], ddq_ext[:, n]), strict=True
        ):
            s[:, cols] = ext[:, 0]
            e[:, cols] = last
        violations = evaluate_constraints(
            q, dq, ddq, self.limits, start=start, end=end, reachability=reach
        )
        return TrajectoryBatch(
            t=self.t.copy(),
            q=q,
            dq=dq,
            ddq=ddq,
            traced_points=traced[:, :n],
            violations=violations,
            joint_names=self.joint_names,
        )


class PaperArmFamily(_CartesianFamily):
    """Arm stage of the paper: the wrist centre traces eq. 16-18, joints 1-3 follow by IK.

    Parameters
    ----------
    robot :
        An :class:`ident.Robot` built from a DH config of the paper's structure
        (:class:`ident.excitation.ik.ArmGeometry`).
    n_samples :
        Samples per period (default 500: 50 Hz over 10 s).
    period :
        Period ``T`` [s] (default 10 s; fundamental frequency 2 pi / T = 0.6283 rad/s).
    n_harmonics :
        ``N`` (default 3).
    length_unit :
        Metres per unit of the design variables (default 1e-3: millimetres as in Table 3).
    wrist_hold :
        Positions [rad] at which joints 4-6 are held (default 0, 0, 0).
    elbow :
        Elbow branch of the inverse kinematics (+1: ``q3`` in [-90, 90] deg for the paper
        robot).
    bounds :
        Search box (n_vars, 2) in ``length_unit``; default: ``a0``, ``b0`` in [-10, 10],
        ``c0``, ``d0``, ``f0`` in [0, 10] (the paper: "limits +-10 ... a and b span negative
        and positive, others positive") and ``e0`` in [100, 200] (Table 3's values; with
        ``d0`` and ``e0`` both within 10 mm the wrist centre would sit on joint 1's axis, the
        singularity the paper's first recommendation avoids).

    Notes
    -----
    Variables: ``a0(1..N)``, ``b0(1..N)``, ``c0``, ``d0``, ``e0``, ``f0`` (Table 3).
    """

    traced_frame = "wrist_centre"
    moving_joints = (0, 1, 2)
    with_f0 = True
    fourier_z = True

    def __init__(
        self,
        robot: Any,
        *,
        n_samples: int = 500,
        period: float = PAPER_PERIOD,
        n_harmonics: int = PAPER_N_HARMONICS,
        length_unit: float = 1e-3,
        wrist_hold: npt.ArrayLike = (0.0, 0.0, 0.0),
        elbow: int = 1,
        bounds: npt.ArrayLike | None = None,
    ) -> None:
        super().__init__(
            robot,
            n_samples=n_samples,
            period=period,
            n_harmonics=n_harmonics,
            length_unit=length_unit,
            default_bounds={**_PAPER_BOX, "e0": (100.0, 200.0)},
            bounds=bounds,
            hold=wrist_hold,
            hold_name="wrist_hold",
        )
        if elbow not in (1, -1):
            raise ValueError(f"elbow must be +1 or -1, got {elbow}")
        self.elbow = int(elbow)

    def path(self, x: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Wrist-centre path [m, m/s, m/s^2] on the extended grid, (n_particles, n + 1, 3)."""
        return self._cartesian_path(x)

    def trajectories(self, x: npt.ArrayLike) -> TrajectoryBatch:
        """Trajectories of a swarm; ``x`` of shape (n_particles, n_vars) in ``length_unit``."""
        p, dp, ddp = self.path(x)
        sol = arm_inverse_kinematics(self.geometry, p, dp, ddp, elbow=self.elbow)
        q_ext = unwrap_samples(sol.q)
        reach = sol.excess.max(axis=1)
        return self._assemble(q_ext, sol.dq, sol.ddq, q_ext[:, -1], p, reach)
