"""Controller exports (ident.run.exports): each checked by its controller's rules, re-read equal.

The references are independent of the exporters: a scalar transcription of libfranka's
``limitRate`` for joint positions (src/rate_limiting.cpp) run command by command, the closed
form of the quintic plans at the controllers' grids, PyYAML's pure-Python safe loader (what
``ros2 topic pub`` parses with), rosbags' ``AnyReader``, the ``mcap_ros2`` decoder, a regular
expression over the URScript, and Pinocchio's joint names of the URDF.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from ident.errors import ConfigError
from ident.excitation.executable import quintic
from ident.run.exports.common import (
    REREAD_TOLERANCE,
    ExportError,
    ExportSamples,
    resample_quintic,
    target_from_urdf,
)
from ident.run.exports.franka import (
    PANDA_ACCELERATION,
    PANDA_JERK,
    PANDA_VELOCITY,
    prepare_franka,
)
from ident.run.exports.registry import (
    EXPORTERS,
    Exporter,
    check_export_names,
    check_export_robot,
    export_trajectory,
    register_exporter,
)
from ident.run.exports.ros2 import prepare_ros2
from ident.run.exports.urscript import prepare_urscript
from ident.trajectory import JointTrajectory

REPO = Path(__file__).resolve().parents[1]
UR5_URDF = REPO / "robot/urdf/ur5.urdf"
PANDA_URDF = REPO / "robot/urdf/panda.urdf"
PANDA_HOME = np.array([0.0, -0.6, 0.0, -2.2, 0.0, 1.6, 0.8])


def urdf_joint_names(path: Path) -> tuple[str, ...]:
    """The movable joints of a URDF as Pinocchio reads them."""
    model = pin.buildModelFromUrdf(str(path))
    return tuple(model.names[1:])


def rest_to_rest(start, end, duration, dt, names):
    """A quintic rest-to-rest plan sampled every ``dt`` (the closed form, the reference)."""
    n = int(round(duration / dt))
    t = np.arange(n + 1) * dt
    zero = np.zeros_like(start)
    q, dq, ddq = quintic((start, zero, zero), (end, zero, zero), n * dt, t)
    return JointTrajectory(t=t, q=q, dq=dq, ddq=ddq, joint_names=tuple(names)), n * dt


def panda_plan(peak_velocity: float, joint: int = 3, dt: float = 1e-3, duration: float = 0.6):
    """Panda rest-to-rest move of one joint over ``duration`` [s] reaching ``peak_velocity``."""
    names = [f"panda_joint{k}" for k in range(1, 8)]
    end = PANDA_HOME.copy()
    end[joint] += peak_velocity * duration / 1.875  # quintic: peak velocity 1.875 * distance / T
    return rest_to_rest(PANDA_HOME, end, duration, dt, names)


def libfranka_limit_rate(q_commands: np.ndarray) -> np.ndarray:
    """libfranka's limitRate for joint positions, one command at a time (rate_limiting.cpp).

    The robot rests at the first command; returns the commands after limiting.
    """
    dt = 1e-3
    out = np.empty_like(q_commands)
    last_q = q_commands[0].copy()
    last_v = np.zeros(q_commands.shape[1])
    last_a = np.zeros(q_commands.shape[1])
    for k, q in enumerate(q_commands):
        for i in range(q.shape[0]):
            v_cmd = (q[i] - last_q[i]) / dt
            jerk = ((v_cmd - last_v[i]) / dt - last_a[i]) / dt
            a = last_a[i] + max(min(jerk, PANDA_JERK[i]), -PANDA_JERK[i]) * dt
            ratio = PANDA_JERK[i] / PANDA_ACCELERATION[i]
            a_max = min(ratio * (PANDA_VELOCITY[i] - last_v[i]), PANDA_ACCELERATION[i])
            a_min = max(ratio * (-PANDA_VELOCITY[i] - last_v[i]), -PANDA_ACCELERATION[i])
            v = last_v[i] + max(min(a, a_max), a_min) * dt
            out[k, i] = last_q[i] + v * dt
            last_a[i] = (v - last_v[i]) / dt
            last_v[i] = v
            last_q[i] = out[k, i]
    return out


# ------------------------------------------------------------------------------- Franka rules
def test_franka_refuses_a_velocity_above_the_limit_naming_joint_quantity_and_time():
    plan, _ = panda_plan(peak_velocity=2.3)  # joint 4: 2.3 rad/s > 2.1750 rad/s
    target = target_from_urdf(PANDA_URDF.read_text())
    with pytest.raises(ExportError, match=r"panda_joint4.*velocity.*at t = "):
        prepare_franka(plan, target)
    # libfranka would indeed change these commands (clip), by more than rounding
    q = resample_quintic(plan, 1000.0).q
    assert np.max(np.abs(libfranka_limit_rate(q) - q)) > 1e-4


@pytest.mark.parametrize("peak", [0.5, 2.0, 2.1364, 2.13645, 2.1365, 2.1366, 2.2, 3.0])
def test_franka_check_refuses_exactly_what_limit_rate_would_clip(peak):
    """Accepted plans pass libfranka's limitRate unchanged; refused ones are changed by it.

    Joint 4 (V = 2.1365 rad/s). Near the velocity limit, limitRate also bounds the
    acceleration by (J/A)(V - v): a check of |v| <= V, |a| <= A and |j| <= J alone accepts the
    peaks 2.13645 and 2.1365 rad/s, which limitRate clips (by 3e-8 and 1e-7 rad).
    """
    plan, _ = panda_plan(peak_velocity=peak, dt=1.0 / 1000.0)
    target = target_from_urdf(PANDA_URDF.read_text())
    q = resample_quintic(plan, 1000.0).q
    clipped = np.max(np.abs(libfranka_limit_rate(q) - q)) > 1e-12
    try:
        samples = prepare_franka(plan, target)
    except ExportError:
        assert clipped, f"refused although limitRate leaves it unchanged (peak {peak})"
    else:
        assert not clipped, f"accepted although limitRate clips it (peak {peak})"
        np.testing.assert_array_equal(samples.q, q)


# ------------------------------------------------------------------------- files read back
@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """A UR5 plan at 300 Hz (so URScript's 500 Hz is interpolated) and a Panda plan."""
    folder = tmp_path_factory.mktemp("exports")
    ur5 = target_from_urdf(UR5_URDF.read_text(), ddq_max=np.full(6, 8.0))
    start = np.array([0.1, -1.5, 1.2, -1.2, -1.5, 0.3])
    ur_plan, ur_t = rest_to_rest(start, start + 0.5, 1.2, 1.0 / 300.0, urdf_joint_names(UR5_URDF))
    ur_out = export_trajectory(["ros2", "urscript"], ur_plan, ur5, folder / "ur5")
    panda = target_from_urdf(PANDA_URDF.read_text())
    panda_plan_, panda_t = panda_plan(peak_velocity=1.0, dt=1.0 / 300.0)
    panda_out = export_trajectory(["franka", "ros2"], panda_plan_, panda, folder / "panda")
    return {
        "folder": folder,
        "ur": (ur_plan, ur_t, start, ur_out),
        "panda": (panda_plan_, panda_t, panda_out),
    }


def test_everything_requested_is_written(written):
    assert set(written["ur"][3].written) == {"ros2", "urscript"}, written["ur"][3].refused
    assert set(written["panda"][2].written) == {"franka", "ros2"}, written["panda"][2].refused


def quintic_at(t, start, end, duration):
    zero = np.zeros_like(start)
    return quintic((start, zero, zero), (end, zero, zero), duration, np.minimum(t, duration))


def test_ros2_yaml_reads_back_as_the_plan_with_the_urdf_joint_names(written):
    plan = written["ur"][0]
    text = (written["folder"] / "ur5/joint_trajectory.yaml").read_text()
    message = yaml.load(text, Loader=yaml.SafeLoader)  # pure Python, like ros2 topic pub
    assert list(message) == ["header", "joint_names", "points"]
    assert message["header"] == {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""}
    assert tuple(message["joint_names"]) == urdf_joint_names(UR5_URDF)
    points = message["points"]
    assert len(points) == plan.n_samples
    for key, expected in (
        ("positions", plan.q),
        ("velocities", plan.dq),
        ("accelerations", plan.ddq),
    ):
        values = [p[key] for p in points]
        assert all(isinstance(v, float) for row in values for v in row)  # no '1e-05' strings
        np.testing.assert_allclose(np.array(values), expected, rtol=0, atol=REREAD_TOLERANCE)
    t = np.array(
        [p["time_from_start"]["sec"] + 1e-9 * p["time_from_start"]["nanosec"] for p in points]
    )
    np.testing.assert_allclose(t, plan.t, rtol=0, atol=REREAD_TOLERANCE)
    assert np.all(np.diff(t) > 0)
    assert all(0 <= p["time_from_start"]["nanosec"] < 10**9 for p in points)


def bag_message_rosbags(bag: Path):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        messages = list(reader.messages())
        assert len(messages) == 1
        connection, _, raw = messages[0]
        assert (connection.topic, connection.msgtype) == (
            "/joint_trajectory",
            "trajectory_msgs/msg/JointTrajectory",
        )
        return reader.deserialize(raw, connection.msgtype)


def bag_message_mcap_ros2(bag: Path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    (mcap_file,) = bag.glob("*.mcap")
    with mcap_file.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        decoded = list(reader.iter_decoded_messages())
    assert len(decoded) == 1
    schema, channel, _, message = decoded[0]
    assert (schema.name, schema.encoding, channel.message_encoding) == (
        "trajectory_msgs/msg/JointTrajectory",
        "ros2msg",
        "cdr",
    )
    assert channel.topic == "/joint_trajectory"
    return message


@pytest.mark.parametrize("read", [bag_message_rosbags, bag_message_mcap_ros2])
@pytest.mark.parametrize("robot", ["ur", "panda"])
def test_ros2_bag_reads_back_as_the_plan(written, read, robot):
    plan = written[robot][0]
    message = read(
        written["folder"] / ("ur5" if robot == "ur" else "panda") / "joint_trajectory_bag"
    )
    urdf = UR5_URDF if robot == "ur" else PANDA_URDF
    assert tuple(message.joint_names) == tuple(
        n for n in urdf_joint_names(urdf) if n in plan.joint_names
    )
    assert tuple(message.joint_names) == plan.joint_names
    assert len(message.points) == plan.n_samples
    q = np.array([p.positions for p in message.points])
    dq = np.array([p.velocities for p in message.points])
    ddq = np.array([p.accelerations for p in message.points])
    t = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in message.points])
    for got, expected in ((q, plan.q), (dq, plan.dq), (ddq, plan.ddq), (t, plan.t)):
        np.testing.assert_allclose(got, expected, rtol=0, atol=REREAD_TOLERANCE)


