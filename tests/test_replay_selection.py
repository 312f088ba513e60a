"""The replay's robot is the identification's selection: chain, locked joints, mesh folders.

References: Pinocchio forward kinematics of the *full* Panda model (fingers as joints, set to
their lock values) and of its full geometry model; the replay builds a reduced model instead,
so a replay that drew the hand at the fingers' zero, or dropped the locked links, or ignored
``robot.package_dirs``, disagrees.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import umsgpack
from robots import ERD_SHARE, UR5_URDF, rp2_identify_config
from test_replay import animation_of, html_commands, track

from ident.errors import IdentWarning
from ident.model.selection import RobotSelection
from ident.trajectory import JointTrajectory, trajectory_to_csv
from ident.viz.replay import build_replay_scene

ROOT = Path(__file__).resolve().parents[1]
PANDA = ROOT / "robot" / "urdf" / "panda.urdf"
MESHES = ROOT / "robot" / "meshes"  # the Panda's collision meshes (configs/panda.yaml)
ARM = tuple(f"panda_joint{i}" for i in range(1, 8))
LOCK = {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}
FPS = 30.0


def arm_trajectory(duration: float = 1.0, t0: float = 0.0, phase: float = 0.0) -> JointTrajectory:
    """Arm motion sampled at the replay's keyframe rate (frames = samples)."""
    t = np.arange(round(duration * FPS) + 1) / FPS
    q = 0.4 * np.sin(2.0 * t[:, None] + np.arange(7) + phase)
    return JointTrajectory(t=t + t0, q=q, dq=q, ddq=q, joint_names=ARM)


def panda_selection(**changes) -> RobotSelection:
    fields = {"urdf": PANDA, "tip_link": "panda_link7", "lock": LOCK, "package_dirs": [MESHES]}
    return RobotSelection(**{**fields, **changes})


def full_panda_placements(q_arm: np.ndarray, names: list[str]) -> list[pin.SE3]:
    """oMg of the named collision geometries, full model, fingers at their lock values."""
    model = pin.buildModelFromUrdf(str(PANDA))
    geom = pin.buildGeomFromUrdf(
        model, str(PANDA), pin.GeometryType.COLLISION, package_dirs=[str(MESHES)]
    )
    q = pin.neutral(model)
    for name, value in zip(ARM, q_arm, strict=True):
        q[model.joints[model.getJointId(name)].idx_q] = value
    for name, value in LOCK.items():
        q[model.joints[model.getJointId(name)].idx_q] = value
    data, gdata = model.createData(), geom.createData()
    pin.forwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, geom, gdata)
    return [gdata.oMg[geom.getGeometryId(n)].copy() for n in names]


def check_hand_at_lock_pose(commands: list[dict], traj: JointTrajectory) -> None:
    anim = animation_of(commands)
    names = ["panda_hand_0", "panda_leftfinger_0", "panda_rightfinger_0"]
    tracks = {}
    for n in names:
        path = f"/meshcat/replay/robot_0/visuals/{n}"
        _, pos, _ = track(anim, path, "position")
        _, quat, _ = track(anim, path, "quaternion")
        tracks[n] = (pos, quat)
    for k in (0, 11, traj.n_samples - 1):
        for n, ref in zip(names, full_panda_placements(traj.q[k], names), strict=True):
            pos, quat = tracks[n]
            np.testing.assert_allclose(pos[k], ref.translation, atol=1e-9)
            x, y, z, w = quat[k]
            rotation = pin.Quaternion(w, x, y, z).toRotationMatrix()
            np.testing.assert_allclose(rotation, ref.rotation, atol=1e-9)
    # the geometry is the meshes' triangles, not a stick figure's primitives
    hand = [
        c
        for c in commands
        if c["type"] == "set_object" and c["path"].endswith("/visuals/panda_hand_0")
    ]
    (geometry,) = hand[0]["object"]["geometries"]
    assert geometry["type"] == "BufferGeometry"
    vertices = geometry["data"]["attributes"]["position"]["array"].data  # float32 x, y, z
    assert len(vertices) > 12 * 100  # hand.stl: hundreds of vertices


def test_locked_hand_is_drawn_at_its_lock_pose_with_its_meshes():
    traj = arm_trajectory()
    with pytest.warns(IdentWarning, match="collision geometry"):  # visual .dae not shipped
        scene = build_replay_scene(panda_selection(), [traj], fps=FPS, loop=False)
    assert not scene.fallback_geometry
    assert scene.n_visuals == 17  # 8 links + hand + 2 x 4 finger parts (collision meshes)
    check_hand_at_lock_pose([umsgpack.unpackb(c.data) for c in scene.recorder.commands], traj)


