"""The log-reader registry and the built-in readers (CSV wide/long/headerless, ROS 2)."""

import gzip
from pathlib import Path

import numpy as np
import pytest

from ident.errors import ConfigError, DataError
from ident.identify.config import LogConfig, TransmissionConfig
from ident.identify.logs import read_log
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
