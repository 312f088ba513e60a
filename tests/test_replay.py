"""Replay scene and static HTML export (no browser; see test_replay_browser.py for rendering).

The reference for the animated motion is an independent standard-DH product of the paper's
Table 1 (numpy), not Pinocchio: the fixture URDF is that table.
"""

from __future__ import annotations

import base64
import json
import math
import re
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import umsgpack
from robots import ERD_SHARE, UR5_URDF

from ident.errors import DataError, IdentWarning, ModelError
from ident.trajectory import JointTrajectory
from ident.viz.replay import build_replay_scene, joint_configurations, replay_html

DATA = Path(__file__).parent / "data" / "replay"
URDF = DATA / "paper_like_6r.urdf"
JOINTS = tuple(f"joint_{i}" for i in range(1, 7))
# Paper Table 1, standard DH (a [m], d [m], alpha [rad]); flange = frame 6.
DH = [
    (0.300, 0.320, -math.pi / 2),
    (0.700, 0.0, 0.0),
    (0.0, 0.0, -math.pi / 2),
    (0.0, 0.6975, math.pi / 2),
    (0.0, 0.0, -math.pi / 2),
    (0.0, 0.1275, 0.0),
]


def dh_transform(q: np.ndarray) -> np.ndarray:
    """Pose of DH frame len(q) by the product of Rz(q) Tz(d) Tx(a) Rx(alpha) (numpy only)."""
    T = np.eye(4)
    for qi, (a, d, alpha) in zip(q, DH[: len(q)], strict=True):
        c, s, ca, sa = math.cos(qi), math.sin(qi), math.cos(alpha), math.sin(alpha)
        T = T @ np.array(
            [[c, -s * ca, s * sa, a * c], [s, c * ca, -c * sa, a * s], [0, sa, ca, d], [0, 0, 0, 1]]
        )
    return T


def dh_flange(q: np.ndarray) -> np.ndarray:
    """Flange position [m]: origin of DH frame 6."""
    return dh_transform(q)[:3, 3]


def make_trajectory(
    joints=JOINTS, duration: float = 2.0, rate: float = 60.0, phase: float = 0.0
) -> JointTrajectory:
    t = np.arange(round(duration * rate) + 1) / rate
    k = np.arange(len(joints))
    w = 2 * np.pi / duration
    q = 0.5 * np.sin(w * t[:, None] + k + phase)
    dq = 0.5 * w * np.cos(w * t[:, None] + k + phase)
    ddq = -0.5 * w * w * np.sin(w * t[:, None] + k + phase)
    return JointTrajectory(t=t + 3.0, q=q, dq=dq, ddq=ddq, joint_names=tuple(joints))


def html_commands(html: str) -> list[dict]:
    """Decode the msgpack commands embedded in a replay page."""
    block = html[html.index("const commands = [") : html.index("];", html.index("const commands"))]
    return [
        umsgpack.unpackb(base64.b64decode(c)) for c in re.findall(r'"([A-Za-z0-9+/=]+)"', block)
    ]


def animation_of(commands: list[dict]) -> dict:
    (cmd,) = [c for c in commands if c["type"] == "set_animation"]
    return cmd


def track(cmd: dict, path: str, name: str) -> tuple[np.ndarray, np.ndarray, float]:
    (anim,) = [a for a in cmd["animations"] if a["path"] == path]
    (tr,) = [t for t in anim["clip"]["tracks"] if t["name"] == "." + name]
    times = np.array([k["time"] for k in tr["keys"]], dtype=float)
    values = np.array([k["value"] for k in tr["keys"]], dtype=float)
    return times, values, float(anim["clip"]["fps"])


