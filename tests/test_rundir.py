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


def test_finish_writes_one_status_into_run_json_and_result_json(tmp_path):
    """ident run's folder: result.json carries run.json's status and message, set by the one
    call that ends the run (a run whose report failed after result.json was written said
    'complete' in result.json and 'incomplete' in run.json)."""
    run = create_run_dir(tmp_path, "arm", now=NOW, status_copy="result.json")
    run.finish("incomplete", "interrupted before any result")  # no result.json yet: none made
    assert not (run.path / "result.json").exists()
    result = {"status": "running", "message": "saving the run's files", "x": [1.5, None]}
    (run.path / "result.json").write_text(json.dumps(result))
    run.finish("incomplete", "stopped while writing the report (DataError: boom)")
    data = json.loads((run.path / "result.json").read_text())
    state = read_status(run.path)
    assert data["status"] == state["status"] == "incomplete"
    assert (
        data["message"] == state["message"] == "stopped while writing the report (DataError: boom)"
    )
    assert data["x"] == [1.5, None]
    run.finish("complete", "run complete")
    data = json.loads((run.path / "result.json").read_text())
    assert (data["status"], data["message"]) == ("complete", "run complete")
    assert read_status(run.path)["status"] == "complete"
    # another command's result.json (ident identify: its own 'status') is left alone
    other = create_run_dir(tmp_path, "identify", now=NOW)
    (other.path / "result.json").write_text('{"status": "ok"}')
    other.finish("complete", "done")
    assert json.loads((other.path / "result.json").read_text())["status"] == "ok"
