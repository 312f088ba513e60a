"""``ident init``: a run config derived from a URDF, checked against the excitation family's own
evaluation and the run loader; ``ident run --quick`` on arms the configs do not ship."""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from robots import ERD_ROBOTS, PANDA_URDF, RP2_URDF
from typer.testing import CliRunner

from ident.cli import app
from ident.excitation.fourier import JointFourierFamily, fourier_bound_factors
from ident.run.config import load_run_config
from ident.run.init_config import VELOCITY_MARGIN, init_config
from ident.run.setup import load_run

KINOVA = ERD_ROBOTS / "kinova_description/robots/kinova.urdf"
Z1 = ERD_ROBOTS / "z1_description/urdf/z1.urdf"
UR10 = ERD_ROBOTS / "ur_description/urdf/ur10_robot.urdf"
UR3_GRIPPER = ERD_ROBOTS / "ur_description/urdf/ur3_gripper.urdf"
INDEPENDENT_SAFETY = Path(__file__).resolve().parents[1] / "benchmarks" / "independent_safety.py"


def _independent_safety():
    """benchmarks/independent_safety.py: the run's trajectory re-checked without ident."""
    spec = importlib.util.spec_from_file_location("independent_safety", INDEPENDENT_SAFETY)
    module = importlib.util.module_from_spec(spec)
    sys.modules["independent_safety"] = module
    spec.loader.exec_module(module)
    return module


def _corner_designs(family: JointFourierFamily, n: int, rng: np.random.Generator) -> np.ndarray:
    """Designs on the corners of the coefficient box (where the peaks are), q0 anywhere."""
    low, high = family.bounds[:, 0], family.bounds[:, 1]
    x = np.where(rng.random((n, low.size)) < 0.5, low, high)
    q0 = np.array([name.startswith("q0[") for name in family.variable_names])
    x[:, q0] = rng.uniform(low[q0], high[q0], (n, int(q0.sum())))
    return x


@pytest.mark.parametrize("n_harmonics", [2, 4, 5])
def test_bound_factors_bound_the_family_and_are_reached(n_harmonics):
    # independent reference: the family's own series, dense in time, at the worst phase's
    # sign pattern (which reaches the bound) and at random corners (which never exceed it)
    robot = type("R", (), {})()
    robot.joint_names = ("j",)
    robot.q_lower, robot.q_upper = np.array([-10.0]), np.array([10.0])
    robot.dq_max, robot.ddq_max = np.array([np.inf]), np.array([np.inf])
    amp, w = 0.3, 0.7
    family = JointFourierFamily(
        robot, [0], n_harmonics, w, n_samples=4000, amplitude_bound=amp, held_positions=[0.0]
    )
    c_q, c_v, c_a = fourier_bound_factors(n_harmonics)
    batch = family.trajectories(_corner_designs(family, 400, np.random.default_rng(1)))
    _, _, q0 = family.coefficients(_corner_designs(family, 400, np.random.default_rng(1)))
    assert np.abs(batch.q[:, :, 0] - q0).max() <= c_q * amp / w * (1 + 1e-6)
    assert np.abs(batch.dq).max() <= c_v * amp * (1 + 1e-6)
    assert np.abs(batch.ddq).max() <= c_a * amp * w * (1 + 1e-6)
    # the worst sign pattern for the velocity at its worst phase reaches c_v * A
    theta = np.linspace(0.0, 2.0 * np.pi, 20001)
    l = np.arange(2, n_harmonics + 1)[:, None]
    ga, gb = np.cos(l * theta) - np.cos(theta), np.sin(l * theta) - l * np.sin(theta)
    k = int(np.argmax((np.abs(ga) + np.abs(gb)).sum(axis=0)))
    x = np.concatenate([[0.0], amp * np.sign(ga[:, k]), amp * np.sign(gb[:, k])])
    dense = JointFourierFamily(
        robot, [0], n_harmonics, w, n_samples=20000, amplitude_bound=amp, held_positions=[0.0]
    )
    assert np.abs(dense.trajectories(x[None, :]).dq).max() == pytest.approx(c_v * amp, rel=1e-3)


