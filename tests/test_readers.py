"""The log-reader registry and the built-in readers (CSV wide/long/headerless, ROS 2)."""

import gzip
import os
from pathlib import Path

import numpy as np
import pytest

from ident.errors import ConfigError, DataError
from ident.measure.log_config import LogConfig, TransmissionConfig
from ident.measure.logs import read_log
from ident.measure.readers import READERS, LogTable, detect_format, read_tables, register_reader

EXAMPLES = Path(__file__).resolve().parents[1] / "data" / "examples"


def test_toy_reader_registers_and_feeds_read_log(tmp_path):
    # the "Extending" example of docs/logs.md: a JSON log {"t": [...], "q1": [...], ...}
    import json

    def read_json(path, options):
        data = json.loads(path.read_text())
        columns = {k: np.asarray(v, dtype=float) for k, v in data.items()}
        return [LogTable(columns=columns, time="t", source=str(path))]

    register_reader("json", read_json, detect=lambda p: p.suffix == ".json")
    try:
        t = np.arange(50) / 100.0
        log = {"t": t.tolist(), "q1": np.sin(t).tolist(), "tau1": np.cos(t).tolist()}
        (tmp_path / "log.json").write_text(json.dumps(log))
        assert detect_format(tmp_path / "log.json") == "json"
        cfg = LogConfig.model_validate(
            {
                "path": tmp_path / "log.json",
                "position": {"columns": ["q1"]},
                "torque": {"columns": ["tau1"]},
            }
        )
        result = read_log(cfg, TransmissionConfig(), ["j1"])
        np.testing.assert_allclose(result.q[:, 0], np.sin(t))
        assert result.sampling_rate_hz == pytest.approx(100.0)
    finally:
        READERS.pop("json")


def test_unknown_format_lists_registered(tmp_path):
    (tmp_path / "a.csv").write_text("1\n2\n")
    with pytest.raises(ConfigError, match="'cvs' is not registered; use one of .*csv.*Did you"):
        read_tables(tmp_path / "a.csv", "cvs")
    (tmp_path / "a.bin").write_bytes(b"\0")
    with pytest.raises(DataError, match="no reader recognises"):
        detect_format(tmp_path / "a.bin")


@pytest.mark.parametrize("delimiter", [",", "\t", ";", " "])
def test_csv_delimiters_and_header_detection(tmp_path, delimiter):
    rows = ["t q1 q2".replace(" ", delimiter)] + [
        f"{k * 0.01}{delimiter}{k}{delimiter}{-k}" for k in range(5)
    ]
    path = tmp_path / "log.tsv.gz"
    with gzip.open(path, "wt") as f:
        f.write("\n".join(rows) + "\n")
    (table,) = read_tables(path)
    assert list(table.columns) == ["t", "q1", "q2"]
    assert table.time == "t"
    np.testing.assert_array_equal(table.columns["q2"], -np.arange(5.0))


def test_headerless_files_are_named_after_the_file(tmp_path):
    (tmp_path / "q3.txt").write_text("1.0\n2.0\n\n3.0\n")
    (table,) = read_tables(tmp_path / "q3.txt")
    assert list(table.columns) == ["q3"]
    assert table.time is None
    (tmp_path / "m.csv").write_text("1,2\n3,4\n")
    (table,) = read_tables(tmp_path / "m.csv")
    assert list(table.columns) == ["m:1", "m:2"]
    (table,) = read_tables(tmp_path / "m.csv", names=["a", "b"])
    assert list(table.columns) == ["a", "b"]


def test_csv_errors_name_line_and_column(tmp_path):
    (tmp_path / "x.csv").write_text("a,b\n1,2\n3,oops\n")
    with pytest.raises(DataError, match=r"x\.csv: line 3, column 'b' \(field 2\): 'oops'"):
        read_tables(tmp_path / "x.csv")
    (tmp_path / "y.csv").write_text("a,b\n1,2\n3\n")
    with pytest.raises(DataError, match=r"line 3 has 1 fields, the header has 2"):
        read_tables(tmp_path / "y.csv")


