"""LeRobot datasets: values, episodes as segments, bounded memory, and one error line each.

The datasets are written by ``tests/lerobot_datasets.py`` (pyarrow, the v2.x layout); the
expected positions are the written ticks through the closed form ``(ticks - 2048) 2 pi / 4096``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from lerobot_datasets import TICKS_PER_REV, ZERO_TICK, ticks_to_rad, write_dataset
from robots import RP2_URDF
from typer.testing import CliRunner

from ident.cli import app
from ident.errors import DataError
from ident.inputs import ResourceLimitError
from ident.measure.log_config import LogConfig, TransmissionConfig
from ident.measure.logs import read_log
from ident.measure.readers import estimate_read, read_tables

FPS = 30.0
NAMES = ["shoulder_pan", "shoulder_lift", "elbow_flex", "gripper"]
TICKS = {"unit": "ticks", "counts_per_rev": TICKS_PER_REV, "zero_tick": ZERO_TICK}


def _episode(n: int, phase: float, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Integer ticks around the centre (exact in float32), the command a few ticks ahead."""
    t = np.arange(n) / FPS
    state = np.rint(ZERO_TICK + 700.0 * np.sin(np.outer(t, [1.0, 1.7, 2.3, 0.5]) + phase))
    return {
        "observation.state": state,
        "action": state + rng.integers(-6, 7, state.shape),
        "observation.effort": rng.normal(size=state.shape),
    }


def _log_section(path, **position) -> dict:
    return {
        "path": str(path),
        "position": {"columns": ["observation.state"], "exclude": ["gripper"], **position},
        "command": {"columns": ["action"]},
        "torque": {"columns": ["observation.effort"], "exclude": ["gripper"]},
    }


@pytest.mark.parametrize(
    ("variable_lists", "row_group_size", "suffix"),
    [(False, None, ""), (True, 16, ".pos")],  # LeRobot >= 0.2 names motors '<joint>.pos'
)
def test_values_are_the_written_ticks_in_radians_matched_by_name(
    tmp_path, variable_lists, row_group_size, suffix
):
    rng = np.random.default_rng(1)
    episodes = [_episode(90, 0.0, rng), _episode(70, 1.0, rng)]
    root = write_dataset(
        tmp_path / "ds",
        episodes,
        fps=FPS,
        names=[n + suffix for n in NAMES],
        variable_lists=variable_lists,
        row_group_size=row_group_size,
    )
    joints = ("elbow_flex", "shoulder_pan", "shoulder_lift")  # not the dataset's order
    order = [NAMES.index(j) for j in joints]
    cfg = LogConfig.model_validate(_log_section(root, **TICKS))
    log = read_log(cfg, TransmissionConfig(), joints)
    state = np.concatenate([e["observation.state"] for e in episodes])[:, order]
    action = np.concatenate([e["action"] for e in episodes])[:, order]
    effort = np.concatenate([e["observation.effort"] for e in episodes])[:, order]
    np.testing.assert_allclose(log.q, ticks_to_rad(state), rtol=0, atol=1e-12)
    assert log.q_cmd is not None  # the commanded positions, converted as the measured ones
    np.testing.assert_allclose(log.q_cmd, ticks_to_rad(action), rtol=0, atol=1e-12)
    np.testing.assert_allclose(log.tau, effort.astype(np.float32), rtol=0, atol=0)
    assert log.sampling_rate_hz == pytest.approx(FPS, rel=1e-5)
    assert log.warnings == ()


def test_episodes_stay_separate_segments_whatever_the_gap_rule(tmp_path):
    rng = np.random.default_rng(2)
    episodes = [_episode(60, 0.0, rng), _episode(50, 2.0, rng), _episode(40, 4.0, rng)]
    root = write_dataset(tmp_path / "ds", episodes, fps=FPS, names=NAMES)
    # a gap rule that would never split: only the episodes' own boundaries may
    section = {**_log_section(root, **TICKS), "max_gap_s": 100.0}
    log = read_log(LogConfig.model_validate(section), TransmissionConfig(), tuple(NAMES[:3]))
    assert log.segments == ((0, 60), (60, 110), (110, 150))
    for a, b in log.segments:  # each segment is its episode, time uniform inside
        np.testing.assert_allclose(np.diff(log.t[a:b]), 1.0 / FPS, rtol=1e-5)
    # the next episode starts after the previous one's end plus a second (continued time)
    assert log.t[60] - log.t[59] == pytest.approx(1.0, abs=1e-9)
    assert log.warnings == ()  # timestamps restarting at 0 are no backwards jump


