"""Robot files as vendors ship them: limits as the URDF means them, xacro, kinematic loops.

A swapped or non-finite limit is an error naming the joint, the attribute and the file. A
missing limit, a velocity or effort of 0 and an empty position range are UNKNOWN (never read as
"no limit"): every check that needs one names it ("torque not checked on j1: the URDF gives
effort 0") in the certificate, the report and result.json, and ``ident init`` writes an explicit,
commented guess that the run then checks. References: Pinocchio's RNEA for the torques the
check compares, the equivalent plain URDF for a xacro file.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml
from typer.testing import CliRunner

from ident.cli import app
from ident.errors import ConfigError, ModelError
from ident.excitation.check import check_trajectory
from ident.excitation.safety import build_safety_model
from ident.excitation.safety_series import safety_series
from ident.model import Robot
from ident.model.selection import RobotSelection, load_robot
from ident.report.run_report import _safety_text
from ident.report.safety_section import safety_section
from ident.robot.limits import JointLimits

runner = CliRunner()

_INERTIAL = (
    '<inertial><origin xyz="0.2 0 0"/><mass value="{m}"/>'
    '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>'
)


def _urdf(limits: tuple[str, str], kinds: tuple[str, str] = ("revolute", "revolute")) -> str:
    """A two-joint arm: j1 about y (gravity loads it), j2 about z; ``limits``: the inside of
    each joint's ``<limit .../>`` (``None``-like ``""`` drops the element)."""
    joints = []
    for k, (inside, kind, axis) in enumerate(zip(limits, kinds, ("0 1 0", "0 0 1"), strict=True)):
        limit = f"<limit {inside}/>" if inside else ""
        joints.append(
            f'<joint name="j{k + 1}" type="{kind}"><parent link="l{k}"/><child link="l{k + 1}"/>'
            f'<origin xyz="0 0 0.3"/><axis xyz="{axis}"/>{limit}</joint>'
        )
    links = ['<link name="l0"/>'] + [
        f'<link name="l{k}">{_INERTIAL.format(m=2.0)}</link>' for k in (1, 2)
    ]
    return '<?xml version="1.0"?>\n<robot name="arm">' + "".join(links + joints) + "</robot>\n"


GOOD = 'lower="-1" upper="1" velocity="3" effort="40"'


def _write(tmp_path: Path, text: str, name: str = "arm.urdf") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("inside", "expected"),
    [
        ('lower="1.94" upper="-2.04" velocity="3" effort="40"', 'lower="1.94" upper="-2.04"'),
        ('lower="-1" upper="nan" velocity="3" effort="40"', 'upper="nan"'),
        ('lower="-inf" upper="1" velocity="3" effort="40"', 'lower="-inf"'),
        ('lower="-1" upper="1" velocity="1e999" effort="40"', 'velocity="1e999"'),
        ('lower="-1" upper="1" velocity="3" effort="-40"', 'effort="-40"'),
    ],
)
def test_swapped_and_non_finite_limits_are_one_error_line(tmp_path, inside, expected):
    path = _write(tmp_path, _urdf((GOOD, inside)))
    result = runner.invoke(app, ["verify", "--urdf", str(path)])
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert result.exit_code == 2, result.output
    assert len(errors) == 1, result.output
    assert str(path) in errors[0]
    assert "joint 'j2'" in errors[0]
    assert expected in errors[0]


def test_unknown_limits_are_named_with_the_urdf_reason_and_never_infinite_silently(tmp_path):
    path = _write(
        tmp_path,
        _urdf(('lower="0" upper="0" effort="0" velocity="2"', 'effort="5"'), ("revolute",) * 2),
    )
    robot = Robot.from_urdf(path)
    reasons = {(u.kind, u.joint): u.reason for u in robot.unknown_limits}
    assert reasons.pop(("acceleration", "j1")).startswith("the URDF gives no acceleration")
    assert reasons.pop(("acceleration", "j2")).startswith("the URDF gives no acceleration")
    assert reasons == {
        ("position", "j1"): "the URDF gives lower = upper = 0 (an empty range)",
        ("torque", "j1"): "the URDF gives effort 0",
        ("position", "j2"): "the URDF gives no position limit",
        ("velocity", "j2"): "the URDF gives no velocity limit",
    }
    np.testing.assert_array_equal(robot.dq_max, [2.0, np.inf])
    np.testing.assert_array_equal(robot.tau_max, [np.inf, 5.0])
    # a continuous joint's position is unlimited, not unknown; its velocity may be unknown
    continuous = Robot.from_urdf(
        _write(tmp_path, _urdf((GOOD, 'effort="5"'), ("revolute", "continuous")), "c.urdf")
    )
    kinds = {(u.kind, u.joint) for u in continuous.unknown_limits if u.kind != "acceleration"}
    assert kinds == {("velocity", "j2")}
    assert continuous.q_upper[1] == np.inf