def test_urscript_streams_servoj_at_500_hz_through_the_planned_motion(written):
    plan, duration, start, _ = written["ur"]
    text = (written["folder"] / "ur5/trajectory.script").read_text()
    calls = re.findall(r"servoj\(\[([^\]]*)\], 0, 0, ([0-9.]+), ([0-9.]+), ([0-9.]+)\)", text)
    assert {c[1:] for c in calls} == {("0.002", "0.1", "300")}
    q = np.array([[float(v) for v in c[0].split(",")] for c in calls])
    t = np.arange(len(q)) * 0.002
    assert t[-1] >= duration - 1e-12 > t[-2]
    expected = quintic_at(t, start, start + 0.5, duration)[0]  # the closed form at 500 Hz
    np.testing.assert_allclose(q, expected, rtol=0, atol=REREAD_TOLERANCE)
    lines = text.splitlines()  # comments, one def ... end block, then the call
    code = [line for line in lines if not line.startswith("#")]
    assert code[0] == "def ident_trajectory():"
    assert code[-2:] == ["end", "ident_trajectory()"]
    assert all(line.startswith("  ") for line in code[1:-2])
    assert "halt" in text  # never moves to the start posture on its own


def test_franka_file_is_the_plan_at_1_khz(written):
    plan, duration, _ = written["panda"]
    path = written["folder"] / "panda/franka_q_1khz.csv"
    q = np.loadtxt(path, delimiter=",", comments="#")
    t = np.arange(len(q)) * 1e-3
    assert q.shape[1] == 7
    assert t[-1] >= duration - 1e-12 > t[-2]
    end = plan.q[-1]
    expected = quintic_at(t, plan.q[0], end, duration)[0]
    np.testing.assert_allclose(q, expected, rtol=0, atol=REREAD_TOLERANCE)


