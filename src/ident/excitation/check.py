"""Dense safety check of a trajectory at the controller's rate, before anything is reported.

:func:`check_trajectory` evaluates every constraint a robot needs at every sample of a grid at
least as fine as ``rate_hz`` (default 1 kHz): the clearance of every checked link pair and
obstacle of a :class:`~ident.excitation.safety.SafetyModel`, the joint position, velocity and
acceleration limits, the torque limits (nominal inverse dynamics), and the position and velocity
limits of the robot's mimic joints, which move with their leaders (:func:`follower_checks`). A
trajectory is ``usable`` only when every one of them holds at every sample; a trajectory with a
non-finite state is never usable.

Clearances are a certificate (:func:`certified_clearances`): measured on the exact collision
geometry (meshes as coal BVH, primitives as primitives) for every pair the safety model checks,
and bounded between the samples by the largest relative motion of the two bodies over each step
(:func:`step_displacements`), so that a margin kept at the samples but not in between is found.

Where the samples come from (say which, :attr:`SafetyReport.resampling`):

- ``"none"``: the given samples are already at least as fine as ``rate_hz`` and are checked as
  they are. This is the case for a family evaluated at the dense times
  (:func:`dense_family_states`: the excitation families are closed forms, so this is exact) and
  for the executable trajectory of :mod:`ident.excitation.executable`.
- ``"cubic_hermite"``: coarser samples are interpolated on a uniform grid at ``rate_hz``:
  ``q`` by the cubic Hermite interpolant of ``(q, dq)``, ``dq`` by that of ``(dq, ddq)``, and
  ``ddq`` by a not-a-knot cubic spline. Between samples this is an approximation; prefer the
  family's closed form.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.excitation.constraints import JointLimits
from ident.excitation.family import FloatArray
from ident.excitation.safety import SafetyModel, joint_torques
from ident.robot.limits import LIMIT_KINDS, describe_unknown
from ident.robot.mimic import Mimic

__all__ = [
    "MIN_CHECK_RATE_HZ",
    "SELF_COLLISION_NOT_CHECKED",
    "ConstraintCheck",
    "SafetyReport",
    "certified_clearances",
    "check_trajectory",
    "dense_family_states",
    "follower_checks",
    "is_limit_check",
    "not_run_note",
    "step_displacements",
    "unchecked_checks",
]

MIN_CHECK_RATE_HZ = 1000.0


@dataclass(frozen=True)
class ConstraintCheck:
    """The worst sample of one constraint.

    Attributes
    ----------
    name :
        ``clearance:<link>|<link or obstacle>``, ``position:<joint>``, ``velocity:<joint>``,
        ``acceleration:<joint>`` or ``torque:<joint>``.
    kind :
        ``clearance``, ``position``, ``velocity``, ``acceleration`` or ``torque``.
    value :
        The worst value: the smallest clearance [m], or the largest ``|dq|``, ``|ddq|``,
        ``|tau|``, or the position farthest past (or closest to) a bound [SI].
    limit :
        The required clearance [m], or the limit the value is compared with [SI].
    time :
        When the worst value occurs [s].
    excess :
        By how much the limit is violated (> 0) or kept (<= 0), in the unit of ``value``:
        ``clearance_m - clearance``, ``|dq| - dq_max``, ``max(q - upper, lower - q)``, ...
    ratio :
        ``value / limit`` for velocity, acceleration and torque (<= 1 is within the limit),
        ``nan`` otherwise.
    between :
        For a clearance: a certified lower bound of the clearance over the whole motion,
        between the samples too (:func:`certified_clearances`) [m]; ``excess`` is measured
        from it. ``nan`` otherwise.
    """

    name: str
    kind: str
    value: float
    limit: float
    time: float
    excess: float
    ratio: float = float("nan")
    between: float = float("nan")

    @property
    def ok(self) -> bool:
        """True when the constraint holds at every sample."""
        return bool(np.isfinite(self.excess) and self.excess <= 0.0)

    def describe(self) -> str:
        """One line: what, when, by how much."""
        unit = "m" if self.kind == "clearance" else ""
        if self.kind == "clearance":
            where = f"{self.name}: clearance {self.value:.4f} m at t = {self.time:.3f} s"
            if np.isfinite(self.between) and self.between < self.value:
                where += f" (>= {self.between:.4f} m between samples)"
            if self.ok:
                return f"{where} (margin {self.limit:.3f} m)"
            return f"{where}, below the {self.limit:.3f} m margin by {self.excess:.4f} m"
        if self.kind == "position":
            return (
                f"{self.name}: {self.value:.4f} at t = {self.time:.3f} s, past the limit "
                f"{self.limit:.4f} by {self.excess:.4f}{unit}"
            )
        return (
            f"{self.name}: {self.value:.4g} at t = {self.time:.3f} s, {self.ratio:.3f} x the "
            f"limit {self.limit:.4g}"
        )


@dataclass(frozen=True, eq=False)  # arrays: no field-wise ==
class SafetyReport:
    """Result of :func:`check_trajectory`; ``usable`` is the verdict.

    Attributes
    ----------
    usable :
        True when every constraint holds at every checked sample.
    rate_hz :
        Rate of the checked grid [Hz].
    resampling :
        ``"none"`` or ``"cubic_hermite"`` (see the module docstring).
    t :
        Checked times [s], shape (n_checked,).
    pair_names :
        Link pairs, columns of ``clearance``.
    clearance :
        Signed distances [m], shape (n_checked, n_pairs).
    velocity_ratio, acceleration_ratio, torque_ratio :
        ``|dq| / dq_max``, ``|ddq| / ddq_max``, ``|tau| / effort`` per joint, shape
        (n_checked, nq); 0 where the limit is unknown.
    checks :
        The worst sample of every constraint.
    not_checked :
        ``(what, reason)`` of everything the check leaves out: the safety model's excluded
        robot link pairs (``what`` = ``"<link>|<link>"``: adjacent, SRDF, reference contact,
        always in contact) and its constant-distance environment pairs (judged once when the
        model was built), then the limits it could not check (``what`` = ``"<kind>:<joint>"``,
        :meth:`checks_not_run`), because nobody gave them (``"the URDF gives effort 0"``) or
        ``safety.torque_limits`` is off.
    """

    usable: bool
    rate_hz: float
    resampling: str
    t: FloatArray
    pair_names: tuple[str, ...]
    clearance: FloatArray
    velocity_ratio: FloatArray
    acceleration_ratio: FloatArray
    torque_ratio: FloatArray
    checks: tuple[ConstraintCheck, ...]
    not_checked: tuple[tuple[str, str], ...] = ()

    def checks_not_run(self) -> tuple[str, ...]:
        """The limit checks left out, one line each:
        ``"torque not checked on j1: the URDF gives effort 0"``."""
        return tuple(describe_unknown(w, r) for w, r in self.not_checked if is_limit_check(w))

    def failures(self) -> tuple[ConstraintCheck, ...]:
        """The violated constraints, worst clearance first."""
        bad = [c for c in self.checks if not c.ok]
        return tuple(sorted(bad, key=lambda c: (c.kind != "clearance", -c.excess)))

    def check(self, name: str) -> ConstraintCheck:
        """The check named ``name``."""
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(f"no check named {name!r}; checks: {', '.join(c.name for c in self.checks)}")

    @property
    def min_clearance(self) -> ConstraintCheck | None:
        """The link pair or obstacle with the smallest clearance (``None`` without pairs)."""
        pairs = [c for c in self.checks if c.kind == "clearance"]
        return min(pairs, key=lambda c: c.value) if pairs else None

    def unchecked(self) -> tuple[str, ...]:
        """The whole checks left out (:func:`unchecked_checks` of :attr:`not_checked`)."""
        return unchecked_checks(self.not_checked)

    def summary(self) -> str:
        """``"usable (...)"`` or ``"unsafe: <worst failure>; ..."`` in one line, followed by
        the whole checks left out (:meth:`unchecked`) and ``"; N checks not run: ..."`` when a
        limit was unknown."""
        caveats = "".join(f"; {c}" for c in self.unchecked())
        not_run = caveats + not_run_note(self.checks_not_run())
        if self.usable:
            worst = self.min_clearance
            extra = f"; smallest clearance {worst.describe()}" if worst is not None else ""
            return f"usable at {self.rate_hz:g} Hz{extra}{not_run}"
        fails = self.failures()
        shown = "; ".join(c.describe() for c in fails[:3])
        more = f" (+{len(fails) - 3} more)" if len(fails) > 3 else ""
        return f"unsafe: {shown}{more}{not_run}"


def is_limit_check(what: str) -> bool:
    """True for a ``not_checked`` entry naming a limit check (``"torque:j1"``), not a pair."""
    kind, sep, _ = what.partition(":")
    return bool(sep) and kind in LIMIT_KINDS


def not_run_note(lines: Sequence[str]) -> str:
    """``"; N checks not run: <line>; <line>"`` (the first lines of each reason grouped),
    ``""`` for none: what a verdict appends so that it never reads as complete."""
    if not lines:
        return ""
    grouped: dict[str, list[str]] = {}
    for line in lines:  # "<kind> not checked on <joint>: <reason>"
        head, _, reason = line.partition(": ")
        kind, _, joint = head.partition(" not checked on ")
        grouped.setdefault(f"{kind}\0{reason}", []).append(joint)
    parts = []
    for key, joints in grouped.items():
        kind, reason = key.split("\0")
        parts.append(f"{kind} not checked on {', '.join(joints)}: {reason}")
    n = len(lines)
    return f"; {n} check{'s' if n != 1 else ''} not run: " + "; ".join(parts)


def dense_family_states(
    family: Any, x: npt.ArrayLike, rate_hz: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """One period of a family's trajectory evaluated at ``rate_hz`` or finer, in closed form.

    The family is re-sampled with ``n = ceil(period * rate_hz)`` samples per period
    (``family.with_samples(n)``), so every state is the family's formula at the dense times;
    the grid step is ``period / n <= 1 / rate_hz``.

    Returns
    -------
    :
        ``t`` [s] shape (n,), ``q, dq, ddq`` shape (n, nq).

    Raises
    ------
    TypeError
        If the family cannot be re-sampled (no ``with_samples``); interpolate its samples
        with :func:`check_trajectory` instead.
    """
    with_samples = getattr(family, "with_samples", None)
    if with_samples is None:
        raise TypeError(f"{type(family).__name__} has no with_samples(n_samples)")
    n = int(np.ceil(float(family.period) * float(rate_hz) - 1e-9))
    batch = with_samples(n).trajectories(np.asarray(x, dtype=float)[None, :])
    return batch.t, batch.q[0], batch.dq[0], batch.ddq[0]


def _resample(
    t: FloatArray, q: FloatArray, dq: FloatArray, ddq: FloatArray, rate_hz: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    from scipy.interpolate import CubicHermiteSpline, CubicSpline

    n = int(np.ceil((t[-1] - t[0]) * rate_hz - 1e-9)) + 1
    dense = np.linspace(t[0], t[-1], n)
    return (
        dense,
        CubicHermiteSpline(t, q, dq, axis=0)(dense),
        CubicHermiteSpline(t, dq, ddq, axis=0)(dense),
        CubicSpline(t, ddq, axis=0)(dense),
    )


SUBDIVISIONS = 8  # a step whose bound fails is cut into this many (cubic Hermite)


def step_displacements(
    safety: SafetyModel, t: FloatArray, dq: FloatArray, ddq: FloatArray
) -> FloatArray:
    """A bound on how far the two bodies of each pair move relative to each other per step.

    Over the step ``[t_k, t_k+1]`` joint ``j`` turns by at most ``|dq_j| dt``, with ``|dq_j|``
    bounded by ``max(|dq_j(t_k)|, |dq_j(t_k+1)|) + max(|ddq_j(t_k)|, |ddq_j(t_k+1)|) dt / 2``
    (the acceleration taken within its sampled values over one step); a point at most
    ``reach_j`` from the joint's origin moves by at most ``reach_j`` times that
    (:attr:`SafetyModel.motion_coefficients`, summed over the joints and both bodies, except
    the joints above both bodies, which move them together).

    Returns
    -------
    :
        Shape (n - 1, n_pairs) [m].
    """
    dt = np.diff(t)[:, None]
    speed = np.maximum(np.abs(dq[:-1]), np.abs(dq[1:]))
    speed = speed + 0.5 * dt * np.maximum(np.abs(ddq[:-1]), np.abs(ddq[1:]))
    return np.asarray((speed * dt) @ safety.motion_coefficients.T)


def certified_clearances(
    safety: SafetyModel, t: FloatArray, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Exact clearances at the samples, and a certified lower bound between them.

    Between samples ``k`` and ``k+1`` with clearances ``d_k`` and ``d_k+1``, whose bodies move
    relative to each other by at most ``D_k`` (:func:`step_displacements`), the clearance is
    at least ``(d_k + d_k+1 - D_k) / 2`` (a distance changes no faster than the bodies move).
    Steps where this bound falls below the margin while both samples keep it are cut into
    :data:`SUBDIVISIONS` (positions from the cubic Hermite interpolant of ``q`` and ``dq``,
    whose error, ``dt^4 / 384`` times the largest fourth derivative of ``q``, is below 1e-9
    rad at 1 kHz for the excitations here) and bounded again with ``D_k / SUBDIVISIONS``. The
    exact (mesh) distance is computed wherever the hulls are within ``margin + 2 D + 1 mm``,
    except where the last exact value less the ``D`` summed since keeps that much
    (conservative advancement, :meth:`SafetyModel.clearances` with ``travel``).

    Returns
    -------
    :
        The clearances at the samples [m], shape (n, n_pairs) (exact where they matter, a
        lower bound elsewhere; each pair's smallest value exact), and each pair's certified
        lower bound over the whole motion [m], shape (n_pairs,).
    """
    n, n_pairs = q.shape[0], safety.n_pairs
    if n_pairs == 0:
        return np.full((n, 0), np.inf), np.full(0, np.inf)
    finite = bool(np.all(np.isfinite(q)) and np.all(np.isfinite(dq)) and np.all(np.isfinite(ddq)))
    if n < 2 or not finite:
        clearance = safety.clearances(q)
        return clearance, clearance.min(axis=0)
    step = step_displacements(safety, t, dq, ddq)
    near = np.zeros((n, n_pairs))
    near[:-1] = step
    near[1:] = np.maximum(near[1:], step)
    margin = safety.clearance_m
    travel = np.vstack([np.zeros((1, n_pairs)), np.cumsum(step, axis=0)])
    clearance = safety.clearances(q, within=margin + 2.0 * near + 1e-3, travel=travel)
    bound = 0.5 * (clearance[:-1] + clearance[1:] - step)
    weak = (bound < margin) & (clearance[:-1] >= margin) & (clearance[1:] >= margin)
    for k in np.flatnonzero(weak.any(axis=1)):
        pairs = np.flatnonzero(weak[k])
        fine = _hermite(t[k], t[k + 1], q[k], q[k + 1], dq[k], dq[k + 1], SUBDIVISIONS)
        inner = safety.pair_clearances(fine[1:-1], pairs.tolist())
        d = np.vstack([clearance[k, pairs], inner, clearance[k + 1, pairs]])
        sub = 0.5 * (d[:-1] + d[1:] - step[k, pairs] / SUBDIVISIONS)
        bound[k, pairs] = sub.min(axis=0)
    return clearance, bound.min(axis=0)


