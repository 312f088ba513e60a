"""Causes named right: what a hostile input really is, not a guess ("not found", "damaged").

References: the file system's own word on what a path is (os.mkfifo, /dev/zero, a folder); a
log read in joint order against the same log with its columns permuted (equal to the bit); a
ROS 2 bag written with rosbags whose type the bag does not define; MuJoCo's default handler
(which writes MUJOCO_LOG.TXT into the working folder).
"""

import os
import warnings
from pathlib import Path

import numpy as np
import pytest

from ident.errors import ConfigError, DataError, IdentWarning, ModelError
from ident.identify.config import LogConfig, TransmissionConfig
from ident.measure.log_tables import joint_order
from ident.measure.logs import read_log

HOSTILE = Path(__file__).resolve().parent / "data" / "hostile"
RP2 = HOSTILE / "base" / "rp2.urdf"


def test_fifo_device_and_folder_are_named_and_never_opened(tmp_path):
    """A FIFO would block open() forever and /dev/zero never ends: refused before reading."""
    from ident.excitation.safety import _read_srdf
    from ident.model import Robot

    fifo = tmp_path / "robot.urdf"
    os.mkfifo(fifo)
    for path, cause in ((fifo, "is not a regular file"), (Path("/dev/zero"), "is not a "
                        "regular file"), (tmp_path, "is a folder")):  # fmt: skip
        with pytest.raises(ModelError, match=cause):
            Robot.from_urdf(path)
        with pytest.raises(ConfigError, match=f"safety.srdf: {path} {cause}"):
            _read_srdf(path)


def _log(tmp_path: Path, header: list[str], q: np.ndarray, columns=None) -> LogConfig:
    path = tmp_path / f"{'-'.join(header)}.csv"
    rows = "\n".join(",".join(repr(float(x)) for x in row) for row in q)
    path.write_text(",".join(header) + "\n" + rows + "\n")
    return LogConfig(
        sampling_rate_hz=100.0,
        position={"path": path, "columns": columns},
        torque={"path": path, "columns": columns},
    )


def test_columns_named_after_the_joints_are_matched_by_name(tmp_path):
    joints = ("shoulder", "slider")
    q = np.column_stack([np.sin(np.arange(50) / 7.0), 0.1 * np.cos(np.arange(50) / 5.0)])
    reference = read_log(_log(tmp_path, ["shoulder", "slider"], q), TransmissionConfig(), joints)
    for header, columns in (
        (["slider", "shoulder"], None),  # the file's order, no list
        (["q_slider", "q_shoulder"], ["q_slider", "q_shoulder"]),  # listed in the file's order
    ):
        log = read_log(_log(tmp_path, header, q[:, ::-1], columns), TransmissionConfig(), joints)
        np.testing.assert_array_equal(log.q, reference.q)
        np.testing.assert_array_equal(log.tau, reference.tau)
    # names that do not name the joints keep the config's (joint) order
    other = read_log(_log(tmp_path, ["a", "b"], q[:, ::-1]), TransmissionConfig(), joints)
    np.testing.assert_array_equal(other.q, reference.q[:, ::-1])
    assert joint_order(["tau/wrist_1", "tau/wrist_11"], ("wrist_11", "wrist_1")) == [1, 0]
    assert joint_order(["q_a", "q_a"], ("a", "b")) is None


def test_a_config_listing_too_many_columns_names_the_config_and_field(tmp_path):
    q = np.zeros((20, 3))
    cfg = _log(tmp_path, ["a", "b", "c"], q, columns=["a", "b", "c"])
    with pytest.raises(ConfigError, match=r"^my.yaml: log.position.columns lists 3 columns"):
        read_log(cfg, TransmissionConfig(), ("shoulder", "slider"), source="my.yaml")


def test_a_ros_type_the_bag_does_not_define_is_named(tmp_path):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from ident.measure.readers import read_tables

    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg("float64 x", "my_pkg/msg/Blob"))
    Blob = store.types["my_pkg/msg/Blob"]
    with Writer(tmp_path / "bag", version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        conn = writer.add_connection("/blob", "my_pkg/msg/Blob", msgdef="", rihs01="RIHS01_00")
        writer.write(conn, 1, store.serialize_cdr(Blob(x=1.0), "my_pkg/msg/Blob"))
    with pytest.raises(DataError) as info:
        read_tables(tmp_path / "bag")
    assert "topic /blob: message type my_pkg/msg/Blob is not known" in str(info.value)
    assert "damaged" not in str(info.value)


def test_mujoco_warnings_write_no_file_into_the_working_folder(tmp_path, monkeypatch):
    import mujoco

    import ident.measure.mujoco_model  # noqa: F401 - routes MuJoCo's warnings

    monkeypatch.chdir(tmp_path)
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><joint/><geom size="1"/></body></worldbody></mujoco>'
    )
    data = mujoco.MjData(model)
    data.qpos[:] = np.nan
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mujoco.mj_step(model, data)
    assert data.warning[mujoco.mjtWarning.mjWARN_BADQPOS].number == 1  # MuJoCo did warn
    assert any(issubclass(w.category, IdentWarning) and "QPOS" in str(w.message) for w in caught)
    assert list(tmp_path.iterdir()) == []