# ---------------------------------------------------------------------------- other refusals
def test_ros2_refuses_names_the_urdf_does_not_have_and_non_monotonic_time():
    target = target_from_urdf(UR5_URDF.read_text())
    start = np.zeros(6)
    names = list(urdf_joint_names(UR5_URDF))
    plan, _ = rest_to_rest(start, start + 0.1, 1.0, 1e-3, names[:-1] + ["wrist3"])
    with pytest.raises(ExportError, match="wrist3.*not movable joints"):
        prepare_ros2(plan, target)
    swapped, _ = rest_to_rest(start, start + 0.1, 1.0, 1e-3, [names[1], names[0], *names[2:]])
    with pytest.raises(ExportError, match="order"):
        prepare_ros2(swapped, target)
    good, _ = rest_to_rest(start, start + 0.1, 1.0, 1e-3, names)
    t = good.t.copy()
    t[5] = t[4] + 1e-10  # equal to t[4] once rounded to the nanosecond
    bad_time = JointTrajectory(
        t=t, q=good.q, dq=good.dq, ddq=good.ddq, joint_names=good.joint_names
    )
    with pytest.raises(ExportError, match="time_from_start is not strictly increasing at point 5"):
        prepare_ros2(bad_time, target)


def test_urscript_refuses_a_speed_above_the_ur5_datasheet():
    target = target_from_urdf(UR5_URDF.read_text(), ddq_max=np.full(6, 100.0))
    names = urdf_joint_names(UR5_URDF)
    start = np.zeros(6)
    end = start.copy()
    end[2] = 1.0
    # peak 1.875 rad / 0.55 s = 3.41 rad/s > 180 deg/s = 3.14 rad/s
    plan, _ = rest_to_rest(start, end, 0.55, 1e-3, names)
    with pytest.raises(ExportError, match=r"elbow_joint.*speed.*ur5 datasheet.*3\.14159"):
        prepare_urscript(plan, target)
    slow, _ = rest_to_rest(start, end, 0.7, 1e-3, names)  # 2.68 rad/s
    prepare_urscript(slow, target)
    assert math.isclose(1.875 / 0.7, 2.678, rel_tol=1e-3)