def test_only_the_named_features_are_read_and_the_ceiling_holds(tmp_path, monkeypatch):
    rng = np.random.default_rng(3)
    root = write_dataset(tmp_path / "ds", [_episode(3000, 0.0, rng)], fps=FPS, names=NAMES)
    (table,) = read_tables(root, columns=["observation.state/shoulder_pan"])
    assert sorted({c.split("/")[0] for c in table.columns}) == [
        "episode_index",
        "frame_index",
        "observation.state",
        "timestamp",
    ]
    estimate = estimate_read(root, columns=["observation.state"])
    arrays = 8 * 3000 * (4 + 3)  # 4 joints, timestamp, frame and episode index as float64
    assert arrays <= estimate.memory_bytes < 2 * arrays
    monkeypatch.setenv("IDENT_MAX_MEMORY_GB", str(0.5 * arrays / 1e9))
    with pytest.raises(ResourceLimitError, match="3000 frames"):
        read_tables(root, columns=["observation.state"])


def test_one_episode_file_alone_and_a_folder_without_info(tmp_path):
    rng = np.random.default_rng(4)
    root = write_dataset(tmp_path / "ds", [_episode(20, 0.0, rng)] * 2, fps=FPS, names=NAMES)
    episode = root / "data" / "chunk-000" / "episode_000001.parquet"
    (table,) = read_tables(episode)  # meta/info.json two folders up: named joints
    assert "observation.state/elbow_flex" in table.columns
    assert table.warnings == ()
    (root / "meta" / "info.json").unlink()
    (table,) = read_tables(episode)
    assert "observation.state/2" in table.columns
    assert "fps not checked" in table.warnings[0]
    with pytest.raises(DataError, match="meta/info.json not found"):
        read_tables(root, "lerobot")


def test_an_empty_episode_is_skipped_and_named_all_empty_is_refused(tmp_path):
    rng = np.random.default_rng(6)
    episodes = [_episode(30, 0.0, rng), _episode(0, 1.0, rng), _episode(20, 2.0, rng)]
    root = write_dataset(tmp_path / "ds", episodes, fps=FPS, names=NAMES)
    cfg = LogConfig.model_validate(_log_section(root, **TICKS))
    log = read_log(cfg, TransmissionConfig(), tuple(NAMES[:3]))
    state = np.concatenate([e["observation.state"] for e in episodes])[:, :3]
    np.testing.assert_allclose(log.q, ticks_to_rad(state), rtol=0, atol=1e-12)
    assert log.segments == ((0, 30), (30, 50))  # the two episodes that hold frames
    (warning,) = log.warnings
    assert "1 episode file(s) hold no frames, skipped" in warning
    assert "data/chunk-000/episode_000001.parquet" in warning
    empty = write_dataset(tmp_path / "empty", [episodes[1]] * 2, fps=FPS, names=NAMES)
    with pytest.raises(DataError, match=r"no frames: every episode file is empty \(data/"):
        read_log(LogConfig.model_validate(_log_section(empty, **TICKS)), TransmissionConfig(),
                 tuple(NAMES[:3]))  # fmt: skip


def test_logs_inspect_topic_reads_a_dataset_feature_and_is_refused_where_none(tmp_path):
    rng = np.random.default_rng(7)
    root = write_dataset(tmp_path / "ds", [_episode(10, 0.0, rng)], fps=FPS, names=NAMES)
    result = CliRunner().invoke(app, ["logs", "inspect", str(root), "--topic", "action"])
    assert result.exit_code == 0, result.output
    assert "action/elbow_flex" in result.output
    assert "observation.state/" not in result.output  # only the feature asked for
    for args, part in (
        ([str(root), "--topic", "observation.joints"], "topic 'observation.joints' is not a "
         "feature of this LeRobot dataset (its features are its topics: observation.state, "
         "action, observation.effort"),
        ([str(root / "meta" / "info.json"), "--format", "csv", "--topic", "/joint_states"],
         "is a csv log, which has no topics"),
    ):  # fmt: skip
        result = CliRunner().invoke(app, ["logs", "inspect", *args])
        assert result.exit_code == 2, result.output
        (line,) = result.output.splitlines()
        assert line.startswith("error: "), line
        assert part in line, line