def _sweep(robot: Robot, amplitude: tuple[float, float]) -> tuple[np.ndarray, ...]:
    """One period of a sine sweep, 1 kHz: q_j = a_j sin(2 pi t) (shape (1001, 2) each)."""
    t = np.linspace(0.0, 1.0, 1001)
    w = 2.0 * np.pi
    a = np.asarray(amplitude)
    q = np.sin(w * t)[:, None] * a
    dq = w * np.cos(w * t)[:, None] * a
    ddq = -(w**2) * np.sin(w * t)[:, None] * a
    return t, q, dq, ddq


def _check(robot: Robot, amplitude: tuple[float, float]):  # noqa: ANN202 - a SafetyReport
    safety = build_safety_model(robot, {"floor": {"enabled": False}, "self_collision": False})
    return check_trajectory(robot, safety, *_sweep(robot, amplitude))


def test_a_sweep_past_the_range_is_never_certified_when_the_urdf_swaps_it(tmp_path):
    correct = 'lower="-1.5" upper="1.5" velocity="20" effort="400"'
    robot = Robot.from_urdf(_write(tmp_path, _urdf((correct, correct))))
    report = _check(robot, (1.94, 0.5))
    assert not report.usable  # the correct range catches the sweep
    assert report.check("position:j1").excess == pytest.approx(1.94 - 1.5, abs=1e-9)
    swapped = correct.replace('lower="-1.5" upper="1.5"', 'lower="1.5" upper="-1.5"')
    with pytest.raises(ModelError, match=r"joint 'j1'.*lower is above upper"):
        Robot.from_urdf(_write(tmp_path, _urdf((swapped, correct)), "swapped.urdf"))
    # an empty range is unknown: the sweep is usable only with the check named as not run
    empty = correct.replace('lower="-1.5" upper="1.5"', 'lower="0" upper="0"')
    report = _check(
        Robot.from_urdf(_write(tmp_path, _urdf((empty, correct)), "e.urdf")), (1.94, 0.5)
    )
    assert report.usable
    assert "position:j1" not in {c.name for c in report.checks}
    assert (  # with the range the optimizer assumed; and both unknown accelerations
        "3 checks not run: position not checked on j1: the URDF gives lower = upper = 0 (an "
        "empty range); the optimizer assumed a guessed range [-3.142, 3.142] rad"
    ) in report.summary()


def test_an_unknown_prismatic_range_is_guessed_in_metres_and_named_so(tmp_path):
    empty = 'lower="0" upper="0" velocity="3" effort="40"'
    robot = Robot.from_urdf(
        _write(tmp_path, _urdf((empty, empty), ("revolute", "prismatic")), "rp.urdf")
    )
    # the joint types from Pinocchio's own model: the guess follows them
    kinds = [robot.model.joints[i].shortname() for i in (1, 2)]
    assert kinds == ["JointModelRY", "JointModelPZ"]
    limits = JointLimits.from_robot(robot)
    lower, upper = limits.finite_position_box()
    np.testing.assert_array_equal(lower, [-np.pi, -1.0])  # rad, m
    np.testing.assert_array_equal(upper, [np.pi, 1.0])
    # a bound given in the config keeps the joint types (tighten_limits)
    selection = RobotSelection(urdf=robot.urdf_path, limits={"j1": {"lower": -1, "upper": 1}})
    lower, upper = JointLimits.from_robot(load_robot(selection)).finite_position_box()
    np.testing.assert_array_equal(upper, [1.0, 1.0])
    report = _check(robot, (0.5, 0.2))  # the check names the guess, in the joint's unit
    assert "optimizer assumed a guessed range [-1, 1] m" in report.summary()
    assert "optimizer assumed a guessed range [-3.142, 3.142] rad" in report.summary()