def _hermite(
    t0: float, t1: float, q0: FloatArray, q1: FloatArray, v0: FloatArray, v1: FloatArray, m: int
) -> FloatArray:
    """``m + 1`` postures of the cubic Hermite interpolant on ``[t0, t1]``, ends included."""
    h = t1 - t0
    s = np.linspace(0.0, 1.0, m + 1)[:, None]
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    return np.asarray(h00 * q0 + h10 * h * v0 + h01 * q1 + h11 * h * v1)


def _ratio(value: FloatArray, limit: FloatArray) -> FloatArray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(np.isfinite(limit), np.abs(value) / limit, 0.0)


def check_trajectory(
    robot: Any,
    safety: SafetyModel,
    t: npt.ArrayLike,
    q: npt.ArrayLike,
    dq: npt.ArrayLike,
    ddq: npt.ArrayLike,
    rate_hz: float = MIN_CHECK_RATE_HZ,
) -> SafetyReport:
    """Check every constraint of a trajectory at ``rate_hz`` (>= 1 kHz).

    Parameters
    ----------
    robot :
        The robot: its mimic joints (``mimic_joints``), whose own position and velocity limits
        are checked through their leaders (:func:`follower_checks`); the leaders' limits and
        the nominal model come from ``safety``.
    safety :
        The safety model (collision geometry, environment, margin, limits).
    t :
        Times [s], shape (n_samples,), increasing.
    q, dq, ddq :
        Joint states [rad, rad/s, rad/s^2], shape (n_samples, nq).
    rate_hz :
        Check rate [Hz], at least :data:`MIN_CHECK_RATE_HZ`; coarser input is interpolated
        (see the module docstring).

    Returns
    -------
    :
        The report; ``usable`` is False when any constraint is violated at any sample or a
        state is not finite.

    Raises
    ------
    ValueError
        For ``rate_hz`` below 1 kHz, or arrays of inconsistent shapes.
    """
    t, q, dq, ddq, finite, resampling = _dense_samples(safety.limits.nq, t, q, dq, ddq, rate_hz)
    clearance, between = certified_clearances(safety, t, q, dq, ddq)
    checks = _clearance_checks(safety, t, clearance, between)
    (velocity_ratio, acceleration_ratio, torque_ratio), limit_checks = _limit_checks(
        robot, safety, t, q, dq, ddq, finite
    )
    checks += limit_checks
    usable = finite and all(c.ok for c in checks)
    return SafetyReport(
        usable=bool(usable),
        rate_hz=float(rate_hz),
        resampling=resampling,
        t=t,
        pair_names=safety.pair_names,
        clearance=clearance,
        velocity_ratio=velocity_ratio,
        acceleration_ratio=acceleration_ratio,
        torque_ratio=torque_ratio,
        checks=tuple(checks),
        not_checked=_not_checked(safety) + _limits_not_checked(safety),
    )


