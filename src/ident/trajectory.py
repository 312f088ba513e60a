"""Joint-space trajectories and their CSV exchange format.

The CSV written into every run folder (``trajectory.csv``) and read by ``ident replay``:
one header line, then one row per sample, SI units::

    t, q_<joint>..., dq_<joint>..., ddq_<joint>..., [tau_<joint>...]

``t`` [s]; ``q`` [rad] (revolute) or [m] (prismatic); ``dq``, ``ddq`` their first and second
time derivatives; ``tau`` [N*m] or [N], optional. Joint names are those of the URDF; every
block names the same joints in the same order.

A position-only file ``t, q_<joint>...`` (what a motion log often holds) is read when the
caller allows it (``ident replay`` does): velocities and accelerations are then derived by
finite differences (see :func:`read_trajectory_csv`).
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
    source :
        The file the trajectory was read from (named in messages), or ``None``.
    """

    t: FloatArray
    q: FloatArray
    dq: FloatArray
    ddq: FloatArray
    joint_names: tuple[str, ...]
    tau: FloatArray | None = None
    source: str | None = None

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


def _column_blocks(path: Path, header: list[str]) -> dict[str, list[str]]:
    """Joint names of each column block ``{prefix: [joint, ...]}`` of a trajectory header.

    Checks the column names, the block order ``q, dq, ddq, tau`` and that every block names
    the same joints in the same order.
    """
    if not header or header[0] != "t":
        raise DataError(
            f"{path}: the first column must be 't' (time [s]); header is {header[:4]}..."
        )
    blocks: dict[str, list[str]] = {}
    order: list[str] = []
    for column in header[1:]:
        # longest prefix first: 'ddq_x' is not 'dq_x', 'dq_x' is not 'q_x'
        prefix = next((p for p in ("ddq", "dq", "tau", "q") if column.startswith(p + "_")), None)
        if prefix is None or not column[len(prefix) + 1 :]:
            raise DataError(
                f"{path}: column '{column}' is not one of t, q_<joint>, dq_<joint>, "
                "ddq_<joint>, tau_<joint>; rename or remove it."
            )
        if prefix in blocks and order[-1] != prefix:
            raise DataError(
                f"{path}: the {prefix}_* columns are not contiguous (column '{column}'); "
                "expected order t, q_*, dq_*, ddq_*[, tau_*]."
            )
        if prefix not in blocks:
            order.append(prefix)
            blocks[prefix] = []
        blocks[prefix].append(column[len(prefix) + 1 :])
    if "q" not in blocks:
        raise DataError(f"{path}: no 'q_<joint>' columns found in the header.")
    names = blocks["q"]
    duplicated = sorted({n for n in names if names.count(n) > 1})
    if duplicated:
        raise DataError(f"{path}: joints {duplicated} appear twice among the q_* columns.")
    expected_order = [p for p in _PREFIXES if p in blocks]
    if order != expected_order:
        raise DataError(
            f"{path}: column blocks in the order {', '.join(p + '_*' for p in order)}; "
            "expected order t, q_*, dq_*, ddq_*[, tau_*]."
        )
    _check_same_joints(path, blocks)
    return blocks


def _check_same_joints(path: Path, blocks: dict[str, list[str]]) -> None:
    """Every block must name the q_* block's joints, in the same order."""
    names = blocks["q"]
    if all(block == names for block in blocks.values()):
        return
    sizes = {prefix: len(block) for prefix, block in blocks.items()}
    if len(set(sizes.values())) > 1:
        counts = ", ".join(f"{n} {p}_*" for p, n in sizes.items())
        raise DataError(
            f"{path}: the column blocks have different joint counts ({counts}); every block "
            f"must have one column per joint. Joint names per block: "
            + "; ".join(f"{p}_*: {block}" for p, block in blocks.items())
            + "."
        )
    differing = []
    for k in range(len(names)):
        row = {prefix: block[k] for prefix, block in blocks.items()}
        if len(set(row.values())) > 1:
            differing.append(", ".join(f"{p}_{n}" for p, n in row.items()))
    if sorted(names) == sorted(blocks[next(p for p in blocks if blocks[p] != names)]):
        why = "the same joints in another order"
    else:
        why = "different joint names"
    raise DataError(
        f"{path}: inconsistent joint names across the column blocks ({why}): "
        + "; ".join(f"[{d}]" for d in differing[:6])
        + ". Every block (q_*, dq_*, ddq_*, tau_*) must name the same joints in the same "
        "order; rename the columns that differ."
    )


