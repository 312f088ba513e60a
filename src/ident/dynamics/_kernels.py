"""Compiled (numba) kernels of the Newton-Euler regressor; private.

Scalar arithmetic, scratch buffers allocated once per call, nothing allocated in the sample
loop: past a few thousand samples, writing a regressor tensor costs more than computing it
(benchmarks/bench_regressor.py). The math is the one documented in
:mod:`ident.dynamics.regressor`; :func:`ident.dynamics.regressor.joint_torque_regressor_numpy`
is the readable reference it is tested against.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ident.dynamics.chain import FloatArray, KinematicChain

__all__ = ["chain_arrays", "regressor_into", "selected_rows_into"]

Arr = np.ndarray  # numba ignores annotations; the kernels take float64 (int64, bool) arrays


def chain_arrays(chain: KinematicChain) -> tuple[FloatArray, FloatArray, np.ndarray, FloatArray]:
    """Contiguous arrays the kernels take: placements, axes, prismatic (int8), gravity."""
    return (
        np.ascontiguousarray(chain.placements, dtype=np.float64),
        np.ascontiguousarray(chain.axes, dtype=np.float64),
        np.ascontiguousarray(chain.prismatic, dtype=np.int8),
        np.ascontiguousarray(chain.gravity, dtype=np.float64),
    )


def states(q: Arr, dq: Arr, ddq: Arr) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``q, dq, ddq`` as the kernels take them: C-contiguous float64, read-only views.

    Numba compiles one specialization per argument type, and an array's read-only flag is
    part of its type: callers passing read-only logs (``Observations``) and writeable arrays
    made the kernels compile twice, 6-13 s of CPU each on a first run (cold cache)."""

    def read_only(a: Arr) -> FloatArray:
        view = np.ascontiguousarray(a, dtype=np.float64).view()
        view.flags.writeable = False
        return view

    return read_only(q), read_only(dq), read_only(ddq)


@njit(cache=True, fastmath=True, inline="always")
def _scratch(n: int) -> tuple[Arr, Arr, Arr, Arr, Arr, Arr]:
    """Per-call buffers of :func:`_forward`: rot[i], pos[i] = parent_R_i, parent_p_i; per joint
    frame vel[i] = (v, w), acc[i] = (classical linear acceleration a + w x v, alpha); and the
    joint position each rotation and position was last computed for (valid where the flag is
    set)."""
    return (
        np.empty((n, 3, 3)),
        np.empty((n, 3)),
        np.empty((n, 6)),
        np.empty((n, 6)),
        np.empty(n),
        np.zeros(n, dtype=np.bool_),
    )


@njit(cache=True, fastmath=True, inline="always")
def _joint_placement(
    placement: Arr, kx: float, ky: float, kz: float, prismatic: bool, qi: float, rot: Arr, pos: Arr
) -> None:
    """``rot`` (3, 3) and ``pos`` (3,): the joint frame in its parent's, from the joint's fixed
    ``placement`` (3, 4), unit axis ``k`` and position ``qi`` [rad or m]."""
    if prismatic:
        for r in range(3):
            for c in range(3):
                rot[r, c] = placement[r, c]
            pos[r] = placement[r, 3] + qi * (
                placement[r, 0] * kx + placement[r, 1] * ky + placement[r, 2] * kz
            )
        return
    s = np.sin(qi)
    c = np.cos(qi)
    t = 1.0 - c
    # Rodrigues: R_joint = c I + s [k]x + t k k^T
    j00 = c + t * kx * kx
    j01 = t * kx * ky - s * kz
    j02 = t * kx * kz + s * ky
    j10 = t * ky * kx + s * kz
    j11 = c + t * ky * ky
    j12 = t * ky * kz - s * kx
    j20 = t * kz * kx - s * ky
    j21 = t * kz * ky + s * kx
    j22 = c + t * kz * kz
    for r in range(3):
        p0, p1, p2 = placement[r, 0], placement[r, 1], placement[r, 2]
        rot[r, 0] = p0 * j00 + p1 * j10 + p2 * j20
        rot[r, 1] = p0 * j01 + p1 * j11 + p2 * j21
        rot[r, 2] = p0 * j02 + p1 * j12 + p2 * j22
        pos[r] = placement[r, 3]


Chain = tuple[Arr, Arr, Arr, Arr]  # the arrays of chain_arrays
Scratch = tuple[Arr, Arr, Arr, Arr, Arr, Arr]  # of _scratch: rot, pos, vel, acc, last_q, known


@njit(cache=True, fastmath=True, inline="always")
def _moved(q: Arr, last_q: Arr, known: Arr, i: int) -> bool:
    """Whether joint i's rot[i], pos[i] must be computed for q[i] (not kept from the previous
    sample: a held joint needs no sin, cos, product of rotations); records q[i] as computed."""
    moved = not (known[i] and q[i] == last_q[i])
    last_q[i] = q[i]
    known[i] = True
    return moved