def _dense_samples(
    nq: int,
    t: npt.ArrayLike,
    q: npt.ArrayLike,
    dq: npt.ArrayLike,
    ddq: npt.ArrayLike,
    rate_hz: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, bool, str]:
    """The samples checked: ``t, q, dq, ddq`` as given when they are at least as fine as
    ``rate_hz`` [Hz] (or not finite), else interpolated on a uniform grid at ``rate_hz``
    (:func:`_resample`); whether every state is finite, and the resampling used
    (:attr:`SafetyReport.resampling`).

    Raises
    ------
    ValueError
        For ``rate_hz`` below :data:`MIN_CHECK_RATE_HZ`, or arrays of inconsistent shapes.
    """
    if not rate_hz >= MIN_CHECK_RATE_HZ:
        raise ValueError(f"rate_hz must be >= {MIN_CHECK_RATE_HZ:g} Hz, got {rate_hz}")
    t, q, dq, ddq = _checked_arrays(nq, t, q, dq, ddq)
    finite = bool(np.all(np.isfinite(q)) and np.all(np.isfinite(dq)) and np.all(np.isfinite(ddq)))
    resampling = "none"
    if t.shape[0] > 1 and finite and np.max(np.diff(t)) > (1.0 + 1e-9) / rate_hz:
        t, q, dq, ddq = _resample(t, q, dq, ddq, rate_hz)
        resampling = "cubic_hermite"
    return t, q, dq, ddq, finite, resampling


