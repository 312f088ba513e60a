import gzip

import numpy as np
import pytest

from ident.errors import ConfigError, DataError
from ident.measure.log_config import LogConfig, TransmissionConfig
from ident.measure.logs import read_csv_columns, read_log, transmission_from_config

JOINTS = ("j1", "j2", "j3")


def _write(path, header, data, gz=False):
    text = (
        ",".join(header) + "\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in data)
    )
    if gz:
        with gzip.open(path, "wt") as f:
            f.write(text + "\n")
    else:
        path.write_text(text + "\n")
    return path


def _log_cfg(tmp_path, q, y, **extra):
    _write(tmp_path / "q.csv", ["a", "b", "c"], q)
    _write(tmp_path / "y.csv.gz", ["a", "b", "c"], y, gz=True)
    cfg = {
        "position": {"path": tmp_path / "q.csv"},
        "torque": {"path": tmp_path / "y.csv.gz"},
        "sampling_rate_hz": 100.0,
    }
    cfg.update(extra)
    return LogConfig.model_validate(cfg)


def test_wide_file_column_selection_and_gzip(tmp_path):
    data = np.arange(12.0).reshape(4, 3)
    _write(tmp_path / "w.csv.gz", ["t", "q1", "tau1"], data, gz=True)
    values, names = read_csv_columns(tmp_path / "w.csv.gz", ["tau1", "q1"])
    np.testing.assert_array_equal(values, data[:, [2, 1]])
    assert names == ["tau1", "q1"]


def test_wrong_column_count_names_file(tmp_path):
    _write(tmp_path / "q.csv", ["a", "b"], np.zeros((5, 2)))
    with pytest.raises(DataError, match=r"q\.csv: position file has 2 columns .* expected 3"):
        read_csv_columns(tmp_path / "q.csv", None, n_expected=3, what="position")


def test_missing_column_lists_header(tmp_path):
    _write(tmp_path / "q.csv", ["a", "b"], np.zeros((5, 2)))
    with pytest.raises(DataError, match=r"column 'c' not found; the header has a, b"):
        read_csv_columns(tmp_path / "q.csv", ["a", "c"])


def test_nan_names_column_and_line(tmp_path):
    data = np.zeros((5, 3))
    data[3, 1] = np.nan
    _write(tmp_path / "q.csv", ["a", "b", "c"], data)
    with pytest.raises(
        DataError, match=r"column 'b' has 1 NaN/inf value\(s\), the first on line 5"
    ):
        read_csv_columns(tmp_path / "q.csv", None)
    data[3, 1] = np.inf
    _write(tmp_path / "q.csv", ["a", "b", "c"], data)
    with pytest.raises(DataError, match=r"column 'b'"):
        read_csv_columns(tmp_path / "q.csv", None)


def test_ragged_row_names_line(tmp_path):
    (tmp_path / "q.csv").write_text("a,b\n1,2\n3\n")
    with pytest.raises(DataError, match=r"line 3 has 1 fields, the header has 2"):
        read_csv_columns(tmp_path / "q.csv", None)


