"""Replay joint trajectories in meshcat: the robot animated at true speed, the traced path drawn.

The scene is built offline (:class:`~ident.viz.recorder.SceneRecorder`): Pinocchio's
``MeshcatVisualizer`` loads the robot's visual geometry from its URDF, the trajectory becomes
a meshcat animation (one keyframe per ``1 / fps`` seconds of replay time, positions and
orientations interpolated by three.js in between), the Cartesian path of the traced frame is a
line, and the camera looks at the whole motion. The same scene is exported as a self-contained
HTML page (:func:`replay_html`) or pushed to a live server (:mod:`ident.viz.server`).

Several trajectories (elites of the optimizer's archive) are shown side by side: one robot per
trajectory, robot ``k`` shifted by ``k`` times a spacing along the world ``y`` axis, all
animations on one time line.

Scene layout (meshcat paths)::

    /meshcat/replay/robot_<k>                     static offset of robot k
    /meshcat/replay/robot_<k>/visuals/<geometry>  animated link geometry (Pinocchio names)
    /meshcat/replay/robot_<k>/path                line through the traced frame's positions
    /meshcat/replay/robot_<k>/marker              animated sphere at the traced frame
    /meshcat/replay/floor                         the floor (:mod:`ident.viz.environment`)
    /meshcat/replay/robot_<k>/environment/<name>  obstacles of robot k
    /meshcat/replay/robot_<k>/closest             closest link at the least clearance

The robot is loaded by :mod:`ident.viz.visual_robot`, the trajectories' keyframes and traced
paths computed by :mod:`ident.viz.motion`; this module records the scene and writes the page.
"""

from __future__ import annotations

import html
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import meshcat
import meshcat.geometry as mg
import numpy as np
import numpy.typing as npt
import pinocchio as pin
from meshcat.animation import Animation
from meshcat.commands import SetAnimation
from pinocchio.visualize import MeshcatVisualizer
from pinocchio.visualize.meshcat_visualizer import loadMesh

from ident.errors import DataError
from ident.model.selection import RobotSelection
from ident.trajectory import JointTrajectory
from ident.viz.environment import (
    CLOSEST_COLOR,
    ClearanceMark,
    ReplayEnvironment,
    draw_environment,
)
from ident.viz.motion import (
    _frame_positions,
    _Motion,
    _replay_motions,
    joint_configurations,
    replay_duration,
    replay_segments,
)
from ident.viz.recorder import SceneRecorder
from ident.viz.visual_robot import (
    _characteristic_length,
    _scene_robot,
    _SceneRobot,
    default_traced_frame,
    load_visual_robot,
    run_robot_selection,
)

__all__ = [
    "DEFAULT_FPS",
    "ReplayScene",
    "build_replay_scene",
    "default_traced_frame",
    "joint_configurations",
    "load_visual_robot",
    "replay_duration",
    "replay_html",
    "replay_segments",
    "run_robot_selection",
]


FloatArray = npt.NDArray[np.float64]


DEFAULT_FPS = 30.0


# Line colours of robots 0, 1, ... (0xRRGGBB), cycled: dark and saturated, so they stand out
# on meshcat's light sky and on the grey floor (no white, no yellow).
_PATH_COLORS = (0xC2255C, 0x1971C2, 0x2B8A3E, 0xD9480F, 0x6741D9, 0x0B7285)


_ROOT = "replay"


