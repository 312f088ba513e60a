"""The trajectory a controller runs: approach from home, the excitation repeated, return home.

:func:`executable_trajectory` samples, at the controller's rate,

1. an **approach**: a quintic polynomial per joint from rest at the home posture to the state
   ``(q, dq, ddq)`` of the excitation at ``t = 0`` (the paper's Cartesian families start in
   motion, the joint Fourier family at rest: the quintic matches position, velocity and
   acceleration either way, so the commanded motion is C2);
2. the **excitation**, ``n_periods`` periods of the family's closed form evaluated at the
   controller's grid (``family.with_samples``, see
   :func:`ident.excitation.check.dense_family_states`);
3. a **return**: a quintic from the excitation's state at the end of the last period (the
   state at ``t = 0``, the motion being periodic) to rest at home.

The durations of the transitions are the shortest (on a 20 % grid, from the rest-to-rest bound
``T >= 1.875 |dq| / v_max`` and ``T >= sqrt(5.774 |dq| / a_max)``) for which the transition stays
within ``limit_fraction`` of every velocity and acceleration limit, checked at every sample.
The transitions follow joint space: they are not planned around obstacles. The whole
trajectory must pass :func:`ident.excitation.check.check_trajectory` like the excitation itself;
if an approach collides, choose another home posture.

The output is a :class:`ident.trajectory.JointTrajectory` on a uniform grid of step
``period / round(period * rate_hz)`` (the controller's rate, adjusted so that one period holds
a whole number of samples), ready for :func:`ident.trajectory.trajectory_to_csv`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.excitation.constraints import JointLimits
from ident.excitation.family import FloatArray
from ident.trajectory import JointTrajectory

__all__ = ["executable_trajectory", "quintic", "transition_duration"]

# used to size a transition where a limit is unknown [rad/s], [rad/s^2]
_FALLBACK_VELOCITY = 1.0
_FALLBACK_ACCELERATION = 2.0


def quintic(
    start: tuple[FloatArray, FloatArray, FloatArray],
    end: tuple[FloatArray, FloatArray, FloatArray],
    duration: float,
    t: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Quintic polynomials matching position, velocity and acceleration at both ends.

    Parameters
    ----------
    start, end :
        ``(q, dq, ddq)`` at ``t = 0`` and at ``t = duration``, each of shape (nq,).
    duration :
        ``T`` [s] > 0.
    t :
        Times [s] in ``[0, T]``, shape (n_samples,).

    Returns
    -------
    :
        ``q, dq, ddq``, each of shape (n_samples, nq).
    """
    (p0, v0, a0), (p1, v1, a1) = start, end
    big_t = float(duration)
    # q(s) = sum_k c_k s^k with c_0..c_2 from the start state, c_3..c_5 from the end state
    m = np.array(
        [
            [big_t**3, big_t**4, big_t**5],
            [3 * big_t**2, 4 * big_t**3, 5 * big_t**4],
            [6 * big_t, 12 * big_t**2, 20 * big_t**3],
        ]
    )
    rhs = np.stack(
        [
            p1 - (p0 + v0 * big_t + 0.5 * a0 * big_t**2),
            v1 - (v0 + a0 * big_t),
            a1 - a0,
        ]
    )
    c3, c4, c5 = np.linalg.solve(m, rhs)
    s = np.asarray(t, dtype=float)[:, None]
    q = p0 + v0 * s + 0.5 * a0 * s**2 + c3 * s**3 + c4 * s**4 + c5 * s**5
    dq = v0 + a0 * s + 3 * c3 * s**2 + 4 * c4 * s**3 + 5 * c5 * s**4
    ddq = a0 + 6 * c3 * s + 12 * c4 * s**2 + 20 * c5 * s**3
    return q, dq, ddq


def transition_duration(
    start: tuple[FloatArray, FloatArray, FloatArray],
    end: tuple[FloatArray, FloatArray, FloatArray],
    limits: JointLimits,
    *,
    limit_fraction: float = 0.5,
    timestep: float = 1e-3,
    min_duration: float = 0.5,
) -> float:
    """Shortest quintic duration [s] keeping ``|dq|``, ``|ddq|`` within a fraction of the limits.

    Starts from the rest-to-rest bound and grows by 20 % until every sample (``timestep``
    apart) is within ``limit_fraction`` of the velocity and acceleration limits; the result is
    a whole number of time steps.

    Raises
    ------
    ValueError
        If no duration up to 1000 times the first guess works (a boundary state beyond the
        limits).
    """
    vmax = limit_fraction * np.where(np.isfinite(limits.dq_max), limits.dq_max, _FALLBACK_VELOCITY)
    amax = limit_fraction * np.where(
        np.isfinite(limits.ddq_max), limits.ddq_max, _FALLBACK_ACCELERATION
    )
    delta = np.abs(np.asarray(end[0]) - np.asarray(start[0]))
    guess = max(
        min_duration,
        float(np.max(1.875 * delta / vmax)),
        float(np.max(np.sqrt(5.774 * delta / amax))),
    )
    duration = guess
    while duration <= 1000.0 * guess:
        duration = np.ceil(duration / timestep - 1e-9) * timestep
        t = np.linspace(0.0, duration, int(round(duration / timestep)) + 1)
        _, dq, ddq = quintic(start, end, duration, t)
        if np.all(np.abs(dq) <= vmax) and np.all(np.abs(ddq) <= amax):
            return float(duration)
        duration *= 1.2
    raise ValueError(
        "no transition duration keeps the velocity and acceleration within "
        f"{limit_fraction:g} of the limits; the excitation's start state exceeds them"
    )