def test_long_csv_pivots_and_checks_rows(tmp_path):
    lines = ["time,joint,pos"] + [
        f"{k},{j},{k * 10 + i}" for k in range(4) for i, j in enumerate(["a", "b"])
    ]
    (tmp_path / "l.csv").write_text("\n".join(lines) + "\n")
    (table,) = read_tables(tmp_path / "l.csv", "csv_long")
    assert set(table.columns) == {"time", "pos/a", "pos/b"}
    np.testing.assert_array_equal(table.columns["pos/b"], [1, 11, 21, 31])
    (tmp_path / "m.csv").write_text("\n".join(lines[:-1]) + "\n")
    with pytest.raises(DataError, match="joint 'b' has 3 rows for 4 time stamps"):
        read_tables(tmp_path / "m.csv", "csv_long")


def test_rosbag_and_mcap_read_joint_states():
    (bag,) = read_tables(EXAMPLES / "bag")
    (mcap,) = read_tables(EXAMPLES / "joint_states.mcap")
    assert detect_format(EXAMPLES / "bag") == "rosbag"
    assert detect_format(EXAMPLES / "joint_states.mcap") == "mcap"
    assert bag.time == "/joint_states/t"
    for name in ("position", "velocity", "effort"):
        for j in ("j1", "j2", "j3"):
            key = f"/joint_states/{name}/{j}"
            np.testing.assert_array_equal(bag.columns[key], mcap.columns[key])
    # header stamps, relative to the first message; +-25 % jitter around 10 ms
    t = bag.columns["/joint_states/t"]
    assert t[0] == 0.0
    assert 0.0074 < np.diff(t).min()
    assert np.diff(t).max() < 0.0126
    with pytest.raises(DataError, match="topic.* /nope"):
        read_tables(EXAMPLES / "bag", topics=["/nope"])


def test_units_sides_scale_sign(tmp_path):
    n = 40
    t = np.arange(n) / 100.0
    q = np.column_stack([np.sin(t), np.cos(t)])
    rows = ["t,p1,p2,c1,c2"] + [
        f"{t[k]},{np.rad2deg(q[k, 0]) * 50},{-np.rad2deg(q[k, 1]) * 1000},{k},{2 * k}"
        for k in range(n)
    ]
    (tmp_path / "w.csv").write_text("\n".join(rows) + "\n")
    cfg = LogConfig.model_validate(
        {
            "path": tmp_path / "w.csv",
            "position": {
                "columns": ["p1", "p2"],
                "unit": "deg",
                "side": "motor",
                "scale": [1.0, 1e-3],
                "sign": [1, -1],
            },
            "torque": {"columns": ["c1", "c2"], "unit": "mA", "side": "joint"},
        }
    )
    trans = TransmissionConfig(gear_ratios=[50.0, 1.0], torque_constants=[2.0, 3.0])
    log = read_log(cfg, trans, ["j1", "j2"])
    # positions motor side through the gear; torques joint side: only k and the unit
    np.testing.assert_allclose(log.q, q, atol=1e-12)
    np.testing.assert_allclose(log.tau[:, 0], np.arange(n) * 1e-3 * 2.0)
    np.testing.assert_allclose(log.tau[:, 1], 2 * np.arange(n) * 1e-3 * 3.0)
    with pytest.raises(ValueError, match="allowed: N\\*m, N, A, mA"):
        LogConfig.model_validate(
            {"path": "x", "position": {"columns": ["a"]}, "torque": {"unit": "Nm"}}
        )


