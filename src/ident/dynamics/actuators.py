"""Actuator laws: what drives a joint, and so what the torque of its log is.

Two kinds (:data:`ACTUATOR_LAWS`, the identify config's ``actuator.kind``):

- ``motor``: a torque source whose torque (or current) is logged; the log's torque is the
  measurement of ``tau = Y(q, dq, ddq) theta + friction + Ia ddq``.
- ``position``: a position servo (Feetech, Dynamixel, a PD loop in a drive; MuJoCo's
  ``<position>`` with ``kv = kd``) that logs its command ``q_cmd`` and no torque. Its torque is
  the actuator's law::

      tau_j(t) = clip(kp_j e_j(t) - kd_j dq_j(t), -forcerange_j, forcerange_j),
      e_j(t) = q_cmd_j(t - d) - q_j(t)

  with ``d`` the command's transport delay. Where the clip is inactive, the identification
  equation ``Y theta + fv dq + fs sign(dq) + Ia ddq = kp e - kd dq`` is linear and homogeneous
  in ``[theta, fv, fs, Ia, kp, kd]``: the column of ``kp_j`` is ``e_j`` in row ``j`` (the
  torque per unit gain, :func:`servo_error`), and that of ``kd_j`` is ``-dq_j``, the viscous
  friction's column with the opposite sign. So ``kd_j`` and ``fv_j`` are never separable: the
  data see ``kd_j + fv_j`` (the ``fv{j}`` column). :mod:`ident.identify.actuators` fixes the
  common scale and estimates the rest.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.errors import ConfigError

__all__ = [
    "ACTUATOR_LAWS",
    "ActuatorLaw",
    "actuator_law",
    "saturated_samples",
    "servo_error",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True)
class ActuatorLaw:
    """One kind of actuator.

    Attributes
    ----------
    kind :
        Its name (``actuator.kind``).
    logs_torque :
        The log carries the joint torque (``log.torque`` required), else it has none.
    needs_command :
        The law needs the commanded positions (``log.command`` required).
    law :
        The torque law in words, for messages and reports.
    """

    kind: str
    logs_torque: bool
    needs_command: bool
    law: str


#: The actuator kinds, by name.
ACTUATOR_LAWS: dict[str, ActuatorLaw] = {
    "motor": ActuatorLaw("motor", True, False, "tau logged (torque or current)"),
    "position": ActuatorLaw(
        "position",
        False,
        True,
        "tau = clip(kp (q_cmd(t - d) - q) - kd dq, +-forcerange)",
    ),
}


def actuator_law(kind: str) -> ActuatorLaw:
    """The law named ``kind``; :class:`ConfigError` listing the kinds when there is none."""
    try:
        return ACTUATOR_LAWS[kind]
    except KeyError:
        raise ConfigError(
            f"actuator.kind = {kind!r}; allowed: {', '.join(ACTUATOR_LAWS)}"
        ) from None


def servo_error(
    q: FloatArray,
    q_cmd: FloatArray,
    delay_samples: float,
    segments: Sequence[tuple[int, int]],
) -> FloatArray:
    """The servo's position error ``e = q_cmd(t - d) - q`` [rad or m], shape (n_samples, nv).

    ``q``, ``q_cmd``: measured and commanded positions (n_samples, nv) on one uniform grid per
    segment; ``delay_samples``: ``d`` in samples (>= 0, a fraction allowed). Within each
    ``(start, stop)`` segment the command is shifted by ``d`` samples; its first samples hold
    the segment's first command (the servo held it before the log starts, as a delayed MuJoCo
    actuator's history does). A fraction ``f`` of a sample mixes the neighbouring shifts,
    ``(1 - f) q_cmd(t - floor(d)) + f q_cmd(t - floor(d) - 1)``: a command held over each
    period and delayed by ``d`` applies the one for a share ``1 - f`` of the period and the
    one before for ``f``, and the period's mean force is what moves the sample's
    acceleration.
    """
    d = float(delay_samples)
    if not d >= 0.0:
        raise ValueError(f"delay_samples = {d} must be >= 0")
    whole = int(np.floor(d))
    frac = d - whole
    delayed = _shifted(q_cmd, whole, segments)
    if frac > 0.0:
        delayed = (1.0 - frac) * delayed + frac * _shifted(q_cmd, whole + 1, segments)
    return delayed - q


def _shifted(x: FloatArray, d: int, segments: Sequence[tuple[int, int]]) -> FloatArray:
    """``x`` (n, nv) delayed by ``d`` whole samples within each segment, its first held."""
    out = np.empty_like(x)
    for a, b in segments:
        k = min(d, b - a)
        out[a : a + k] = x[a]
        out[a + k : b] = x[a : b - k]
    return out


def saturated_samples(
    e: FloatArray,
    dq: FloatArray,
    kp: npt.ArrayLike,
    damping: npt.ArrayLike,
    forcerange: npt.ArrayLike,
    margin: float = 0.02,
) -> BoolArray:
    """Samples (n_samples, nv) where the servo may have reached its force range.

    Only ``kd + fv`` (``damping``, N*m*s/rad) is known, not ``kd``: with ``0 <= kd <= kd + fv``
    the unclipped force ``kp e - kd dq`` lies between ``kp e`` and ``kp e - (kd + fv) dq``
    (it is linear in ``kd``), so a sample is saturated when either end reaches
    ``(1 - margin) forcerange`` (the margin covers the estimates' errors).
    """
    limit = (1.0 - margin) * np.asarray(forcerange, dtype=float)
    force = np.asarray(kp) * e
    other = force - np.asarray(damping) * dq
    return (np.abs(force) >= limit) | (np.abs(other) >= limit)
