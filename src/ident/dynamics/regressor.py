"""Hand-derived joint-torque regressor: recursive Newton-Euler, linear in the parameters.

The formulation the paper cites (Atkeson, An and Hollerbach 1986; Khalil and Dombre 2002):
with each body's inertia taken about its own frame origin, the Newton-Euler wrench of body
``i`` is linear in its ten standard parameters,

    f_i = m_i (a_i + w_i x v_i) + (alpha_i x + w_i x w_i x) h_i
    n_i = Ibar_i alpha_i + w_i x (Ibar_i w_i) - (a_i + w_i x v_i) x h_i

(``h = m c`` the first moment, ``Ibar`` the inertia about the origin, ``v, w, a, alpha`` the
spatial velocity and acceleration of the frame origin in frame ``i``, gravity entered as the
base acceleration ``-g``), so ``f_i = A_i(v_i, a_i) phi_i`` with ``A_i`` of shape (6, 10).
Joint ``j`` carries the wrenches of all bodies ``i >= j`` of a serial chain:
``Y[j, block i] = S_j^T  jX*_i  A_i``. Frames, axes and the parameter order are Pinocchio's
(see :mod:`ident.dynamics.chain` and :mod:`ident.dynamics.parameters`), so ``Y`` equals
``pin.computeJointTorqueRegressor``.

Two implementations: a compiled numba kernel (scalar arithmetic, no allocation in the sample
loop; the default) and a numpy version vectorized over samples (the readable reference).
"""

from __future__ import annotations

import numpy as np

from ident.dynamics.chain import FloatArray, KinematicChain
from ident.errors import DataError

__all__ = ["joint_torque_regressor", "joint_torque_regressor_numpy", "project_rows"]