def test_gap_and_windows_make_segments(tmp_path):
    t = np.concatenate([np.arange(300), 500 + np.arange(300)]) / 100.0
    rows = ["t,q,tau"] + [f"{v},{np.sin(v)},{np.cos(v)}" for v in t]
    (tmp_path / "g.csv").write_text("\n".join(rows) + "\n")
    base = {
        "path": tmp_path / "g.csv",
        "position": {"columns": ["q"]},
        "torque": {"columns": ["tau"]},
    }
    log = read_log(LogConfig.model_validate(base), TransmissionConfig(), ["j"])
    assert log.segments == ((0, 300), (300, 600))
    windowed = LogConfig.model_validate({**base, "windows": [{"start_s": 1.0, "end_s": 2.0}]})
    log = read_log(windowed, TransmissionConfig(), ["j"])
    assert log.segments == ((0, 101),)
    np.testing.assert_allclose(log.q[:, 0], np.sin(np.arange(100, 201) / 100.0))


# ---------------------------------------------------------------------------------------------
# bounds and time as it goes wrong: ROS 2 logs, text, numpy archives

HOSTILE_LOGS = Path(__file__).resolve().parent / "data" / "hostile" / "logs"
ROS_JOINTS = ("j1", "j2", "j3")


def _ramp(n: int, nj: int = 3) -> np.ndarray:
    return np.arange(n)[:, None] * 0.001 + np.arange(nj)[None, :]


def test_mcap_keeps_recorded_order_and_the_time_rule_splits_a_jump(tmp_path):
    import ros_logs

    n = 400
    stamps = 100.0 + np.arange(n) * 0.01
    stamps[200:] -= 5.0  # the clock goes back 5 s half way
    path = ros_logs.joint_states(tmp_path / "jump.mcap", _ramp(n), stamps, names=ROS_JOINTS)
    (table,) = read_tables(path)
    # not sorted: the table keeps the order of the recording
    np.testing.assert_allclose(table.columns["/joint_states/position/j1"], _ramp(n)[:, 0])
    t = table.columns["/joint_states/t"]
    assert t[199] > t[200]
    cfg = LogConfig.model_validate(
        {
            "path": path,
            "position": {"columns": [f"/joint_states/position/{j}" for j in ROS_JOINTS]},
            "torque": {"columns": [f"/joint_states/effort/{j}" for j in ROS_JOINTS]},
        }
    )
    log = read_log(cfg, TransmissionConfig(), ROS_JOINTS)
    assert log.segments == ((0, 200), (200, 400))
    np.testing.assert_allclose(log.q[200], _ramp(n)[200])  # the sample after the jump
    (warning,) = log.warnings
    assert "time goes back 1 time(s) (largest jump 4.99 s), the first at sample 200" in warning


def test_missing_stamps_use_the_recorded_time_for_the_whole_topic(tmp_path):
    import ros_logs

    n = 60
    stamps = [None if k % 4 == 1 else 3.0 + 0.01 * k for k in range(n)]  # sim time, some unset
    path = ros_logs.joint_states(tmp_path / "s.mcap", _ramp(n), stamps, names=ROS_JOINTS)
    (table,) = read_tables(path)
    t = table.columns["/joint_states/t"]
    # the recorder's clock (1 ms steps), never a mix of two clocks 1.7e9 s apart
    np.testing.assert_allclose(t, np.arange(n) * 1e-3, atol=1e-12)
    (warning,) = table.warnings
    assert "15 of 60 messages have no header.stamp, the first is message 1" in warning
    # every stamp set: the stamps
    path = ros_logs.joint_states(
        tmp_path / "ok.mcap", _ramp(n), 3.0 + 0.01 * np.arange(n), names=ROS_JOINTS
    )
    (table,) = read_tables(path)
    np.testing.assert_allclose(table.columns["/joint_states/t"], 0.01 * np.arange(n), atol=1e-9)
    assert table.warnings == ()


def test_repeated_joint_name_is_refused_naming_it():
    with pytest.raises(DataError, match="name lists joint 'shoulder' 3 times"):
        read_tables(HOSTILE_LOGS / "repeated_name.mcap")


