"""Vectorized clearances of primitive geometry, for the optimization's cheap constraint term.

Pinocchio + coal evaluate one posture at a time (about 2 us per pair on the paper robot, plus
a Python loop over postures). The cheap term of the optimization needs a swarm's postures at
once, so robot geometry that is a cylinder, capsule or sphere is handled here as array code
over all postures:

- forward kinematics of the joint frames, batched over postures (Rodrigues rotations);
- each such geometry is a segment (the axis; a point for a sphere) with a radius, and its
  distance to a half-space is exact (a cylinder's lowest point along the normal is
  ``n.c - h |n.u| - r sqrt(1 - (n.u)^2)``, a capsule's ``n.c - h |n.u| - r``);
- between two of them, and to a sphere obstacle, the distance is that of the swept spheres
  (segment-segment distance minus the radii): exact for capsules and spheres, a *lower bound*
  for cylinders (the capsule contains the cylinder). Where that bound is within the margin,
  :meth:`ident.excitation.safety.SafetyModel.fast_clearances` asks coal for the exact value
  (a broad phase: most pairs of a swarm are far apart).

Other pairs (meshes, boxes) stay with coal. The dense check never uses this module.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

__all__ = ["joint_frames", "segment_distances"]

_EPS = 1e-12


def joint_frames(
    placements: FloatArray, axes: FloatArray, prismatic: npt.NDArray[np.bool_], q: FloatArray
) -> FloatArray:
    """World poses of the joint frames of a serial chain, batched over postures.

    Parameters
    ----------
    placements :
        Joint placements in the parent joint frame at q = 0, shape (n_joints, 4, 4).
    axes :
        Unit joint axes in the joint frames, shape (n_joints, 3).
    prismatic :
        Prismatic joints, shape (n_joints,).
    q :
        Positions [rad or m], shape (n_postures, n_joints).

    Returns
    -------
    :
        Shape (n_postures, n_joints, 4, 4) [m].
    """
    n_post, n_joints = q.shape
    out = np.empty((n_post, n_joints, 4, 4))
    current = np.broadcast_to(np.eye(4), (n_post, 4, 4))
    for j in range(n_joints):  # down the chain; every posture at once
        motion = np.broadcast_to(np.eye(4), (n_post, 4, 4)).copy()
        k = axes[j]
        if prismatic[j]:
            motion[:, :3, 3] = q[:, j, None] * k
        else:
            skew = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
            s, c = np.sin(q[:, j]), np.cos(q[:, j])
            motion[:, :3, :3] = (
                np.eye(3) + s[:, None, None] * skew + (1.0 - c)[:, None, None] * (skew @ skew)
            )
        current = current @ placements[j] @ motion
        out[:, j] = current
    return out


def segment_distances(p1: FloatArray, q1: FloatArray, p2: FloatArray, q2: FloatArray) -> FloatArray:
    """Distance between segments ``[p1, q1]`` and ``[p2, q2]``, shapes (..., 3) -> (...).

    Closest points of two segments (Ericson, *Real-Time Collision Detection*, 5.1.9), with the
    degenerate cases (a segment of length 0) handled by the clamps.
    """
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("...i,...i", d1, d1)
    e = np.einsum("...i,...i", d2, d2)
    f = np.einsum("...i,...i", d2, r)
    c = np.einsum("...i,...i", d1, r)
    b = np.einsum("...i,...i", d1, d2)
    denom = a * e - b * b
    safe_a = np.where(a > _EPS, a, 1.0)
    safe_e = np.where(e > _EPS, e, 1.0)
    s = np.where(denom > _EPS * np.maximum(a * e, _EPS), (b * f - c * e) / np.where(
        denom > 0.0, denom, 1.0), 0.0)  # fmt: skip
    s = np.clip(s, 0.0, 1.0)
    t = (b * s + f) / safe_e
    s = np.where(t < 0.0, np.clip(-c / safe_a, 0.0, 1.0), np.where(t > 1.0, np.clip(
        (b - c) / safe_a, 0.0, 1.0), s))  # fmt: skip
    t = np.clip(t, 0.0, 1.0)
    # degenerate first segment: closest point of the second one to p1
    s = np.where(a > _EPS, s, 0.0)
    t = np.where(a > _EPS, t, np.clip(f / safe_e, 0.0, 1.0))
    t = np.where(e > _EPS, t, 0.0)
    s = np.where((e <= _EPS) & (a > _EPS), np.clip(-c / safe_a, 0.0, 1.0), s)
    closest = (p1 + s[..., None] * d1) - (p2 + t[..., None] * d2)
    return np.sqrt(np.einsum("...i,...i", closest, closest))
