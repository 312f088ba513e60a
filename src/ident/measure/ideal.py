"""Simulated joint measurements along an excitation trajectory.

The "robot" is Pinocchio's recursive Newton-Euler algorithm (``pin.rnea``) on a model that
carries the true inertial parameters (the URDF written from the robot config). A
:class:`NoiseModel` then corrupts what a controller would log:

- joint torques get zero-mean Gaussian noise, one standard deviation per joint [N*m];
- optionally, joint positions are quantized by an incremental encoder
  (``encoder_counts_per_rev`` counts per joint revolution, step ``2*pi / counts`` [rad]),
  and velocities and accelerations are then obtained by numerical differentiation of the
  quantized positions (second-order central differences, ``numpy.gradient``), optionally
  after a zero-phase Butterworth low-pass filter (``filter_cutoff_hz``).

Torques are always computed from the exact state; only what is *measured* is corrupted, so
an estimate built on the measured state carries both the torque noise and the
errors-in-variables of the differentiated encoder signal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.errors import DataError
from ident.signals import central_differences, zero_phase_lowpass

__all__ = [
    "Measurements",
    "NoiseModel",
    "differentiate",
    "inverse_dynamics",
    "quantize",
    "simulate_measurements",
]

FloatArray = npt.NDArray[np.float64]
RngLike = np.random.Generator | int | None


@dataclass(frozen=True, slots=True, kw_only=True)
class NoiseModel:
    """How simulated measurements are corrupted.

    Attributes
    ----------
    torque_std :
        Standard deviation of the Gaussian torque noise [N*m]: one value for every joint,
        or one per joint (length ``nv``). ``0`` gives noise-free torques.
    encoder_counts_per_rev :
        Encoder resolution [counts per revolution]; ``None`` measures ``q`` exactly and
        passes the exact ``dq`` and ``ddq`` through.
    filter_cutoff_hz :
        Cut-off [Hz] of a zero-phase Butterworth low-pass filter applied to the quantized
        positions before differentiation; ``None`` for no filter. Only used with an encoder.
    filter_order :
        Order of that filter.
    """

    torque_std: float | tuple[float, ...] = 0.0
    encoder_counts_per_rev: int | None = None
    filter_cutoff_hz: float | None = None
    filter_order: int = 4

    def __post_init__(self) -> None:
        std = np.atleast_1d(np.asarray(self.torque_std, dtype=float))
        if std.ndim != 1 or np.any(~np.isfinite(std)) or np.any(std < 0.0):
            raise DataError(
                f"noise model: torque_std must be finite and >= 0 N*m, got {self.torque_std!r}"
            )
        if self.encoder_counts_per_rev is not None and self.encoder_counts_per_rev < 1:
            raise DataError(
                "noise model: encoder_counts_per_rev must be a positive integer or null, "
                f"got {self.encoder_counts_per_rev}"
            )
        if self.filter_cutoff_hz is not None and not self.filter_cutoff_hz > 0.0:
            raise DataError(
                f"noise model: filter_cutoff_hz must be > 0 Hz or null, got {self.filter_cutoff_hz}"
            )

    @property
    def is_noise_free(self) -> bool:
        """True when the measurements equal the simulated truth."""
        return self.encoder_counts_per_rev is None and not np.any(np.asarray(self.torque_std))

    def torque_std_per_joint(self, nv: int) -> FloatArray:
        """Torque noise standard deviation per joint [N*m], shape (nv,)."""
        std = np.atleast_1d(np.asarray(self.torque_std, dtype=float))
        if std.size == 1:
            return np.full(nv, float(std[0]))
        if std.size != nv:
            raise DataError(
                f"noise model: torque_std has {std.size} values but the robot has {nv} joints; "
                "give one value for all joints or one per joint."
            )
        return std.copy()


@dataclass(frozen=True, eq=False)
class Measurements:
    """What a controller would log along a trajectory, and the truth behind it.

    Attributes
    ----------
    t :
        Time stamps [s], shape (n_samples,).
    q, dq, ddq :
        Measured positions [rad], velocities [rad/s], accelerations [rad/s^2],
        shapes (n_samples, nq), (n_samples, nv), (n_samples, nv).
    tau :
        Measured joint torques [N*m], shape (n_samples, nv).
    tau_true :
        Noise-free torques of the exact state [N*m], shape (n_samples, nv).
    torque_std :
        Standard deviation of the torque noise per joint [N*m], shape (nv,).
    """

    t: FloatArray
    q: FloatArray
    dq: FloatArray
    ddq: FloatArray
    tau: FloatArray
    tau_true: FloatArray
    torque_std: FloatArray

    def __post_init__(self) -> None:
        for a in (self.t, self.q, self.dq, self.ddq, self.tau, self.tau_true, self.torque_std):
            a.setflags(write=False)


def inverse_dynamics(model: object, q: FloatArray, dq: FloatArray, ddq: FloatArray) -> FloatArray:
    """Joint torques of a Pinocchio model along sampled states (``pin.rnea``).

    Parameters
    ----------
    model :
        A ``pinocchio.Model`` holding the true inertial parameters.
    q, dq, ddq :
        Positions, velocities, accelerations; shapes (n_samples, nq), (n_samples, nv),
        (n_samples, nv).

    Returns
    -------
    :
        Torques [N*m], shape (n_samples, nv).
    """
    import pinocchio as pin

    q, dq, ddq = _as_states(model, q, dq, ddq)
    data = model.createData()  # type: ignore[attr-defined]
    tau = np.empty((q.shape[0], model.nv))  # type: ignore[attr-defined]
    for k in range(q.shape[0]):  # Pinocchio evaluates one state at a time
        tau[k] = pin.rnea(model, data, q[k], dq[k], ddq[k])
    return tau


def quantize(q: FloatArray, counts_per_rev: int) -> FloatArray:
    """Round joint positions to the nearest encoder count.

    Parameters
    ----------
    q :
        Positions [rad], any shape.
    counts_per_rev :
        Encoder counts per revolution; the step is ``2*pi / counts_per_rev`` [rad].

    Returns
    -------
    :
        Quantized positions [rad], same shape as ``q``.
    """
    step = 2.0 * np.pi / counts_per_rev
    return np.round(np.asarray(q, dtype=float) / step) * step


def differentiate(
    t: FloatArray,
    q: FloatArray,
    *,
    filter_cutoff_hz: float | None = None,
    filter_order: int = 4,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Velocities and accelerations by numerical differentiation of sampled positions.

    Second-order central differences inside, second-order one-sided differences at both
    ends (``numpy.gradient(..., edge_order=2)``), applied twice. With ``filter_cutoff_hz``
    the positions first pass a zero-phase Butterworth low-pass filter
    (``scipy.signal.sosfiltfilt``; its gain is squared, -6 dB at the cut-off).

    Parameters
    ----------
    t :
        Uniformly spaced time stamps [s], shape (n_samples,), n_samples >= 3.
    q :
        Positions [rad], shape (n_samples, n_joints).

    Returns
    -------
    q_filtered, dq, ddq :
        Positions (filtered or as given) [rad], velocities [rad/s], accelerations
        [rad/s^2]; each of shape (n_samples, n_joints).

    Raises
    ------
    DataError
        If ``t`` is not uniformly spaced and increasing, or the cut-off is at or above
        the Nyquist frequency.
    """
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    if t.ndim != 1 or t.shape[0] < 3 or q.shape[0] != t.shape[0]:
        raise DataError(
            f"differentiate: need >= 3 samples with t of shape (n,) and q of shape (n, nj); "
            f"got t {t.shape}, q {q.shape}"
        )
    steps = np.diff(t)
    timestep_s = float(np.mean(steps))
    if timestep_s <= 0.0 or np.max(np.abs(steps - timestep_s)) > 1e-9 * max(1.0, t[-1]):
        raise DataError("differentiate: time stamps must be increasing and uniformly spaced.")
    if filter_cutoff_hz is not None:
        sampling_rate_hz = 1.0 / timestep_s
        if filter_cutoff_hz >= 0.5 * sampling_rate_hz:
            raise DataError(
                f"differentiate: filter_cutoff_hz = {filter_cutoff_hz} Hz is at or above the "
                f"Nyquist frequency {0.5 * sampling_rate_hz:g} Hz of the sampling; lower it."
            )
        q = zero_phase_lowpass(q, sampling_rate_hz, filter_cutoff_hz, filter_order)
    dq, ddq = central_differences(q, 1.0 / timestep_s)
    return q, dq, ddq