@dataclass(frozen=True)
class ReplayScene:
    """A recorded meshcat scene of one or more replayed trajectories.

    Attributes
    ----------
    recorder :
        The recorded meshcat commands; ``recorder.static_html()`` exports them.
    duration :
        Length of the animation in replay time [s] (trajectory duration / speed).
    robot_paths :
        meshcat path of each robot's root node, e.g. ``"/meshcat/replay/robot_0"``.
    traced_frame :
        Name of the Pinocchio frame whose path is drawn.
    n_visuals :
        Number of visual geometries per robot.
    fallback_geometry :
        True when the URDF's visuals could not be loaded and a stick figure is shown.
    labels, colors :
        Name of each robot's trajectory and the colour of its path and marker (0xRRGGBB).
    """

    recorder: SceneRecorder
    duration: float
    robot_paths: tuple[str, ...]
    traced_frame: str
    n_visuals: int
    fallback_geometry: bool
    labels: tuple[str, ...] = ()
    colors: tuple[int, ...] = ()
    environment_paths: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def caption_html(self) -> str:
        """One line per robot: its path colour, label and duration, for the static page."""
        rows = [
            f'<span style="color:#{color:06x}">&#9632;</span> robot {k}: {html.escape(label)}'
            for k, (label, color) in enumerate(zip(self.labels, self.colors, strict=True))
        ]
        head = f"traced frame {html.escape(self.traced_frame)}, {self.duration:.2f} s"
        return "<br>".join([head, *rows, *(html.escape(n) for n in self.notes)])


class _BakedMeshVisualizer(MeshcatVisualizer):
    """Pinocchio's meshcat visualizer that sends meshes as triangles loaded by coal.

    Pinocchio sends Collada files to the browser as they are, and meshcat's viewer 0.3.2
    misplaces the parts of Z-up Collada files (the UR5 falls apart). The triangles coal
    loaded for Pinocchio (with the URDF's mesh scale applied) are what Pinocchio's own
    kinematics use; they are also smaller to embed. Their placement is ``oMg`` without scale.
    """

    def loadMeshFromFile(self, geometry_object: pin.GeometryObject) -> object:  # noqa: N802
        """Return the coal triangle mesh of a mesh file, else Pinocchio's loader."""
        import coal

        if isinstance(geometry_object.geometry, coal.BVHModelBase):
            return loadMesh(geometry_object.geometry)
        return super().loadMeshFromFile(geometry_object)


def _set_camera(vis: meshcat.Visualizer, points: FloatArray, n_robots: int) -> None:
    """Look at the bounding box of ``points`` (world [m], shape (n, 3)) from front-right-above.

    meshcat's orbit controls look at, and turn about, the viewer's origin; so the scene
    (robots, grid, axes) is shifted to put the centre of the motion there. A row of robots
    (along ``y``) is seen nearly from the front, so none hides another.
    """
    lower, upper = points.min(axis=0), points.max(axis=0)
    centre = (lower + upper) / 2
    radius = max(float(np.linalg.norm(upper - lower)) / 2, 0.2)
    direction = np.array([1.0, -1.1, 0.7]) if n_robots == 1 else np.array([1.0, -0.3, 0.55])
    # The 75 deg vertical field of view sees a sphere of radius R from 1.64 R.
    offset = 1.7 * radius * direction / np.linalg.norm(direction)
    shift = pin.SE3(np.eye(3), -centre).homogeneous
    for node in (_ROOT, "/Grid", "/Axes"):
        vis[node].set_transform(shift)
    # The camera object lives in /Cameras/default/rotated (three.js y-up), where world
    # (x, y, z) is (x, z, -y).
    vis["/Cameras/default/rotated/<object>"].set_property(
        "position", [float(offset[0]), float(offset[2]), float(-offset[1])]
    )


