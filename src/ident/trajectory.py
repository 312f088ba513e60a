"""Joint-space trajectories and their CSV exchange format.

The CSV written into every run folder (``trajectory.csv``) and read by ``ident replay``:
one header line, then one row per sample, SI units::

    t, q_<joint>..., dq_<joint>..., ddq_<joint>..., [tau_<joint>...]

``t`` [s]; ``q`` [rad] (revolute) or [m] (prismatic); ``dq``, ``ddq`` their first and second
time derivatives; ``tau`` [N*m] or [N], optional. Joint names are those of the URDF.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ident.errors import DataError

__all__ = ["JointTrajectory", "read_trajectory_csv", "trajectory_to_csv"]

FloatArray = npt.NDArray[np.float64]

_PREFIXES = ("q", "dq", "ddq", "tau")


@dataclass(frozen=True, eq=False)
class JointTrajectory:
    """Sampled joint motion of a serial robot.

    Attributes
    ----------
    t :
        Time stamps [s], shape (n_samples,), strictly increasing.
    q, dq, ddq :
        Positions, velocities, accelerations, shape (n_samples, n_joints).
    joint_names :
        Names of the joints, in column order.
    tau :
        Joint torques/forces, shape (n_samples, n_joints), or ``None``.
    """

    t: FloatArray
    q: FloatArray
    dq: FloatArray
    ddq: FloatArray
    joint_names: tuple[str, ...]
    tau: FloatArray | None = None

    def __post_init__(self) -> None:
        n, nj = self.q.shape[0], len(self.joint_names)
        arrays = {"q": self.q, "dq": self.dq, "ddq": self.ddq}
        if self.tau is not None:
            arrays["tau"] = self.tau
        if self.t.shape != (n,):
            raise DataError(f"trajectory: t has shape {self.t.shape}, expected ({n},)")
        for name, a in arrays.items():
            if a.shape != (n, nj):
                raise DataError(
                    f"trajectory: {name} has shape {a.shape}, expected ({n}, {nj}) "
                    f"for joints {list(self.joint_names)}"
                )
        for a in (self.t, *arrays.values()):
            a.setflags(write=False)

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])


def trajectory_to_csv(trajectory: JointTrajectory) -> str:
    """Serialize a trajectory to the CSV format described in the module docstring."""
    names = trajectory.joint_names
    columns = [trajectory.t[:, None], trajectory.q, trajectory.dq, trajectory.ddq]
    header = ["t"] + [f"{p}_{j}" for p in _PREFIXES[:3] for j in names]
    if trajectory.tau is not None:
        columns.append(trajectory.tau)
        header += [f"tau_{j}" for j in names]
    buffer = io.StringIO()
    np.savetxt(buffer, np.hstack(columns), delimiter=",", fmt="%.17g")
    return ",".join(header) + "\n" + buffer.getvalue()


def read_trajectory_csv(path: str | Path) -> JointTrajectory:
    """Read a trajectory CSV; every problem is a :class:`DataError` naming the file.

    Raises
    ------
    DataError
        Missing file, missing or inconsistent columns, non-numeric or non-finite values,
        time not strictly increasing.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: trajectory file not found.")
    with path.open(encoding="utf-8") as f:
        header = [h.strip() for h in f.readline().strip().split(",")]
    if not header or header[0] != "t":
        raise DataError(
            f"{path}: the first column must be 't' (time [s]); header is {header[:4]}..."
        )
    q_cols = [h for h in header if h.startswith("q_")]
    names = tuple(h[2:] for h in q_cols)
    if not names:
        raise DataError(f"{path}: no 'q_<joint>' columns found in the header.")
    has_tau = any(h.startswith("tau_") for h in header)
    expected = ["t"] + [
        f"{p}_{j}" for p in (_PREFIXES if has_tau else _PREFIXES[:3]) for j in names
    ]
    if header != expected:
        missing = [c for c in expected if c not in header]
        raise DataError(
            f"{path}: columns do not match the trajectory format; missing {missing[:6]}, "
            f"expected order t, q_*, dq_*, ddq_*[, tau_*]."
        )
    try:
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as e:
        raise DataError(f"{path}: non-numeric value: {e}") from e
    if data.shape[0] < 2:
        raise DataError(f"{path}: needs at least 2 samples, found {data.shape[0]}.")
    bad = ~np.isfinite(data)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise DataError(
            f"{path}: non-finite value in column '{header[col]}' at data row {row + 1}."
        )
    t = data[:, 0]
    if np.any(np.diff(t) <= 0):
        row = int(np.argmax(np.diff(t) <= 0)) + 2
        raise DataError(f"{path}: time column 't' is not strictly increasing (row {row}).")
    nj = len(names)
    blocks = [data[:, 1 + k * nj : 1 + (k + 1) * nj] for k in range(4 if has_tau else 3)]
    return JointTrajectory(
        t=t,
        q=blocks[0],
        dq=blocks[1],
        ddq=blocks[2],
        joint_names=names,
        tau=blocks[3] if has_tau else None,
    )