def _check_states(
    chain: KinematicChain, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Return C-contiguous float64 (n_samples, n) arrays or raise DataError."""
    n = chain.n_joints
    arrays = []
    for name, x in (("q", q), ("dq", dq), ("ddq", ddq)):
        x = np.ascontiguousarray(np.asarray(x, dtype=np.float64))
        if x.ndim == 1:
            x = x[None, :]
        if x.ndim != 2 or x.shape[1] != n:
            raise DataError(f"{name} must have shape (n_samples, {n}), got {np.shape(x)}")
        arrays.append(x)
    if not arrays[0].shape == arrays[1].shape == arrays[2].shape:
        raise DataError(
            f"q, dq, ddq must have the same number of samples, got "
            f"{arrays[0].shape[0]}, {arrays[1].shape[0]}, {arrays[2].shape[0]}"
        )
    return arrays[0], arrays[1], arrays[2]


def joint_torque_regressor(
    chain: KinematicChain, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> FloatArray:
    """Joint-torque regressor of a serial chain, vectorized over samples.

    Parameters
    ----------
    chain :
        Kinematic chain (:func:`~ident.dynamics.chain.chain_from_model`).
    q, dq, ddq :
        Positions [rad or m], velocities [rad/s or m/s], accelerations [rad/s^2 or m/s^2];
        shapes (n_samples, nq), (n_samples, nv), (n_samples, nv) (a single state of shape
        (nq,) is accepted as one sample).

    Returns
    -------
    :
        Regressor of shape (n_samples, nv, 10 * n_bodies) so that ``Y @ params`` gives the
        joint torques [N*m or N] of shape (n_samples, nv); parameters in the order of
        :func:`~ident.dynamics.parameters.parameter_names`. With mimic joints
        (``chain.coupled``) the bodies' regressor at the expanded state is projected on the
        independent joints: ``Y = G^T Y_bodies`` (:meth:`KinematicChain.coupling`), so a
        leader's row is its own plus ``m`` times its follower's.
    """
    q, dq, ddq = _check_states(chain, q, dq, ddq)
    from ident.dynamics import _kernels

    if chain.coupled:
        q, dq, ddq = chain.body_states(q, dq, ddq)
    nb = chain.n_bodies
    out = np.empty((q.shape[0], nb, 10 * nb))
    _kernels.regressor_into(*_kernels.chain_arrays(chain), *_kernels.states(q, dq, ddq), out)
    return project_rows(chain, out)


def project_rows(chain: KinematicChain, y: FloatArray) -> FloatArray:
    """Rows of the bodies' joints, shape (n_samples, nb, k), summed onto the independent
    joints with the mimic multipliers: ``G^T y``, shape (n_samples, nv, k); ``y`` itself
    without mimic joints."""
    if not chain.coupled:
        return y
    return np.einsum("bj,sbk->sjk", chain.coupling(), y)


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.cross(a, b, axis=-1)


def _rotation_about(axis: FloatArray, angle: FloatArray) -> FloatArray:
    """Rodrigues rotation matrices about a unit ``axis`` (3,), angles (n_samples,)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def _skew(x: FloatArray) -> FloatArray:
    """Cross-product matrices of vectors (n_samples, 3) -> (n_samples, 3, 3)."""
    out = np.zeros(x.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -x[..., 2], x[..., 1]
    out[..., 1, 0], out[..., 1, 2] = x[..., 2], -x[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -x[..., 1], x[..., 0]
    return out


def _inertia_map(u: FloatArray) -> FloatArray:
    """Matrices L(u) with ``Ibar @ u == L(u) @ [Ixx, Ixy, Iyy, Ixz, Iyz, Izz]``, (n, 3, 6)."""
    out = np.zeros(u.shape[:-1] + (3, 6))
    u0, u1, u2 = u[..., 0], u[..., 1], u[..., 2]
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 3] = u0, u1, u2
    out[..., 1, 1], out[..., 1, 2], out[..., 1, 4] = u0, u1, u2
    out[..., 2, 3], out[..., 2, 4], out[..., 2, 5] = u0, u1, u2
    return out


def joint_torque_regressor_numpy(
    chain: KinematicChain, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> FloatArray:
    """Same as :func:`joint_torque_regressor`, in numpy vectorized over samples.

    Slower than the compiled kernel for small chains; kept as a readable reference.
    """
    q, dq, ddq = _check_states(chain, q, dq, ddq)
    if chain.coupled:
        q, dq, ddq = chain.body_states(q, dq, ddq)
    n_samples, n = q.shape
    rotations = np.empty((n, n_samples, 3, 3))  # parent_R_i
    translations = np.empty((n, n_samples, 3))  # parent_p_i [m]
    blocks = []  # A_i, (n_samples, 6, 10): body wrench [f; n] = A_i @ phi_i in frame i
    v = np.zeros((n_samples, 3))
    w = np.zeros((n_samples, 3))
    a = np.broadcast_to(-chain.gravity, (n_samples, 3)).copy()  # gravity as base acceleration
    alpha = np.zeros((n_samples, 3))
    for i in range(n):
        placement, axis = chain.placements[i], chain.axes[i]
        if chain.prismatic[i]:
            rotation = np.broadcast_to(placement[:3, :3], (n_samples, 3, 3))
            translation = placement[:3, 3] + q[:, i, None] * (placement[:3, :3] @ axis)
        else:
            rotation = placement[:3, :3] @ _rotation_about(axis, q[:, i])
            translation = np.broadcast_to(placement[:3, 3], (n_samples, 3))
        rotations[i], translations[i] = rotation, translation
        # motion transform parent -> i: move to the new origin, then rotate into frame i
        v = np.einsum("sji,sj->si", rotation, v + _cross(w, translation))
        w = np.einsum("sji,sj->si", rotation, w)
        a = np.einsum("sji,sj->si", rotation, a + _cross(alpha, translation))
        alpha = np.einsum("sji,sj->si", rotation, alpha)
        s_dq = axis * dq[:, i, None]
        if chain.prismatic[i]:
            v = v + s_dq
            a = a + axis * ddq[:, i, None] + _cross(w, s_dq)
        else:
            w = w + s_dq
            alpha = alpha + axis * ddq[:, i, None] + _cross(w, s_dq)
            a = a + _cross(v, s_dq)
        a_c = a + _cross(w, v)  # classical acceleration of the origin
        block = np.zeros((n_samples, 6, 10))
        block[:, :3, 0] = a_c
        block[:, :3, 1:4] = _skew(alpha) + _skew(w) @ _skew(w)
        block[:, 3:, 1:4] = -_skew(a_c)
        block[:, 3:, 4:] = _inertia_map(alpha) + _skew(w) @ _inertia_map(w)
        blocks.append(block)
    out = np.zeros((n_samples, n, 10 * n))
    for i in range(n):
        force, moment = blocks[i][:, :3], blocks[i][:, 3:]
        for j in range(i, -1, -1):
            axis = chain.axes[j]
            projected = force if chain.prismatic[j] else moment
            out[:, j, 10 * i : 10 * i + 10] = np.einsum("k,skc->sc", axis, projected)
            if j > 0:  # force transform i -> parent: rotate, then moment about the new origin
                force = rotations[j] @ force
                moment = rotations[j] @ moment + np.cross(
                    translations[j][:, :, None], force, axis=1
                )
    return project_rows(chain, out)