def test_init_kinova_keeps_every_design_within_the_velocity_margin(tmp_path):
    out = tmp_path / "kinova.yaml"
    result = init_config(KINOVA, out)
    out.write_text(result.text)
    setup = load_run(out)  # the loader and every check of ident run
    family, robot = setup.family, setup.robot
    # the Kinova's velocity limits (0.63-0.84 rad/s): the whole box within 80 % of them
    batch = family.trajectories(_corner_designs(family, 300, np.random.default_rng(0)))
    peak = np.abs(batch.dq).max(axis=(0, 1))
    assert np.all(peak <= VELOCITY_MARGIN * robot.dq_max + 1e-9)
    assert peak.max() > 0.5 * VELOCITY_MARGIN * robot.dq_max.min()  # not a trivially small box
    accel = np.abs(batch.ddq).max(axis=(0, 1))
    assert np.all(accel <= robot.ddq_max + 1e-9)
    # acceleration limits: the stated rule of thumb (the URDF has none), marked as a guess
    np.testing.assert_allclose(robot.ddq_max, 3.0 * robot.dq_max, rtol=1e-2)
    config = yaml.safe_load(result.text)
    assert config["measurement"]["source"] == "mujoco"
    # continuous joints and velocity-bound ones: the position ranges never bind the box, the
    # period stays 10 s and the log three periods
    assert config["excitation"]["options"]["base_frequency"] == 2.0 * np.pi / 10.0
    assert config["measurement"]["n_periods"] == 3
    text_lines = result.text.splitlines()
    guessed = ("acceleration_limits:", "viscous:", "coulomb:", "armature:", "torque_noise_std:")
    for key in (*guessed, "floor:", "clearance_m:", "encoder_counts_per_rev:"):
        line = next(s for s in text_lines if s.strip().startswith(key))
        assert "guess" in line, line
    # friction scales with the effort limits (40, 80, 40, 20, 20, 20 N*m); the noise is at
    # most 0.3 % of them (and 1 % of the torque the motion needs)
    effort = np.array([40.0, 80.0, 40.0, 20.0, 20.0, 20.0])
    viscous = np.array(config["measurement"]["friction"]["viscous"])
    np.testing.assert_allclose(viscous, 0.02 * effort, rtol=1e-2)
    noise = np.array(config["measurement"]["torque_noise_std"])
    assert np.all(noise > 0)
    assert np.all(noise <= 0.003 * effort * 1.01)
    assert result.quick_seconds < result.seconds
    # the worst cases: the run's estimate with the retry at a wider safety margin (the
    # safety model's CPU per posture is timed again by each build: within a factor)
    assert result.worst_seconds == pytest.approx(setup.estimate.worst_seconds, rel=0.5)
    assert result.seconds < result.worst_seconds
    assert result.quick_seconds < result.quick_worst_seconds < result.worst_seconds
    # --quick optimizes: 410 designs (30 left the UR10's elbow inertia 27.8 % off), still a
    # fraction of the full budget's
    quick, full = config["quick"]["emupso"], config["emupso"]
    designs = quick["n_particles"] * (quick["maxiter"] + 1) * quick["n_runs"]
    assert 400 <= designs < full["n_particles"] * (full["maxiter"] + 1) * full["n_runs"] / 5


def test_init_locks_grippers_and_says_why(tmp_path):
    # Panda: two finger joints branch at the tip (suggested_locks), locked with their reason
    result = init_config(PANDA_URDF, tmp_path / "panda.yaml")
    lock = yaml.safe_load(result.text)["robot"]["lock"]
    assert set(lock) == {"panda_finger_joint1", "panda_finger_joint2"}
    assert any("panda_finger_joint1" in n and "gripper finger" in n for n in result.notes)
    # Z1: a serial chain whose last joint is its gripper
    result = init_config(Z1, tmp_path / "z1.yaml")
    assert yaml.safe_load(result.text)["robot"]["lock"] == {"jointGripper": 0.0}
    assert any("jointGripper" in n and "gripper" in n for n in result.notes)
    (tmp_path / "z1.yaml").write_text(result.text)
    assert load_run_config(tmp_path / "z1.yaml").robot.lock == {"jointGripper": 0.0}


def test_init_tip_link_locks_the_rest(tmp_path):
    result = init_config(PANDA_URDF, tmp_path / "p.yaml", tip_link="panda_link5")
    config = yaml.safe_load(result.text)
    assert config["robot"]["tip_link"] == "panda_link5"
    assert "panda_joint6" in config["robot"]["lock"]
    assert any("outside the chain" in n for n in result.notes)


def test_init_cli_writes_into_a_new_folder_a_config_that_loads(tmp_path):
    out = tmp_path / "new" / "kinova.yaml"
    res = CliRunner().invoke(app, ["init", str(KINOVA), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "estimated wall time" in res.output
    assert "if the design is retried at a wider safety margin" in res.output
    config = load_run_config(out)  # relative paths, resolved from the new folder
    assert config.robot.urdf.resolve() == KINOVA.resolve()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["missing.urdf"], "missing.urdf"),
        ([str(KINOVA), "--lock", "no_such_joint=0.1"], "no_such_joint"),
        ([str(KINOVA), "--tip-link", "no_such_link"], "no_such_link"),
    ],
)
def test_init_bad_input_one_error_line_nothing_written(tmp_path, args, needle):
    out = tmp_path / "sub" / "cfg.yaml"
    res = CliRunner().invoke(app, ["init", *args, "-o", str(out)])
    assert res.exit_code == 2
    lines = [s for s in res.output.splitlines() if s.strip()]
    assert len(lines) == 1
    assert lines[0].startswith("error:")
    assert needle in lines[0]
    assert not out.exists()
    assert not out.parent.exists()


