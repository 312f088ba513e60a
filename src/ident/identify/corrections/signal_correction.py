"""The ``signals:`` section applied where a log is read: the torque's delay and gains.

Model of the measured torque (:mod:`ident.identify.corrections.signal_errors`)::

    tau_measured_j(t) = g_j tau_j(t - d) + o_j

**Delay.** ``signals.delay_s`` given, or ``auto``: :func:`estimate_log_delay` fits the
configured model (the base parameters and extra columns of ``model:``) to the log's first
segment, at most :data:`MAX_DELAY_SAMPLES` raw samples of it, for delays on a grid within
``max_delay_s`` and keeps the best
(:func:`ident.identify.corrections.signal_errors.estimate_delay`). The positions are low-passed as
the identification does it, the torques with the same zero-phase filter (so that the filter shifts
neither). :func:`shift_torque` then advances every segment's torque by the delay (linear
interpolation; the last ``d`` seconds of a segment hold its last value, and fall in the trimmed
edge).

**Gains** (``ident payload`` with ``payload.without`` and ``signals.gain_reference``): the
gains are estimated from both logs against the payload's known mass
(:mod:`ident.identify.payload.payload_gain`) after the delay is removed, and each joint's torque is
divided by its gain in both logs. A joint whose gain is not determined to
:data:`MAX_GAIN_STD` (the payload does not load it enough) keeps gain 1.

The offsets ``o_j`` are the model's offset columns (``model.offset``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from ident.blas import one_blas_thread
from ident.dynamics.chain import chain_from_model
from ident.dynamics.parameter_model import ParameterModel, build_parameter_model
from ident.errors import DataError
from ident.identify.config import ModelConfig, PreprocessConfig, SignalsConfig
from ident.identify.corrections.signal_errors import DelayEstimate, estimate_delay
from ident.identify.estimation import preprocess
from ident.identify.estimation.accumulate import BaseColumns
from ident.identify.payload.payload import PayloadResult, identify_payload, read_payload_logs
from ident.identify.payload.payload_config import PayloadConfig
from ident.identify.payload.payload_gain import (
    PayloadGains,
    estimate_payload_gains,
    payload_gain_observations,
)
from ident.measure.logs import RobotLog
from ident.model import Robot

__all__ = [
    "MAX_DELAY_SAMPLES",
    "MAX_GAIN_STD",
    "SignalCorrection",
    "applied_gains",
    "correct_log",
    "correct_payload_logs",
    "estimate_log_delay",
    "identify_corrected_payload",
    "shift_torque",
]

FloatArray = npt.NDArray[np.float64]

#: Raw samples of the first segment the delay is estimated on. The regressor at the raw rate
#: takes ``8 * nv * n_base`` bytes a sample and is held about four times (computed, filtered,
#: the rows of the fit and their Q factor): 20 000 samples of a 7-joint arm with 70 base
#: columns are 4 x 78 MB.
MAX_DELAY_SAMPLES = 20_000
#: Low-pass of the positions before they are differentiated for the delay fit [Hz].
DELAY_POSITION_CUTOFF_HZ = 30.0
#: The one filter on both the regressor and the torque of the delay fit [Hz] (parallel
#: filtering). On UR5 and Panda logs with a 5 ms delay: 4.87 and 5.46 ms at 5 Hz; 5.51 and
#: 6.61 ms at 10 Hz; 5.04 and 3.33 ms at 2 Hz.
DELAY_FIT_CUTOFF_HZ = 5.0
#: Time dropped at each end of the delay fit, after its filters [s] (their transients).
DELAY_EDGE_S = 0.5
#: A gain whose standard deviation is above this is not applied (the joint keeps gain 1).
MAX_GAIN_STD = 0.01


def shift_torque(log: RobotLog, delay_s: float, how: str = "given") -> RobotLog:
    """``log`` with the torque advanced by ``delay_s`` [s] in each segment: ``tau(t + d)``.

    A record (``step: signals.delay_s``, the delay in ``delay_s``, ``how`` it was found) is
    added to the log's records (the report's processing table and ``result.json``).
    """
    if delay_s == 0.0:
        return log
    tau = np.empty_like(log.tau)
    for a, b in log.segments:
        t = log.t[a:b]
        for j in range(tau.shape[1]):
            tau[a:b, j] = np.interp(t + delay_s, t, log.tau[a:b, j])
    record = {
        "step": "signals.delay_s",
        "detail": f"torque advanced by {1e3 * delay_s:.2f} ms ({how})",
        "delay_s": delay_s,
    }
    return replace(log, tau=tau, records=(*log.records, record))


def estimate_log_delay(
    log: RobotLog, pm: ParameterModel, robot: Robot, max_delay_s: float, trim_samples: int = 0
) -> DelayEstimate:
    """The torque's delay behind the positions on ``log``'s first segment (module docstring).

    Parallel filtering: the positions are low-passed at :data:`DELAY_POSITION_CUTOFF_HZ` and
    differentiated, the regressor ``Y(q, dq, ddq)`` and the torque are then low-passed by the
    same :data:`DELAY_FIT_CUTOFF_HZ` filter, so that both sides of ``tau = Y theta`` carry the
    same filter (a Coulomb step is smeared alike on both; the identification's own position
    filter, 10 Hz on the shipped configs, leaves the closed loop's acceleration content in
    the torque only and biased the delay by 5-7 ms on UR5 and Panda). ``trim_samples``
    (at least :data:`DELAY_EDGE_S` of samples) are dropped at each end, after the filters.

    Raises
    ------
    DataError
        If the segment is shorter than four times ``max_delay_s`` after trimming.
    """
    a, b = log.segments[0]
    fs = log.sampling_rate_hz
    edge = max(trim_samples, int(np.ceil(DELAY_EDGE_S * fs)))
    b = min(b, a + MAX_DELAY_SAMPLES + 2 * edge)
    cutoff = min(DELAY_POSITION_CUTOFF_HZ, 0.2 * fs)
    q, _ = preprocess.lowpass(log.q[a:b], fs, cutoff)
    dq, ddq, _ = preprocess.differentiate(q, fs)
    Y = BaseColumns(chain_from_model(robot.model), pm)(q, dq, ddq)
    fit = min(DELAY_FIT_CUTOFF_HZ, 0.5 * cutoff)
    Y, _ = preprocess.lowpass(Y, fs, fit, what="regressor")
    tau, _ = preprocess.lowpass(log.tau[a:b], fs, fit, what="tau")
    inner = slice(edge, b - a - edge)
    if inner.stop - inner.start < 2:
        raise DataError(
            f"the log's first segment ({b - a} samples) is too short to estimate the delay "
            f"after dropping {edge} samples at each end."
        )
    return estimate_delay(log.t[a:b][inner], tau[inner], Y[inner], max_delay_s=max_delay_s)


def applied_gains(gains: PayloadGains) -> FloatArray:
    """The gains the torque is divided by, shape (nv,): each estimated gain whose standard
    deviation is at most :data:`MAX_GAIN_STD`, else 1 (a joint the payload barely loads: a
    badly determined gain would add more error than the gain error it removes)."""
    determined = np.isfinite(gains.gains) & (gains.gain_std <= MAX_GAIN_STD)
    return np.where(determined, gains.gains, 1.0)


@dataclass(frozen=True, eq=False)
class SignalCorrection:
    """What the ``signals:`` section did.

    Attributes
    ----------
    delay_s :
        The delay removed [s] (given or estimated).
    delay :
        The estimate when ``delay_s: auto``, else None.
    gains :
        The gains divided out (``ident payload`` with a gain reference), else None.
    logs :
        The corrected logs, in the order given (``(with_payload, without_payload)``, or one).
    """

    delay_s: float
    delay: DelayEstimate | None
    gains: PayloadGains | None
    logs: tuple[RobotLog, ...]

    @property
    def changed(self) -> bool:
        """Whether a delay or gains were removed (or estimated)."""
        return self.delay_s != 0.0 or self.delay is not None or self.gains is not None

    def summary(self) -> dict:
        """JSON-ready values for ``result.json`` / ``payload.json``."""
        out: dict = {"delay_s": self.delay_s, "delay_estimated": self.delay is not None}
        if self.delay is not None:
            out["delay_fit_relative_residual"] = self.delay.residual
        if self.gains is not None:
            out["torque_gains"] = self.gains.summary()
            out["torque_gains"]["applied"] = applied_gains(self.gains).tolist()
        return out

    def line(self) -> str:
        """One line for the terminal and the report."""
        how = "estimated" if self.delay is not None else "given"
        text = f"torque delay {1e3 * self.delay_s:.2f} ms ({how})"
        if self.gains is not None:
            g = ", ".join(
                "n/a" if not np.isfinite(v) else f"{v:.4f} +- {s:.4f}"
                for v, s in zip(self.gains.gains, self.gains.gain_std, strict=True)
            )
            text += f"; torque gains (payload of known mass) [{g}]"
            kept = np.flatnonzero(applied_gains(self.gains) == 1.0) + 1
            if kept.size:
                text += f"; not applied (not determined) on joints {kept.tolist()}"
        return text


def _delay(
    signals: SignalsConfig, log: RobotLog, pp: PreprocessConfig, pm: ParameterModel, robot: Robot
) -> tuple[float, DelayEstimate | None, str]:
    """The delay [s], its estimate (``auto``) or None, and how it was found (words)."""
    if signals.delay_s != "auto":
        return float(signals.delay_s), None, "given"
    found = estimate_log_delay(log, pm, robot, signals.max_delay_s, pp.trim_samples)
    how = (
        f"estimated within +-{1e3 * signals.max_delay_s:g} ms, fit relative residual "
        f"{found.residual:.4f}"
    )
    return found.delay_s, found, how


def correct_log(
    signals: SignalsConfig,
    robot: Robot,
    pp: PreprocessConfig,
    model: ModelConfig,
    log: RobotLog,
    *,
    source: str = "config",
) -> SignalCorrection:
    """``log`` with the configured (or estimated) delay removed (``ident identify``)."""
    if signals.delay_s == 0.0:
        return SignalCorrection(0.0, None, None, (log,))
    pp, _, _ = preprocess.resolve_for_log(pp, log)
    with one_blas_thread():  # small solves: threads only wait
        pm = build_parameter_model(robot.model, model.extra_terms(robot.nv, source))
        delay_s, found, how = _delay(signals, log, pp, pm, robot)
    return SignalCorrection(delay_s, found, None, (shift_torque(log, delay_s, how),))


def correct_payload_logs(
    signals: SignalsConfig,
    robot: Robot,
    pp: PreprocessConfig,
    model: ModelConfig,
    with_payload: RobotLog,
    without_payload: RobotLog | None,
    *,
    source: str = "config",
) -> SignalCorrection:
    """Both logs of ``ident payload`` with the delay (estimated on the log without the
    payload when there is one) and, with ``signals.gain_reference``, the gains removed."""
    given = (with_payload,) if without_payload is None else (with_payload, without_payload)
    if signals.delay_s == 0.0 and signals.gain_reference is None:
        return SignalCorrection(0.0, None, None, given)
    with one_blas_thread():  # small solves: threads only wait
        resolved, _, _ = preprocess.resolve_for_log(pp, with_payload)
        pm = build_parameter_model(robot.model, model.extra_terms(robot.nv, source))
        delay_s, found, how = _delay(signals, without_payload or with_payload, resolved, pm, robot)
        logs = [shift_torque(with_payload, delay_s, how)]
        if without_payload is not None:
            logs.append(shift_torque(without_payload, delay_s, how))
        gains = None
        if signals.gain_reference is not None and without_payload is not None:
            chain = chain_from_model(robot.model)
            red = payload_gain_observations(logs[0], logs[1], resolved, chain, pm)
            n_arm = red.n_params - 10
            gains = estimate_payload_gains(red, n_arm, signals.gain_reference.payload_mass_kg)
            divide = applied_gains(gains)
            record = {
                "step": "signals.gain_reference",
                "detail": "torque divided by the gains (payload of known mass; 1: not "
                f"determined to {100 * MAX_GAIN_STD:g} %): "
                + ", ".join(f"{g:.4f}" for g in divide),
                "torque_gains": divide.tolist(),
            }
            logs = [replace(x, tau=x.tau / divide, records=(*x.records, record)) for x in logs]
        return SignalCorrection(delay_s, found, gains, tuple(logs))


def identify_corrected_payload(cfg: PayloadConfig, robot: Robot) -> PayloadResult:
    """``ident payload``: read both logs, remove ``cfg.signals``' delay and gains, estimate
    the payload (:func:`ident.identify.payload.payload.identify_payload`); the result's ``signals``
    says what was removed."""
    source = str(cfg.source or "config")
    with_log, without_log = read_payload_logs(cfg, robot.model)
    correction = correct_payload_logs(
        cfg.signals, robot, cfg.preprocess, cfg.model, with_log, without_log, source=source
    )
    logs = (correction.logs[0], correction.logs[1] if without_log is not None else None)
    result = identify_payload(cfg, robot=robot, logs=logs)
    if not correction.changed:
        return result
    return replace(result, signals={**correction.summary(), "line": correction.line()})
