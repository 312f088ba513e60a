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

With ``fill_limits=True`` the design's ``a``, ``b`` of each moving joint are the *shape* of its
motion: the family multiplies them by the joint's gain (:meth:`JointFourierFamily.fill_gains`),
the largest factor that keeps the joint's position within its limits about ``q0``, its velocity
and its acceleration within theirs over the whole period (between samples too: the peaks are
bounded by :func:`fill_margin`), so that every design touches at least one of its joint's limits.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.excitation.constraints import JointLimits, evaluate_constraints
from ident.excitation.family import FloatArray, TrajectoryBatch, check_design, sample_times

__all__ = [
    "JointFourierFamily",
    "FILL_SAMPLES_PER_HARMONIC",
    "fill_margin",
    "fourier_bound_factors",
    "fourier_series",
    "resolve_joints",
]


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


def fourier_bound_factors(n_harmonics: int) -> tuple[float, float, float]:
    """Worst-case peaks of the series per unit coefficient bound, over the whole search box.

    With every free coefficient ``|a_l|, |b_l| <= A`` (``l = 2..N``) and the first harmonic
    fixed by the rest conditions, for every design of the box and every time

        |q - q0| <= c_q A / w,   |dq| <= c_v A,   |ddq| <= c_a A w.

    The factors are the maxima over the phase ``theta = w t`` of the sums of the absolute
    contributions of each free coefficient (sampled on 20001 phases; the sums are smooth
    in theta, so the sampled maximum is within 1e-6 relative of the true one).

    Parameters
    ----------
    n_harmonics :
        ``N`` >= 2.

    Returns
    -------
    :
        ``(c_q, c_v, c_a)``, dimensionless; for N = 4 about (10.0, 12.4, 17.4).
    """
    if n_harmonics < 2:
        raise ValueError(f"n_harmonics must be >= 2 (rest conditions), got {n_harmonics}")
    theta = np.linspace(0.0, 2.0 * np.pi, 20001)
    l = np.arange(2, n_harmonics + 1, dtype=float)[:, None]
    s1, c1 = np.sin(theta), np.cos(theta)
    sl, cl = np.sin(l * theta), np.cos(l * theta)
    # a_l enters with (cos l th - cos th) in dq; b_l with (sin l th - l sin th) (b_1 = -sum l b_l)
    c_q = (np.abs(sl / l - s1) + np.abs(l * c1 - cl / l)).sum(axis=0).max()
    c_v = (np.abs(cl - c1) + np.abs(sl - l * s1)).sum(axis=0).max()
    c_a = (np.abs(l * sl - s1) + l * np.abs(cl - c1)).sum(axis=0).max()
    return float(c_q), float(c_v), float(c_a)


#: The fill gains are computed on ``FILL_SAMPLES_PER_HARMONIC * N`` samples per period, a grid
#: that depends on ``N`` only (not on ``n_samples``): a design is the same motion at any rate.
FILL_SAMPLES_PER_HARMONIC = 256
#: Relative slack of the fill gains against round-off (far below :func:`fill_margin`).
FILL_ROUNDOFF = 1e-12


def fill_margin(n_harmonics: int, samples_per_period: int) -> float:
    """Relative bound of a trigonometric polynomial's peak between uniform samples.

    For ``f`` of degree ``N`` (frequencies ``w l``, ``l <= N``) sampled ``M`` times per period,
    at the peak ``t*`` of ``|f|``, ``f'(t*) = 0`` and a sample lies within ``h / 2 = pi / (w M)``;
    Taylor and Bernstein's inequality (``max |f''| <= (N w)^2 max |f|``) give
    ``max |f| <= max_k |f(t_k)| (1 + eps)`` and, for a zero-mean ``f``,
    ``max f <= max_k f(t_k) + eps max_k |f(t_k)|``, with ``delta = (pi N / M)^2 / 2`` and
    ``eps = delta / (1 - delta)``.

    Parameters
    ----------
    n_harmonics :
        ``N``.
    samples_per_period :
        ``M`` (> ``pi N sqrt(2)``).

    Returns
    -------
    :
        ``eps``, dimensionless; 7.5e-5 for the fill grid (``M = 256 N``).
    """
    delta = 0.5 * (np.pi * n_harmonics / samples_per_period) ** 2
    if not delta < 1.0:
        raise ValueError(f"{samples_per_period} samples are too few for {n_harmonics} harmonics")
    return float(delta / (1.0 - delta))