def test_mcap_bomb_refused_before_decompression():
    path = HOSTILE_LOGS / "zstd_bomb.mcap"
    assert path.stat().st_size < 20_000  # 2 x 160 MB of zeros inside
    import tracemalloc

    tracemalloc.start()
    try:
        with pytest.raises(DataError, match=r"declares 160000502 bytes once decompressed"):
            read_tables(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20e6


@pytest.mark.parametrize("compression", ["none", "zstd"])
def test_flipped_bytes_end_in_one_data_error(tmp_path, compression):
    import ros_logs

    source = ros_logs.joint_states(
        tmp_path / "a.mcap", _ramp(300), 1.0 + 0.01 * np.arange(300), compression=compression
    )
    for seed in range(12):
        damaged = ros_logs.flip_bytes(source, tmp_path / f"f{seed}.mcap", n=6, seed=seed)
        try:
            tables = read_tables(damaged)
        except DataError:
            continue
        assert tables  # read: the CRCs did not cover the flipped bytes (the summary)


def test_bag_declaring_a_missing_compression():
    with pytest.raises(DataError, match="cannot read the ROS 2 bag .*ZstdError"):
        read_tables(HOSTILE_LOGS / "bag_zstd_declared")


# VmHWM, this process's own peak [kB]: ru_maxrss starts at the parent's (the pytest worker's,
# often above this child's whole run), inherited at exec, and would make the growth 0
_RSS = """
import sys
from ident.measure.readers import read_tables
def peak_kb():
    with open("/proc/self/status") as f:
        return next(int(x.split()[1]) for x in f if x.startswith("VmHWM:"))
read_tables(sys.argv[1])  # imports, decoders: warm
before = peak_kb()
(table,) = read_tables(sys.argv[2])
after = peak_kb()
print((after - before) * 1024, sum(c.nbytes for c in table.columns.values()))
"""


def test_mcap_streams_in_memory_proportional_to_its_columns(tmp_path):
    """50 000 JointState messages of 7 joints: the reader's peak is a small multiple of the
    columns it returns (9 MB), not of the decoded messages (the dict per message of the
    previous reader: 150 MB)."""
    import subprocess
    import sys

    import ros_logs

    n = 50_000
    q = np.random.default_rng(0).normal(size=(n, 7))
    big = ros_logs.joint_states(tmp_path / "big.mcap", q, 1.0 + 1e-3 * np.arange(n))
    small = ros_logs.joint_states(tmp_path / "small.mcap", q[:10], 1.0 + 1e-3 * np.arange(10))
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src")}
    out = subprocess.run(
        [sys.executable, "-c", _RSS, str(small), str(big)],
        capture_output=True,
        text=True,
        check=True,
        env=env,
    ).stdout.split()
    growth, columns = float(out[0]), float(out[1])
    assert columns == pytest.approx(n * 22 * 8)
    assert growth < 4 * columns + 16e6, (growth, columns)


def test_mcap_refused_above_the_memory_ceiling_before_allocating(tmp_path, monkeypatch):
    import ros_logs

    path = ros_logs.joint_states(tmp_path / "a.mcap", _ramp(2000, 7), 1.0 + 1e-3 * np.arange(2000))
    monkeypatch.setenv("IDENT_MAX_MEMORY_GB", "0.0001")  # 100 kB
    with pytest.raises(ConfigError, match=r"2000 messages x 21 values.*IDENT_MAX_MEMORY_GB"):
        read_tables(path)
    from ident.measure.readers import estimate_read

    estimate = estimate_read(path)
    assert estimate is not None
    assert "2000 messages" in estimate.what
    # the first message decoded: 21 numbers, a stamp and a time of 8 bytes each per message
    # (plus the chunks' records), not the serialized size bound (~2000 x 430 bytes)
    assert 2000 * 23 * 8 <= estimate.memory_bytes < 1.25 * 2000 * 23 * 8


def test_csv_refuses_devices_long_lines_and_bombs(tmp_path, monkeypatch):
    with pytest.raises(DataError, match="/dev/zero: is not a regular file"):
        read_tables("/dev/zero", "csv")
    # one line of 4 MB in a 4 kB .gz: refused at that line, before reading on
    one_line = tmp_path / "line.csv.gz"
    with gzip.open(one_line, "wb") as f:
        f.write(b"t,q\n0,1\n" + b"1" * (4 << 20))
    with pytest.raises(DataError, match="line 3 is longer than 1048576 characters"):
        read_tables(one_line)
    # many lines: 24 MB of "0,0,0" (a 3 GiB bomb scaled down): refused at the ceiling
    many = tmp_path / "many.csv.gz"
    with gzip.open(many, "wb", compresslevel=1) as f:
        f.write(b"t,q1,q2\n")
        f.write(b"0,0,0\n" * (4 << 20))
    monkeypatch.setenv("IDENT_MAX_MEMORY_GB", "0.01")
    # counted before anything is allocated: 12 bytes of numbers per 6 characters of text
    with pytest.raises(ConfigError, match="many.csv.gz: reading at least 349525 lines"):
        read_tables(many)
    from ident.measure.readers import estimate_read

    estimate = estimate_read(many)  # from the gzip trailer: 24 MB of text before reading it
    # three numbers and a line number per row, plus one block of text
    assert estimate.memory_bytes == pytest.approx(8 * 4 * (4 << 20) + 32e6, rel=0.01)


def test_csv_blocks_give_the_same_table_as_one_parse(tmp_path, monkeypatch):
    from ident.measure.readers import csv as csv_reader

    rng = np.random.default_rng(3)
    data = rng.normal(size=(1000, 4))
    lines = ["t,a,b,c"] + [",".join(repr(float(v)) for v in row) for row in data]
    lines.insert(500, "")  # a blank line: file line numbers still count it
    (tmp_path / "x.csv").write_text("\n".join(lines) + "\n")
    monkeypatch.setattr(csv_reader, "BLOCK_LINES", 64)
    (table,) = read_tables(tmp_path / "x.csv")
    for k, name in enumerate("tabc"):
        np.testing.assert_array_equal(table.columns[name], data[:, k])
        assert table.columns[name].flags.c_contiguous
    assert table.line_numbers[498] == 500
    assert table.line_numbers[499] == 502


def test_npz_checked_from_its_headers(tmp_path, monkeypatch):
    for name, match in [
        ("empty", "holds no arrays"),
        ("not_zip", "not a numpy archive"),
        ("object", "array 't' holds object values"),
        ("string", "array 't' holds <U1 values"),
        ("declares_100M", r"declares shape \(100000000,\).*holds 8128 bytes"),
    ]:
        with pytest.raises(DataError, match=match):
            read_tables(HOSTILE_LOGS / f"{name}.npz")
    # a real compressed archive of 10 million samples (800 kB on disk) above the ceiling
    np.savez_compressed(tmp_path / "big.npz", t=np.zeros(10_000_000))
    monkeypatch.setenv("IDENT_MAX_MEMORY_GB", "0.05")  # read as float64 plus one 256 kB block
    with pytest.raises(ConfigError, match="about 80.3 MB of memory.*IDENT_MAX_MEMORY_GB"):
        read_tables(tmp_path / "big.npz")
    np.savez(tmp_path / "ok.npz", t=np.arange(5.0), q=np.ones((5, 2)), rate=100.0)
    (table,) = read_tables(tmp_path / "ok.npz")
    assert list(table.columns) == ["t", "q/0", "q/1"]  # the scalar is not a column


def test_bag_with_mcap_storage_is_checked_for_bombs_too(tmp_path):
    import shutil

    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    bag = tmp_path / "bag"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection("/cmd", "std_msgs/msg/Float64MultiArray", typestore=store)
        Array = store.types["std_msgs/msg/Float64MultiArray"]
        Layout = store.types["std_msgs/msg/MultiArrayLayout"]
        msg = Array(layout=Layout(dim=[], data_offset=0), data=np.zeros(3))
        writer.write(conn, 1, store.serialize_cdr(msg, conn.msgtype))
    (storage,) = bag.glob("*.mcap")
    shutil.copy(HOSTILE_LOGS / "zstd_bomb.mcap", storage)  # same topic and type
    with pytest.raises(DataError, match="a zstd chunk declares 160000502 bytes"):
        read_tables(bag)


def test_gzip_text_estimated_from_its_trailer_before_reading(tmp_path, monkeypatch):
    """A .csv.gz whose trailer says 3 GiB of text (an 11 MB bomb) is refused from the
    estimate alone, before a byte is decompressed: ``ident identify`` checks it first."""
    from ident.inputs import check_job
    from ident.measure.logs import estimate_log

    path = tmp_path / "bomb.csv.gz"
    with gzip.open(path, "wb") as f:
        f.write(b"t,q1,q2,tau1,tau2\n" + b"0,0,0,0,0\n" * 1000)
    data = bytearray(path.read_bytes())
    data[-4:] = (3 << 30).to_bytes(4, "little")  # what the real 3 GiB file's trailer holds
    path.write_bytes(bytes(data))
    cfg = LogConfig.model_validate(
        {
            "path": path,
            "time": {"column": "t"},
            "position": {"columns": ["q1", "q2"]},
            "torque": {"columns": ["tau1", "tau2"]},
        }
    )
    estimate = estimate_log(cfg)
    rows = (3 << 30) / 10  # 10 characters per line
    # reading (5 numbers and a line number per row, one block) and the signals beside it
    assert estimate.memory_bytes == pytest.approx(2 * (8 * 6 * rows + 32e6), rel=0.01)
    monkeypatch.setenv("IDENT_MAX_MEMORY_GB", "2")
    with pytest.raises(ConfigError, match=r"reading the log \(bomb.csv.gz\).*above the memory"):
        check_job(estimate)


def test_long_csv_keeps_the_file_order_and_refuses_nan_stamps(tmp_path):
    # two joints; the clock goes back after the third sample
    times = [10.0, 10.01, 10.02, 5.0, 5.01]
    rows = ["t,joint,pos"]
    for k, t in enumerate(times):
        rows += [f"{t},b,{k + 0.5}", f"{t},a,{k}"]  # joints in any order within a sample
    (tmp_path / "l.csv").write_text("\n".join(rows) + "\n")
    (table,) = read_tables(tmp_path / "l.csv", "csv_long")
    np.testing.assert_array_equal(table.columns["t"], times)  # not sorted
    np.testing.assert_array_equal(table.columns["pos/a"], [0, 1, 2, 3, 4])
    np.testing.assert_array_equal(table.columns["pos/b"], [0.5, 1.5, 2.5, 3.5, 4.5])
    rows[7] = "nan,b,9"  # line 8
    (tmp_path / "l.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(DataError, match="NaN or infinite, the first at line 8"):
        read_tables(tmp_path / "l.csv", "csv_long")


def test_mcap_cut_off_by_a_crash_reads_its_complete_chunks_with_a_warning(tmp_path):
    import ros_logs

    n = 3000
    q = _ramp(n)
    full = ros_logs.joint_states(
        tmp_path / "full.mcap", q, 1.0 + 1e-3 * np.arange(n), chunk_size=20_000
    )
    data = full.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])  # no summary, no footer, half a chunk at the end
    (table,) = read_tables(cut)
    k = table.n_samples
    assert 0 < k < n
    np.testing.assert_array_equal(table.columns["/joint_states/position/j2"], q[:k, 1])
    (warning,) = table.warnings
    assert f"the file ends early or is damaged after {k} messages" in warning
    # a file cut before its first complete chunk: nothing to read, one error
    cut.write_bytes(data[:200])
    with pytest.raises(DataError, match="cannot read the MCAP file"):
        read_tables(cut)