def test_static_html_is_self_contained_and_animates_the_dh_motion():
    traj = make_trajectory()
    html = replay_html(URDF, [traj], speed=0.5, fps=30.0)
    assert html.startswith("<!DOCTYPE html>")
    assert "new MeshCat.Viewer" in html
    # Nothing to fetch: no external script, stylesheet or image.
    assert not re.search(r"<script[^>]+src=|<link[^>]+href=|<img[^>]+src=", html)
    commands = html_commands(html)
    objects = {c["path"] for c in commands if c["type"] == "set_object"}
    assert sum(p.startswith("/meshcat/replay/robot_0/visuals/") for p in objects) == 12
    assert "/meshcat/replay/robot_0/path" in objects

    anim = animation_of(commands)
    assert anim["options"]["repetitions"] == math.inf  # loops by default
    times, positions, fps = track(anim, "/meshcat/replay/robot_0/marker", "position")
    # 2 s at half speed -> 4 s of replay at 30 keyframes/s.
    assert fps == 30.0
    assert times[-1] / fps == pytest.approx(4.0)
    np.testing.assert_array_equal(times, np.arange(121))
    # Keyframe k shows trajectory time k * speed / fps = k / 60 = sample k: no interpolation.
    expected = np.array([dh_flange(q) for q in traj.q])
    np.testing.assert_allclose(positions, expected, atol=1e-9)

    # The path line passes through the same DH positions (float32 in the scene).
    (line,) = [c for c in commands if c["path"] == "/meshcat/replay/robot_0/path"]
    geometry = line["object"]["geometries"][0]
    points = np.frombuffer(geometry["data"]["attributes"]["position"]["array"].data, np.float32)
    np.testing.assert_allclose(points.reshape(-1, 3), expected, atol=1e-6)


def test_link_keyframes_follow_forward_kinematics():
    # The last link's housing turns about joint 6's axis; its position is the wrist centre.
    traj = make_trajectory()
    scene = build_replay_scene(URDF, [traj], fps=60.0, loop=False)
    commands = [umsgpack.unpackb(c.data) for c in scene.recorder.commands]
    anim = animation_of(commands)
    assert anim["options"]["repetitions"] == 1
    _, positions, _ = track(anim, "/meshcat/replay/robot_0/visuals/link_6_0", "position")
    _, quats, _ = track(anim, "/meshcat/replay/robot_0/visuals/link_6_0", "quaternion")
    for k in (0, 37, 120):
        # The housing is centred on joint 6: origin of DH frame 5, axis z5.
        T5 = dh_transform(traj.q[k, :5])
        np.testing.assert_allclose(positions[k], T5[:3, 3], atol=1e-9)
        # three.js quaternion (x, y, z, w): z axis of the housing = z axis of frame 5.
        x, y, z, w = quats[k]
        z_axis = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
        np.testing.assert_allclose(z_axis, T5[:3, 2], atol=1e-9)
    assert scene.duration == pytest.approx(2.0)


def test_joint_columns_are_matched_by_name():
    traj = make_trajectory()
    order = [3, 0, 5, 1, 4, 2]
    shuffled = JointTrajectory(
        t=traj.t,
        q=traj.q[:, order],
        dq=traj.dq[:, order],
        ddq=traj.ddq[:, order],
        joint_names=tuple(JOINTS[i] for i in order),
    )
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(URDF))
    np.testing.assert_array_equal(
        joint_configurations(model, shuffled), joint_configurations(model, traj)
    )


def test_joint_name_mismatch_names_both_lists():
    traj = make_trajectory(joints=("a1", "a2", "a3", "a4", "a5", "a6"))
    with pytest.raises(DataError, match=r"\['a1'.*joint_1") as info:
        replay_html(URDF, [traj])
    assert "missing from the trajectory" in str(info.value)
    with pytest.raises(DataError, match="joint_6"):
        replay_html(URDF, [make_trajectory(joints=JOINTS[:5])])


def test_unknown_traced_frame_lists_frames():
    with pytest.raises(ModelError, match="no frame 'flang'.*Did you mean.*flange"):
        replay_html(URDF, [make_trajectory()], traced_frame="flang")


def test_bad_inputs_are_identerrors(tmp_path):
    with pytest.raises(DataError, match="no trajectory"):
        replay_html(URDF, [])
    with pytest.raises(DataError, match="speed"):
        replay_html(URDF, [make_trajectory()], speed=0.0)
    with pytest.raises(ModelError, match="not found"):
        replay_html(tmp_path / "nope.urdf", [make_trajectory()])
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/><joint name='j'/></robot>")
    with pytest.raises(ModelError, match="bad.urdf"):
        replay_html(bad, [make_trajectory()])