def _limit_checks(
    robot: Any,
    safety: SafetyModel,
    t: FloatArray,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    finite: bool,
) -> tuple[tuple[FloatArray, FloatArray, FloatArray], list[ConstraintCheck]]:
    """The joint limits' checks, in order: the positions, the peaks of the velocity,
    acceleration and torque of every joint (the torques from the nominal inverse dynamics,
    ``inf`` when a state is not finite), and the limits of ``robot``'s mimic joints
    (:func:`follower_checks`); with the velocity, acceleration and torque ratios to the
    limits, shape (n_samples, nv)."""
    # the safety model carries the robot's model, names and limits; the robot its mimic joints
    mimics = tuple(getattr(robot, "mimic_joints", ()))
    limits = safety.limits
    checks = _position_checks(limits, t, q, finite)
    velocity_ratio = _ratio(dq, limits.dq_max)
    acceleration_ratio = _ratio(ddq, limits.ddq_max)
    if finite:
        tau = joint_torques(safety.robot_model, q, dq, ddq)
    else:
        tau = np.full(dq.shape, np.inf)
    torque_ratio = _ratio(tau, safety.effort_max)
    for kind, series, limit, ratio in (
        ("velocity", dq, limits.dq_max, velocity_ratio),
        ("acceleration", ddq, limits.ddq_max, acceleration_ratio),
        ("torque", tau, safety.effort_max, torque_ratio),
    ):
        checks += _peak_checks(kind, limits.joint_names, t, series, limit, ratio, finite)
    checks += follower_checks(mimics, limits.joint_names, t, q, dq, finite)
    return (velocity_ratio, acceleration_ratio, torque_ratio), checks