def test_effort_zero_is_named_torque_not_checked_and_the_verdict_says_so(tmp_path):
    known = 'lower="-3" upper="3" velocity="20" effort="0.5"'
    robot = Robot.from_urdf(_write(tmp_path, _urdf((known, known))))
    report = _check(robot, (1.0, 0.5))
    # the known effort is compared with Pinocchio's inverse dynamics (an independent reference)
    t, q, dq, ddq = _sweep(robot, (1.0, 0.5))
    data = robot.model.createData()
    tau = np.array([pin.rnea(robot.model, data, *s) for s in zip(q, dq, ddq, strict=True)])
    assert report.check("torque:j1").value == pytest.approx(np.abs(tau[:, 0]).max(), rel=1e-9)
    assert not report.usable  # 0.5 N*m cannot hold a 2 kg link out at 0.2 m
    zero = known.replace('effort="0.5"', 'effort="0"')
    robot = Robot.from_urdf(_write(tmp_path, _urdf((zero, known)), "zero.urdf"))
    report = _check(robot, (1.0, 0.5))
    assert "torque:j1" not in {c.name for c in report.checks}
    assert report.checks_not_run()[0] == "torque not checked on j1: the URDF gives effort 0"
    assert "checks not run: " in report.summary()  # j1 torque and both accelerations
    series = safety_series(report)
    assert series["checks_not_run"] == len(report.checks_not_run()) == 3
    data = {
        "elites": [{"rank": 1, "safety_series": series}],
        "chosen_elite": 1 if report.usable else None,
        "safety": {
            "ok": report.usable,
            "checks_not_run": list(report.checks_not_run()),
            "message": report.summary(),
        },
    }
    text = "\n".join(safety_section(data, set()))
    assert "every constraint holds" not in text
    assert "**3 checks not run**" in text
    assert "- torque not checked on j1: the URDF gives effort 0" in text
    if report.usable:
        assert _safety_text(data).startswith("checked constraints hold, **3 checks not run**")


def test_robot_limits_fill_in_what_the_urdf_leaves_unknown(tmp_path):
    unknown = 'velocity="0" effort="0"'
    path = _write(tmp_path, _urdf((unknown, GOOD)))
    selection = RobotSelection(
        urdf=path,
        acceleration_limits=100.0,
        limits={"j1": {"lower": -0.5, "upper": 0.5, "velocity": 2.0, "effort": 0.5}},
    )
    robot = load_robot(selection)
    assert robot.unknown_limits == ()
    np.testing.assert_array_equal(robot.tau_max, [0.5, 40.0])
    report = _check(robot, (1.0, 0.5))
    failed = {c.name for c in report.failures()}
    assert {"position:j1", "velocity:j1", "torque:j1"} <= failed
    assert report.checks_not_run() == ()
    with pytest.raises(ConfigError, match="robot.limits names 'j9'"):
        load_robot(RobotSelection(urdf=path, limits={"j9": {"effort": 1.0}}))
    for bad, message in (
        ({"lower": 1.0, "upper": -1.0}, r"limits.j1\n.*lower = 1.0 is not below upper = -1.0"),
        ({"effort": 0.0}, r"limits.j1\n.*effort = 0.0: give a positive limit"),
        ({"velocity": float("inf")}, r"limits.j1.velocity\n.*finite number"),
    ):
        with pytest.raises(ValueError, match=message):
            RobotSelection.model_validate({"urdf": str(path), "limits": {"j1": bad}})


@pytest.mark.slow
def test_init_writes_a_commented_guess_for_each_unknown_limit_and_the_run_checks_it(tmp_path):
    from ident.run.init_config import init_config

    path = _write(tmp_path, _urdf(('lower="0" upper="0" effort="0" velocity="2"', 'effort="5"')))
    result = init_config(path, tmp_path / "arm.yaml")
    text = result.text
    assert "# guess: the URDF gives effort 0 for j1; set your robot's" in text
    assert "# guess: the URDF gives no velocity limit for j2; set your robot's" in text
    limits = yaml.safe_load(text)["robot"]["limits"]
    assert set(limits["j1"]) == {"lower", "upper", "effort"}
    assert set(limits["j2"]) >= {"velocity"}
    assert limits["j1"]["lower"] < 0 < limits["j1"]["upper"]
    assert limits["j1"]["effort"] > 0
    data = yaml.safe_load(text)["robot"]
    robot = load_robot(RobotSelection.model_validate({**data, "urdf": str(path)}))
    assert robot.unknown_limits == ()  # every check of the run has a limit