def _rp2_case(tmp_path, name: str) -> tuple[str, list[str]]:
    """A dataset of the rp2 arm (joints shoulder, slider and a gripper) broken as ``name``
    says, its config, and the parts the one error line must hold."""
    rng = np.random.default_rng(5)
    names = ["shoulder", "slider", "gripper"]
    episodes = [{k: v[:, :3] for k, v in _episode(40, p, rng).items()} for p in (0.0, 1.0)]
    info, position, expect = None, dict(TICKS), ["error:"]
    if name == "missing_column":
        for e in episodes:
            del e["observation.effort"]
        expect += ["'observation.effort' not found", "observation.state/shoulder, ", "action/"]
    elif name == "timestamp_back":
        stamps = np.arange(40) / FPS
        stamps[25] = stamps[23]
        episodes[1]["timestamp"] = stamps
        expect += ["episode_000001.parquet", "'timestamp' of episode 1", "at frame 25"]
    elif name == "ticks_as_rad":
        position = {"unit": "rad"}
        expect += ["log.position of joint 'shoulder'", "read as rad", "unit: ticks"]
    elif name == "fps":
        info = {"fps": 50}
        expect += ["info.json: fps = 50", "episode 0", "30 Hz"]
    elif name == "joint_names":
        names = ["shoulder", "elbow", "gripper"]
        expect += ["'observation.state' names shoulder, elbow", "not in the URDF: elbow",
                   "no column for: slider"]  # fmt: skip
    root = write_dataset(tmp_path / "ds", episodes, fps=FPS, names=names, info=info)
    cfg = {"name": "lerobot", "robot": {"urdf": str(RP2_URDF)}, "log": _log_section(root)}
    cfg["log"]["position"].update(position)
    (tmp_path / "cfg.yaml").write_text(json.dumps(cfg))
    return str(tmp_path / "cfg.yaml"), expect


@pytest.mark.parametrize(
    "name", ["missing_column", "timestamp_back", "ticks_as_rad", "fps", "joint_names"]
)
def test_bad_dataset_is_one_error_line_exit_2_nothing_written(tmp_path, name):
    config, expect = _rp2_case(tmp_path, name)
    out = tmp_path / "runs"
    result = CliRunner().invoke(app, ["identify", config, "--out", str(out), "--no-replay"])
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert result.exit_code == 2, result.output
    assert len(errors) == 1, result.output
    assert "Traceback" not in result.output
    for part in expect:
        assert part in errors[0], (part, errors[0])
    assert not out.exists()


def test_long_episode_keeps_its_frame_time_where_float32_stamps_blur(tmp_path):
    """A 600 s episode at 30 fps: its float32 stamps (``frame / fps`` rounded, as LeRobot writes
    them) step unevenly past 512 s; the reader takes ``frame_index / fps`` (exact, so the log
    is not resampled), and an episode whose stamps are not ``frame / fps`` (recorded jitter)
    keeps its own stamps."""
    n = 18_000
    state = np.full((n, 4), float(ZERO_TICK))
    stamps = np.arange(n) / FPS
    assert np.ptp(np.diff(stamps.astype(np.float32).astype(float))) > 1e-3 / FPS  # the blur
    root = write_dataset(tmp_path / "long", [{"observation.state": state}], fps=FPS, names=NAMES)
    position = {"columns": ["observation.state"], "exclude": ["gripper"], **TICKS}
    section = {"path": str(root), "position": position}
    log = read_log(LogConfig.model_validate(section), TransmissionConfig(), tuple(NAMES[:3]))
    np.testing.assert_array_equal(log.t, stamps)  # frame / fps in float64, exactly
    assert not any(r["step"] == "resample" for r in log.records)
    jitter = stamps[:300] + np.random.default_rng(6).uniform(-2e-4, 2e-4, 300)
    episode = {"observation.state": state[:300], "timestamp": jitter}
    (table,) = read_tables(write_dataset(tmp_path / "jitter", [episode], fps=FPS, names=NAMES))
    np.testing.assert_array_equal(table.columns["timestamp"], jitter.astype(np.float32))