@pytest.mark.parametrize("servo", [[], ["--servo"]])
def test_init_refuses_an_existing_output_unless_force(tmp_path, servo):
    out = tmp_path / "mine.yaml"
    out.write_text("# my edited config\n")
    res = CliRunner().invoke(app, ["init", str(RP2_URDF), *servo, "-o", str(out)])
    assert res.exit_code == 2
    (line,) = [s for s in res.output.splitlines() if s.strip()]
    assert line.startswith(f"error: --output {out}: exists")
    assert "--force" in line
    assert out.read_text() == "# my edited config\n"  # untouched
    if servo:  # the servo config is written in milliseconds: --force replaces the file
        res = CliRunner().invoke(app, ["init", str(RP2_URDF), *servo, "-o", str(out), "--force"])
        assert res.exit_code == 0, res.output
        assert yaml.safe_load(out.read_text())["robot"]["urdf"].endswith("rp2.urdf")


# One robot end to end (a gripper welded to the flange, its meshes from the package); the
# others of the robot zoo (Kinova's 0.63-0.84 rad/s limits, Z1's locked gripper joint, UR10,
# SO-101, xArm7, Baxter) take minutes each and run in `benchmarks/bench_quickstart.py --zoo`.
ROBOTS = [
    ("ur3_gripper", UR3_GRIPPER),
]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "urdf"), ROBOTS, ids=[r[0] for r in ROBOTS])
def test_init_then_run_quick_succeeds_first_time(tmp_path, name, urdf):
    config = tmp_path / f"{name}.yaml"
    ident = [sys.executable, "-c", "from ident.cli import main; main()"]
    init = subprocess.run([*ident, "init", str(urdf), "-o", str(config)], capture_output=True)
    assert init.returncode == 0, init.stderr.decode()
    start = time.perf_counter()
    run = subprocess.run(
        [*ident, "run", str(config), "--quick", "--no-replay", "--out", str(tmp_path / "runs")],
        capture_output=True,
    )
    seconds = time.perf_counter() - start
    assert run.returncode == 0, run.stderr.decode()[-2000:]
    (folder,) = (tmp_path / "runs").iterdir()
    result = json.loads((folder / "result.json").read_text())
    assert result["safety"]["ok"] is True
    assert (folder / "trajectory.csv").is_file()
    assert "| Verdict |" in (folder / "report.md").read_text()
    # the trajectory re-checked with plain Pinocchio + coal on the URDF's meshes, at >= 1 kHz:
    # limits, RNEA torques, every link pair ident does not exclude (its exclusions adjacent or
    # one body), the floor; the smallest clearance is the one ident reports (to its 0.1 mm)
    verdict = _independent_safety().check_run_folder(folder)
    assert verdict.ok, verdict.summary()
    assert verdict.rate_hz >= 1000.0 - 1e-6
    assert not verdict.not_checked
    assert not any("excluded by ident, but" in n for n in verdict.notes), verdict.notes
    reported = re.search(r"clearance (\d+\.\d+) m at", result["safety"]["message"])
    smallest = min(verdict.clearance_m, verdict.floor_m)  # ident reports either
    assert smallest == pytest.approx(float(reported.group(1)), abs=1e-4)
    print(f"{name}: ident run --quick {seconds:.1f} s; independent check: {verdict.summary()}")


PEDESTAL_URDF = """<?xml version="1.0"?>
<robot name="pedestal_arm">
  <link name="base">
    <inertial><mass value="5"/>
      <inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 -0.2"/><geometry><box size="0.2 0.2 0.4"/></geometry></collision>
  </link>
  <link name="link1">
    <inertial><origin xyz="0 0 0.15"/><mass value="2"/>
      <inertia ixx="0.02" iyy="0.02" izz="0.005" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.15"/><geometry><box size="0.08 0.08 0.2"/></geometry></collision>
  </link>
  <link name="link2">
    <inertial><origin xyz="0.15 0 0"/><mass value="1"/>
      <inertia ixx="0.002" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0.2 0 0"/><geometry><box size="0.2 0.06 0.06"/></geometry></collision>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="link1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="2" effort="50"/></joint>
  <joint name="j2" type="revolute"><parent link="link1"/><child link="link2"/>
    <origin xyz="0 0 0.35"/><axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" velocity="2" effort="30"/></joint>
</robot>
"""


def test_init_floor_lies_under_the_base_geometry(tmp_path):
    # the base is a 0.4 m pedestal below the root frame: the floor is at its foot, z = -0.4
    urdf = tmp_path / "pedestal.urdf"
    urdf.write_text(PEDESTAL_URDF)
    result = init_config(urdf, tmp_path / "p.yaml")
    floor = yaml.safe_load(result.text)["safety"]["floor"]
    assert floor["z"] == pytest.approx(-0.4, abs=1e-3)
    assert floor["z"] <= -0.4