def _round_down(value: float) -> str:
    """``value`` rounded down to 2 significant digits, as text (a bound that stays safe)."""
    if not np.isfinite(value) or value <= 0.0:
        return f"{value:g}"
    scale = 10.0 ** (np.floor(np.log10(value)) - 1)
    return f"{np.floor(value / scale) * scale:.2g}"


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
    fill_limits :
        Scale each moving joint's ``a``, ``b`` by its gain (:meth:`fill_gains`) so that the
        motion reaches the joint's limits (position about ``q0``, velocity, acceleration),
        like FIGAROH's per-joint gain. The design's coefficients are then a shape: only
        their ratios matter, and :meth:`coefficients` / :meth:`trajectories` return the scaled
        motion. Default False (the coefficients are used as they are).

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
        fill_limits: bool = False,
    ) -> None:
        _check_settings(n_harmonics, base_frequency, n_samples, fill_limits)
        self.limits = JointLimits.from_robot(robot)
        self.joint_names = self.limits.joint_names
        self.moving_joints = resolve_joints(self.joint_names, moving_joints)
        self.n_harmonics = int(n_harmonics)
        self.base_frequency = float(base_frequency)
        self.period = 2.0 * np.pi / self.base_frequency
        self.n_samples = int(n_samples)
        self.t = sample_times(self.n_samples, self.period)
        self.fill_limits = bool(fill_limits)
        n_fill = FILL_SAMPLES_PER_HARMONIC * self.n_harmonics
        self.fill_times = sample_times(n_fill, self.period)
        self.fill_margin = fill_margin(self.n_harmonics, n_fill)
        lower, upper = self.limits.finite_position_box()
        self.held_positions = _held(held_positions, lower, upper)
        moving = list(self.moving_joints)
        self.amplitude_given = amplitude_bound is not None
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

    def amplitude_limits(self) -> FloatArray:
        """Largest coefficient bound per moving joint that keeps every design of the box
        within the joint's velocity and acceleration limits [rad/s], shape (n_moving,).

        From :func:`fourier_bound_factors`: ``min(dq_max / c_v, ddq_max / (w c_a))``
        (``inf`` for a joint without limits).
        """
        _, c_v, c_a = fourier_bound_factors(self.n_harmonics)
        moving = list(self.moving_joints)
        by_velocity = self.limits.dq_max[moving] / c_v
        by_acceleration = self.limits.ddq_max[moving] / (self.base_frequency * c_a)
        return np.asarray(np.minimum(by_velocity, by_acceleration), dtype=float)

    def feasibility_advice(self, violated: Sequence[str] = ()) -> str:
        """Name the amplitude setting that makes the box infeasible, with its value and a fix.

        Only when velocity or acceleration constraints are among ``violated`` (or nothing is
        known about what failed) and some joint's coefficient bound lets a design of the box
        exceed its limit. Empty otherwise (the fault is elsewhere: positions, floor, ...).
        """
        kinds = {name.split(":")[0] for name in violated}
        if violated and not kinds & {"velocity", "acceleration"}:
            return ""
        _, c_v, c_a = fourier_bound_factors(self.n_harmonics)
        per_joint = self.bounds[:, 1].reshape(len(self.moving_joints), 2 * self.n_harmonics - 1)
        amp = np.abs(per_joint[:, 1:]).max(axis=1)  # the a, b coefficients of each joint
        allowed = self.amplitude_limits()
        ratio = amp / allowed
        k = int(np.argmax(ratio))
        if not ratio[k] > 1.0:
            return ""
        j = self.moving_joints[k]
        name = self.joint_names[j]
        setting = (
            "excitation.options.amplitude_bound"
            if self.amplitude_given
            else "the default amplitude bound (half of each velocity limit)"
        )
        dq_max, ddq_max = self.limits.dq_max[j], self.limits.ddq_max[j]
        w = self.base_frequency
        if amp[k] * c_v / dq_max >= amp[k] * w * c_a / ddq_max:
            excess = (
                f"velocity limit {dq_max:.3g} rad/s (a design of the box reaches "
                f"{c_v:.3g} x {amp[k]:.3g} = {c_v * amp[k]:.3g} rad/s)"
            )
        else:
            excess = (
                f"acceleration limit {ddq_max:.3g} rad/s^2 (a design of the box reaches "
                f"{c_a:.3g} x {amp[k]:.3g} x base_frequency {w:.3g} = "
                f"{c_a * amp[k] * w:.3g} rad/s^2)"
            )
        fix = float(np.min(allowed))
        return (
            f"{setting} {amp[k]:.3g} rad/s exceeds joint {j + 1} ({name})'s {excess} at the "
            f"chosen harmonics (n_harmonics {self.n_harmonics}); set "
            f"excitation.options.amplitude_bound <= {_round_down(fix)} (every design of the box "
            "then keeps within every joint's velocity and acceleration limits)"
        )

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
        a = np.concatenate([a1, a_free], axis=2)
        b = np.concatenate([b1, b_free], axis=2)
        if self.fill_limits:
            gain = self.fill_gains(a, b, q0)[:, :, None]
            a, b = a * gain, b * gain
        return a, b, q0

    def fill_gains(self, a: FloatArray, b: FloatArray, q0: FloatArray) -> FloatArray:
        """Per particle and moving joint, the largest factor ``s >= 0`` of ``a, b`` that keeps
        the joint within its limits over the whole period.

        On the fill grid (:data:`FILL_SAMPLES_PER_HARMONIC` ``* N`` samples per period) the
        peaks of ``g = q - q0``, ``dq`` and ``ddq`` are inflated by :func:`fill_margin`'s
        ``eps`` into bounds valid between the samples too: ``g_up = max g + eps max |g|``,
        ``g_down = max(-g) + eps max |g|``, ``V = (1 + eps) max |dq|``,
        ``A = (1 + eps) max |ddq|``. Then ``s = (1 - 1e-12) min((q_upper - q0) / g_up,
        (q0 - q_lower) / g_down, dq_max / V, ddq_max / A)`` (an infinite limit drops its term;
        ``q0`` outside its limits gives 0). A joint that does not move (all peaks 0) or has no
        finite limit keeps ``s = 1``.

        Parameters
        ----------
        a, b :
            Unscaled coefficients [rad/s], shape (n_particles, n_moving, N).
        q0 :
            Offsets [rad], shape (n_particles, n_moving).

        Returns
        -------
        :
            Gains, dimensionless, shape (n_particles, n_moving).
        """
        # fourier_series's formulas, laid out (P, n_moving, M) for matrix products
        wl = self.base_frequency * np.arange(1, self.n_harmonics + 1)
        phase = np.outer(wl, self.fill_times)  # (N, M)
        s, c = np.sin(phase), np.cos(phase)
        g = (a / wl) @ s - (b / wl) @ c
        dq = a @ c + b @ s
        ddq = (b * wl) @ c - (a * wl) @ s
        eps = self.fill_margin
        spread = np.abs(g).max(axis=2)
        peaks = (
            g.max(axis=2) + eps * spread,
            (-g).max(axis=2) + eps * spread,
            (1.0 + eps) * np.abs(dq).max(axis=2),
            (1.0 + eps) * np.abs(ddq).max(axis=2),
        )
        moving = list(self.moving_joints)
        limits = self.limits
        rooms = (
            np.maximum(limits.q_upper[moving] - q0, 0.0),
            np.maximum(q0 - limits.q_lower[moving], 0.0),
            np.broadcast_to(limits.dq_max[moving], q0.shape),
            np.broadcast_to(limits.ddq_max[moving], q0.shape),
        )
        gain = np.full(q0.shape, np.inf)
        for peak, room in zip(peaks, rooms, strict=True):
            ratio = np.divide(room, peak, out=np.full(q0.shape, np.inf), where=peak > 0.0)
            gain = np.minimum(gain, ratio)
        gain = np.where(np.isfinite(gain), gain * (1.0 - FILL_ROUNDOFF), 1.0)
        return np.asarray(gain, dtype=float)

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