def test_selection_package_dirs_load_meshes_and_the_warning_names_the_option():
    names = (
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
    )
    t = np.arange(11) / 10
    q = np.tile(0.1 * t[:, None], (1, 6))
    traj = JointTrajectory(t=t, q=q, dq=q, ddq=q, joint_names=names)
    with warnings.catch_warnings():
        warnings.simplefilter("error", IdentWarning)  # meshes found through the selection
        scene = build_replay_scene(RobotSelection(urdf=UR5_URDF, package_dirs=[ERD_SHARE]), [traj])
    assert not scene.fallback_geometry
    assert scene.n_visuals == 7
    # no mesh folder: the collision meshes beside the URDF (robot/meshes) are found as ROS
    # would, the visual ones nowhere; the warning counts them and names the caller's option
    panda = panda_selection(package_dirs=[])
    with pytest.warns(
        IdentWarning,
        match=r"10 visual meshes not found: .*link0\.dae.*\(and 7 more\); showing the "
        r"collision geometry.*robot\.package_dirs in the config",
    ):
        scene = build_replay_scene(
            panda, [arm_trajectory()], package_hint="robot.package_dirs in the config"
        )
    assert not scene.fallback_geometry


def _replay(*args):
    from typer.testing import CliRunner

    from ident.cli import app

    return CliRunner().invoke(app, ["replay", *map(str, args)])


def test_cli_lock_and_package_dir(tmp_path):
    traj = arm_trajectory()
    csv = tmp_path / "arm.csv"
    csv.write_text(trajectory_to_csv(traj))
    out = tmp_path / "panda.html"
    base = ["--urdf", PANDA, "--trajectory", csv, "--html", out, "--package-dir", MESHES]
    # without --lock: the fingers are joints the trajectory does not move -> one error line
    result = _replay(*base)
    assert result.exit_code == 2
    assert not out.exists()
    assert "error:" in result.output
    assert "--lock" in result.output
    result = _replay(
        *base,
        "--tip-link",
        "panda_link7",
        "--lock",
        "panda_finger_joint1=0.02",
        "--lock",
        "panda_finger_joint2=0.02",
        "--no-loop",
    )
    assert result.exit_code == 0, result.output
    check_hand_at_lock_pose(html_commands(out.read_text()), traj)


def test_run_folder_replay_uses_the_runs_locks(tmp_path):
    """``ident run``'s write_replay and ``ident replay RUN_DIR`` take the config's robot."""
    from ident.report.run_data import write_replay

    run = tmp_path / "run"
    (run / "elites").mkdir(parents=True)
    (run / "robot.urdf").write_text(PANDA.read_text())
    traj = arm_trajectory()
    (run / "elites" / "elite_1.csv").write_text(trajectory_to_csv(traj))
    (run / "trajectory.csv").write_text(trajectory_to_csv(traj))
    robot = json.loads(panda_selection().model_dump_json())  # as result.json keeps it
    data = {"name": "panda", "chosen_elite": 1, "config": {"robot": robot}}
    (run / "result.json").write_text(json.dumps(data))
    note = write_replay(run)
    assert note.startswith("replay.html written"), note
    assert "collision geometry" in note
    assert "robot.package_dirs" in note
    check_hand_at_lock_pose(html_commands((run / "replay.html").read_text()), traj)
    out = tmp_path / "again.html"
    result = _replay(run, "--html", out, "--no-loop")
    assert result.exit_code == 0, result.output
    check_hand_at_lock_pose(html_commands(out.read_text()), traj)


def test_two_segment_log_replays_both_segments():
    first = arm_trajectory(duration=1.0, t0=5.0)
    second = arm_trajectory(duration=0.5, t0=2.0, phase=1.0)  # time jumps backwards
    gap = arm_trajectory(duration=0.5, t0=20.0, phase=2.0)  # then a 13.5 s gap
    parts = (first, second, gap)
    log = JointTrajectory(
        t=np.concatenate([p.t for p in parts]),
        q=np.vstack([p.q for p in parts]),
        dq=np.vstack([p.dq for p in parts]),
        ddq=np.vstack([p.ddq for p in parts]),
        joint_names=ARM,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentWarning)
        scene = build_replay_scene(panda_selection(), [log], fps=FPS, loop=False)
    commands = [umsgpack.unpackb(c.data) for c in scene.recorder.commands]
    anim = animation_of(commands)
    # the traced path: one line per segment, none drawn across a jump or a gap
    lines = [c["path"] for c in commands if c["type"] == "set_object" and "/path" in c["path"]]
    root = "/meshcat/replay/robot_0"
    assert sorted(lines) == [f"{root}/path", f"{root}/path_2", f"{root}/path_3"]
    frames = sum(p.n_samples for p in parts)  # 31 + 16 + 16: every segment, gaps skipped
    times, positions, _ = track(anim, "/meshcat/replay/robot_0/visuals/panda_hand_0", "position")
    assert len(times) == frames
    assert scene.duration == pytest.approx((frames - 1) / FPS)
    assert any("3 segments" in n for n in scene.notes)
    # each segment's frames show that segment's motion (the hand where the log puts it)
    start = 0
    for p in parts:
        (ref,) = full_panda_placements(p.q[-1], ["panda_hand_0"])
        np.testing.assert_allclose(positions[start + p.n_samples - 1], ref.translation, atol=1e-9)
        start += p.n_samples


