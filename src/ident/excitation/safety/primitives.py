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

:func:`primitive_distances` is the compiled (numba) kernel of the last two items, one posture
at a time with scalar arithmetic; :func:`segment_distances` is the same segment distance over
arrays (tested against closed forms).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

__all__ = ["joint_frames", "primitive_distances", "segment_distances"]

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
    q = np.ascontiguousarray(q, dtype=np.float64)
    out = np.empty((q.shape[0], q.shape[1], 4, 4))
    _joint_frames_into(
        np.ascontiguousarray(placements, dtype=np.float64),
        np.ascontiguousarray(axes, dtype=np.float64),
        np.ascontiguousarray(prismatic, dtype=np.bool_),
        q,
        out,
    )
    return out


@njit(cache=True, nogil=True)
def _joint_frames_into(
    placements: FloatArray, axes: FloatArray, prismatic: npt.NDArray[np.bool_], q: FloatArray,
    out: FloatArray,
) -> None:  # fmt: skip
    """Kernel of :func:`joint_frames`: ``T_j = T_{j-1} P_j M_j(q_j)`` per posture, with the
    Rodrigues rotation ``M = I + s [k]x + (1 - c) [k]x^2`` (or a translation along k)."""
    n_joints = q.shape[1]
    current = np.empty((4, 4))
    step = np.empty((4, 4))
    motion = np.empty((4, 4))
    for n in range(q.shape[0]):
        current[:] = 0.0
        for i in range(4):
            current[i, i] = 1.0
        for j in range(n_joints):
            kx, ky, kz = axes[j, 0], axes[j, 1], axes[j, 2]
            motion[:] = 0.0
            for i in range(4):
                motion[i, i] = 1.0
            if prismatic[j]:
                motion[0, 3], motion[1, 3], motion[2, 3] = q[n, j] * kx, q[n, j] * ky, q[n, j] * kz
            else:
                s, t = math.sin(q[n, j]), 1.0 - math.cos(q[n, j])
                # [k]x^2 = k k^T - |k|^2 I
                kk = kx * kx + ky * ky + kz * kz
                k = (kx, ky, kz)
                skew = ((0.0, -kz, ky), (kz, 0.0, -kx), (-ky, kx, 0.0))
                for r in range(3):
                    for c in range(3):
                        sq = k[r] * k[c] - (kk if r == c else 0.0)
                        motion[r, c] += s * skew[r][c] + t * sq
            for r in range(4):  # step = current @ placements[j]
                for c in range(4):
                    acc = 0.0
                    for m in range(4):
                        acc += current[r, m] * placements[j, m, c]
                    step[r, c] = acc
            for r in range(4):  # current = step @ motion
                for c in range(4):
                    acc = 0.0
                    for m in range(4):
                        acc += step[r, m] * motion[m, c]
                    current[r, c] = acc
                    out[n, j, r, c] = acc


@njit(cache=True)
def _clip01(x: float) -> float:
    return min(max(x, 0.0), 1.0)


@njit(cache=True)
def _segment_distance(p1: FloatArray, q1: FloatArray, p2: FloatArray, q2: FloatArray) -> float:
    """Distance between segments ``[p1, q1]`` and ``[p2, q2]`` (Ericson 5.1.9), scalar."""
    a = e = f = c = b = 0.0
    for i in range(3):
        d1, d2, r = q1[i] - p1[i], q2[i] - p2[i], p1[i] - p2[i]
        a += d1 * d1
        e += d2 * d2
        f += d2 * r
        c += d1 * r
        b += d1 * d2
    if a <= _EPS and e <= _EPS:  # two points
        s = t = 0.0
    elif a <= _EPS:  # the first segment is a point: closest point of the second to it
        s, t = 0.0, _clip01(f / e)
    elif e <= _EPS:  # the second segment is a point
        s, t = _clip01(-c / a), 0.0
    else:
        denom = a * e - b * b
        s = _clip01((b * f - c * e) / denom) if denom > _EPS * max(a * e, _EPS) else 0.0
        t = (b * s + f) / e
        if t < 0.0:
            s, t = _clip01(-c / a), 0.0
        elif t > 1.0:
            s, t = _clip01((b - c) / a), 1.0
    out = 0.0
    for i in range(3):
        dx = (p1[i] + s * (q1[i] - p1[i])) - (p2[i] + t * (q2[i] - p2[i]))
        out += dx * dx
    return math.sqrt(out)


