"""``ident logs inspect``: a new user's log, its skeleton, and an identification from it.

The log is one a controller might write and that no example config describes: semicolons,
column names with brackets (``time[s]``, ``q[0]``, ``i[0]``), time stamps that start at 1234.5 s
with +-30 % jitter, joint-side positions in degrees and motor currents in A. The reference is
the simulation's truth (Pinocchio RNEA of the URDF's inertials + the friction below).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml
from typer.testing import CliRunner

from ident.cli import app

REPO = Path(__file__).resolve().parents[1]
URDF = REPO / "data" / "examples" / "arm3.urdf"
FV = np.array([0.8, 0.6, 0.3])  # N*m*s/rad
FS = np.array([1.5, 1.0, 0.5])  # N*m
GEAR = np.array([100.0, 80.0, 50.0])
KT = np.array([0.05, 0.04, 0.03])  # N*m/A
runner = CliRunner()


def _log(path: Path, n: int = 12000, rate_hz: float = 500.0) -> Path:
    rng = np.random.default_rng(11)
    t = 1234.5 + np.concatenate([[0.0], np.cumsum(rng.uniform(0.7, 1.3, n - 1) / rate_hz)])
    w = 2.0 * np.pi * 0.125 * np.arange(1, 6)
    a, b = rng.normal(scale=0.5, size=(2, 5, 3)) / np.arange(1, 6)[None, :, None]
    s, c = np.sin(np.outer(t - t[0], w)), np.cos(np.outer(t - t[0], w))
    q, dq, ddq = s @ a + c @ b, (c * w) @ a - (s * w) @ b, -(s * w**2) @ a - (c * w**2) @ b
    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    tau = np.array([pin.rnea(model, data, *x) for x in zip(q, dq, ddq, strict=True)])
    tau += FV * dq + FS * np.sign(dq) + rng.normal(scale=0.03, size=tau.shape)
    current = tau / (GEAR * KT)  # tau = N k i
    rows = np.column_stack([t, np.degrees(q), current, current * 1.1])
    header = "time[s];q[0];q[1];q[2];i[0];i[1];i[2];i_cmd[0];i_cmd[1];i_cmd[2]"
    path.write_text(header + "\n" + "\n".join(";".join(f"{v:.9g}" for v in r) for r in rows))
    return path


def _simulated(n: int, rate_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Uniform time [s], joint angles [rad] and joint torques [N*m] (RNEA + friction + noise)
    of the Fourier motion of :func:`_log`."""
    rng = np.random.default_rng(12)
    t = np.arange(n) / rate_hz
    w = 2.0 * np.pi * 0.125 * np.arange(1, 6)
    a, b = rng.normal(scale=0.5, size=(2, 5, 3)) / np.arange(1, 6)[None, :, None]
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q, dq, ddq = s @ a + c @ b, (c * w) @ a - (s * w) @ b, -(s * w**2) @ a - (c * w**2) @ b
    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    tau = np.array([pin.rnea(model, data, *x) for x in zip(q, dq, ddq, strict=True)])
    tau += FV * dq + FS * np.sign(dq) + rng.normal(scale=0.03, size=tau.shape)
    return t, q, tau


@pytest.fixture(scope="module")
def inspected(tmp_path_factory) -> tuple[Path, str]:
    log = _log(tmp_path_factory.mktemp("log") / "robot_log.csv")
    result = runner.invoke(app, ["logs", "inspect", str(log)])
    assert result.exit_code == 0, result.output
    return log, result.output


def test_inspect_finds_time_rate_and_jitter(inspected) -> None:
    _, output = inspected
    line = next(x for x in output.splitlines() if x.startswith("  time 'time[s]'"))
    assert "12000 samples" in line
    rate = float(re.search(r"([\d.]+) Hz \(median step\)", line).group(1))
    assert rate == pytest.approx(500.0, rel=0.01)
    jitter = float(re.search(r"jitter max ([\d.]+) %", line).group(1))
    assert 25 <= jitter <= 32  # the steps vary by +-30 % about their median


def test_skeleton_names_the_columns_units_and_transmission(inspected) -> None:
    log, output = inspected
    cfg = yaml.safe_load(output.split("config skeleton (check every line):")[1])
    section = cfg["log"]
    assert section["time"] == {"column": "time[s]", "unit": "s"}
    assert section["position"]["columns"] == ["q[0]", "q[1]", "q[2]"]
    assert section["position"]["unit"] == "deg"  # values up to ~100: not radians
    # measured currents, not the commanded ones
    assert section["torque"] == {"columns": ["i[0]", "i[1]", "i[2]"], "unit": "A", "side": "motor"}
    assert set(cfg["transmission"]) == {"gear_ratios", "torque_constants"}