def _checked_arrays(
    nq: int, t: npt.ArrayLike, q: npt.ArrayLike, dq: npt.ArrayLike, ddq: npt.ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """``t`` shape (n,) and ``q, dq, ddq`` shape (n, nq) as float arrays; ValueError otherwise."""
    t = np.asarray(t, dtype=float)
    q, dq, ddq = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, dq, ddq))
    if t.ndim != 1 or any(a.shape != (t.shape[0], nq) for a in (q, dq, ddq)):
        raise ValueError(
            f"t must have shape (n,) and q, dq, ddq shape (n, {nq}); got {t.shape}, "
            f"{q.shape}, {dq.shape}, {ddq.shape}"
        )
    return t, q, dq, ddq


def _clearance_checks(
    safety: SafetyModel, t: FloatArray, clearance: FloatArray, between: FloatArray
) -> list[ConstraintCheck]:
    """The smallest clearance [m] of every checked pair, at the samples (shape (n, n_pairs))
    or certified ``between`` them (shape (n_pairs,)), against the safety margin."""
    checks = []
    for k, pair in enumerate(safety.pair_names):
        i = int(np.argmin(clearance[:, k]))
        value = float(clearance[i, k])
        lowest = min(value, float(between[k]))
        checks.append(
            ConstraintCheck(
                f"clearance:{pair}",
                "clearance",
                value,
                safety.clearance_m,
                float(t[i]),
                safety.clearance_m - lowest,
                between=float(between[k]),
            )  # fmt: skip
        )
    return checks


