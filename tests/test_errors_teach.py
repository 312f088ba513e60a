"""Errors that teach: each message names the setting and its value, and shows a fix that works."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from robots import ERD_ROBOTS, ERD_SHARE
from typer.testing import CliRunner

from ident.cli import app
from ident.errors import ConfigError
from ident.excitation.family import feasibility_advice
from ident.excitation.fourier import JointFourierFamily
from ident.excitation.safety import SafetyConfig
from ident.model.selection import RobotSelection, load_robot
from ident.run.config import load_run_config
from ident.run.examples import SECTION_EXAMPLES, unsafe_run_advice
from ident.run.init_config import init_config
from ident.run.setup import load_run

REPO = Path(__file__).resolve().parents[1]
UR5 = REPO / "robot/urdf/ur5.urdf"
KINOVA = ERD_ROBOTS / "kinova_description/robots/kinova.urdf"


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize("missing", ["excitation", "robot"])
def test_missing_section_shows_an_example_that_loads(tmp_path, missing):
    sections = {
        "robot": (
            f"robot: {{urdf: {UR5}, package_dirs: [{REPO / 'robot/meshes'}], "
            "acceleration_limits: 8.0}"
        ),
        "excitation": "excitation: {family: joint_fourier}",
    }
    given = "\n".join(v for k, v in sections.items() if k != missing) + "\n"
    with pytest.raises(ConfigError, match=f"missing required key '{missing}'") as info:
        load_run_config(_write(tmp_path / "a.yaml", given))
    message = str(info.value)
    example = re.search(rf"'({missing}: \{{.*\}})'", message)
    assert example is not None, message
    assert "ident init" in message
    if missing == "excitation":  # the example, pasted as it stands, gives a config that runs
        setup = load_run(_write(tmp_path / "b.yaml", given + example.group(1) + "\n"))
        assert setup.family.n_harmonics == 4
    else:  # the robot example loads once its path names a file
        fixed = example.group(1).replace("path/to/robot.urdf", str(UR5))
        assert load_run_config(_write(tmp_path / "b.yaml", fixed + "\n" + given))


def test_every_section_example_validates():
    for key, text in SECTION_EXAMPLES.items():
        data = yaml.safe_load(text)
        assert list(data) == [key]
    SafetyConfig.model_validate(yaml.safe_load(SECTION_EXAMPLES["safety"])["safety"])


def _kinova(acceleration: float = 2.0):
    return load_robot(RobotSelection(urdf=KINOVA, acceleration_limits=acceleration))


def _velocity_violations(family: JointFourierFamily, rng: np.random.Generator) -> float:
    """Share of designs on the corners of the coefficient box that break a velocity limit."""
    low, high = family.bounds[:, 0], family.bounds[:, 1]
    x = np.where(rng.random((300, low.size)) < 0.5, low, high)
    batch = family.trajectories(x)
    names = batch.violations.names
    cols = [i for i, n in enumerate(names) if n.startswith(("velocity", "acceleration"))]
    return float((batch.violations.values[:, cols] > 0).any(axis=1).mean())


def test_fourier_advice_names_the_amplitude_joint_limit_and_a_fix_that_works():
    robot = _kinova()
    family = JointFourierFamily(
        robot, range(6), 4, 2 * np.pi / 10, n_samples=200, amplitude_bound=0.4
    )
    advice = feasibility_advice(family, ("velocity:j2s6s200_joint_1",))
    assert "excitation.options.amplitude_bound 0.4 rad/s" in advice
    assert "joint 1 (j2s6s200_joint_1)'s velocity limit 0.628 rad/s" in advice
    assert "Cartesian" not in advice
    assert "circle" not in advice
    fix = float(re.search(r"amplitude_bound <= ([0-9.e-]+)", advice).group(1))
    assert fix == pytest.approx(0.628 / 12.43, rel=0.05)  # dq_max / c_v at 4 harmonics
    assert _velocity_violations(family, np.random.default_rng(0)) > 0.9
    fixed = JointFourierFamily(
        robot, range(6), 4, 2 * np.pi / 10, n_samples=200, amplitude_bound=fix
    )
    assert _velocity_violations(fixed, np.random.default_rng(0)) == 0.0
    assert feasibility_advice(fixed, ("velocity:j2s6s200_joint_1",)) != advice


def test_fourier_advice_names_the_acceleration_when_it_binds():
    family = JointFourierFamily(
        _kinova(acceleration=0.2), range(6), 4, 2 * np.pi / 10, amplitude_bound=0.04
    )
    advice = feasibility_advice(family, ("acceleration:j2s6s200_joint_1",))
    assert "acceleration limit 0.2 rad/s^2" in advice
    assert "amplitude_bound 0.04" in advice


def test_fourier_advice_blames_nothing_of_its_own_when_the_fault_is_elsewhere():
    family = JointFourierFamily(_kinova(), range(6), 4, amplitude_bound=0.4)
    advice = feasibility_advice(family, ("clearance:j2s6s200_link_2|floor",))
    assert "amplitude_bound 0.4" not in advice
    assert "circle" not in advice
    assert "excitation.bounds" in advice


def _kinova_config(tmp_path: Path, **changes) -> dict:
    data = yaml.safe_load(init_config(KINOVA, tmp_path / "k.yaml").text)
    data["quick"] = {
        "n_samples": 60,
        "elites": {"n_particles": 4, "n_elites": 1, "maxiter": 3},
        "emupso": {
            "n_particles": 4,
            "maxiter": 2,
            "stagnation": 2,
            "n_runs": 1,
            "n_report_elites": 1,
        },
    }
    data["measurement"]["n_periods"] = 1
    for key, value in changes.items():
        data[key] = value
    return data


@pytest.mark.slow
def test_infeasible_fourier_run_names_amplitude_bound_not_a_circle(tmp_path):
    data = _kinova_config(tmp_path)
    data["excitation"]["options"]["amplitude_bound"] = 0.4  # the UR5's value
    config = _write(tmp_path / "k04.yaml", yaml.safe_dump(data))
    res = CliRunner().invoke(
        app, ["run", str(config), "--quick", "--no-replay", "--out", str(tmp_path / "runs")]
    )
    assert res.exit_code == 2, res.output
    error = [line for line in res.output.splitlines() if line.startswith("error:")][0]
    assert "excitation.options.amplitude_bound 0.4 rad/s" in error
    assert "velocity limit 0.628 rad/s" in error
    assert "amplitude_bound <= 0.05" in error
    assert "circle" not in error
    assert "widen" not in error
    # an infeasible excitation is an input error: found before the run folder exists
    assert not (tmp_path / "runs").exists() or not any((tmp_path / "runs").iterdir())


def test_unsafe_advice_suggests_the_safety_section_only_when_absent():
    assert unsafe_run_advice(True) == ""
    advice = unsafe_run_advice(False)
    assert "no safety: section" in advice
    assert SECTION_EXAMPLES["safety"] in advice


@pytest.mark.slow
def test_unsafe_run_without_safety_section_suggests_it(tmp_path):
    data = _kinova_config(tmp_path)
    del data["safety"]  # the optimizer does not see the floor ...
    # ... and the mean posture of joint 2 lays the arm on it (its fingers 0.2 m deep at 4.9 rad)
    data["excitation"]["bounds"]["q0[j2s6s200_joint_2]"] = [5.0, 5.3]
    config = _write(tmp_path / "unsafe.yaml", yaml.safe_dump(data))
    res = CliRunner().invoke(
        app, ["run", str(config), "--quick", "--no-replay", "--out", str(tmp_path / "runs")]
    )
    assert res.exit_code == 1, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert any("floor" in e and "no safety: section" in e for e in errors), errors
    assert ERD_SHARE.is_dir()