def _long_rows(n: int, joints: list[str]) -> list[str]:
    """A long log of ``n`` stamps: at each stamp one row per joint (7 significant digits)."""
    rng = np.random.default_rng(3)
    return [
        f"{k * 1e-3!r},{j},{rng.normal():.7g},{rng.normal():.7g}" for k in range(n) for j in joints
    ]


@pytest.mark.parametrize("layout", ["grouped", "any order"])
def test_long_csv_by_blocks_equals_the_line_reader(tmp_path, monkeypatch, layout):
    from ident.measure.readers import csv_long

    joints = [" j1", "7", "j2 ", "j3"]  # spaces stripped as split_fields does; a number
    rows = _long_rows(40, joints)
    if layout == "any order":  # the rows of two stamps swapped in the third block
        rows[9], rows[13] = rows[13], rows[9]
    text = "time,joint,pos,tau\r\n" + "\r\n".join(rows[:30]) + "\r\n\r\n" + "\n".join(rows[30:])
    path = tmp_path / "l.csv.gz"  # decompressed on the fly; the last line without a break
    path.write_bytes(gzip.compress(text.encode()))
    lines = csv_long.read_csv_long(path, {}, block_bytes=0)[0].columns
    # about three rows a block: every stamp's four rows are split across blocks
    monkeypatch.setattr(csv_long, "blocks", None)  # the line reader is not used
    by_blocks = csv_long.read_csv_long(path, {}, block_bytes=100)[0].columns
    assert (
        list(by_blocks)
        == list(lines)
        == ["time"] + [f"{v}/{j.strip()}" for j in joints for v in ("pos", "tau")]
    )
    for name, column in lines.items():
        np.testing.assert_array_equal(by_blocks[name], column, err_msg=name)
    assert lines["time"].size == 40