def _isolated(tmp_path):
    """A folder whose parent and grandparent hold nothing else: a missing mesh is searched by
    its path's tail there (``ident.robot.meshes``), and in a shared temporary root another
    test's copy of the same meshes would be found (order-dependent results)."""
    folder = tmp_path / "a" / "b" / "c"
    folder.mkdir(parents=True)
    return folder


def test_missing_meshes_fall_back_to_a_stick_figure(tmp_path):
    text = URDF.read_text().replace(
        '<geometry><box size="0.3 0.3 0.1"/></geometry>',
        '<geometry><mesh filename="package://nowhere/meshes/base.stl"/></geometry>',
    )
    urdf = _isolated(tmp_path) / "missing_mesh.urdf"
    urdf.write_text(text)
    with pytest.warns(IdentWarning, match="base.stl.*stick figure"):
        scene = build_replay_scene(urdf, [make_trajectory()])
    assert scene.fallback_geometry
    # One sphere per joint, one cylinder per nonzero joint offset (joints 2, 3, 5) and the
    # segment from joint 6 to the flange.
    assert scene.n_visuals == 6 + 3 + 1
    commands = [umsgpack.unpackb(c.data) for c in scene.recorder.commands]
    visuals = [c for c in commands if c["type"] == "set_object" and "/visuals/" in c["path"]]
    assert len(visuals) == scene.n_visuals


def test_elites_side_by_side():
    trajs = [make_trajectory(phase=p, duration=d) for p, d in ((0.0, 2.0), (1.0, 1.5), (2.0, 2.0))]
    scene = build_replay_scene(URDF, trajs, spacing=1.5)
    assert scene.robot_paths == tuple(f"/meshcat/replay/robot_{k}" for k in range(3))
    commands = [umsgpack.unpackb(c.data) for c in scene.recorder.commands]
    offsets = {
        c["path"]: np.array(c["matrix"]).reshape(4, 4).T[:3, 3]
        for c in commands
        if c["type"] == "set_transform" and c["path"] in scene.robot_paths
    }
    for k, path in enumerate(scene.robot_paths):
        np.testing.assert_allclose(offsets[path], [0.0, 1.5 * k, 0.0])
    anim = animation_of(commands)
    durations = {
        a["path"]: a["clip"]["tracks"][0]["keys"][-1]["time"] / a["clip"]["fps"]
        for a in anim["animations"]
        if a["path"].endswith("/marker")
    }
    assert durations["/meshcat/replay/robot_1/marker"] == pytest.approx(1.5)
    assert durations["/meshcat/replay/robot_2/marker"] == pytest.approx(2.0)
    assert scene.duration == pytest.approx(2.0)


