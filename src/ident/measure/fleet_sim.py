"""Simulated logs of a fleet: units of one robot model doing routine motion, each with its own
friction and torque offsets.

A unit's routine motion is a cycle repeated (a periodic joint trajectory: one period of the
rigid-body torques, computed once with Pinocchio's RNEA of the shared model, the rotor
inertias added). The unit's log then adds, at every sample, its own viscous and Coulomb
friction (``fv dq + fs sign(dq)``) and offsets, Gaussian torque noise, and quantizes the
positions to the encoder's counts (:func:`ident.measure.ideal.quantize`). The positions are
offset before the quantization by a fraction of a count per joint that wanders from one
repetition of the cycle to the next (linearly): a robot
repeats its motion to its repeatability (a UR5's 0.1 mm is some 8 counts of a 2^19-count
encoder), not to a count, so the quantization's error differs from cycle to cycle (without
the offsets every cycle's positions were quantized identically: an error repeated in every
window of the log, which no statistic of the log can see). From ``rise_at_s``
on, the friction is ``1 + rise`` times larger (wear). The log is built where it is called
(a :class:`SimulatedUnitLog` is small and picklable: a Dask worker simulates its own log).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.measure.ideal import quantize
from ident.measure.logs import RobotLog

__all__ = ["SimulatedUnitLog"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class SimulatedUnitLog:
    """One unit's log of ``seconds`` of its repeated cycle (module docstring; SI).

    ``q``, ``dq`` (n, nv): one period of the cycle at ``rate_hz``; ``tau_rigid`` (n, nv): its
    rigid-body and rotor-inertia torques [N*m]; ``fv``, ``fs``, ``offset``, ``noise_std``
    (nv,): the unit's friction [N*m*s/rad, N*m], offsets and torque noise [N*m];
    ``start_s``: where in the cycle the log starts [s] (a unit's later log continues it).
    """

    q: FloatArray
    dq: FloatArray
    tau_rigid: FloatArray
    rate_hz: float
    seconds: float
    fv: FloatArray
    fs: FloatArray
    offset: FloatArray
    noise_std: FloatArray
    seed: int
    joint_names: tuple[str, ...]
    counts_per_rev: int | None = 524288
    rise: float = 0.0
    rise_at_s: float | None = None
    start_s: float = 0.0

    def __call__(self) -> RobotLog:
        n = int(round(self.seconds * self.rate_hz))
        period = self.q.shape[0]
        k = (int(round(self.start_s * self.rate_hz)) + np.arange(n)) % period
        q, dq = self.q[k], self.dq[k]
        t = np.arange(n) / self.rate_hz
        scale = np.ones((n, 1))
        if self.rise_at_s is not None:
            scale[t >= self.rise_at_s] = 1.0 + self.rise
        rng = np.random.default_rng(self.seed)
        tau = self.tau_rigid[k] + scale * (self.fv * dq + self.fs * np.sign(dq)) + self.offset
        tau += rng.standard_normal(tau.shape) * self.noise_std
        if self.counts_per_rev is not None:
            # the offset wanders linearly from cycle to cycle (a step would be a ddq impulse)
            k0 = int(round(self.start_s * self.rate_hz))
            knots = np.arange(k0 // period, (k0 + n) // period + 2) * period
            phase = rng.random((knots.size, q.shape[1]))  # counts
            count = 2 * np.pi / self.counts_per_rev
            drift = np.column_stack(
                [np.interp(k0 + np.arange(n), knots, phase[:, j]) for j in range(q.shape[1])]
            )
            q = quantize(q + drift * count, self.counts_per_rev)
        return RobotLog(
            t=t, q=q, tau=tau, sampling_rate_hz=self.rate_hz, joint_names=self.joint_names
        )
