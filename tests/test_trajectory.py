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


def _write_rows(path, header, rows):
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(map(repr, r)) for r in rows))
    return path


def test_read_sets_the_source_and_keeps_the_full_format(tmp_path):
    path = tmp_path / "trajectory.csv"
    path.write_text(trajectory_to_csv(_trajectory(True)))
    assert read_trajectory_csv(path).source == str(path)
    # the default reader still requires dq and ddq, naming what is missing
    header = ["t", "q_joint_a", "q_joint_b"]
    pos = _write_rows(tmp_path / "pos.csv", header, [[0.0, 1.0, 2.0], [1.0, 1.5, 2.5]])
    with pytest.raises(DataError, match=r"pos.csv: .*missing the dq_\* and ddq_\* columns"):
        read_trajectory_csv(pos)


def test_position_only_file_derives_velocity_and_acceleration(tmp_path):
    # Non-uniform time stamps; np.gradient (2nd order) is exact on quadratics, so the
    # closed-form derivatives of q = c0 + c1 t + c2 t^2 are the reference.
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.01, 0.03, size=40))
    c = np.array([[0.2, -1.0], [0.7, 0.3], [-0.4, 1.5]])  # rows: c0, c1, c2; columns: joints
    q = c[0] + c[1] * t[:, None] + c[2] * t[:, None] ** 2
    path = _write_rows(
        tmp_path / "log.csv", ["t", "q_j1", "q_j2"], np.column_stack([t, q]).tolist()
    )
    traj = read_trajectory_csv(path, allow_positions_only=True)
    assert traj.joint_names == ("j1", "j2")
    assert traj.tau is None
    np.testing.assert_array_equal(traj.q, q)
    np.testing.assert_allclose(traj.dq, c[1] + 2 * c[2] * t[:, None], rtol=0, atol=1e-9)
    np.testing.assert_allclose(traj.ddq, np.broadcast_to(2 * c[2], q.shape), rtol=0, atol=1e-6)
    # a sine sampled at 1 kHz: second-order accurate (error ~ h^2 w^3 / 6 inside)
    t = np.arange(2001) / 1000.0
    q = np.sin(3.0 * t)[:, None]
    path = _write_rows(tmp_path / "sine.csv", ["t", "q_j"], np.column_stack([t, q]).tolist())
    traj = read_trajectory_csv(path, allow_positions_only=True)
    np.testing.assert_allclose(traj.dq[:, 0], 3.0 * np.cos(3.0 * t), atol=1e-4)
    np.testing.assert_allclose(traj.ddq[1:-1, 0], -9.0 * np.sin(3.0 * t[1:-1]), atol=2e-2)


def _renamed(tmp_path, old, new, with_tau=True):
    lines = trajectory_to_csv(_trajectory(with_tau)).splitlines()
    lines[0] = lines[0].replace(old, new, 1)  # the first match: the q_ block's column
    path = tmp_path / "renamed.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_one_renamed_column_is_reported_as_inconsistent_names(tmp_path):
    path = _renamed(tmp_path, "q_joint_b,", "q_jnt_b,")
    with pytest.raises(DataError) as info:
        read_trajectory_csv(path)
    message = str(info.value)
    assert message.startswith(f"{path}: inconsistent joint names across the column blocks")
    assert "[q_jnt_b, dq_joint_b, ddq_joint_b, tau_joint_b]" in message
    assert "missing" not in message  # not the misleading "missing ['tau_jnt_b']"
    # a tau column renamed: the same plain message, naming the odd one
    path = _renamed(tmp_path, "tau_joint_a", "tau_jointa")
    with pytest.raises(DataError, match=r"inconsistent joint names.*tau_jointa"):
        read_trajectory_csv(path)


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ("dq_joint_b,", "", r"different joint counts \(2 q_\*, 1 dq_\*, 2 ddq_\*\)"),
        ("q_joint_a,", "x_joint_a,", r"column 'x_joint_a' is not one of t, q_<joint>"),
        ("q_joint_b,", "q_joint_a,", r"joints \['joint_a'\] appear twice"),
        ("t,", "time,", "first column must be 't'"),
    ],
)
def test_bad_headers_are_named(tmp_path, old, new, match):
    path = _renamed(tmp_path, old, new, with_tau=False)
    with pytest.raises(DataError, match=match):
        read_trajectory_csv(path, allow_positions_only=True)


def test_blocks_out_of_order_are_rejected(tmp_path):
    traj = _trajectory(False)
    names = traj.joint_names
    header = ["t"] + [f"{p}_{j}" for p in ("q", "ddq", "dq") for j in names]
    rows = np.hstack([traj.t[:, None], traj.q, traj.ddq, traj.dq]).tolist()
    with pytest.raises(DataError, match=r"order q_\*, ddq_\*, dq_\*; expected order t, q_\*"):
        read_trajectory_csv(_write_rows(tmp_path / "o.csv", header, rows))