def _check_settings(
    n_harmonics: int, base_frequency: float, n_samples: int, fill_limits: object
) -> None:
    """Raise ``ValueError`` for a setting of :class:`JointFourierFamily` out of its range."""
    if not isinstance(fill_limits, (bool, np.bool_)):
        raise ValueError(f"fill_limits must be true or false, got {fill_limits!r}")
    if n_harmonics < 2:
        raise ValueError(f"n_harmonics must be >= 2 (rest conditions), got {n_harmonics}")
    if not base_frequency > 0.0:
        raise ValueError(f"base_frequency must be > 0 rad/s, got {base_frequency}")
    if n_samples < 2 * n_harmonics + 1:
        raise ValueError(f"n_samples must be >= {2 * n_harmonics + 1}, got {n_samples}")


def _held(held_positions: npt.ArrayLike | None, lower: FloatArray, upper: FloatArray) -> FloatArray:
    """Read-only positions (nq,) of the joints that do not move [rad or m]: the given ones, or
    0 clipped into the finite position box (``lower``, ``upper``)."""
    nq = lower.shape[0]
    if held_positions is None:
        held = np.clip(np.zeros(nq), lower, upper)
    else:
        held = np.asarray(held_positions, dtype=float).copy()
        if held.shape != (nq,):
            raise ValueError(f"held_positions must have shape ({nq},), got {held.shape}")
    held.setflags(write=False)
    return held