def simulate_measurements(
    model: object,
    t: FloatArray,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    noise: NoiseModel,
    *,
    rng: RngLike = None,
) -> Measurements:
    """Simulate a logged experiment: true torques by RNEA, then the noise model.

    Parameters
    ----------
    model :
        A ``pinocchio.Model`` with the true inertial parameters.
    t :
        Time stamps [s], shape (n_samples,).
    q, dq, ddq :
        Exact commanded motion; shapes (n_samples, nq), (n_samples, nv), (n_samples, nv).
    noise :
        The noise model.
    rng :
        Generator or seed for the torque noise (the only random draw).

    Returns
    -------
    :
        Measured state and torques, with the noise-free torques alongside.
    """
    rng = np.random.default_rng(rng)
    q, dq, ddq = _as_states(model, q, dq, ddq)
    t = np.array(t, dtype=float)
    tau_true = inverse_dynamics(model, q, dq, ddq)
    nv = tau_true.shape[1]
    std = noise.torque_std_per_joint(nv)
    # Draw even for zero std so that the random stream does not depend on the noise level.
    tau = tau_true + rng.standard_normal(tau_true.shape) * std[None, :]
    if noise.encoder_counts_per_rev is None:
        q_m, dq_m, ddq_m = q.copy(), dq.copy(), ddq.copy()
    else:
        q_m, dq_m, ddq_m = differentiate(
            t,
            quantize(q, noise.encoder_counts_per_rev),
            filter_cutoff_hz=noise.filter_cutoff_hz,
            filter_order=noise.filter_order,
        )
    return Measurements(t=t, q=q_m, dq=dq_m, ddq=ddq_m, tau=tau, tau_true=tau_true, torque_std=std)


def _as_states(
    model: object, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    q, dq, ddq = (np.ascontiguousarray(a, dtype=float) for a in (q, dq, ddq))
    nq, nv = model.nq, model.nv  # type: ignore[attr-defined]
    n = q.shape[0] if q.ndim == 2 else -1
    if q.shape != (n, nq) or dq.shape != (n, nv) or ddq.shape != (n, nv):
        raise DataError(
            f"measurements: expected q ({n}, {nq}), dq and ddq ({n}, {nv}); "
            f"got {q.shape}, {dq.shape}, {ddq.shape}"
        )
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(dq)) and np.all(np.isfinite(ddq))):
        raise DataError("measurements: the trajectory contains NaN or infinite values.")
    return q, dq, ddq