def build_replay_scene(
    robot: str | Path | RobotSelection,
    trajectories: Sequence[JointTrajectory],
    *,
    traced_frame: str | None = None,
    speed: float = 1.0,
    loop: bool = True,
    fps: float = DEFAULT_FPS,
    package_dirs: Sequence[str | Path] = (),
    spacing: float | None = None,
    labels: Sequence[str] | None = None,
    environment: ReplayEnvironment | None = None,
    marks: Sequence[ClearanceMark | None] | None = None,
    package_hint: str = "--package-dir",
) -> ReplayScene:
    """Record a meshcat scene replaying one or more trajectories of the robot of a URDF.

    Parameters
    ----------
    robot :
        A URDF, or a robot selection (:class:`~ident.model.selection.RobotSelection`: the
        chain, the locked joints and their values, ``package_dirs``) as the identification
        uses it (:func:`load_visual_robot`); visuals from primitives or meshes
        (``package://`` URIs are looked up in the selection's and ``package_dirs``).
    trajectories :
        Trajectories of the moving joints to replay; one robot each, side by side along
        world ``y``. A trajectory whose time jumps backwards or has gaps is replayed segment
        after segment (:func:`replay_segments`), each start named in the caption.
    traced_frame :
        Pinocchio frame whose Cartesian path is drawn (``None``: ``flange``, ``tool0``, ...,
        else the model's last frame).
    speed, loop, fps :
        Replay speed factor (1: true speed, 0.5: half speed); repeat the animation forever
        instead of playing it once; keyframes per second of replay time [1/s].
    spacing, labels :
        Distance between robots [m] (``None``: 1.2 times the largest extent of the motion);
        name of each trajectory (default ``trajectory 0``, ...), shown in the page's caption.
    environment, marks :
        Floor and obstacles (:class:`~ident.viz.environment.ReplayEnvironment`; ``None``: a
        floor at z = 0 and no obstacle); per trajectory, the moment of its smallest clearance
        (or ``None``): a sphere at the closest link at that time, and a caption line.
    package_hint :
        The option of the calling command that gives mesh folders, named in the warning when
        meshes are missing.

    Returns the recorded scene. Raises :class:`DataError` (no trajectory, joint names not the
    URDF's) or :class:`ModelError` (unreadable URDF, unknown traced frame).
    """
    selection = robot if isinstance(robot, RobotSelection) else RobotSelection(urdf=Path(robot))
    labels, marks = _checked_scene_options(trajectories, speed, fps, labels, marks)
    scene_robot = _scene_robot(selection, traced_frame, package_dirs, package_hint)
    motions = _replay_motions(scene_robot, trajectories, fps, speed, Path(selection.path))
    env = environment if environment is not None else ReplayEnvironment()
    return _record_scene(
        scene_robot, motions, labels, marks, spacing=spacing, fps=fps, loop=loop, environment=env
    )


def _checked_scene_options(
    trajectories: Sequence[JointTrajectory],
    speed: float,
    fps: float,
    labels: Sequence[str] | None,
    marks: Sequence[ClearanceMark | None] | None,
) -> tuple[Sequence[str], Sequence[ClearanceMark | None]]:
    """Check the replay options of :func:`build_replay_scene`; the labels and marks, one per
    trajectory (defaults: ``trajectory <k>`` and no mark). Raises :class:`DataError`."""
    if len(trajectories) == 0:
        raise DataError("no trajectory to replay.")
    if not (math.isfinite(speed) and speed > 0.0):
        raise DataError(f"speed = {speed} must be a positive factor (1 = true speed).")
    if labels is None:
        labels = [f"trajectory {k}" for k in range(len(trajectories))]
    if len(labels) != len(trajectories):
        raise DataError(f"{len(labels)} labels for {len(trajectories)} trajectories.")
    if marks is None:
        marks = [None] * len(trajectories)
    if len(marks) != len(trajectories):
        raise DataError(f"{len(marks)} clearance marks for {len(trajectories)} trajectories.")
    if not (math.isfinite(fps) and fps >= 1.0):
        raise DataError(f"fps = {fps} must be >= 1 keyframe per second.")
    return labels, marks


