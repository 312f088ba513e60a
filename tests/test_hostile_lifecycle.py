"""Lifecycle under hostile conditions: nothing finished is lost, SIGTERM acts like Ctrl-C."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from ident.cli import app
from ident.errors import ConfigError, ModelError
from ident.inputs import (
    JobEstimate,
    ResourceLimitError,
    check_job,
    check_output_dir,
    check_output_file,
    check_urdf_numbers,
    read_urdf_text,
    safe_component,
)

ROOT = Path(__file__).resolve().parents[1]
TINY = "seed: 1\nruns: 2\npopsize: 10\nmax_nfev: 100\nmethods: [pso]\nfunctions: [sphere]\n"


def test_bench_name_cannot_leave_the_campaigns_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "c.yaml").write_text("name: ../../escape\n" + TINY)
    res = CliRunner().invoke(app, ["bench", "c.yaml", "--no-progress"])
    assert res.exit_code == 0, res.output
    (folder,) = (tmp_path / "campaigns").iterdir()
    assert folder.name.startswith("escape-")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.yaml", "campaigns"]


def test_bench_out_taken_during_the_campaign_goes_to_a_new_folder(tmp_path, monkeypatch):
    import ident.bench.campaign as campaign

    out = tmp_path / "camp"
    real = campaign.run_campaign

    def run_and_meanwhile_take_out(*args, **kwargs):
        out.mkdir()
        (out / "someone-else.txt").write_text("mine")
        return real(*args, **kwargs)

    monkeypatch.setattr(campaign, "run_campaign", run_and_meanwhile_take_out)
    (tmp_path / "c.yaml").write_text(TINY)
    res = CliRunner().invoke(
        app, ["bench", str(tmp_path / "c.yaml"), "--out", str(out), "--no-progress"]
    )
    assert res.exit_code == 0, res.output
    assert "was taken meanwhile" in res.output
    assert (out / "someone-else.txt").read_text() == "mine"
    assert (tmp_path / "camp-2" / "runs.csv").is_file()


def test_bench_refuses_a_used_out_before_running(tmp_path):
    out = tmp_path / "camp"
    out.mkdir()
    (out / "runs.csv").write_text("old")
    (tmp_path / "c.yaml").write_text(TINY)
    res = CliRunner().invoke(app, ["bench", str(tmp_path / "c.yaml"), "--out", str(out)])
    assert res.exit_code == 2
    assert "never overwritten" in res.stderr
    assert "runs:" not in res.stdout  # refused before the campaign started
    assert [p.name for p in out.iterdir()] == ["runs.csv"]


def test_sigterm_stops_bench_like_ctrl_c_and_leaves_nothing(tmp_path):
    config = tmp_path / "c.yaml"
    config.write_text(
        "seed: 1\nruns: 30\npopsize: 10\nmax_nfev: 30000\nfunctions: [sphere]\n"
        "methods: [emupso, pso, woa, gwo, goa, de]\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from ident.cli import main; main()",
            "bench",
            str(config),
            "--out",
            str(tmp_path / "camp"),
            "--no-progress",
        ],  # fmt: skip
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=tmp_path,
    )
    assert proc.stdout is not None
    assert "runs:" in proc.stdout.readline()  # the campaign has started
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr
    assert "Traceback" not in stderr
    assert not (tmp_path / "camp").exists()


def test_output_checks_refuse_pseudo_file_systems_files_and_used_folders(tmp_path):
    with pytest.raises(ConfigError, match="/proc"):
        check_output_dir("/proc/ident", "--out")
    with pytest.raises(ConfigError, match="/proc"):
        check_output_file("/proc/self/x.html", "--html")
    (tmp_path / "f").write_text("x")
    with pytest.raises(ConfigError, match="not a folder"):
        check_output_dir(tmp_path / "f", "--out")
    with pytest.raises(ConfigError, match="is a file"):
        check_output_dir(tmp_path / "f" / "sub", "--out")
    with pytest.raises(ConfigError, match="not empty"):
        check_output_dir(tmp_path, "--out", must_be_new_or_empty=True)
    with pytest.raises(ConfigError, match="is a folder"):
        check_output_file(tmp_path, "--html")
    assert check_output_dir(tmp_path / "new" / "deeper", "--out") == tmp_path / "new" / "deeper"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]  # checks create nothing


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("../../x", "x"),
        ("/etc/passwd", "etc_passwd"),
        ("..", "run"),
        ("a b/c", "a_b_c"),
        ("ok-name_1.2", "ok-name_1.2"),
        ("", "run"),
        ("\x00", "run"),
    ],  # fmt: skip
)
def test_safe_component(name, expected):
    assert safe_component(name) == expected


def test_job_ceilings_come_from_the_environment(monkeypatch):
    job = JobEstimate("job", memory_bytes=3e9, seconds=7200.0)
    monkeypatch.setenv("IDENT_MAX_MEMORY_GB", "4")
    monkeypatch.setenv("IDENT_MAX_HOURS", "3")
    assert check_job(job) is job
    monkeypatch.setenv("IDENT_MAX_HOURS", "1")
    with pytest.raises(ResourceLimitError, match="IDENT_MAX_HOURS"):
        check_job(job)
    monkeypatch.setenv("IDENT_MAX_HOURS", "3")
    monkeypatch.setenv("IDENT_MAX_MEMORY_GB", "2")
    with pytest.raises(ResourceLimitError, match="IDENT_MAX_MEMORY_GB"):
        check_job(job)
    monkeypatch.setenv("IDENT_MAX_MEMORY_GB", "nan")
    with pytest.raises(ConfigError, match="IDENT_MAX_MEMORY_GB"):
        check_job(job)


def test_urdf_with_a_dtd_is_refused_by_ident_and_why(tmp_path):
    """Pinocchio's parser and Python's disagree on entities: one error line, before any work."""
    import xml.etree.ElementTree as ET

    text = (
        '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY m "2.0">]>\n<robot name="r">'
        '<link name="a"><inertial><mass value="&m;"/>'
        '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link></robot>\n'
    )
    path = tmp_path / "r.urdf"
    path.write_text(text)
    assert ET.fromstring(text).find("link/inertial/mass").get("value") == "2.0"
    with pytest.raises(ModelError, match=r"line 2: a <!DOCTYPE> declaration"):
        read_urdf_text(path)


def test_urdf_writer_check_refuses_non_finite_numbers():
    check_urdf_numbers('<robot name="r"><joint name="j"><limit upper="1.5"/></joint></robot>', "c")
    with pytest.raises(ModelError, match=r"upper='inf' in <limit>"):
        check_urdf_numbers('<robot name="r"><limit upper="inf"/></robot>', "c.yaml")


# ---------------------------------------------------------------------------------------------
# Operating-system failures: one line, nothing half-written, the run folder says why


def _fail_writes(monkeypatch, code, name="*"):
    """Make ident.fileio's write primitive fail with ``code`` for files matching ``name``."""
    import fnmatch

    import ident.fileio as fileio

    write = fileio._write_data

    def failing(file, data, path):
        if fnmatch.fnmatch(path.name, name):
            file.write(data[: len(data) // 2])
            raise OSError(code, os.strerror(code))
        return write(file, data, path)

    monkeypatch.setattr(fileio, "_write_data", failing)


def test_failed_write_names_the_file_and_leaves_the_old_one(tmp_path, monkeypatch):
    import errno

    from ident.fileio import atomic_write_text, describe_os_error

    target = tmp_path / "report.html"
    target.write_text("old report")
    _fail_writes(monkeypatch, errno.ENOSPC)
    with pytest.raises(OSError, match="No space left") as info:
        atomic_write_text(target, "x" * 100_000)
    assert info.value.errno == errno.ENOSPC
    assert info.value.filename == str(target)  # the file, not the temporary one
    assert target.read_text() == "old report"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.html"]
    line = describe_os_error(info.value)
    assert line.startswith(f"{target}: No space left on device (the disk is full")


def test_run_folder_that_cannot_hold_run_json_is_removed(tmp_path, monkeypatch):
    import errno

    from ident.errors import IdentError
    from ident.run.rundir import create_run_dir

    _fail_writes(monkeypatch, errno.ENOSPC, "run.json")
    with pytest.raises(IdentError, match=r"run\.json: cannot write the run state \(No space"):
        create_run_dir(tmp_path / "runs", "x")
    assert list((tmp_path / "runs").iterdir()) == []


def test_marking_incomplete_on_a_full_disk_never_hides_the_first_error(tmp_path, monkeypatch):
    import errno

    from ident.run.rundir import create_run_dir, read_status

    run = create_run_dir(tmp_path, "x")
    _fail_writes(monkeypatch, errno.ENOSPC)  # now nothing can be written
    run.finish("incomplete", "stopped while saving the results")  # no exception
    assert read_status(run.path)["status"] == "running"  # what the disk still holds
    monkeypatch.undo()
    _fail_writes(monkeypatch, errno.ENOSPC, "INCOMPLETE")
    run.finish("incomplete", "stopped while saving the results: disk full")
    state = read_status(run.path)
    assert (state["status"], state["message"]) == (
        "incomplete",
        "stopped while saving the results: disk full",
    )


def test_report_on_a_running_folder_says_so(tmp_path):
    """A folder still marked running gets a warning; with nothing saved, one error as well."""
    import json
    import shutil

    run = tmp_path / "run"
    shutil.copytree(ROOT / "tests/data/hostile/os/real_run", run)
    (run / "run.json").write_text(json.dumps({"status": "running", "started_at": "t0"}))
    res = CliRunner().invoke(app, ["report", str(run)])
    assert res.exit_code == 0, res.output
    assert "warning:" in res.output
    assert "still running (run.json: status 'running' since t0)" in res.output
    assert (run / "report.html").is_file()
    (run / "run.json").write_text(json.dumps({"status": "complete"}))
    res = CliRunner().invoke(app, ["report", str(run)])
    assert res.exit_code == 0
    assert "warning:" not in res.output


def _mount_tmpfs(path: Path, size: str) -> bool:
    """Mount a tmpfs of ``size`` on ``path`` (root only; False where that is not allowed)."""
    if os.geteuid() != 0 or sys.platform != "linux":
        return False
    path.mkdir(parents=True, exist_ok=True)
    proc = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
        capture_output=True,
        check=False,
    )
    return proc.returncode == 0


def _disk(tmp_path, size):
    disk = tmp_path / "disk"
    if not _mount_tmpfs(disk, size):
        pytest.skip("cannot mount a tmpfs here (needs root on Linux)")
    try:
        yield disk
    finally:
        subprocess.run(["umount", str(disk)], check=False)


@pytest.fixture
def tiny_disk(tmp_path):
    """A real 64 kB file system: writes beyond it fail with ENOSPC from the kernel."""
    yield from _disk(tmp_path, "64k")


@pytest.fixture
def small_disk(tmp_path):
    """A real 2 MB file system (remounted read-only by the test)."""
    yield from _disk(tmp_path, "2m")


def test_a_really_full_disk_is_one_line_and_leaves_nothing(tiny_disk):
    """The replay page (about 1 MB) on a 64 kB disk: the kernel's ENOSPC, not a simulated one."""
    good = ROOT / "tests/data/hostile/runfolder/good"
    res = CliRunner().invoke(app, ["replay", str(good), "--html", str(tiny_disk / "r.html")])
    assert res.exit_code == 2, res.output
    (line,) = [x for x in res.output.splitlines() if x.startswith("error:")]
    assert f"{tiny_disk / 'r.html'}: No space left on device" in line
    assert list(tiny_disk.iterdir()) == []


def test_a_read_only_run_folder_is_one_line_for_report(small_disk):
    import shutil

    shutil.copytree(ROOT / "tests/data/hostile/os/real_run", small_disk / "run", dirs_exist_ok=True)
    before = sorted(p.name for p in (small_disk / "run").rglob("*"))
    subprocess.run(["mount", "-o", "remount,ro", str(small_disk)], check=True)
    res = CliRunner().invoke(app, ["report", str(small_disk / "run")])
    assert res.exit_code == 2, res.output
    (line,) = [x for x in res.output.splitlines() if x.startswith("error:")]
    assert "Read-only file system (the file system is read-only" in line
    assert sorted(p.name for p in (small_disk / "run").rglob("*")) == before


# ---------------------------------------------------------------------------------------------
# SIGTERM at every file a command writes: complete after the last file, else incomplete and
# named (tests/lifecycle_signals.py)


def _only_child(parent: Path):
    def find():
        children = list(parent.iterdir()) if parent.is_dir() else []
        return children[0] if children else None

    return find


@pytest.mark.slow
def test_sigterm_at_each_file_of_bench(tmp_path):
    from lifecycle_signals import sigterm_at_each_file

    (tmp_path / "c.yaml").write_text(TINY)
    out = tmp_path / "camp"
    args = ["bench", str(tmp_path / "c.yaml"), "--out", str(out), "--no-progress"]
    reset = lambda: shutil.rmtree(out, ignore_errors=True)  # noqa: E731
    n = sigterm_at_each_file(
        args, lambda: out if out.is_dir() else None, tmp_path, reset=reset, at=(1, 5)
    )
    assert n >= 8  # run.json, 5 CSV files, campaign.json, report.md, figures, report.html


@pytest.mark.slow
def test_sigterm_at_each_file_of_run(tmp_path):
    """ident run, interrupted at its first file and at one among the elites' and the model's
    files, says its folder is incomplete; a run left alone completes."""
    from lifecycle_signals import sigterm_at_each_file

    out = tmp_path / "runs"
    args = ["run", str(ROOT / "configs/wrist.yaml"), "--quick", "--out", str(out), "--no-replay"]
    reset = lambda: shutil.rmtree(out, ignore_errors=True)  # noqa: E731
    n = sigterm_at_each_file(args, _only_child(out), tmp_path, reset=reset, at=(1, 5))
    assert n >= 8  # run.json, config, robot, trajectory, elites, figures, result, reports


@pytest.mark.slow
def test_sigterm_at_each_file_of_identify(tmp_path):
    from lifecycle_signals import sigterm_at_each_file

    out = tmp_path / "runs"
    config = ROOT / "tests/data/hostile/identify/base.yaml"
    args = ["identify", str(config), "--out", str(out), "--no-replay"]
    reset = lambda: shutil.rmtree(out, ignore_errors=True)  # noqa: E731
    n = sigterm_at_each_file(args, _only_child(out), tmp_path, reset=reset, at=(1, 6))
    assert n >= 8  # run.json, result.json, the model files, figures, report.md, report.html


@pytest.mark.slow
def test_sigterm_at_each_file_of_report_then_report_completes(tmp_path):
    """Interrupted, the folder says the report is missing; the next report completes it."""
    from lifecycle_signals import sigterm_at_each_file

    run = tmp_path / "run"
    source = ROOT / "tests/data/hostile/os/real_run"
    before = sum(1 for p in source.rglob("*") if p.is_file())

    def reset():
        shutil.rmtree(run, ignore_errors=True)
        shutil.copytree(source, run)

    n = sigterm_at_each_file(
        ["report", str(run)], lambda: run, tmp_path, reset=reset, before=before, at=(1, 3)
    )
    assert n >= 3  # figures, report.md, report.html
    # an interrupted report, then a whole one: complete again, with the run's message
    reset()
    message = json.loads((run / "run.json").read_text())["message"]
    import ident.run.rundir as rundir

    with pytest.raises(rundir.FolderInterrupted), rundir.rewriting(run, "report"):
        raise KeyboardInterrupt
    state = rundir.read_status(run)
    assert (state["status"], state["missing"]) == ("incomplete", "report")
    res = CliRunner().invoke(app, ["report", str(run)])
    assert res.exit_code == 0, res.output
    state = rundir.read_status(run)
    assert (state["status"], state["message"]) == ("complete", message)
    assert not (run / "INCOMPLETE").exists()


def test_signal_while_the_folder_is_created_is_held_until_the_guard(tmp_path, monkeypatch):
    """SIGTERM between mkdir and run.json (the moment 'ident identify' left 'running')."""
    import ident.run.rundir as rundir
    from ident.cli._common import user_errors

    real = rundir.RunDir.update

    def update_then_signal(self, **fields):
        real(self, **fields)
        if fields == {}:  # create_run_dir's first run.json
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(rundir.RunDir, "update", update_then_signal)
    with pytest.raises(typer.Exit) as info, user_errors():
        with rundir.run_folder(tmp_path, "x"):
            raise AssertionError("the held signal must stop the block before its first line")
    assert info.value.exit_code == 130
    (folder,) = tmp_path.iterdir()
    state = rundir.read_status(folder)
    assert state["status"] == "incomplete"
    assert (folder / "INCOMPLETE").is_file()


def test_write_error_in_a_folder_names_it_and_marks_it(tmp_path, monkeypatch):
    """bench on a full disk: exit 2, one line naming the file and the folder, incomplete."""
    import errno

    _fail_writes(monkeypatch, errno.ENOSPC, "stats.csv")
    (tmp_path / "c.yaml").write_text(TINY)
    out = tmp_path / "camp"
    res = CliRunner().invoke(app, ["bench", str(tmp_path / "c.yaml"), "--out", str(out)])
    assert res.exit_code == 2, res.output
    (line,) = [x for x in res.stderr.splitlines() if x.startswith("error:")]
    assert f"{out / 'stats.csv'}: No space left on device" in line
    assert f"({out} is incomplete)" in line
    state = json.loads((out / "run.json").read_text())
    assert state["status"] == "incomplete"
    assert "No space left" in state["message"]
    assert (out / "INCOMPLETE").is_file()
    assert (out / "runs.csv").is_file()  # what was written before stays
