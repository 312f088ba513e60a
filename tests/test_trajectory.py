import numpy as np
import pytest

from ident.errors import DataError
from ident.trajectory import JointTrajectory, read_trajectory_csv, trajectory_to_csv


def _trajectory(with_tau: bool) -> JointTrajectory:
    rng = np.random.default_rng(0)
    n, names = 7, ("joint_a", "joint_b")
    return JointTrajectory(
        t=np.linspace(0.0, 1.0, n),
        q=rng.normal(size=(n, 2)),
        dq=rng.normal(size=(n, 2)),
        ddq=rng.normal(size=(n, 2)),
        joint_names=names,
        tau=rng.normal(size=(n, 2)) if with_tau else None,
    )


@pytest.mark.parametrize("with_tau", [True, False])
def test_csv_round_trip_is_exact(tmp_path, with_tau):
    traj = _trajectory(with_tau)
    path = tmp_path / "trajectory.csv"
    path.write_text(trajectory_to_csv(traj))
    back = read_trajectory_csv(path)
    assert back.joint_names == traj.joint_names
    for name in ("t", "q", "dq", "ddq"):
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name))
    if with_tau:
        np.testing.assert_array_equal(back.tau, traj.tau)
    else:
        assert back.tau is None


def test_nan_is_reported_with_column(tmp_path):
    text = trajectory_to_csv(_trajectory(False)).splitlines()
    row = text[3].split(",")
    row[2] = "nan"
    text[3] = ",".join(row)
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(text) + "\n")
    with pytest.raises(DataError, match=r"q_joint_b.*row 3"):
        read_trajectory_csv(path)


def test_non_increasing_time_is_rejected(tmp_path):
    text = trajectory_to_csv(_trajectory(False)).splitlines()
    text[2], text[3] = text[3], text[2]
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(text) + "\n")
    with pytest.raises(DataError, match="strictly increasing"):
        read_trajectory_csv(path)


def test_shape_mismatch_is_rejected():
    with pytest.raises(DataError, match="dq has shape"):
        JointTrajectory(
            t=np.zeros(3),
            q=np.zeros((3, 2)),
            dq=np.zeros((3, 1)),
            ddq=np.zeros((3, 2)),
            joint_names=("a", "b"),
        )
