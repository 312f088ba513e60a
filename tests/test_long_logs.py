"""Long logs in bounded memory: reading keeps the named signals once, and the chunked
identification of an MCAP log equals the in-memory one.

The figures of one hour at 1 kHz are in ``benchmarks/bench_identify_long.py``; these tests hold
the per-sample costs that make them, on logs of a few seconds.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import yaml

from ident.identify.config import PreprocessConfig, load_identify_config
from ident.identify.estimation import log_chunks
from ident.identify.estimation.preprocess import resolve_for_log
from ident.measure.log_config import TransmissionConfig
from ident.measure.logs import read_log
from ident.measure.readers import read_tables

ROOT = Path(__file__).resolve().parents[1]
JOINTS = [f"j{k + 1}" for k in range(7)]


def _traced_peak(fn):
    """``(fn(), peak bytes allocated while it ran)`` (numpy's allocations are traced)."""
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        before = tracemalloc.get_traced_memory()[0]
        out = fn()
        peak = tracemalloc.get_traced_memory()[1] - before
    finally:
        tracemalloc.stop()
    return out, peak


def _log_config(path: Path, **log) -> object:
    from ident.measure.log_config import LogConfig

    return LogConfig.model_validate({"path": str(path), **log})


@pytest.fixture(scope="module")
def joint_state_mcap(tmp_path_factory):
    """50 000 JointState messages of 7 joints at 1 kHz: positions q, velocities 2 q,
    efforts 3 q."""
    import ros_logs

    n = 50_000
    rng = np.random.default_rng(0)
    q = np.cumsum(rng.normal(scale=1e-3, size=(n, 7)), axis=0)
    path = tmp_path_factory.mktemp("mcap") / "long.mcap"
    ros_logs.joint_states(path, q, 1.0 + 1e-3 * np.arange(n), names=JOINTS)
    return path, q


def test_mcap_log_keeps_only_the_named_signals(joint_state_mcap):
    """Read for positions and efforts, a JointState log keeps those 14 columns once: about
    210 bytes per message at the peak (t, q, tau: 120 bytes) plus one chunk, where the
    previous reader held every message of the file as an object (about 800 bytes each, 2.9 GB
    for one hour at 1 kHz) and kept all 21 columns."""
    path, q = joint_state_mcap
    cfg = _log_config(
        path,
        position={"columns": [f"/joint_states/position/{j}" for j in JOINTS]},
        torque={"columns": [f"/joint_states/effort/{j}" for j in JOINTS]},
    )
    log, peak = _traced_peak(lambda: read_log(cfg, TransmissionConfig(), JOINTS))
    n = q.shape[0]
    np.testing.assert_array_equal(log.q, q)
    np.testing.assert_array_equal(log.tau, 3.0 * q)
    np.testing.assert_allclose(np.diff(log.t), 1e-3, rtol=1e-6)
    # the same values as the table read whole (every column of the topic)
    (whole,) = read_tables(path)
    assert len(whole.columns) == 1 + 21
    np.testing.assert_array_equal(log.q[:, 2], whole.columns["/joint_states/position/j3"])
    assert peak < 250 * n + 8e6, f"{peak / n:.0f} bytes per message"


def test_mcap_column_not_found_lists_every_column(joint_state_mcap):
    from ident.errors import DataError

    path, _ = joint_state_mcap
    cfg = _log_config(
        path,
        position={"columns": [f"/joint_states/position/{j}" for j in JOINTS]},
        torque={"columns": [f"/joint_states/efort/{j}" for j in JOINTS]},
    )
    # read filtered first: the message still names the columns the file has
    with pytest.raises(DataError, match=r"efort/j1' not found \(closest: /joint_states/effort"):
        read_log(cfg, TransmissionConfig(), JOINTS)


def test_npz_log_is_not_copied(tmp_path):
    """A numpy archive's (n, 7) signals become the log's q and tau as they are: the peak of
    reading is the arrays once and the time checks (t, q, tau: 120 bytes per sample; 1.22 x
    at the peak), not copies of the signals (3.2 x). The time checks and the automatic
    settings' spectra hold a few arrays of the time column's size at once, not one per step
    (an hour at 1 kHz: 29 MB each)."""
    n = 50_000
    rng = np.random.default_rng(1)
    t = np.arange(n) * 1e-3
    q, tau = rng.normal(size=(2, n, 7))
    np.savez(tmp_path / "log.npz", t=t, q=q, tau=tau)
    cfg = _log_config(
        tmp_path / "log.npz",
        position={"columns": [f"q/{k}" for k in range(7)]},
        torque={"columns": [f"tau/{k}" for k in range(7)]},
    )
    log, peak = _traced_peak(lambda: read_log(cfg, TransmissionConfig(), JOINTS))
    np.testing.assert_array_equal(log.q, q)
    np.testing.assert_array_equal(log.tau, tau)
    arrays = t.nbytes + q.nbytes + tau.nbytes
    assert peak < 1.8 * arrays, (peak, arrays)  # copies of the signals: 3.2 x
    # above the arrays: 3.3 columns of t (the stamps and their steps, a median's copy); 8.3
    # when the time rule copied the clean column and the summary each step and deviation
    assert peak - arrays < 4.5 * t.nbytes, (peak - arrays) / t.nbytes
    # the spectra, a joint at a time: 5.1 columns (the window, the centred index, the joint's
    # windowed positions, its spectrum); 6.1 with the previous joint's power and sum still held
    _, peak = _traced_peak(lambda: resolve_for_log(PreprocessConfig(), log))
    assert peak < 5.5 * t.nbytes, peak / t.nbytes
    # columns in another order are copied, in that order
    cfg = _log_config(
        tmp_path / "log.npz",
        position={"columns": [f"q/{k}" for k in (1, 0, 2, 3, 4, 5, 6)]},
        torque={"columns": [f"tau/{k}" for k in range(0, 7)]},
    )
    np.testing.assert_array_equal(
        read_log(cfg, TransmissionConfig(), JOINTS).q, q[:, [1, 0, 2, 3, 4, 5, 6]]
    )


def test_mcap_chunked_identification_equals_in_memory(tmp_path):
    """The example arm's log as an MCAP: by chunks (of 300 samples) and in memory, the same
    estimate to 1e-10 and the same held-out prediction."""
    import ros_logs

    from ident.identify.pipeline.real import identify

    data = np.loadtxt(ROOT / "data" / "examples" / "wide.csv", delimiter=",", skiprows=1)
    t, q, tau = data[:, 0], data[:, 1:4], data[:, 4:7]
    path = ros_logs.joint_states(
        tmp_path / "arm3.mcap", q, 1.0 + t, names=["j1", "j2", "j3"], efforts=tau
    )
    cfg = yaml.safe_load((ROOT / "configs" / "examples" / "wide-csv.yaml").read_text())
    cfg["robot"]["urdf"] = str(ROOT / "data" / "examples" / "arm3.urdf")
    cfg["log"] = {
        "path": str(path),
        "position": {"columns": [f"/joint_states/position/j{k}" for k in (1, 2, 3)]},
        "torque": {"columns": [f"/joint_states/effort/j{k}" for k in (1, 2, 3)]},
    }
    results = []
    for mode in ("never", "always"):
        cfg["preprocess"].update(chunked=mode, chunk_samples=300)
        (tmp_path / f"{mode}.yaml").write_text(yaml.safe_dump(cfg))
        results.append(identify(load_identify_config(tmp_path / f"{mode}.yaml")))
    memory, chunked = results
    assert any(r["step"] == "chunked accumulation" for r in chunked.records)
    np.testing.assert_array_equal(memory.log.q, q)
    x0, x1 = memory.estimate.x, chunked.estimate.x
    assert np.linalg.norm(x1 - x0) <= 1e-10 * np.linalg.norm(x0)
    np.testing.assert_allclose(
        chunked.predictions["identified"].tau_pred,
        memory.predictions["identified"].tau_pred,
        rtol=0,
        atol=1e-9,
    )


def _joint_state_file(path: Path, q: np.ndarray, frame_ids, names) -> Path:
    """``/joint_states`` messages with a frame id and joint names per message (small
    chunks: several per file)."""
    import ros_logs
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = store.types
    with open(path, "wb") as f:
        writer = Writer(f, chunk_size=1 << 16, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="ident tests")
        schema = writer.register_schema(
            "sensor_msgs/msg/JointState", "ros2msg", ros_logs.JOINT_STATE.encode()
        )
        channel = writer.register_channel("/joint_states", "cdr", schema)
        for k, row in enumerate(q):
            stamp = types["builtin_interfaces/msg/Time"](
                sec=1 + k // 1000, nanosec=k % 1000 * 10**6
            )
            msg = types["sensor_msgs/msg/JointState"](
                header=types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_ids[k]),
                name=list(names[k]),
                position=row,
                velocity=2.0 * row,
                effort=3.0 * row,
            )
            data = bytes(store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
            writer.add_message(channel, log_time=k * 10**6, data=data, publish_time=k * 10**6)
        writer.finish()
    return path


def test_joint_states_read_at_once_equal_the_decoder_and_keep_its_checks(tmp_path):
    """Messages that differ from the topic's first one in more than the stamp and numbers
    (a longer frame id) are decoded one by one, with the same values; a joint renamed in
    the middle (same length) is refused as the decoder-only path refuses it."""
    n = 3000
    q = np.random.default_rng(2).normal(size=(n, 3))
    frames = ["" if k % 500 else "base_link" for k in range(n)]
    names = [("a1", "a2", "a3")] * n
    (table,) = read_tables(_joint_state_file(tmp_path / "frames.mcap", q, frames, names))
    for j in range(3):
        np.testing.assert_array_equal(table.columns[f"/joint_states/position/a{j + 1}"], q[:, j])
        np.testing.assert_array_equal(table.columns[f"/joint_states/effort/a{j + 1}"], 3 * q[:, j])
    np.testing.assert_allclose(table.columns["/joint_states/t"], np.arange(n) * 1e-3, atol=1e-12)
    renamed = [("a1", "a2", "a3") if k < 2000 else ("a1", "b2", "a3") for k in range(n)]
    from ident.errors import DataError

    with pytest.raises(DataError, match="changes its fields"):
        read_tables(_joint_state_file(tmp_path / "renamed.mcap", q, [""] * n, renamed))


@pytest.mark.skipif(not log_chunks._LIBC, reason="glibc only (mallopt)")
def test_large_blocks_are_handed_back_when_freed():
    """After :func:`map_large_blocks` (set by ``ident identify`` when it starts), a freed
    array of 20 MB leaves the resident set even after a larger one was freed; glibc's own rule
    would have raised its threshold to that one's 30 MB and kept the 20 MB in the heap,
    resident (an hour's log-length temporaries stayed so through the identification: ~60 MB).

    In a fresh interpreter, as ``ident identify`` sets it: in a test worker whose heap holds
    free chunks from earlier tests, glibc serves a 20 MB request from them (mmap is only for
    what the heap cannot give), which is the allocator's choice, not the setting's."""
    script = (
        "import numpy as np\n"
        "from ident.identify.estimation import log_chunks\n"
        "def rss():\n"
        "    with open('/proc/self/status') as f:\n"
        "        return next(int(x.split()[1]) for x in f if x.startswith('VmRSS:')) / 1024\n"
        "log_chunks.map_large_blocks()\n"
        "big = np.ones(30 << 17)\n"  # 30 MB, touched
        "del big\n"
        "block = np.ones(20 << 17)\n"  # 20 MB
        "before = rss()\n"
        "del block\n"
        "print(before - rss())\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(log_chunks.__file__).parents[3])}
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    assert float(out.stdout) > 15.0