def test_a_robot_the_controller_cannot_drive_is_refused_before_the_run():
    ur5 = target_from_urdf(UR5_URDF.read_text())
    with pytest.raises(ConfigError, match="franka: libfranka commands 7 joints"):
        check_export_robot(["ros2", "franka"], ur5.joint_names, ur5)
    panda = target_from_urdf(PANDA_URDF.read_text())
    names = [f"panda_joint{k}" for k in range(1, 8)]
    with pytest.raises(ConfigError, match="urscript: the robot 'panda' is not a Universal"):
        check_export_robot(["urscript"], names, panda)
    check_export_robot(["ros2", "franka"], names, panda)


def test_unknown_export_names_are_one_config_error_listing_the_valid_ones():
    with pytest.raises(
        ConfigError,
        match=r"'frank' is not a known export; did you mean 'franka'\? "
        r"valid: ros2, urscript, franka\.$",
    ):
        check_export_names(["ros2", "frank"])
    assert check_export_names(["franka", "ros2", "franka"]) == ["franka", "ros2"]


def test_a_file_that_does_not_read_back_as_written_is_removed_and_refused(tmp_path):
    """A writer that rounds to 6 digits: the re-read in the code path catches it."""

    def prepare(trajectory, target):
        return ExportSamples(trajectory.t, trajectory.q, None, None, trajectory.joint_names)

    def write(samples, folder):
        path = folder / "rounded.txt"
        np.savetxt(path, samples.q, fmt="%.6g")
        return [path]

    def read(path):
        q = np.loadtxt(path, ndmin=2)
        return ExportSamples(np.arange(len(q)) * 1e-3, q, None, None, ("a", "b"))

    register_exporter("rounded", Exporter(prepare, write, read), replace=True)
    try:
        plan, _ = rest_to_rest(np.zeros(2), np.full(2, 0.123456789), 0.1, 1e-3, ["a", "b"])
        outcome = export_trajectory(
            ["rounded"], plan, target_from_urdf("<robot name='x'/>"), tmp_path
        )
    finally:
        del EXPORTERS["rounded"]
    assert outcome.written == {}
    assert "does not read back" in outcome.refused["rounded"]
    assert not (tmp_path / "rounded.txt").exists()


def test_registry_toy_example_of_the_docs(tmp_path, monkeypatch):
    """The "Extending" example of docs/execute.md, read from the docs and run as written."""
    from ident.run.config import ControllerSection
    from ident.run.exports import registry

    monkeypatch.setattr(registry, "EXPORTERS", dict(registry.EXPORTERS))  # undone afterwards
    text = (REPO / "docs" / "execute.md").read_text()
    section = text[text.index("## Extending") :]
    exec(re.search(r"```python\n(.*?)```", section, re.S).group(1), {})
    assert "q250" in registry.EXPORTERS
    with pytest.raises(ValueError, match="registered already"):
        registry.register_exporter("q250", registry.EXPORTERS["q250"])
    assert ControllerSection(export=["q250", "ros2"]).export == ["q250", "ros2"]
    plan, duration = rest_to_rest(np.zeros(2), np.ones(2), 0.5, 1e-3, ["j1", "j2"])
    outcome = registry.export_trajectory(
        ["q250"], plan, target_from_urdf("<robot name='x'/>"), tmp_path
    )
    assert outcome.written == {"q250": [tmp_path / "q_250hz.txt"]}, outcome.refused
    q = np.loadtxt(tmp_path / "q_250hz.txt")
    t = np.arange(len(q)) / 250.0
    np.testing.assert_allclose(q, quintic_at(t, np.zeros(2), np.ones(2), duration)[0], atol=1e-12)


