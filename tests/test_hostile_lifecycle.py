"""Lifecycle under hostile conditions: nothing finished is lost, SIGTERM acts like Ctrl-C."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
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
