"""Compiled (numba) kernels of the Newton-Euler regressor; private.

Scalar arithmetic, scratch buffers allocated once per call, nothing allocated in the sample
loop (DESIGN.md, performance notes). The math is the one documented in
:mod:`ident.dynamics.regressor`; :func:`ident.dynamics.regressor.joint_torque_regressor_numpy`
is the readable reference it is tested against.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ident.dynamics.chain import FloatArray, KinematicChain

__all__ = ["chain_arrays", "regressor_into", "selected_rows_into"]


def chain_arrays(chain: KinematicChain) -> tuple[FloatArray, FloatArray, np.ndarray, FloatArray]:
    """Contiguous arrays the kernels take: placements, axes, prismatic (int8), gravity."""
    return (
        np.ascontiguousarray(chain.placements, dtype=np.float64),
        np.ascontiguousarray(chain.axes, dtype=np.float64),
        np.ascontiguousarray(chain.prismatic, dtype=np.int8),
        np.ascontiguousarray(chain.gravity, dtype=np.float64),
    )


@njit(cache=True)
def _forward(placements, axes, prismatic, gravity, q, dq, ddq, rot, pos, vel, acc):  # noqa: PLR0913
    """Kinematics of one sample: parent_R_i, parent_p_i, and per joint frame
    vel[i] = (v, w), acc[i] = (classical linear acceleration a + w x v, alpha)."""
    n = q.shape[0]
    vx = vy = vz = wx = wy = wz = 0.0
    ax, ay, az = -gravity[0], -gravity[1], -gravity[2]  # gravity as base acceleration
    bx = by = bz = 0.0  # angular acceleration
    for i in range(n):
        kx, ky, kz = axes[i, 0], axes[i, 1], axes[i, 2]
        if prismatic[i]:
            for r in range(3):
                for c in range(3):
                    rot[i, r, c] = placements[i, r, c]
                pos[i, r] = placements[i, r, 3] + q[i] * (
                    placements[i, r, 0] * kx + placements[i, r, 1] * ky + placements[i, r, 2] * kz
                )
        else:
            s = np.sin(q[i])
            c = np.cos(q[i])
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
                p0, p1, p2 = placements[i, r, 0], placements[i, r, 1], placements[i, r, 2]
                rot[i, r, 0] = p0 * j00 + p1 * j10 + p2 * j20
                rot[i, r, 1] = p0 * j01 + p1 * j11 + p2 * j21
                rot[i, r, 2] = p0 * j02 + p1 * j12 + p2 * j22
                pos[i, r] = placements[i, r, 3]
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


@njit(cache=True)
def _body_block(vel, acc, i, block):
    """Body wrench regressor A_i (6, 10) in frame i: [f; n] = A_i @ phi_i."""
    for r in range(6):
        for c in range(10):
            block[r, c] = 0.0
    wx, wy, wz = vel[i, 3], vel[i, 4], vel[i, 5]
    cx, cy, cz = acc[i, 0], acc[i, 1], acc[i, 2]
    bx, by, bz = acc[i, 3], acc[i, 4], acc[i, 5]
    # force: m * a_c + ([alpha]x + [w]x[w]x) h
    block[0, 0], block[1, 0], block[2, 0] = cx, cy, cz
    block[0, 1] = -(wy * wy + wz * wz)
    block[0, 2] = wx * wy - bz
    block[0, 3] = wx * wz + by
    block[1, 1] = wx * wy + bz
    block[1, 2] = -(wx * wx + wz * wz)
    block[1, 3] = wy * wz - bx
    block[2, 1] = wx * wz - by
    block[2, 2] = wy * wz + bx
    block[2, 3] = -(wx * wx + wy * wy)
    # moment, first moments: -[a_c]x h
    block[3, 2], block[3, 3] = cz, -cy
    block[4, 1], block[4, 3] = -cz, cx
    block[5, 1], block[5, 2] = cy, -cx
    # moment, inertia [Ixx, Ixy, Iyy, Ixz, Iyz, Izz]: L(alpha) + [w]x L(w)
    # L(u) = [[u0, u1, 0, u2, 0, 0], [0, u0, u1, 0, u2, 0], [0, 0, 0, u0, u1, u2]]
    block[3, 4] = bx
    block[3, 5] = by - wx * wz
    block[3, 6] = -wy * wz
    block[3, 7] = bz + wx * wy
    block[3, 8] = wy * wy - wz * wz
    block[3, 9] = wy * wz
    block[4, 4] = wx * wz
    block[4, 5] = bx + wy * wz
    block[4, 6] = by
    block[4, 7] = wz * wz - wx * wx
    block[4, 8] = bz - wx * wy
    block[4, 9] = -wx * wz
    block[5, 4] = -wx * wy
    block[5, 5] = wx * wx - wy * wy
    block[5, 6] = wx * wy
    block[5, 7] = bx - wy * wz
    block[5, 8] = by + wx * wz
    block[5, 9] = bz


@njit(cache=True)
def _sample(
    placements,
    axes,
    prismatic,
    gravity,
    q,
    dq,
    ddq,
    body_used,
    row_min,
    rot,
    pos,
    vel,
    acc,
    block,
    y,
):
    """Regressor of one sample into y (n, 10 n); only bodies with body_used, rows >= row_min."""
    n = q.shape[0]
    _forward(placements, axes, prismatic, gravity, q, dq, ddq, rot, pos, vel, acc)
    for i in range(n):
        if not body_used[i]:
            continue
        _body_block(vel, acc, i, block)
        for j in range(i, row_min - 1, -1):
            kx, ky, kz = axes[j, 0], axes[j, 1], axes[j, 2]
            off = 0 if prismatic[j] else 3
            for c in range(10):
                y[j, 10 * i + c] = (
                    kx * block[off, c] + ky * block[off + 1, c] + kz * block[off + 2, c]
                )
            if j > row_min:
                # force transform frame j -> parent: f' = R f, n' = R n + p x f'
                r = rot[j]
                px, py, pz = pos[j, 0], pos[j, 1], pos[j, 2]
                for c in range(10):
                    f0, f1, f2 = block[0, c], block[1, c], block[2, c]
                    n0, n1, n2 = block[3, c], block[4, c], block[5, c]
                    g0 = r[0, 0] * f0 + r[0, 1] * f1 + r[0, 2] * f2
                    g1 = r[1, 0] * f0 + r[1, 1] * f1 + r[1, 2] * f2
                    g2 = r[2, 0] * f0 + r[2, 1] * f1 + r[2, 2] * f2
                    block[0, c], block[1, c], block[2, c] = g0, g1, g2
                    block[3, c] = r[0, 0] * n0 + r[0, 1] * n1 + r[0, 2] * n2 + py * g2 - pz * g1
                    block[4, c] = r[1, 0] * n0 + r[1, 1] * n1 + r[1, 2] * n2 + pz * g0 - px * g2
                    block[5, c] = r[2, 0] * n0 + r[2, 1] * n1 + r[2, 2] * n2 + px * g1 - py * g0


@njit(cache=True)
def regressor_into(placements, axes, prismatic, gravity, q, dq, ddq, out):
    """Full regressor of every sample into out (n_samples, n, 10 n), zero-filled here."""
    n = q.shape[1]
    rot = np.empty((n, 3, 3))
    pos = np.empty((n, 3))
    vel = np.empty((n, 6))
    acc = np.empty((n, 6))
    block = np.empty((6, 10))
    body_used = np.ones(n, dtype=np.bool_)
    for k in range(q.shape[0]):
        y = out[k]
        for j in range(n):
            for c in range(10 * n):
                y[j, c] = 0.0
        _sample(
            placements,
            axes,
            prismatic,
            gravity,
            q[k],
            dq[k],
            ddq[k],
            body_used,
            0,
            rot,
            pos,
            vel,
            acc,
            block,
            y,
        )


@njit(cache=True)
def selected_rows_into(
    placements, axes, prismatic, gravity, q, dq, ddq, start, stop, rows, columns, weights, out
):
    """Weighted rows/columns of samples start..stop-1, sample-major, into
    out[(k - start) * len(rows) + r, c] = weights[r] * Y_k[rows[r], columns[c]]."""
    n = q.shape[1]
    rot = np.empty((n, 3, 3))
    pos = np.empty((n, 3))
    vel = np.empty((n, 6))
    acc = np.empty((n, 6))
    block = np.empty((6, 10))
    y = np.zeros((n, 10 * n))  # entries of unused bodies stay zero and are never read
    body_used = np.zeros(n, dtype=np.bool_)
    for c in range(columns.shape[0]):
        body_used[columns[c] // 10] = True
    row_min = n
    for r in range(rows.shape[0]):
        row_min = min(row_min, rows[r])
    n_rows = rows.shape[0]
    for k in range(start, stop):
        _sample(
            placements,
            axes,
            prismatic,
            gravity,
            q[k],
            dq[k],
            ddq[k],
            body_used,
            row_min,
            rot,
            pos,
            vel,
            acc,
            block,
            y,
        )
        base = (k - start) * n_rows
        for r in range(n_rows):
            j = rows[r]
            w = weights[r]
            for c in range(columns.shape[0]):
                col = columns[c]
                # body below the row: zero by construction (serial chain)
                out[base + r, c] = w * y[j, col] if col // 10 >= j else 0.0