def _record_scene(
    robot: _SceneRobot,
    motions: list[_Motion],
    labels: Sequence[str],
    marks: Sequence[ClearanceMark | None],
    *,
    spacing: float | None,
    fps: float,
    loop: bool,
    environment: ReplayEnvironment,
) -> ReplayScene:
    """Record the scene: robot ``k`` (its motion, traced path, marker, clearance mark)
    shifted by ``k * spacing`` [m] along world ``y``, the environment, the camera.

    ``spacing=None``: 1.2 times the largest extent of the motions (at least 0.3 m). Other
    arguments as in :func:`build_replay_scene`.
    """
    if spacing is None:
        spacing = 1.2 * max(max(float(np.ptp(m.points, axis=0).max()) for m in motions), 0.3)
    recorder = SceneRecorder()
    vis = meshcat.Visualizer(window=recorder)
    animation = Animation(default_framerate=fps)
    marker_radius = float(np.clip(0.015 * _characteristic_length(robot.model), 0.004, 0.03))
    roots = [f"{_ROOT}/robot_{k}" for k in range(len(motions))]
    camera_points = []
    notes: list[str] = []
    for k, (root, motion, mark) in enumerate(zip(roots, motions, marks, strict=True)):
        offset = np.array([0.0, k * spacing, 0.0])
        _draw_robot(vis, animation, robot, root, offset, motion.keyframes)
        _draw_traced_path(vis, animation, robot, root, motion, _path_color(k), marker_radius)
        camera_points.append(motion.points + offset)
        if mark is not None:
            position = _mark_position(robot.model, motion.trajectory, motion.q, mark)
            if position is not None:
                _draw_closest(vis, root, position, 2.0 * marker_radius)
            notes.append(f"robot {k}: {mark.describe()} (red sphere)")
        notes += _segment_notes(k, motion.segment_starts, fps)
    everything = np.vstack(camera_points)
    bounds = (everything.min(axis=0), everything.max(axis=0))
    environment_paths = draw_environment(vis, _ROOT, roots, environment, bounds)
    vis.window.send(SetAnimation(animation, play=True, repetitions=math.inf if loop else 1))
    _set_camera(vis, everything, len(motions))
    return ReplayScene(
        recorder=recorder,
        duration=max((m.keyframes.shape[0] - 1) / fps for m in motions),
        robot_paths=tuple(f"/meshcat/{root}" for root in roots),
        traced_frame=robot.frame_name,
        n_visuals=len(robot.geometry.geometryObjects),
        fallback_geometry=robot.fallback,
        labels=tuple(labels),
        colors=tuple(_path_color(k) for k in range(len(motions))),
        environment_paths=environment_paths,
        notes=tuple(notes),
    )


def _path_color(k: int) -> int:
    """Colour (0xRRGGBB) of robot ``k``'s path and marker."""
    return _PATH_COLORS[k % len(_PATH_COLORS)]


def _draw_robot(
    vis: meshcat.Visualizer,
    animation: Animation,
    robot: _SceneRobot,
    root: str,
    offset: FloatArray,
    keyframes: FloatArray,
) -> None:
    """Load the robot's visual geometry under ``root``, placed at ``offset`` [m] (world,
    shape (3,)), and animate it through ``keyframes`` (shape (n_frames, nq))."""
    viz = _BakedMeshVisualizer(robot.model, None, robot.geometry)
    with warnings.catch_warnings():
        # Pinocchio warns through UserWarning for each unsupported geometry; keep them,
        # but not its meshcat-version notice about get_image.
        warnings.filterwarnings("ignore", message=".*get_image.*")
        viz.initViewer(viewer=vis)
        viz.loadViewerModel(rootNodeName=root)
    vis[root].set_transform(pin.SE3(np.eye(3), offset).homogeneous)
    _animate_robot(viz, animation, vis, root, keyframes)


def _draw_traced_path(
    vis: meshcat.Visualizer,
    animation: Animation,
    robot: _SceneRobot,
    root: str,
    motion: _Motion,
    color: int,
    marker_radius: float,
) -> None:
    """Draw the traced frame's path (``root/path``, ``root/path_2``, ...) and a sphere of
    ``marker_radius`` [m] (``root/marker``) that follows the frame, keyframe by keyframe."""
    for s, line in enumerate(motion.path_lines):
        vis[f"{root}/path" + (f"_{s + 1}" if s else "")].set_object(
            mg.Line(
                mg.PointsGeometry(line.T.astype(np.float32)),
                mg.LineBasicMaterial(color=color),
            )
        )
    vis[f"{root}/marker"].set_object(mg.Sphere(marker_radius), mg.MeshLambertMaterial(color=color))
    marker_path = _frame_positions(robot.model, motion.keyframes, robot.frame_id)
    for frame, position in enumerate(marker_path):
        with animation.at_frame(vis, frame) as frame_vis:
            frame_vis[f"{root}/marker"].set_transform(pin.SE3(np.eye(3), position).homogeneous)