def executable_trajectory(
    family: Any,
    x: npt.ArrayLike,
    home: npt.ArrayLike,
    *,
    rate_hz: float = 1000.0,
    n_periods: int = 1,
    limit_fraction: float = 0.5,
) -> JointTrajectory:
    """Approach + ``n_periods`` excitation periods + return, sampled at the controller's rate.

    Parameters
    ----------
    family :
        The excitation family (must support ``with_samples``, as the shipped families do).
    x :
        The design, shape (n_vars,).
    home :
        Home posture [rad or m], shape (nq,): the robot starts and ends there at rest.
    rate_hz, n_periods :
        Controller rate [Hz]; periods of the excitation (>= 1).
    limit_fraction :
        Fraction of the velocity and acceleration limits the transitions may use.

    Returns
    -------
    :
        The trajectory, ``t`` starting at 0 [s]; its samples ``t_k = k * dt`` with
        ``dt = period / round(period * rate_hz)``. Raises ``ValueError`` for
        ``n_periods < 1``, ``rate_hz <= 0`` or a home posture of the wrong shape.
    """
    limits, home = _limits_and_home(family, home, rate_hz, n_periods)
    n = int(round(float(family.period) * rate_hz))
    dt = float(family.period) / n
    if not hasattr(family, "with_samples"):
        raise ValueError(f"{type(family).__name__} cannot be evaluated at the controller's rate")
    batch = family.with_samples(n).trajectories(np.asarray(x, dtype=float)[None, :])
    q, dq, ddq = batch.q[0], batch.dq[0], batch.ddq[0]
    rest = np.zeros(limits.nq)
    first = (q[0], dq[0], ddq[0])
    n_in, n_out = _transition_steps((home, rest, rest), first, limits, limit_fraction, dt)
    # the approach's end is the excitation's first sample; the return starts at the end of
    # the last period
    t_in = np.arange(n_in, dtype=np.float64) * dt
    t_out = np.arange(n_out + 1, dtype=np.float64) * dt
    a = quintic((home, rest, rest), first, n_in * dt, t_in)
    r = quintic(first, (home, rest, rest), n_out * dt, t_out)
    parts = [
        np.concatenate([a[k], np.tile(s, (n_periods, 1)), r[k]]) for k, s in enumerate((q, dq, ddq))
    ]
    total = parts[0].shape[0]
    return JointTrajectory(
        t=np.arange(total, dtype=np.float64) * dt,
        q=parts[0],
        dq=parts[1],
        ddq=parts[2],
        joint_names=tuple(limits.joint_names),
    )


def _limits_and_home(
    family: Any, home: npt.ArrayLike, rate_hz: float, n_periods: int
) -> tuple[Any, FloatArray]:
    """The family's joint limits and the home posture as an array (nq,); raises the
    ``ValueError`` of :func:`executable_trajectory` for a bad argument."""
    if n_periods < 1:
        raise ValueError(f"n_periods must be >= 1, got {n_periods}")
    if not rate_hz > 0.0:
        raise ValueError(f"rate_hz must be > 0 Hz, got {rate_hz}")
    limits = family.limits if hasattr(family, "limits") else None
    if limits is None:
        raise ValueError("the family must expose its joint limits as family.limits")
    home = np.asarray(home, dtype=float)
    if home.shape != (limits.nq,):
        raise ValueError(f"home must have shape ({limits.nq},), got {home.shape}")
    return limits, home


def _transition_steps(
    at_home: tuple[FloatArray, FloatArray, FloatArray],
    first: tuple[FloatArray, FloatArray, FloatArray],
    limits: Any,
    limit_fraction: float,
    dt: float,
) -> tuple[int, int]:
    """Controller steps of the approach (home at rest -> ``first`` (q, dq, ddq)) and of the
    return (-> home at rest), each within ``limit_fraction`` of the limits, ``dt`` [s]."""
    approach_time = transition_duration(
        at_home, first, limits, limit_fraction=limit_fraction, timestep=dt
    )
    return_time = transition_duration(
        first, at_home, limits, limit_fraction=limit_fraction, timestep=dt
    )
    return int(round(approach_time / dt)), int(round(return_time / dt))