def test_yaml_floats_that_pyyaml_would_read_as_strings_are_spelled_as_floats(tmp_path):
    """repr(1e-05) is '1e-05', a string for YAML 1.1 (PyYAML, ros2 topic pub)."""
    names = urdf_joint_names(UR5_URDF)
    plan, _ = rest_to_rest(np.zeros(6), np.full(6, 0.1), 0.5, 1e-3, names)
    q = plan.q.copy()
    q[0, :3] = [1e-05, -2e-07, 3e-300]
    odd = JointTrajectory(t=plan.t, q=q, dq=plan.dq, ddq=plan.ddq, joint_names=names)
    outcome = export_trajectory(["ros2"], odd, target_from_urdf(UR5_URDF.read_text()), tmp_path)
    assert "ros2" in outcome.written, outcome.refused
    message = yaml.safe_load((tmp_path / "joint_trajectory.yaml").read_text())
    assert message["points"][0]["positions"][:3] == [1e-05, -2e-07, 3e-300]


def test_a_file_consistent_with_itself_but_not_with_the_plan_is_refused(tmp_path, monkeypatch):
    """An exporter off by one sample writes and reads back its own samples exactly; the
    comparison with the plan at the shared times catches it."""
    from ident.run.exports import registry

    def prepare(trajectory, target):
        q = np.vstack([trajectory.q[:1], trajectory.q[:-1]])  # one sample late
        return ExportSamples(trajectory.t, q, None, None, trajectory.joint_names)

    def write(samples, folder):
        path = folder / "late.txt"
        np.savetxt(path, samples.q, fmt="%.17g")
        return [path]

    def read(path):
        q = np.loadtxt(path, ndmin=2)
        return ExportSamples(np.arange(len(q)) * 1e-3, q, None, None, ("a", "b"))

    monkeypatch.setattr(registry, "EXPORTERS", dict(registry.EXPORTERS))
    register = registry.register_exporter
    register("late", Exporter(prepare, write, read))
    plan, _ = rest_to_rest(np.zeros(2), np.ones(2), 0.5, 1e-3, ["a", "b"])
    target = target_from_urdf("<robot name='x'/>")
    outcome = registry.export_trajectory(["late"], plan, target, tmp_path)
    assert outcome.written == {}
    assert re.search(
        r"joint 'a' position differs from the plan by .* at t = ", outcome.refused["late"]
    )
    assert not (tmp_path / "late.txt").exists()


def test_resampled_files_are_compared_with_the_plan_where_times_coincide(written):
    from ident.run.exports.common import compare_with_plan
    from ident.run.exports.franka import read_franka
    from ident.run.exports.ros2 import read_ros2

    plan = written["panda"][0]  # 300 Hz plan, 1 kHz file: shared every 10 ms
    reread = read_franka(written["folder"] / "panda/franka_q_1khz.csv")
    assert compare_with_plan(reread, plan, "franka") == int(np.floor(plan.t[-1] / 0.01 + 1e-9)) + 1
    ur_plan = written["ur"][0]  # the ROS 2 message holds the plan's samples, ns-rounded times
    bag = read_ros2(written["folder"] / "ur5/joint_trajectory_bag")
    assert compare_with_plan(bag, ur_plan, "ros2") == ur_plan.n_samples


def test_quintic_hermite_equals_scipy_bpoly_on_a_non_polynomial_signal():
    from scipy.interpolate import BPoly

    from ident.run.exports.common import quintic_hermite

    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.002, 0.01, 200))  # non-uniform samples
    w = np.array([3.0, 7.0])
    q, dq, ddq = (
        np.sin(w * t[:, None]),
        w * np.cos(w * t[:, None]),
        -(w**2) * np.sin(w * t[:, None]),
    )
    times = np.sort(rng.uniform(t[0], t[-1], 500))
    ours = quintic_hermite(t, q, dq, ddq, times)
    for j in range(2):
        spline = BPoly.from_derivatives(t, np.stack([q[:, j], dq[:, j], ddq[:, j]], 1))
        for order in range(3):
            np.testing.assert_allclose(ours[order][:, j], spline(times, nu=order), atol=1e-9)