def _xacro_files(tmp_path: Path) -> tuple[Path, Path]:
    """``arm.urdf.xacro`` (a macro from ``$(find armdesc)``, ``${pi/2}`` expressions) and the
    plain URDF it stands for."""
    share = tmp_path / "share" / "armdesc" / "urdf"
    share.mkdir(parents=True)
    (share / "parts.xacro").write_text(
        '<robot xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:macro name="body" '
        f'params="name m"><link name="${{name}}">{_INERTIAL.format(m="${m}")}</link>'
        "</xacro:macro></robot>"
    )
    joints = (
        '<joint name="j1" type="revolute"><parent link="l0"/><child link="l1"/>'
        '<origin xyz="0 0 0.3" rpy="{rpy} 0 0"/><axis xyz="0 1 0"/>'
        '<limit lower="{low}" upper="{high}" velocity="3" effort="40"/></joint>'
    )
    xacro = (
        '<?xml version="1.0"?>\n<robot name="arm" xmlns:xacro="http://www.ros.org/wiki/xacro">'
        '<xacro:include filename="$(find armdesc)/urdf/parts.xacro"/>'
        '<xacro:property name="reach" value="${pi/2}"/><link name="l0"/>'
        '<xacro:body name="l1" m="${2*0.75}"/>'
        + joints.format(rpy="${pi/2}", low="${-reach}", high="${reach}")
        + "</robot>"
    )
    plain = (
        '<?xml version="1.0"?>\n<robot name="arm"><link name="l0"/>'
        f'<link name="l1">{_INERTIAL.format(m=1.5)}</link>'
        + joints.format(rpy=repr(np.pi / 2), low=repr(-np.pi / 2), high=repr(np.pi / 2))
        + "</robot>"
    )
    return _write(tmp_path, xacro, "arm.urdf.xacro"), _write(tmp_path, plain, "plain.urdf")


def test_a_xacro_file_is_expanded_without_ros(tmp_path):
    xacro, plain = _xacro_files(tmp_path)
    robot = Robot.from_urdf(xacro, package_dirs=[tmp_path / "share"])
    reference = Robot.from_urdf(plain)
    np.testing.assert_allclose(robot.parameters(), reference.parameters(), atol=1e-12)
    np.testing.assert_allclose(
        robot.model.jointPlacements[1].homogeneous,
        reference.model.jointPlacements[1].homogeneous,
        atol=1e-12,
    )
    np.testing.assert_allclose(robot.q_upper, [np.pi / 2], atol=1e-12)
    assert "${" not in robot.urdf_text  # the copy a run keeps is the expanded URDF


def test_a_xacro_file_that_cannot_be_expanded_is_one_error_line_with_the_command(
    tmp_path, monkeypatch
):
    xacro, _ = _xacro_files(tmp_path)
    result = runner.invoke(app, ["verify", "--urdf", str(xacro)])  # no package folder given
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert result.exit_code == 2, result.output
    assert len(errors) == 1, result.output
    assert "$(find armdesc)" in errors[0]
    assert "--package-dir" in errors[0]
    assert "xacro arm.urdf.xacro > arm.urdf" in errors[0]
    broken = _write(tmp_path, xacro.read_text().replace("${pi/2}", "${nope/2}"), "b.xacro")
    with pytest.raises(ModelError, match=r"xacro cannot expand.*nope.*xacro b.xacro > b.urdf"):
        Robot.from_urdf(broken, package_dirs=[tmp_path / "share"])
    monkeypatch.setitem(sys.modules, "xacro", None)  # not installed
    with pytest.raises(ModelError, match=r"xacro package is not installed.*xacro arm.urdf"):
        Robot.from_urdf(xacro, package_dirs=[tmp_path / "share"])


def test_a_kinematic_loop_is_named_as_one(tmp_path):
    text = _urdf((GOOD, GOOD)).replace('<child link="l2"/>', '<child link="l1"/>')
    path = _write(tmp_path, text)
    result = runner.invoke(app, ["verify", "--urdf", str(path)])
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert result.exit_code == 2, result.output
    assert len(errors) == 1, result.output
    assert errors[0] == (
        f"error: {path}: link 'l1' is the child of joints 'j1' and 'j2' (a kinematic loop); "
        "ident reads tree-shaped URDFs: remove one of the joints."
    )


def test_xacro_left_in_comments_is_not_expanded(tmp_path, monkeypatch):
    # vendors' URDFs (TIAGo, xArm7) keep commented-out xacro: the file is a plain URDF
    text = _urdf((GOOD, GOOD)).replace(
        '<link name="l0"/>', '<link name="l0"/><!-- <link name="${prefix}x"/> $(find p) -->'
    )
    monkeypatch.setitem(sys.modules, "xacro", None)  # expanding would fail
    robot = Robot.from_urdf(_write(tmp_path, text))
    assert robot.joint_names == ("j1", "j2")