def test_mesh_urdf_with_package_dirs():
    share, urdf = ERD_SHARE, UR5_URDF
    names = (
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error", IdentWarning)  # meshes found: no fallback
        scene = build_replay_scene(
            urdf, [make_trajectory(joints=names, duration=1.0)], package_dirs=[share]
        )
    assert not scene.fallback_geometry
    assert scene.traced_frame == "tool0"
    assert scene.n_visuals == 7


# ----------------------------------------------------------------------------- CLI


def make_run_dir(tmp_path: Path, *, elites: int = 0, traced_frame: str | None = None) -> Path:
    from ident.trajectory import trajectory_to_csv

    run = tmp_path / "run"
    (run / "elites").mkdir(parents=True)
    (run / "robot.urdf").write_text(URDF.read_text())
    (run / "trajectory.csv").write_text(trajectory_to_csv(make_trajectory()))
    for k in range(1, elites + 1):
        # As in `ident run`: elite 1 is the chosen trajectory.
        csv = trajectory_to_csv(make_trajectory(phase=float(k - 1), duration=1.0 + k))
        if k == 1:
            csv = (run / "trajectory.csv").read_text()
        (run / "elites" / f"elite_{k}.csv").write_text(csv)
        (run / "elites" / f"elite_{k}_path.csv").write_text("t,x,y,z\n0,0,0,0\n1,0,0,0\n")
    if traced_frame is not None:
        result = {"excitation": {"traced_frame": traced_frame}}
        (run / "result.json").write_text(json.dumps(result), encoding="utf-8")
    return run


def test_cli_html_from_run_dir_with_elites(tmp_path):
    from typer.testing import CliRunner

    from ident.cli import app

    run = make_run_dir(tmp_path, elites=3, traced_frame="link_5")
    out = tmp_path / "page.html"
    result = CliRunner().invoke(app, ["replay", str(run), "--elites", "--html", str(out)])
    assert result.exit_code == 0, result.output
    assert "3 trajectory(ies)" in result.output  # chosen = elite 1, shown once
    assert "traced frame link_5" in result.output  # from result.json
    page = out.read_text()
    for k, name in enumerate(("trajectory.csv", "elite_2.csv", "elite_3.csv")):
        assert f"robot {k}: {name}" in page  # caption: which robot replays which file
    commands = html_commands(out.read_text())
    roots = {c["path"] for c in commands if c["path"].count("/") == 3 and "robot_" in c["path"]}
    assert roots == {f"/meshcat/replay/robot_{k}" for k in range(3)}


def test_cli_bad_inputs_exit_2_with_a_message(tmp_path):
    from typer.testing import CliRunner

    from ident.cli import app

    runner = CliRunner()
    run = make_run_dir(tmp_path)
    (run / "trajectory.csv").unlink()
    result = runner.invoke(app, ["replay", str(run), "--html", str(tmp_path / "x.html")])
    assert result.exit_code == 2
    assert "no trajectory.csv" in result.output
    assert not (tmp_path / "x.html").exists()

    csv = tmp_path / "other.csv"
    from ident.trajectory import trajectory_to_csv

    csv.write_text(trajectory_to_csv(make_trajectory(joints=("a", "b", "c", "d", "e", "f"))))
    result = runner.invoke(
        app, ["replay", "--urdf", str(URDF), "--trajectory", str(csv), "--html", "y.html"]
    )
    assert result.exit_code == 2
    assert "joint_1" in result.output
    assert "'a'" in result.output

    result = runner.invoke(app, ["replay", "--urdf", str(URDF)])
    assert result.exit_code == 2
    assert "--trajectory" in result.output

    result = runner.invoke(app, ["replay", str(run), "--elites", "--html", "z.html"])
    assert result.exit_code == 2


def _invoke_replay(*args):
    from typer.testing import CliRunner

    from ident.cli import app

    return CliRunner().invoke(app, ["replay", *map(str, args)])


def _write_csv(path: Path, traj: JointTrajectory) -> Path:
    from ident.trajectory import trajectory_to_csv

    path.write_text(trajectory_to_csv(traj))
    return path


def test_cli_joint_count_mismatch_names_the_csv_and_the_urdf(tmp_path):
    csv = _write_csv(tmp_path / "five.csv", make_trajectory(joints=JOINTS[:5]))
    result = _invoke_replay("--urdf", URDF, "--trajectory", csv, "--html", tmp_path / "x.html")
    assert result.exit_code == 2
    message = result.output
    assert f"trajectory {csv} has 5 joints {list(JOINTS[:5])}" in message
    assert f"URDF {URDF} has 6 joints {list(JOINTS)}" in message
    assert "missing from the trajectory: ['joint_6']" in message
    assert "unknown to the URDF" not in message  # nothing extra: not printed as []
    assert not (tmp_path / "x.html").exists()


def test_cli_paper_trajectory_on_ur5_names_both_sides(tmp_path):
    csv = _write_csv(tmp_path / "paper.csv", make_trajectory(duration=0.5))
    urdf = _isolated(tmp_path) / "ur5_robot.urdf"  # away from its meshes (beside the original)
    urdf.write_text(UR5_URDF.read_text())
    result = _invoke_replay("--urdf", urdf, "--trajectory", csv, "--html", tmp_path / "x.html")
    assert result.exit_code == 2
    message = " ".join(result.output.split())  # undo the terminal's line wrapping
    # no --package-dir: no meshes, one warning line naming the option
    assert "warning:" in message
    assert "stick figure" in message
    assert "with --package-dir" in message
    assert f"the joints of trajectory {csv} {list(JOINTS)}" in message
    assert f"do not match the joints of URDF {urdf} ['shoulder_pan_joint'" in message
    assert "'wrist_3_joint']" in message
    assert "unknown to the URDF: ['joint_1'" in message
    assert not (tmp_path / "x.html").exists()


def test_cli_renamed_column_says_the_names_are_inconsistent(tmp_path):
    csv = _write_csv(tmp_path / "t.csv", make_trajectory())
    text = csv.read_text()
    csv.write_text(text.replace("q_joint_2,", "q_jnt_2,", 1))  # the q_ block only
    result = _invoke_replay("--urdf", URDF, "--trajectory", csv, "--html", tmp_path / "x.html")
    assert result.exit_code == 2
    message = " ".join(result.output.split())
    assert "inconsistent joint names across the column blocks" in message
    assert "[q_jnt_2, dq_joint_2, ddq_joint_2]" in message
    assert "missing" not in message


def test_cli_replays_a_position_only_csv_like_the_full_one(tmp_path):
    traj = make_trajectory()
    full = _write_csv(tmp_path / "full.csv", traj)
    positions = tmp_path / "positions.csv"
    header = "t," + ",".join(f"q_{j}" for j in JOINTS)
    np.savetxt(
        positions, np.column_stack([traj.t, traj.q]), delimiter=",", header=header, comments=""
    )
    pages = {}
    for csv in (full, positions):
        out = tmp_path / f"{csv.stem}.html"
        result = _invoke_replay("--urdf", URDF, "--trajectory", csv, "--html", out)
        assert result.exit_code == 0, result.output
        pages[csv.stem] = animation_of(html_commands(out.read_text()))
    # The replay uses positions only: the same keyframes, and the DH reference motion.
    path = "/meshcat/replay/robot_0/marker"
    _, expected, _ = track(pages["full"], path, "position")
    _, got, _ = track(pages["positions"], path, "position")
    np.testing.assert_allclose(got, expected, atol=1e-12)
    # keyframe k (30 /s) shows sample 2 k (60 Hz)
    np.testing.assert_allclose(got, [dh_flange(q) for q in traj.q[::2]], atol=1e-9)


def _children(pid: int) -> list[int]:
    """Child processes of ``pid`` (Linux /proc)."""
    out = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        out += [int(c) for c in (task / "children").read_text().split()]
    return out


def _read_line_with(proc, needle: str, timeout: float) -> str:
    """First stdout line of ``proc`` containing ``needle`` (a reader thread: no pipe stall)."""
    import queue
    import threading

    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=lambda: [lines.put(x) for x in proc.stdout], daemon=True).start()
    seen = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=0.2)
        except queue.Empty:
            if proc.poll() is not None:
                break
            continue
        seen.append(line)
        if needle in line:
            return line
    proc.kill()
    raise AssertionError(f"no line with {needle!r}; stdout {seen}, stderr {proc.stderr.read()}")


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
@pytest.mark.parametrize("stop_signal", ["SIGINT", "SIGTERM"])
def test_cli_live_server_loopback_next_free_port_and_clean_stop(tmp_path, stop_signal):
    import signal
    import socket
    import subprocess
    import sys
    import urllib.request

    from ident.viz.server import find_free_port

    run = make_run_dir(tmp_path)
    busy_port = find_free_port(7600)
    with socket.socket() as busy:  # a port in use on 127.0.0.1: the server takes the next one
        busy.bind(("127.0.0.1", busy_port))
        busy.listen()
        proc = subprocess.Popen(
            [sys.executable, "-c", "from ident.cli import main; main()"]
            + ["replay", str(run), "--port", str(busy_port)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            # a user's shell gives Ctrl-C its default action; a test runner's worker may ignore
            # SIGINT, and an ignored SIGINT is inherited (Python then never raises
            # KeyboardInterrupt): the child gets the shell's disposition back
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        try:
            line = _read_line_with(proc, "http://", timeout=60)
            url = line.split()[1]
            port = int(url.split(":")[2].split("/")[0])
            assert url == f"http://127.0.0.1:{port}/static/"
            assert port > busy_port
            with urllib.request.urlopen(url, timeout=5) as response:
                assert response.status == 200
                assert b"MeshCat.Viewer" in response.read()
            # The server is a thread of the command: no process that could outlive it.
            assert _children(proc.pid) == []
            proc.send_signal(getattr(signal, stop_signal))  # Ctrl-C or kill
            assert proc.wait(timeout=20) == 130
            assert "interrupted" in proc.stderr.read()
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(("127.0.0.1", port), timeout=2).close()
