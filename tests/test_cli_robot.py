from pathlib import Path

import pinocchio as pin
import pytest
import typer
from typer.testing import CliRunner

from ident.cli.robot import register
from ident.robot.robot_config import load_robot_config
from ident.robot.urdf import urdf_from_description

DATA = Path("tests/data/robots")


def _app() -> typer.Typer:
    app = typer.Typer()

    @app.callback()
    def main() -> None:
        """Keep `urdf` a sub-command even when it is the only one registered."""

    register(app)
    return app


def _run(*args):
    return CliRunner().invoke(_app(), list(map(str, args)))


def test_urdf_writes_file_and_says_where(tmp_path):
    output = tmp_path / "sub" / "paper6r.urdf"
    result = _run("urdf", "configs/paper6r.yaml", "-o", output)
    assert result.exit_code == 0, result.output
    assert str(output) in result.output
    text = output.read_text()
    assert text == urdf_from_description(load_robot_config("configs/paper6r.yaml"))
    assert pin.buildModelFromUrdf(str(output)).nq == 6
    assert not list(output.parent.glob(".*.tmp"))  # atomic write leaves no temporary file


def test_real_entry_point_has_urdf_command():
    from ident.cli import app

    result = CliRunner().invoke(app, ["urdf", "--help"])
    assert result.exit_code == 0
    assert "CONFIG" in result.output


@pytest.mark.parametrize(
    ("config", "expected"),
    [
        ("nope.yaml", "config file not found"),
        ("bad_columns.yaml", "dh.rows[1] has 3 values but dh.columns lists 4"),
        ("bad_rows.yaml", "give one DH row, one joints entry and one links entry per joint"),
        ("bad_key.yaml", "did you mean 'inertia_com'"),
        ("bad_mass.yaml", "mass must be > 0"),
        ("bad_triangle.yaml", "triangle inequality"),
        ("bad_limits.yaml", "must be below upper"),
    ],
)
def test_bad_config_one_line_exit_2(config, expected, tmp_path):
    output = tmp_path / "out.urdf"
    result = _run("urdf", DATA / config, "-o", output)
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    assert lines[0].startswith("error: ")
    assert str(DATA / config) in lines[0]
    assert expected in lines[0]
    assert "Traceback" not in result.output
    assert not output.exists()


def test_malformed_yaml(tmp_path):
    config = tmp_path / "broken.yaml"
    config.write_text("name: x\ndh: {convention: standard, rows: [[1, 2,\n")
    result = _run("urdf", config, "-o", tmp_path / "out.urdf")
    assert result.exit_code == 2
    assert "malformed YAML at line" in result.output


def test_urdf_refuses_an_existing_output_unless_force(tmp_path):
    output = tmp_path / "mine.urdf"
    output.write_text("<robot name='edited'/>\n")
    result = _run("urdf", "configs/paper6r.yaml", "-o", output)
    assert result.exit_code == 2
    (line,) = [s for s in result.output.splitlines() if s.strip()]
    assert line.startswith(f"error: --output {output}: exists")
    assert "--force" in line
    assert output.read_text() == "<robot name='edited'/>\n"  # untouched
    result = _run("urdf", "configs/paper6r.yaml", "-o", output, "--force")
    assert result.exit_code == 0, result.output
    assert output.read_text() == urdf_from_description(load_robot_config("configs/paper6r.yaml"))