def test_non_numeric_cell_names_file_line_and_column(tmp_path):
    # QA: a bad cell on file line 52 was reported as numpy's "row 50, column 2"
    data = np.zeros((60, 3))
    _write(tmp_path / "q.csv", ["a", "b", "c"], data)
    lines = (tmp_path / "q.csv").read_text().splitlines()
    lines[51] = "0.0,abc,0.0"  # file line 52 (the header is line 1)
    (tmp_path / "q.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError) as e:
        read_csv_columns(tmp_path / "q.csv", None)
    assert str(e.value) == (
        f"{tmp_path / 'q.csv'}: line 52, column 'b' (field 2): 'abc' is not a number; "
        "clean or trim the log."
    )
    assert "row" not in str(e.value)


def test_line_numbers_are_file_lines_with_blank_lines(tmp_path):
    path = tmp_path / "q.csv"
    path.write_text("a,b\n1,2\n\n3,4\n5,x\n")  # the bad cell is on file line 5
    with pytest.raises(DataError, match=r"line 5, column 'b' \(field 2\): 'x' is not a number"):
        read_csv_columns(path, None)
    path.write_text("a,b\n1,2\n\n3,4\n5\n")
    with pytest.raises(DataError, match=r"line 5 has 1 fields"):
        read_csv_columns(path, None)
    path.write_text("a,b\n1,2\n\n3,nan\n")
    with pytest.raises(
        DataError, match=r"column 'b' has 1 NaN/inf value\(s\), the first on line 4"
    ):
        read_csv_columns(path, None)
    # time column: the first non-increasing time is named by its file line too
    q = np.zeros((6, 3))
    (tmp_path / "t.csv").write_text("time\n0.0\n0.01\n\n0.02\n0.02\n0.04\n0.05\n")
    cfg = _log_cfg(
        tmp_path, q, q, sampling_rate_hz=None, time={"path": tmp_path / "t.csv", "column": "time"}
    )
    # a duplicated stamp: the later sample is dropped, the warning names its file line
    log = read_log(cfg, TransmissionConfig(), JOINTS)
    # 5 stamps left (0.03 missing): resampled onto the uniform 100 Hz grid
    np.testing.assert_allclose(log.t, np.arange(6) * 0.01, atol=1e-12)
    assert any(r["step"] == "resample" for r in log.records)
    (warning,) = log.warnings
    assert "1 duplicated time stamp(s) dropped" in warning
    assert "first at line 6 (t = 0.02 s)" in warning
    # a NaN stamp is refused, naming its file line
    (tmp_path / "t.csv").write_text("time\n0.0\n0.01\n\n0.02\nnan\n0.04\n0.05\n")
    with pytest.raises(DataError, match=r"NaN or infinite, the first at line 6 \(nan\)"):
        read_log(cfg, TransmissionConfig(), JOINTS)


def test_transmission_round_trip_and_power_balance(tmp_path):
    rng = np.random.default_rng(0)
    cfg = TransmissionConfig(
        gear_ratios=[10.0, -20.0, 30.0],
        coupling=[{"motor": 3, "joint": 2, "ratio": 30.0}],
        zero_offsets=[0.0, -0.5, 0.25],
    )
    trans = transmission_from_config(cfg, 3)
    q = rng.normal(size=(50, 3))
    q_motor = (q - trans.zero_offsets) @ trans.position_matrix.T
    np.testing.assert_allclose(trans.joint_positions(q_motor), q, atol=1e-12)
    # power balance: joint power equals motor power for any motor torques and speeds
    y = rng.normal(size=(50, 3))
    dq = rng.normal(size=(50, 3))
    dq_motor = dq @ trans.position_matrix.T
    tau = trans.joint_torques(y)
    np.testing.assert_allclose(np.sum(tau * dq, axis=1), np.sum(y * dq_motor, axis=1), atol=1e-10)
    assert trans.coupled_pairs() == [(2, 1)]


def test_transmission_errors():
    with pytest.raises(ConfigError, match="gear_ratios has 2 entries"):
        transmission_from_config(TransmissionConfig(gear_ratios=[1.0, 2.0]), 3)
    with pytest.raises(ConfigError, match=r"coupling\[0\]"):
        transmission_from_config(
            TransmissionConfig(coupling=[{"motor": 4, "joint": 1, "ratio": 1.0}]), 3
        )


def test_read_log_converts_units_and_sides(tmp_path):
    rng = np.random.default_rng(1)
    q = rng.normal(size=(20, 3))
    y = rng.normal(size=(20, 3))
    cfg = _log_cfg(tmp_path, np.rad2deg(q), y, position_unit="deg", side="motor")
    trans = TransmissionConfig(gear_ratios=[2.0, 2.0, 2.0], torque_constants=[0.5, 1.0, 2.0])
    log = read_log(cfg, trans, JOINTS)
    np.testing.assert_allclose(log.q, q / 2.0, atol=1e-12)
    np.testing.assert_allclose(log.tau, 2.0 * y * [0.5, 1.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(log.t, np.arange(20) / 100.0)
    assert log.sampling_rate_hz == 100.0
    assert [r["step"] for r in log.records] == ["read", "units", "transmission"]


def test_time_column_checks(tmp_path):
    q = np.zeros((10, 3))
    t = np.arange(10) * 0.01
    _write(tmp_path / "t.csv", ["time"], t[:, None])
    cfg = _log_cfg(
        tmp_path, q, q, sampling_rate_hz=None, time={"path": tmp_path / "t.csv", "column": "time"}
    )
    log = read_log(cfg, TransmissionConfig(), JOINTS)
    assert log.sampling_rate_hz == pytest.approx(100.0)
    # a backwards jump: split there, the parts kept in their order, and said where
    t_bad = t.copy()
    t_bad[5:] -= 0.1
    _write(tmp_path / "t.csv", ["time"], t_bad[:, None])
    log = read_log(cfg, TransmissionConfig(), JOINTS)
    assert log.segments == ((0, 5), (5, 10))
    (warning,) = log.warnings
    assert "t.csv: time column 'time': time goes back 1 time(s)" in warning
    assert "first at line 7 (0.04 s then -0.05 s)" in warning
    assert log.t[5] - log.t[4] >= 1.0  # the later part starts after the earlier one
    # seconds read as ns: refused, naming the unit
    cfg_ns = _log_cfg(
        tmp_path,
        q,
        q,
        sampling_rate_hz=None,
        time={"path": tmp_path / "t.csv", "column": "time", "unit": "ns"},
    )
    _write(tmp_path / "t.csv", ["time"], t[:, None])
    with pytest.raises(DataError, match=r"unit ns.*rate of 1e\+11 Hz.*check log.time.unit"):
        read_log(cfg_ns, TransmissionConfig(), JOINTS)
    t_bad = t.copy()
    t_bad[5:] += 0.003
    _write(tmp_path / "t.csv", ["time"], t_bad[:, None])
    log = read_log(cfg, TransmissionConfig(), JOINTS)  # non-uniform: resampled, and said so
    assert "resample" in [r["step"] for r in log.records]
    np.testing.assert_allclose(np.diff(log.t), 0.01, rtol=1e-9)


def test_time_base_exclusive(tmp_path):
    with pytest.raises(ValueError, match="exactly one of log.time"):
        LogConfig.model_validate({"position": {"path": "a"}, "torque": {"path": "b"}})


def test_current_needs_constants(tmp_path):
    cfg = _log_cfg(tmp_path, np.zeros((5, 3)), np.zeros((5, 3)), torque_unit="A")
    with pytest.raises(ConfigError, match="torque_constants"):
        read_log(cfg, TransmissionConfig(), JOINTS)


def test_sample_count_mismatch(tmp_path):
    _write(tmp_path / "q.csv", ["a", "b", "c"], np.zeros((5, 3)))
    _write(tmp_path / "y.csv.gz", ["a", "b", "c"], np.zeros((6, 3)), gz=True)
    cfg = LogConfig.model_validate(
        {
            "position": {"path": tmp_path / "q.csv"},
            "torque": {"path": tmp_path / "y.csv.gz"},
            "sampling_rate_hz": 10.0,
        }
    )
    with pytest.raises(DataError, match="has 5 samples but .* has 6"):
        read_log(cfg, TransmissionConfig(), JOINTS)


def test_second_file_joined_on_time_duplicates_dropped_and_more_logs_named(tmp_path):
    """Torques in a second file with their own stamps, one duplicated: the duplicate is dropped
    with a warning naming that file's line, and the torques are interpolated exactly (cubic
    signals through a cubic spline); the same file as a ``more:`` log is named as such."""
    t = np.arange(100) / 100.0
    q = np.column_stack([t, t**2, t**3])
    t2 = t + 0.004  # the torque logger runs 4 ms later
    y = np.column_stack([t2, 2 * t2, t2**3])
    t2[30] = t2[29]  # a duplicated stamp (the row carries another value: it is dropped)
    _write(tmp_path / "q.csv", ["t", "q1", "q2", "q3"], np.column_stack([t, q]))
    _write(tmp_path / "y.csv", ["t", "y1", "y2", "y3"], np.column_stack([t2, y]))
    section = {
        "files": [{"path": tmp_path / "q.csv"}, {"path": tmp_path / "y.csv"}],
        "time": {"column": "t"},
        "position": {"columns": ["q1", "q2", "q3"]},
        "torque": {"columns": ["y1", "y2", "y3"]},
    }
    log = read_log(LogConfig.model_validate(section), TransmissionConfig(), JOINTS)
    (warning,) = log.warnings
    assert "y.csv: time column 't': 1 duplicated time stamp(s) dropped" in warning
    assert "first at line 32" in warning
    # only the span both files cover is kept: from the first position stamp after 0.004 s
    t_abs = log.t + 0.01
    np.testing.assert_allclose(log.q[:, 0], t_abs, atol=1e-12)
    expected = np.column_stack([t_abs, 2 * t_abs, t_abs**3])
    np.testing.assert_allclose(log.tau, expected, atol=1e-12)
    # as a second log (more:), the warning says which
    more = {**section, "more": [dict(section)]}
    log = read_log(LogConfig.model_validate(more), TransmissionConfig(), JOINTS)
    assert len(log.warnings) == 2
    assert log.warnings[1].startswith("log.more[0]: ")