def _derivative(values: FloatArray, t: FloatArray) -> FloatArray:
    """Time derivative along axis 0 by ``np.gradient`` (second order where possible)."""
    return np.gradient(values, t, axis=0, edge_order=2 if t.shape[0] >= 3 else 1)


def read_trajectory_csv(path: str | Path, *, allow_positions_only: bool = False) -> JointTrajectory:
    """Read a trajectory CSV; every problem is a :class:`DataError` naming the file.

    Parameters
    ----------
    path :
        CSV in the format of the module docstring.
    allow_positions_only :
        Also accept ``t, q_<joint>...[, tau_<joint>...]`` without the ``dq_*`` and
        ``ddq_*`` blocks (used by ``ident replay``, which needs positions only). The
        velocities [rad/s] and accelerations [rad/s^2] are then derived from the positions
        by ``np.gradient`` over ``t`` (central differences inside, second-order one-sided at
        the ends; first order for 2 samples), ``ddq`` from ``dq`` the same way. They are
        estimates: amplified noise, no filtering. ``False`` (default) requires the full
        format.

    Returns
    -------
    :
        The trajectory, ``source`` set to ``str(path)``.

    Raises
    ------
    DataError
        Missing file, unknown, missing or out-of-order columns, joint names that differ
        between the q/dq/ddq/tau blocks, non-numeric or non-finite values, time not strictly
        increasing.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: trajectory file not found.")
    with path.open(encoding="utf-8") as f:
        header = [h.strip() for h in f.readline().strip().split(",")]
    blocks = _column_blocks(path, header)
    names = tuple(blocks["q"])
    positions_only = "dq" not in blocks and "ddq" not in blocks
    if not (positions_only and allow_positions_only):
        _require_derivative_blocks(path, blocks, names, positions_only)
    data = _numeric_rows(path, header)
    t = data[:, 0]
    nj = len(names)
    present = [p for p in _PREFIXES if p in blocks]
    arrays = {p: data[:, 1 + k * nj : 1 + (k + 1) * nj] for k, p in enumerate(present)}
    if positions_only:
        arrays["dq"] = _derivative(arrays["q"], t)
        arrays["ddq"] = _derivative(arrays["dq"], t)
    return JointTrajectory(
        t=t,
        q=arrays["q"],
        dq=arrays["dq"],
        ddq=arrays["ddq"],
        joint_names=names,
        tau=arrays.get("tau"),
        source=str(path),
    )


def _require_derivative_blocks(
    path: Path, blocks: dict[str, list[str]], names: tuple[str, ...], positions_only: bool
) -> None:
    """Raise :class:`DataError` unless the header has the dq_* and ddq_* blocks."""
    missing = [p + "_*" for p in ("dq", "ddq") if p not in blocks]
    if missing:
        hint = " (ident replay also reads position-only files t, q_*)" if positions_only else ""
        raise DataError(
            f"{path}: columns do not match the trajectory format; missing the "
            f"{' and '.join(missing)} columns of joints {list(names)}, expected order "
            f"t, q_*, dq_*, ddq_*[, tau_*]{hint}."
        )


def _numeric_rows(path: Path, header: list[str]) -> FloatArray:
    """The data rows (n_samples, n_columns) of the CSV, checked: numeric, at least 2 samples,
    one value per header column, finite, time (column 0) strictly increasing."""
    try:
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as e:
        raise DataError(f"{path}: non-numeric value: {e}") from e
    if data.shape[0] < 2:
        raise DataError(f"{path}: needs at least 2 samples, found {data.shape[0]}.")
    if data.shape[1] != len(header):
        raise DataError(
            f"{path}: the data rows have {data.shape[1]} values, the header {len(header)} columns."
        )
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
    return data