def _draw_closest(vis: meshcat.Visualizer, root: str, position: FloatArray, radius: float) -> None:
    """A sphere of ``radius`` [m] (``root/closest``) at ``position`` [m], shape (3,): the
    closest link at the least clearance."""
    vis[f"{root}/closest"].set_object(
        mg.Sphere(radius), mg.MeshLambertMaterial(color=CLOSEST_COLOR)
    )
    vis[f"{root}/closest"].set_transform(pin.SE3(np.eye(3), position).homogeneous)


def _segment_notes(k: int, starts: list[int], fps: float) -> list[str]:
    """Caption line of robot ``k`` when its log has several segments starting at keyframes
    ``starts`` (keyframes per second ``fps`` [1/s]); none for one segment."""
    if len(starts) <= 1:
        return []
    at = ", ".join(f"{s / fps:.2f} s" for s in starts[1:])
    return [
        f"robot {k}: {len(starts)} segments of the log (split at gaps or backwards "
        f"time jumps), replayed one after another; segments 2.. start at {at}"
    ]


def _mark_position(
    model: pin.Model, trajectory: JointTrajectory, q: FloatArray, mark: ClearanceMark
) -> FloatArray | None:
    """Position [m] of the first frame named in ``mark.pair`` at ``mark.time`` (or None)."""
    frame = next((n for n in mark.pair.split("|") if model.existFrame(n)), None)
    if frame is None or not math.isfinite(mark.time):
        return None
    at = np.array([np.interp(mark.time, trajectory.t, q[:, k]) for k in range(q.shape[1])])
    return _frame_positions(model, at[None, :], int(model.getFrameId(frame)))[0]


def _animate_robot(
    viz: MeshcatVisualizer,
    animation: Animation,
    vis: meshcat.Visualizer,
    root: str,
    q_frames: FloatArray,
) -> None:
    """Add one keyframe per configuration for every visual geometry of ``viz``.

    The static pose (shown before the animation starts) is the first configuration. Mesh
    scales are baked into the vertices (:class:`_BakedMeshVisualizer`), primitives have
    their size in the geometry: placements carry no scale.
    """
    model, data = viz.model, viz.data
    geom_model, geom_data = viz.visual_model, viz.visual_data
    names = [f"{root}/visuals/{g.name}" for g in geom_model.geometryObjects]
    for frame, q in enumerate(q_frames):
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, geom_model, geom_data)
        if frame == 0:
            for gid, name in enumerate(names):
                vis[name].set_transform(geom_data.oMg[gid].homogeneous)
        with animation.at_frame(vis, frame) as frame_vis:
            for gid, name in enumerate(names):
                frame_vis[name].set_transform(geom_data.oMg[gid].homogeneous)


def replay_html(
    robot: str | Path | RobotSelection,
    trajectories: Sequence[JointTrajectory],
    *,
    traced_frame: str | None = None,
    speed: float = 1.0,
    package_dirs: Sequence[Path] = (),
    loop: bool = True,
    fps: float = DEFAULT_FPS,
    labels: Sequence[str] | None = None,
    environment: ReplayEnvironment | None = None,
    marks: Sequence[ClearanceMark | None] | None = None,
    title: str | None = None,
    package_hint: str = "--package-dir",
) -> str:
    """Self-contained HTML page replaying trajectories of a robot (meshcat's static export).

    The page inlines meshcat's viewer and the scene (robot, animation, traced path, camera);
    it opens from disk, with no server and no network access. Arguments as in
    :func:`build_replay_scene`. Writing the file is the caller's job
    (``ident.fileio.atomic_write_text``). ``title`` is the page's title (default: ``ident
    replay: <urdf stem>``).
    """
    scene = build_replay_scene(
        robot,
        trajectories,
        traced_frame=traced_frame,
        speed=speed,
        loop=loop,
        fps=fps,
        package_dirs=package_dirs,
        labels=labels,
        environment=environment,
        marks=marks,
        package_hint=package_hint,
    )
    stem = robot.path.stem if isinstance(robot, RobotSelection) else Path(robot).stem
    title = title or f"ident replay: {stem}"
    return scene.recorder.static_html(title=title, caption_html=scene.caption_html())