@njit(cache=True, fastmath=True, inline="always")  # inlined: about 15% faster
def _forward(chain: Chain, q: Arr, dq: Arr, ddq: Arr, scratch: Scratch) -> None:
    """Kinematics of one sample into ``scratch`` (the buffers of :func:`_scratch`)."""
    placements, axes, prismatic, gravity = chain
    rot, pos, vel, acc, last_q, known = scratch
    n = q.shape[0]
    vx = vy = vz = wx = wy = wz = bx = by = bz = 0.0  # b: angular acceleration
    ax, ay, az = -gravity[0], -gravity[1], -gravity[2]  # gravity as base acceleration
    for i in range(n):
        kx, ky, kz = axes[i, 0], axes[i, 1], axes[i, 2]
        if _moved(q, last_q, known, i):  # else rot[i], pos[i] as computed for q[i]
            _joint_placement(placements[i], kx, ky, kz, prismatic[i], q[i], rot[i], pos[i])
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        # move the parent's motion to the new origin (in the parent frame)
        ux = vx + wy * pz - wz * py
        uy = vy + wz * px - wx * pz
        uz = vz + wx * py - wy * px
        ex = ax + by * pz - bz * py
        ey = ay + bz * px - bx * pz
        ez = az + bx * py - by * px
        # rotate into frame i: x_i = R^T x_parent
        r = rot[i]
        vx = r[0, 0] * ux + r[1, 0] * uy + r[2, 0] * uz
        vy = r[0, 1] * ux + r[1, 1] * uy + r[2, 1] * uz
        vz = r[0, 2] * ux + r[1, 2] * uy + r[2, 2] * uz
        nwx = r[0, 0] * wx + r[1, 0] * wy + r[2, 0] * wz
        nwy = r[0, 1] * wx + r[1, 1] * wy + r[2, 1] * wz
        nwz = r[0, 2] * wx + r[1, 2] * wy + r[2, 2] * wz
        wx, wy, wz = nwx, nwy, nwz
        ax = r[0, 0] * ex + r[1, 0] * ey + r[2, 0] * ez
        ay = r[0, 1] * ex + r[1, 1] * ey + r[2, 1] * ez
        az = r[0, 2] * ex + r[1, 2] * ey + r[2, 2] * ez
        nbx = r[0, 0] * bx + r[1, 0] * by + r[2, 0] * bz
        nby = r[0, 1] * bx + r[1, 1] * by + r[2, 1] * bz
        nbz = r[0, 2] * bx + r[1, 2] * by + r[2, 2] * bz
        bx, by, bz = nbx, nby, nbz
        sx, sy, sz = kx * dq[i], ky * dq[i], kz * dq[i]
        if prismatic[i]:
            vx += sx
            vy += sy
            vz += sz
            ax += kx * ddq[i] + wy * sz - wz * sy
            ay += ky * ddq[i] + wz * sx - wx * sz
            az += kz * ddq[i] + wx * sy - wy * sx
        else:
            wx += sx
            wy += sy
            wz += sz
            bx += kx * ddq[i] + wy * sz - wz * sy
            by += ky * ddq[i] + wz * sx - wx * sz
            bz += kz * ddq[i] + wx * sy - wy * sx
            ax += vy * sz - vz * sy
            ay += vz * sx - vx * sz
            az += vx * sy - vy * sx
        vel[i, 0], vel[i, 1], vel[i, 2] = vx, vy, vz
        vel[i, 3], vel[i, 4], vel[i, 5] = wx, wy, wz
        # classical acceleration of the origin: a + w x v
        acc[i, 0] = ax + wy * vz - wz * vy
        acc[i, 1] = ay + wz * vx - wx * vz
        acc[i, 2] = az + wx * vy - wy * vx
        acc[i, 3], acc[i, 4], acc[i, 5] = bx, by, bz


