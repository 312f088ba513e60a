"""Torque gains per joint from two logs and a payload of known mass.

A torque signal with a gain error ``g_j`` on joint ``j`` reads ``g_j tau_j`` (plus an offset).
From one arm's log alone the gains are known only up to one common scale; a payload of known
mass ``m`` fixes it. Two logs of the same arm, without (A) and with (B) the payload on the last
link, give for each joint ``j`` the rows::

    A:  tau_A_j = Y_j(A) theta_j
    B:  tau_B_j = Y_j(B) theta_j + g_j Y_n,j(B) phi

with ``Y_j`` the arm's base-parameter and extra columns (friction, rotor inertia, offset) of
row ``j``, ``theta_j = g_j theta`` *free per joint* (a joint's own gain scales every parameter
its row sees, its own friction and offset included, so these absorb nothing the other rows
need), ``Y_n,j`` the 10 columns of the last body and ``phi`` the payload's parameters
(Pinocchio order, about the last joint's frame), shared by every joint, ``phi[0] = m`` known.

Eliminating ``theta_j`` leaves, per joint, the part of row ``j`` that the arm cannot explain:
``r_j = g_j C_j phi`` (``C_j``: the payload columns projected off the arm's columns of row
``j``, both logs stacked; the arm's URDF inertials are never used). The gains and ``phi`` then
follow from the separable fit ``min sum_j ||g_j C_j phi - r_j||^2 / sigma_j^2`` with
``phi[0] = m`` (``sigma_j``: the noise of joint ``j`` from its own unconstrained fit).

Which gains are determined: joint ``j``'s gain is the ratio of its payload torque
``C_j phi`` to the payload's parameters, so it is determined where the payload's torque at
joint ``j`` is excited beyond what the arm's columns absorb (``payload_torque_rms``), and its
standard deviation (from the fit's Jacobian, white-noise assumption) is about
``sigma_j / ||C_j phi||``. A joint the payload does not load (a vertical first axis without
accelerations, a last joint about which the payload's centre of mass lies) has no gain here.

Rows come from the one preprocessing of every identification
(:func:`ident.identify.payload.payload_rows.payload_observations`, chunked, reduced per joint).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from ident.dynamics.chain import KinematicChain
from ident.dynamics.gram import selected_rows
from ident.dynamics.parameter_model import ParameterModel
from ident.errors import DataError
from ident.identify.config import PreprocessConfig
from ident.identify.estimation.accumulate import BaseColumns
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.payload.payload_rows import payload_observations
from ident.measure.logs import RobotLog

__all__ = ["GainColumns", "PayloadGains", "estimate_payload_gains", "payload_gain_observations"]

FloatArray = npt.NDArray[np.float64]

#: Relative tolerance of the rank of a joint's arm columns (after scaling each to unit norm).
RANK_RTOL = 1e-9


class GainColumns:
    """Columns ``[arm base columns | payload (10) | 0]``, shape (n, nv, n_arm + 11).

    The arm's columns are the base parameters of ``pm`` (inertial and extra terms,
    :class:`ident.identify.estimation.accumulate.BaseColumns`); the payload's the last body's 10
    standard columns, zero when ``with_payload`` is False; the last column is zero (no known
    torque is subtracted: :func:`ident.identify.payload.payload_rows.payload_observations`).
    """

    def __init__(self, chain: KinematicChain, pm: ParameterModel, *, with_payload: bool) -> None:
        self.chain = chain
        self.arm = BaseColumns(chain, pm)
        self.n_arm = int(self.arm.order.size)
        self.with_payload = with_payload
        self.last = np.arange(10 * (chain.n_joints - 1), 10 * chain.n_joints)

    def __call__(self, q: FloatArray, dq: FloatArray, ddq: FloatArray) -> FloatArray:
        n, nv = dq.shape
        out = np.zeros((n, nv, self.n_arm + 11))
        out[:, :, : self.n_arm] = self.arm(q, dq, ddq)
        if self.with_payload:
            payload = selected_rows(self.chain, q, dq, ddq, columns=self.last)
            out[:, :, self.n_arm : self.n_arm + 10] = payload.reshape(n, nv, 10)
        return out


def payload_gain_observations(
    with_payload: RobotLog,
    without_payload: RobotLog,
    pp: PreprocessConfig,
    chain: KinematicChain,
    pm: ParameterModel,
) -> ReducedObservations:
    """Both logs' rows ``[arm | payload]``, processed and reduced per joint (module docstring).

    Columns: the ``n_arm`` base columns of ``pm`` then the payload's 10; shape of ``R``
    (nv, n_arm + 10, n_arm + 10).
    """
    red = payload_observations(with_payload, pp, GainColumns(chain, pm, with_payload=True))
    return red.merge(
        payload_observations(without_payload, pp, GainColumns(chain, pm, with_payload=False))
    )


@dataclass(frozen=True, eq=False)
class PayloadGains:
    """Torque gains per joint against a payload of known mass.

    Attributes
    ----------
    gains :
        ``g_j`` (measured / true torque), shape (nv,); NaN where the payload does not load the
        joint (no payload column acts on its row).
    gain_std :
        Standard deviations of ``gains`` (white-noise assumption), shape (nv,).
    phi :
        The payload's parameters, ``phi[0]`` the known mass, shape (10,) (SI, Pinocchio order,
        about the last joint's frame).
    payload_torque_rms :
        RMS of the payload's torque at each joint that the arm's columns cannot absorb
        [N*m], shape (nv,): the excitation each gain is measured from.
    sigma :
        Noise estimate of each joint's rows [N*m], shape (nv,).
    """

    gains: FloatArray
    gain_std: FloatArray
    phi: FloatArray
    payload_torque_rms: FloatArray
    sigma: FloatArray

    def summary(self) -> dict:
        """JSON-ready values."""

        def listed(a: FloatArray) -> list[float | None]:
            return [None if not np.isfinite(v) else float(v) for v in a]

        return {
            "gains": listed(self.gains),
            "gain_std": listed(self.gain_std),
            "payload_torque_rms_nm": listed(self.payload_torque_rms),
            "payload_parameters": self.phi.tolist(),
        }


def _joint_rows(
    red: ReducedObservations, j: int, n_arm: int
) -> tuple[FloatArray, FloatArray, float, int]:
    """``(C_j, r_j, rho_j, dof_j)``: payload columns and torque of joint ``j`` off its arm
    columns (module docstring), from the triangular factor; ``dof_j`` the residual's degrees
    of freedom."""
    M = np.column_stack([red.R[j], red.z[j]])
    A = M[:, :n_arm]
    norms = np.linalg.norm(A, axis=0)
    acting = norms > 0.0
    rank = 0
    if acting.any():
        U, s, _ = np.linalg.svd(A[:, acting] / norms[acting], full_matrices=False)
        rank = int(np.sum(s > RANK_RTOL * s[0]))
        U = U[:, :rank]
        M = M - U @ (U.T @ M)
    C, r = M[:, n_arm:-1], M[:, -1]
    rank_c = int(np.linalg.matrix_rank(C)) if np.any(C) else 0
    return C, r, float(red.rho[j]), int(red.n_rows[j]) - rank - rank_c


def _loaded_rows(
    red: ReducedObservations, n_arm: int
) -> list[tuple[int, FloatArray, FloatArray, float]]:
    """``(j, C_j / s_j, r_j / s_j, s_j)`` of each joint ``j`` whose rows the payload loads
    (:func:`_joint_rows`), ``s_j`` the noise of its own least-squares fit ``C_j psi = r_j``
    [N*m], so that every joint's rows weigh alike.

    Raises
    ------
    DataError
        If no joint's row carries the payload, or too few rows to estimate the noise.
    """
    rows: list[tuple[int, FloatArray, FloatArray, float]] = []
    for j in range(red.n_groups):
        C, r, rho, dof = _joint_rows(red, j, n_arm)
        if not np.any(C):
            continue
        if dof <= 0:
            raise DataError(f"torque gains: joint {j + 1} has too few rows ({red.n_rows[j]}).")
        psi = np.linalg.lstsq(C, r, rcond=None)[0]
        noise = float(np.sqrt((np.sum((C @ psi - r) ** 2) + rho) / dof))
        rows.append((j, C / noise, r / noise, noise))
    if not rows:
        raise DataError("torque gains: the payload's columns act on no joint's rows.")
    return rows


def estimate_payload_gains(red: ReducedObservations, n_arm: int, mass: float) -> PayloadGains:
    """Per-joint torque gains and the payload from reduced rows ``[arm | payload]``.

    Parameters
    ----------
    red :
        Rows of both logs reduced per joint (:func:`payload_gain_observations`): ``n_arm``
        arm columns, then the payload's 10.
    n_arm :
        Number of arm columns.
    mass :
        The payload's known mass [kg], > 0.

    Raises
    ------
    DataError
        If no joint's row carries the payload, or too few rows to estimate the noise.
    """
    nv = red.n_groups
    rows = _loaded_rows(red, n_arm)
    loaded = np.array([j for j, *_ in rows], dtype=np.intp)
    k = loaded.size

    def unpack(x: FloatArray) -> tuple[FloatArray, FloatArray]:
        return x[:k], np.concatenate([[mass], x[k:]])

    def residual(x: FloatArray) -> FloatArray:
        g, phi = unpack(x)
        return np.concatenate([g[i] * (C @ phi) - r for i, (_, C, r, _) in enumerate(rows)])

    def jacobian(x: FloatArray) -> FloatArray:
        g, phi = unpack(x)
        blocks = []
        for i, (_, C, _, _) in enumerate(rows):
            block = np.zeros((C.shape[0], x.size))
            block[:, i] = C @ phi
            block[:, k:] = g[i] * C[:, 1:]
            blocks.append(block)
        return np.vstack(blocks)

    # start: unit gains, phi by linear least squares with the mass fixed
    C_all = np.vstack([C for _, C, _, _ in rows])
    r_all = np.concatenate([r - mass * C[:, 0] for _, C, r, _ in rows])
    phi0 = np.linalg.lstsq(C_all[:, 1:], r_all, rcond=None)[0]
    fit = least_squares(residual, np.concatenate([np.ones(k), phi0]), jac=jacobian, method="lm")
    g, phi = unpack(fit.x)
    J = jacobian(fit.x)
    cov = np.linalg.pinv(J.T @ J)
    gains = np.full(nv, np.nan)
    gain_std = np.full(nv, np.nan)
    gains[loaded] = g
    gain_std[loaded] = np.sqrt(np.clip(np.diag(cov)[:k], 0.0, None))
    payload_rms = np.zeros(nv)
    sigma = np.full(nv, np.nan)
    for j, C, _, s in rows:
        sigma[j] = s
        payload_rms[j] = s * float(np.linalg.norm(C @ phi)) / np.sqrt(max(red.n_rows[j], 1))
    return PayloadGains(
        gains=gains, gain_std=gain_std, phi=phi, payload_torque_rms=payload_rms, sigma=sigma
    )