@njit(cache=True)
def _segment_distances_flat(
    p1: FloatArray, q1: FloatArray, p2: FloatArray, q2: FloatArray, out: FloatArray
) -> None:
    for n in range(out.shape[0]):
        out[n] = _segment_distance(p1[n], q1[n], p2[n], q2[n])


def segment_distances(p1: FloatArray, q1: FloatArray, p2: FloatArray, q2: FloatArray) -> FloatArray:
    """Distance between segments ``[p1, q1]`` and ``[p2, q2]``, shapes (..., 3) -> (...).

    Closest points of two segments (Ericson, *Real-Time Collision Detection*, 5.1.9), with the
    degenerate cases (a segment of length 0) handled apart.
    """
    arrays = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (p1, q1, p2, q2)))
    shape = arrays[0].shape[:-1]
    flat = [np.ascontiguousarray(x.reshape(-1, 3)) for x in arrays]
    out = np.empty(flat[0].shape[0])
    _segment_distances_flat(flat[0], flat[1], flat[2], flat[3], out)
    return out.reshape(shape)


@njit(cache=True)
def primitive_distances(  # noqa: PLR0913
    frames: FloatArray,  # (numba: float64 (n, n_joints + 1, 4, 4), world first)
    joint: IntArray,  # (int64 (n_seg,): frame of each segment)
    centre: FloatArray,  # (float64 (n_seg, 4): centre in its frame, homogeneous)
    axis: FloatArray,  # (float64 (n_seg, 4): unit axis in its frame)
    half: FloatArray,  # (float64 (n_seg,): half-length, 0 for a sphere)
    radius: FloatArray,  # (float64 (n_seg,))
    cylinder: npt.NDArray[np.bool_],  # (bool (n_seg,))
    seg_pairs: IntArray,  # (int64 (n_sp, 3): column, segment, segment)
    plane_pairs: IntArray,  # (int64 (n_pp, 2): column, segment)
    normals: FloatArray,  # (float64 (n_pp, 3): unit normal of the half-space)
    offsets: FloatArray,  # (float64 (n_pp,): d of each half-space n.x <= d)
    out: FloatArray,  # (float64 (n, n_columns): written at the pairs' columns)
) -> None:
    """Distances of segment pairs (swept spheres) and of segments to half-spaces, per posture.

    The formulas of the module docstring; the same as the array code they replace, to
    round-off.
    """
    n_seg = joint.shape[0]
    ends = np.empty((n_seg, 2, 3))
    cs = np.empty((n_seg, 3))
    us = np.empty((n_seg, 3))
    for n in range(frames.shape[0]):
        for k in range(n_seg):
            f = frames[n, joint[k]]
            for i in range(3):
                ci = f[i, 3]
                ui = 0.0
                for j in range(3):
                    ci += f[i, j] * centre[k, j]
                    ui += f[i, j] * axis[k, j]
                cs[k, i], us[k, i] = ci, ui
                ends[k, 0, i] = ci - half[k] * ui
                ends[k, 1, i] = ci + half[k] * ui
        for m in range(seg_pairs.shape[0]):
            col, i, k = seg_pairs[m, 0], seg_pairs[m, 1], seg_pairs[m, 2]
            d = _segment_distance(ends[i, 0], ends[i, 1], ends[k, 0], ends[k, 1])
            out[n, col] = d - radius[i] - radius[k]
        for m in range(plane_pairs.shape[0]):
            col, i = plane_pairs[m, 0], plane_pairs[m, 1]
            nu = us[i, 0] * normals[m, 0] + us[i, 1] * normals[m, 1] + us[i, 2] * normals[m, 2]
            height = cs[i, 0] * normals[m, 0] + cs[i, 1] * normals[m, 1] + cs[i, 2] * normals[m, 2]
            side = radius[i] * math.sqrt(max(1.0 - nu * nu, 0.0)) if cylinder[i] else radius[i]
            out[n, col] = height - offsets[m] - half[i] * abs(nu) - side