@njit(cache=True, fastmath=True, inline="always")
def _sample(
    chain: Chain, q: Arr, dq: Arr, ddq: Arr, row_used: Arr, body_used: Arr, scratch: Scratch, y: Arr
) -> None:
    """Regressor of one sample into y (n, 10 n), entries (j, block i) for i >= j, row_used[j],
    body_used[i] (others untouched): ``Y[j, block i] = S_j^T jX*_i A_i = (iX_j S_j)^T A_i``, the
    joint-j axis carried up the chain as a motion vector (u, r) dotted with the wrench regressor
    of body i, written out with its sparsity (mass: force only; inertia: moment only)."""
    _, axes, prismatic, _ = chain
    rot, pos, vel, acc, _, _ = scratch
    _forward(chain, q, dq, ddq, scratch)
    for j in range(q.shape[0]):
        if not row_used[j]:
            continue
        kx, ky, kz = axes[j, 0], axes[j, 1], axes[j, 2]
        if prismatic[j]:
            ux, uy, uz, rx, ry, rz = kx, ky, kz, 0.0, 0.0, 0.0
        else:
            ux, uy, uz, rx, ry, rz = 0.0, 0.0, 0.0, kx, ky, kz
        for i in range(j, q.shape[0]):
            if i > j:
                # motion transform parent -> i: u' = R^T (u + r x p), r' = R^T r
                R = rot[i]
                px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
                tx = ux + ry * pz - rz * py
                ty = uy + rz * px - rx * pz
                tz = uz + rx * py - ry * px
                ux = R[0, 0] * tx + R[1, 0] * ty + R[2, 0] * tz
                uy = R[0, 1] * tx + R[1, 1] * ty + R[2, 1] * tz
                uz = R[0, 2] * tx + R[1, 2] * ty + R[2, 2] * tz
                sx = R[0, 0] * rx + R[1, 0] * ry + R[2, 0] * rz
                sy = R[0, 1] * rx + R[1, 1] * ry + R[2, 1] * rz
                sz = R[0, 2] * rx + R[1, 2] * ry + R[2, 2] * rz
                rx, ry, rz = sx, sy, sz
            if not body_used[i]:
                continue
            wx, wy, wz = vel[i, 3], vel[i, 4], vel[i, 5]
            cx, cy, cz = acc[i, 0], acc[i, 1], acc[i, 2]
            bx, by, bz = acc[i, 3], acc[i, 4], acc[i, 5]
            c = 10 * i
            # mass: f = m a_c
            y[j, c] = ux * cx + uy * cy + uz * cz
            # first moments: f = (alpha x + w x w x) h, n = -a_c x h:
            # coefficient of h = u x alpha + (u x w) x w + a_c x r
            ex = uy * wz - uz * wy
            ey = uz * wx - ux * wz
            ez = ux * wy - uy * wx
            y[j, c + 1] = uy * bz - uz * by + ey * wz - ez * wy + cy * rz - cz * ry
            y[j, c + 2] = uz * bx - ux * bz + ez * wx - ex * wz + cz * rx - cx * rz
            y[j, c + 3] = ux * by - uy * bx + ex * wy - ey * wx + cx * ry - cy * rx
            # inertia about the origin: n = Ibar alpha + w x Ibar w, so
            # r . n = r . (Ibar alpha) + (r x w) . (Ibar w)
            gx = ry * wz - rz * wy
            gy = rz * wx - rx * wz
            gz = rx * wy - ry * wx
            y[j, c + 4] = rx * bx + gx * wx
            y[j, c + 5] = rx * by + ry * bx + gx * wy + gy * wx
            y[j, c + 6] = ry * by + gy * wy
            y[j, c + 7] = rx * bz + rz * bx + gx * wz + gz * wx
            y[j, c + 8] = ry * bz + rz * by + gy * wz + gz * wy
            y[j, c + 9] = rz * bz + gz * wz


@njit(cache=True, fastmath=True, nogil=True)
def regressor_into(
    placements: Arr, axes: Arr, prismatic: Arr, gravity: Arr, q: Arr, dq: Arr, ddq: Arr, out: Arr
) -> None:
    """Full regressor of every sample into out (n_samples, n, 10 n)."""
    n = q.shape[1]
    chain = (placements, axes, prismatic, gravity)
    scratch = _scratch(n)
    used = np.ones(n, dtype=np.bool_)
    for k in range(q.shape[0]):
        y = out[k]
        for j in range(1, n):  # bodies before the joint: zero (serial chain)
            for c in range(10 * j):
                y[j, c] = 0.0
        _sample(chain, q[k], dq[k], ddq[k], used, used, scratch, y)


@njit(cache=True, fastmath=True, nogil=True)
def selected_rows_into(
    placements: Arr,
    axes: Arr,
    prismatic: Arr,
    gravity: Arr,
    q: Arr,
    dq: Arr,
    ddq: Arr,
    start: int,
    stop: int,
    rows: Arr,
    columns: Arr,
    weights: Arr,
    out: Arr,
) -> None:
    """Weighted rows/columns of samples start..stop-1, sample-major, into
    out[(k - start) * len(rows) + r, c] = weights[r] * Y_k[rows[r], columns[c]]."""
    n = q.shape[1]
    chain = (placements, axes, prismatic, gravity)
    scratch = _scratch(n)
    y = np.zeros((n, 10 * n))  # entries not computed stay zero (bodies before the joint)
    row_used = np.zeros(n, dtype=np.bool_)
    body_used = np.zeros(n, dtype=np.bool_)
    for r in range(rows.shape[0]):
        row_used[rows[r]] = True
    for c in range(columns.shape[0]):
        body_used[columns[c] // 10] = True
    n_rows = rows.shape[0]
    for k in range(start, stop):
        _sample(chain, q[k], dq[k], ddq[k], row_used, body_used, scratch, y)
        base = (k - start) * n_rows
        for r in range(n_rows):
            j = rows[r]
            w = weights[r]
            for c in range(columns.shape[0]):
                out[base + r, c] = w * y[j, columns[c]]