def test_identify_motion_of_a_two_segment_log_replays_both_segments():
    """``ident identify``'s measured motion holds every segment of the log (was: the first),
    and the replay shows them one after another: keyframes = sum over the segments."""
    from ident.identify.config import PreprocessConfig
    from ident.identify.pipeline.core import replay_motion
    from ident.measure.logs import RobotLog

    fs, joints = 100.0, ("j1", "j2", "j3")
    urdf = ROOT / "data" / "examples" / "arm3.urdf"
    n1, n2 = 1001, 601  # 10 s, then 6 s after a 2 s gap
    t = np.concatenate([np.arange(n1) / fs, 12.0 + np.arange(n2) / fs])
    q = np.column_stack([np.sin(0.5 * t + k) for k in range(3)])
    log = RobotLog(
        t=t,
        q=q,
        tau=np.zeros_like(q),
        sampling_rate_hz=fs,
        joint_names=joints,
        segments=((0, n1), (n1, n1 + n2)),
    )
    pp = PreprocessConfig(lowpass={"cutoff_hz": 5.0, "order": 4}, trim_samples=10)
    motion, note = replay_motion(log, pp, joints)
    assert note == ""
    assert motion is not None
    # each segment trimmed by 10 samples at both ends, decimated 2:1 to 50 Hz
    assert motion.t[0] == pytest.approx(0.10)
    assert motion.t[-1] == pytest.approx(12.0 + (n2 - 11) / fs, abs=0.02)
    scene = build_replay_scene(RobotSelection(urdf=urdf), [motion], fps=FPS, loop=False)
    first = motion.t[motion.t < 11.0]
    second = motion.t[motion.t > 11.0]
    spans = (first[-1] - first[0], second[-1] - second[0])
    frames = sum(int(np.floor(s * FPS + 1e-9)) + 1 for s in spans)
    anim = animation_of([umsgpack.unpackb(c.data) for c in scene.recorder.commands])
    times, _, _ = track(anim, "/meshcat/replay/robot_0/marker", "position")
    assert len(times) == frames
    assert any("2 segments" in n for n in scene.notes)


def test_identify_says_when_its_replay_fails(tmp_path, monkeypatch):
    """A replay that fails never passes silently: a 'warning:' line, run.json says what."""
    from typer.testing import CliRunner

    import ident.viz.replay
    from ident.cli import app

    config = rp2_identify_config(tmp_path)  # a 12 s log of the rp2 arm, identified by WLS

    def broken(*args, **kwargs):
        raise RuntimeError("the replay broke")

    monkeypatch.setattr(ident.viz.replay, "replay_html", broken)
    result = CliRunner().invoke(app, ["identify", str(config), "--out", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    assert "warning: no replay: RuntimeError: the replay broke" in result.output
    (run,) = (tmp_path / "runs").iterdir()
    assert not (run / "replay.html").exists()
    state = json.loads((run / "run.json").read_text())
    assert state["replay"] == "no replay: RuntimeError: the replay broke"


def test_cli_html_refuses_an_existing_file_unless_force(tmp_path):
    out = tmp_path / "page.html"
    out.write_text("<p>mine</p>\n")
    missing = tmp_path / "missing.urdf"
    result = _replay("--urdf", missing, "--html", out)
    assert result.exit_code == 2
    (line,) = [s for s in result.output.splitlines() if s.strip()]
    assert line.startswith(f"error: --html {out}: exists")
    assert "--force" in line
    assert out.read_text() == "<p>mine</p>\n"
    # with --force the page passes the check: the next error is the missing --trajectory
    result = _replay("--urdf", missing, "--html", out, "--force")
    assert result.exit_code == 2
    assert "--html" not in result.output
    assert "--trajectory" in result.output
    assert out.read_text() == "<p>mine</p>\n"