def test_long_csv_by_blocks_names_the_line_of_a_bad_value(tmp_path):
    from ident.measure.readers import csv_long

    rows = _long_rows(20, ["a", "b"])
    rows[31] = rows[31].replace(",b,", ",b,1.5x")  # line 33, in the fifth block
    path = tmp_path / "l.csv"
    path.write_text("t,joint,q,tau\n" + "\n".join(rows) + "\n")
    with pytest.raises(DataError, match=r"line 33, column 'q' \(field 2\): '1.5x-?[0-9.]+'"):
        csv_long.read_csv_long(path, {}, block_bytes=200)


def test_long_csv_estimate_counts_the_kept_values(tmp_path):
    from ident.measure.readers import csv_long, estimate_read

    rows = _long_rows(500, [f"j{k}" for k in range(7)])  # 3500 rows, 2 values each
    path = tmp_path / "l.csv"
    path.write_text("t,joint,q,tau\n" + "\n".join(rows) + "\n")
    columns = csv_long.read_csv_long(path, {})[0].columns
    kept = 8.0 * (3500 * 2 + 500)  # the values and the stamps read
    assert sum(c.nbytes for c in columns.values()) == kept
    estimate = estimate_read(path, "csv_long")
    assert estimate is not None
    # one stamp per row counted (rows in any order): within 2x of what a grouped log keeps
    assert kept < estimate.memory_bytes - csv_long._BLOCK_BYTES < 2 * kept
    spaced = tmp_path / "s.csv"  # whitespace-delimited: read line by line, 5x slower
    spaced.write_text(path.read_text().replace(",", " "))
    by_line = estimate_read(spaced, "csv_long")
    assert by_line is not None
    assert by_line.seconds == pytest.approx(5 * estimate.seconds, rel=0.01)