def _position_checks(
    limits: Any, t: FloatArray, q: FloatArray, finite: bool
) -> list[ConstraintCheck]:
    """The sample of every joint with a position limit that comes nearest to (or furthest
    past) it; an infinite excess when a state is not finite."""
    lower, upper = limits.q_lower, limits.q_upper
    with np.errstate(invalid="ignore"):
        past = np.maximum(q - upper, lower - q)
    checks = []
    for j, joint in enumerate(limits.joint_names):
        if not (np.isfinite(lower[j]) or np.isfinite(upper[j])):
            continue
        i = int(np.nanargmax(past[:, j])) if finite else 0
        bound = upper[j] if q[i, j] - upper[j] >= lower[j] - q[i, j] else lower[j]
        excess = float(past[i, j]) if finite else float("inf")
        checks.append(
            ConstraintCheck(
                f"position:{joint}", "position", float(q[i, j]), float(bound), float(t[i]), excess
            )  # fmt: skip
        )
    return checks


def _peak_checks(
    kind: str,
    names: Sequence[str],
    t: FloatArray,
    series: FloatArray,
    limit: FloatArray,
    ratio: FloatArray,
    finite: bool,
) -> list[ConstraintCheck]:
    """The peak of ``|series|`` (shape (n, nq)) of every joint with a finite ``limit``, as a
    ``kind`` check (``ratio``: ``|series| / limit``); an infinite peak when a state is not
    finite."""
    checks = []
    for j, joint in enumerate(names):
        if not np.isfinite(limit[j]):
            continue
        i = int(np.argmax(ratio[:, j])) if finite else 0
        peak = float(abs(series[i, j])) if finite else float("inf")
        checks.append(
            ConstraintCheck(
                f"{kind}:{joint}",
                kind,
                peak,
                float(limit[j]),
                float(t[i]),
                peak - float(limit[j]),
                peak / float(limit[j]),
            )  # fmt: skip
        )
    return checks


