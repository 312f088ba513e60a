import json
from datetime import datetime, timezone

import pytest

from ident.errors import IdentError
from ident.run.rundir import INCOMPLETE_MARKER, RunDir, create_run_dir, read_status

NOW = datetime(2026, 1, 2, 3, 4, 5, tzinfo=timezone.utc)


def test_name_and_initial_state(tmp_path):
    run = create_run_dir(tmp_path / "runs", "wrist", now=NOW, info={"seed": 3})
    assert run.path.name == "wrist-20260102-030405"
    state = read_status(run.path)
    assert state["status"] == "running"
    assert state["seed"] == 3


def test_never_reuses_an_earlier_folder(tmp_path):
    first = create_run_dir(tmp_path, "wrist", now=NOW)
    (first.path / "result.json").write_text("{}")
    second = create_run_dir(tmp_path, "wrist", now=NOW)
    third = create_run_dir(tmp_path, "wrist", now=NOW)
    assert len({first.path, second.path, third.path}) == 3
    assert second.path.name.endswith("-2")
    assert third.path.name.endswith("-3")
    assert (first.path / "result.json").read_text() == "{}"
    assert list(second.path.iterdir()) == [second.path / "run.json"]


def test_unsafe_names_are_sanitized(tmp_path):
    run = create_run_dir(tmp_path, "../my run", now=NOW)
    assert run.path.parent == tmp_path
    assert "/" not in run.path.name
    assert " " not in run.path.name


def test_finish_incomplete_then_complete(tmp_path):
    run = create_run_dir(tmp_path, "arm", now=NOW)
    run.finish("incomplete", "interrupted after 2 of 5 runs")
    assert (run.path / INCOMPLETE_MARKER).read_text().startswith("interrupted")
    state = json.loads((run.path / "run.json").read_text())
    assert state["status"] == "incomplete"
    assert state["wall_time_s"] >= 0
    reopened = RunDir.open(run.path)
    assert reopened.status == "incomplete"
    reopened.finish("complete")
    assert not (run.path / INCOMPLETE_MARKER).exists()
    assert read_status(run.path)["status"] == "complete"
    with pytest.raises(ValueError, match="final status"):
        run.finish("running")


def test_read_status_errors(tmp_path):
    with pytest.raises(IdentError, match="not a run folder"):
        read_status(tmp_path / "missing")
    with pytest.raises(IdentError, match="run.json"):
        read_status(tmp_path)
    (tmp_path / "run.json").write_text("{not json")
    with pytest.raises(IdentError, match="damaged"):
        read_status(tmp_path)