def test_the_completed_skeleton_identifies_the_friction(inspected, tmp_path) -> None:
    """What the docs tell a new user: fill in the robot, the transmission and the model."""
    log, output = inspected
    cfg = yaml.safe_load(output.split("config skeleton (check every line):")[1])
    cfg["transmission"] = {"gear_ratios": GEAR.tolist(), "torque_constants": KT.tolist()}
    cfg |= {"name": "new-user", "robot": {"urdf": str(URDF)}}
    cfg["model"] = {"viscous": True, "coulomb": True}
    path = tmp_path / "new-user.yaml"
    path.write_text(yaml.safe_dump(cfg))
    result = runner.invoke(app, ["identify", str(path), "--out", str(tmp_path), "--no-replay"])
    assert result.exit_code == 0, result.output
    (run,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    import csv

    with (run / "parameters.csv").open() as f:
        x = {row["name"]: float(row["value"]) for row in csv.DictReader(f)}
    np.testing.assert_allclose([x[f"fv{j}"] for j in (1, 2, 3)], FV, rtol=0.05)
    np.testing.assert_allclose([x[f"fs{j}"] for j in (1, 2, 3)], FS, rtol=0.05)


def test_skeleton_of_a_log_in_radians_and_newton_metres(tmp_path) -> None:
    """No currents: no transmission to fill in; a name's unit wins over the range."""
    path = tmp_path / "plain.csv"
    t = np.arange(200) / 100.0
    rows = np.column_stack([t, np.sin(t), 10 * np.cos(t), np.cos(t), np.sin(t)])
    path.write_text(
        "t,pos_rad_1,pos_rad_2,tau_1,tau_2\n" + "\n".join(",".join(map(str, r)) for r in rows)
    )
    result = runner.invoke(app, ["logs", "inspect", str(path)])
    assert result.exit_code == 0, result.output
    cfg = yaml.safe_load(result.output.split("config skeleton (check every line):")[1])
    assert cfg["log"]["time"] == {"column": "t", "unit": "s"}
    assert cfg["log"]["position"] == {"columns": ["pos_rad_1", "pos_rad_2"], "unit": "rad"}
    assert cfg["log"]["torque"] == {"columns": ["tau_1", "tau_2"], "unit": "N*m"}
    assert "transmission" not in cfg


def test_long_csv_with_a_millisecond_stamp_column() -> None:
    """The documented ``--format csv_long`` call on the shipped example: the stamp column
    ``time_ms`` orders the rows and is proposed with its unit (never taken for seconds)."""
    from ident.measure.readers import read_tables

    path = REPO / "data" / "examples" / "long.csv.gz"
    result = runner.invoke(app, ["logs", "inspect", str(path), "--format", "csv_long"])
    assert result.exit_code == 0, result.output
    cfg = yaml.safe_load(result.output.split("config skeleton (check every line):")[1])
    assert cfg["log"]["time"] == {"column": "time_ms", "unit": "ms"}
    assert cfg["log"]["position"]["unit"] == "deg"
    assert cfg["log"]["torque"]["unit"] == "mA"
    (table,) = read_tables(path, "csv_long")
    assert table.time is None  # its unit is unknown to the reader: the config says it
    assert np.all(np.diff(table.columns["time_ms"]) == 10.0)  # 100 Hz, in ms


def test_controller_channels_that_are_not_joints_are_left_out(tmp_path) -> None:
    """A UR RTDE-style recording: TCP pose and speed, robot current, speed scaling and the
    target (commanded) values are not joint measurements."""
    groups = ("target_q", "target_current", "actual_q", "actual_qd", "actual_current")
    names = ["timestamp"] + [f"{g}_{k}" for g in groups for k in range(6)]
    names += [f"actual_TCP_{g}_{k}" for g in ("pose", "speed") for k in range(6)]
    names += ["actual_robot_current", "speed_scaling", "joint_temperatures_0"]
    t = 1.7e9 + np.arange(50) * 0.008
    rows = np.column_stack([t, np.random.default_rng(0).normal(size=(50, len(names) - 1))])
    path = tmp_path / "rtde.csv"
    path.write_text(
        " ".join(names) + "\n" + "\n".join(" ".join(f"{v:.12g}" for v in r) for r in rows)
    )
    result = runner.invoke(app, ["logs", "inspect", str(path)])
    assert result.exit_code == 0, result.output
    log = yaml.safe_load(result.output.split("config skeleton (check every line):")[1])["log"]
    assert log["position"]["columns"] == [f"actual_q_{k}" for k in range(6)]
    assert log["velocity"]["columns"] == [f"actual_qd_{k}" for k in range(6)]
    assert log["torque"]["columns"] == [f"actual_current_{k}" for k in range(6)]


def test_inspect_reports_every_time_anomaly_with_count_and_line(tmp_path) -> None:
    """Duplicates, a backwards jump and a NaN stamp: each with its count and first file line
    (never "inf Hz"), and the rule identify applies."""
    t = np.arange(300) / 100.0
    t[41] = t[40]  # duplicate: file line 43 (header on line 1)
    t[42] = t[40]  # and again
    t[200:] -= 1.0  # back: line 202
    t[250] = np.nan  # line 252
    rows = np.column_stack([t, np.sin(t), np.cos(t)])
    path = tmp_path / "bad.csv"
    path.write_text("t,q1,tau1\n" + "\n".join(",".join(map(str, r)) for r in rows))
    result = runner.invoke(app, ["logs", "inspect", str(path)])
    assert result.exit_code == 0, result.output
    (line,) = [x for x in result.output.splitlines() if x.startswith("  time 't'")]
    assert "100 Hz (median step)" in line
    assert "inf Hz" not in result.output
    assert "1 NaN/inf stamp(s), first at line 252" in line
    assert "2 duplicated stamp(s), first at line 43" in line
    assert "1 backwards jump(s) (largest 0.99 s), first at line 202" in line
    assert "backwards jumps split into segments" in result.output


def test_inspect_names_messages_without_stamps(tmp_path) -> None:
    import ros_logs

    stamps = [None if k < 5 else 2.0 + 0.01 * k for k in range(40)]
    path = ros_logs.joint_states(tmp_path / "m.mcap", np.zeros((40, 2)), stamps)
    result = runner.invoke(app, ["logs", "inspect", str(path)])
    assert result.exit_code == 0, result.output
    assert (
        "warning: " + str(path) + ": /joint_states: 5 of 40 messages have no header.stamp, "
        "the first is message 0" in result.output
    )


def test_identify_warns_of_a_backwards_jump_and_still_identifies(tmp_path) -> None:
    """A bare MCAP whose stamps jump back 5 s half way: one warning naming the place, the
    parts kept as two segments, and the friction identified as on a clean log."""
    import ros_logs

    t, q, tau = _simulated(4000, 200.0)
    stamps = 50.0 + t
    stamps[2000:] -= 5.0 + t[2000] - t[0]  # the second half restarts before the first
    path = tmp_path / "jump.mcap"
    ros_logs.joint_states(path, q, stamps, efforts=tau)
    joints = [f"j{k + 1}" for k in range(3)]
    cfg = {
        "name": "jump",
        "robot": {"urdf": str(URDF)},
        "log": {
            "path": str(path),
            "position": {"columns": [f"/joint_states/position/{j}" for j in joints]},
            "torque": {"columns": [f"/joint_states/effort/{j}" for j in joints]},
        },
        "preprocess": {"lowpass": {"cutoff_hz": 10.0, "order": 4}, "trim_samples": 10},
        "model": {"viscous": True, "coulomb": True},
        "validation": {"identify_fraction": 0.7},
    }
    (tmp_path / "jump.yaml").write_text(yaml.safe_dump(cfg))
    out = tmp_path / "runs"
    result = runner.invoke(
        app, ["identify", str(tmp_path / "jump.yaml"), "--out", str(out), "--no-replay"]
    )
    assert result.exit_code == 0, result.output
    warnings = [x for x in result.output.splitlines() if x.startswith("warning:")]
    assert any(
        "time goes back 1 time(s)" in w and "the first at sample 2000" in w for w in warnings
    ), result.output
    (run,) = list(out.iterdir())
    import csv

    with (run / "parameters.csv").open() as f:
        x = {row["name"]: float(row["value"]) for row in csv.DictReader(f)}
    np.testing.assert_allclose([x[f"fv{j}"] for j in (1, 2, 3)], FV, rtol=0.05)


def test_identify_checks_the_reading_estimate_before_reading(tmp_path, monkeypatch) -> None:
    """The estimate of reading the log (from the MCAP summary: 1200 messages) is checked
    before the file is read: under a tiny time ceiling the job is refused, naming it."""
    import ident.measure.readers.ros as ros

    def never(*args, **kwargs):
        raise AssertionError("the log was read before its estimate was checked")

    monkeypatch.setattr(ros, "message_tables", never)
    monkeypatch.setenv("IDENT_MAX_HOURS", "1e-6")  # 3.6 ms (1200 messages at 10 us: 12 ms)
    config = REPO / "configs" / "examples" / "mcap.yaml"
    result = runner.invoke(app, ["identify", str(config), "--out", str(tmp_path / "runs")])
    assert result.exit_code == 2, result.output
    assert "reading the log (joint_states.mcap): about" in result.output
    assert "above the time ceiling" in result.output
    assert not (tmp_path / "runs").exists()