def follower_checks(
    mimics: Sequence[Mimic],
    joint_names: Sequence[str],
    t: FloatArray,
    q: FloatArray,
    dq: FloatArray,
    finite: bool,
) -> list[ConstraintCheck]:
    """Position and velocity checks of the mimic joints against their own limits.

    A follower moves as ``q_f = m q_l + o``, ``dq_f = m dq_l`` (its leader's columns of ``q``
    and ``dq``, shape (n, nq)); it is named ``position:<follower>``, ``velocity:<follower>``,
    so a trajectory that keeps its leaders within theirs but drives a follower out of its range
    is unsafe by the follower's name.
    """
    if not mimics:
        return []
    columns = [list(joint_names).index(m.leader) for m in mimics]
    scale = np.array([m.multiplier for m in mimics])
    followers = JointLimits(
        joint_names=tuple(m.follower for m in mimics),
        q_lower=np.array([m.q_lower for m in mimics]),
        q_upper=np.array([m.q_upper for m in mimics]),
        dq_max=np.array([m.dq_max for m in mimics]),
        ddq_max=np.full(len(mimics), np.inf),
    )
    q_f = q[:, columns] * scale + np.array([m.offset for m in mimics])
    dq_f = dq[:, columns] * scale
    checks = _position_checks(followers, t, q_f, finite)
    ratio = _ratio(dq_f, followers.dq_max)
    return checks + _peak_checks(
        "velocity", followers.joint_names, t, dq_f, followers.dq_max, ratio, finite
    )


def unchecked_checks(not_checked: Iterable[Sequence[str]]) -> tuple[str, ...]:
    """The whole checks a certificate left out, one phrase each, from its ``not_checked``
    ``(pair, reason)`` entries (those that are no link pair):
    ``"self-collision not checked (safety.self_collision: false)"``, a link without geometry.
    The run's summary line, verdict and report say them next to the outcome."""
    return tuple(
        f"{what} {why}" for what, why in not_checked if "|" not in what and "not checked" in why
    )


SELF_COLLISION_NOT_CHECKED = ("self-collision", "not checked (safety.self_collision: false)")
"""The :attr:`SafetyReport.not_checked` entry of a model built without self-collision."""


def _not_checked(safety: SafetyModel) -> tuple[tuple[str, str], ...]:
    """``(pair, reason)`` of the safety model's excluded and constant-distance pairs, then
    whole checks left out (self-collision off) and its geometry notes (``(link, what)``:
    a visual mesh used for collision, a link without geometry)."""
    config = getattr(safety, "config", None)
    off = () if config is None or config.self_collision else (SELF_COLLISION_NOT_CHECKED,)
    return (
        *(
            (e.pair, e.reason)
            for e in (
                *getattr(safety, "excluded_pairs", ()),
                *getattr(safety, "constant_pairs", ()),
            )
        ),
        *off,
        *getattr(safety, "geometry_notes", ()),
    )


def _limits_not_checked(safety: SafetyModel) -> tuple[tuple[str, str], ...]:
    """``("<kind>:<joint>", reason)`` of the limits the check could not compare with: the
    robot's unknown ones (an unknown position with the guessed range the optimizer's
    reference states assumed, :meth:`JointLimits.finite_position_box`), and
    every torque limit when ``safety.torque_limits`` is off."""
    limits = safety.limits
    out = []
    for u in limits.unknown:
        if u.kind == "torque" and not safety.config.torque_limits:
            continue  # said once below
        reason = u.reason
        if u.kind == "position":
            low, high = limits.finite_position_box()
            j = limits.joint_names.index(u.joint)
            unit = "m" if limits.prismatic[j] else "rad"
            reason += (
                f"; the optimizer assumed a guessed range [{low[j]:.4g}, {high[j]:.4g}] {unit}"
            )
        out.append((u.check, reason))
    if not safety.config.torque_limits:
        out += [(f"torque:{j}", "safety.torque_limits is false") for j in limits.joint_names]
    return tuple(out)
