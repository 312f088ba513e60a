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
"""

from __future__ import annotations

import difflib
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

from ident.errors import DataError, IdentWarning, ModelError
from ident.robot.meshes import check_urdf_meshes
from ident.trajectory import JointTrajectory
from ident.viz.environment import (
    CLOSEST_COLOR,
    ClearanceMark,
    ReplayEnvironment,
    draw_environment,
)
from ident.viz.recorder import SceneRecorder

__all__ = [
    "DEFAULT_FPS",
    "ReplayScene",
    "build_replay_scene",
    "default_traced_frame",
    "joint_configurations",
    "load_visual_robot",
    "replay_html",
]

FloatArray = npt.NDArray[np.float64]

DEFAULT_FPS = 30.0
# Frames tried, in order, when no traced frame is given (the paper robot's flange first).
_PREFERRED_TRACED_FRAMES = ("flange", "tool0", "tool", "ee_link", "wrist_centre")
# Line colours of robots 0, 1, ... (0xRRGGBB), cycled: dark and saturated, so they stand out
# on meshcat's light sky and on the grey floor (no white, no yellow).
_PATH_COLORS = (0xC2255C, 0x1971C2, 0x2B8A3E, 0xD9480F, 0x6741D9, 0x0B7285)
_ROOT = "replay"
# Keep the path line light: a 1 kHz, 60 s log is decimated to at most this many points.
_MAX_PATH_POINTS = 4000


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


def load_visual_robot(
    urdf_path: str | Path, package_dirs: Sequence[str | Path] = ()
) -> tuple[pin.Model, pin.GeometryModel, bool]:
    """Load a URDF's kinematics and visual geometry.

    Parameters
    ----------
    urdf_path :
        URDF file; meshes may be given as ``package://`` URIs or paths relative to the URDF.
    package_dirs :
        Directories that contain the ``package://`` roots (the URDF's folder and its parent
        are always searched).

    Returns
    -------
    model, visual_model, fallback :
        Pinocchio model, visual geometry model and whether the geometry is a stick figure
        built from the kinematics (URDF without visuals, or with meshes that cannot be found:
        an :class:`IdentWarning` names the missing file).

    Raises
    ------
    ModelError
        The file does not exist or is not a URDF Pinocchio can parse.
    """
    urdf_path = Path(urdf_path)
    if not urdf_path.is_file():
        raise ModelError(f"{urdf_path}: URDF file not found.")
    dirs = [str(Path(d)) for d in package_dirs]
    dirs += [str(urdf_path.parent.resolve()), str(urdf_path.parent.resolve().parent)]
    try:
        model = pin.buildModelFromUrdf(str(urdf_path))
    except (RuntimeError, ValueError) as e:
        raise ModelError(f"{urdf_path}: not a valid URDF for Pinocchio: {e}") from e
    check_urdf_meshes(urdf_path, dirs, collision=False)  # before coal: never a segfault
    try:
        visual_model = pin.buildGeomFromUrdf(
            model, str(urdf_path), pin.GeometryType.VISUAL, package_dirs=dirs
        )
    except (RuntimeError, ValueError) as e:
        warnings.warn(
            f"{urdf_path}: cannot load the visual geometry ({e}); showing a stick figure of "
            "the kinematic chain instead. Pass the folder that contains the mesh package "
            "with --package-dir.",
            IdentWarning,
            stacklevel=2,
        )
        return model, stick_figure(model), True
    if len(visual_model.geometryObjects) == 0:
        return model, stick_figure(model), True
    return model, visual_model, False


def _characteristic_length(model: pin.Model) -> float:
    """Sum of the joint and frame offsets [m]: the size of the robot when stretched."""
    length = sum(float(np.linalg.norm(p.translation)) for p in model.jointPlacements)
    tips = [f for f in model.frames if f.type == pin.FrameType.BODY or f.type == pin.OP_FRAME]
    length += max((float(np.linalg.norm(f.placement.translation)) for f in tips), default=0.0)
    return max(length, 0.1)


def stick_figure(model: pin.Model) -> pin.GeometryModel:
    """Visual geometry made of the kinematics: a sphere per joint, a cylinder per link.

    Used when a URDF has no visuals or its meshes are missing, so the motion stays visible.
    """
    import coal  # Pinocchio's geometry library, installed with pin

    size = _characteristic_length(model)
    radius = float(np.clip(0.02 * size, 0.005, 0.05))
    geometry = pin.GeometryModel()
    grey, orange = np.array([0.6, 0.6, 0.65, 1.0]), np.array([0.9, 0.45, 0.1, 1.0])

    def segment(name: str, parent_joint: int, start: FloatArray, end: FloatArray) -> None:
        vector = end - start
        length = float(np.linalg.norm(vector))
        if length < 1e-6:
            return
        rotation = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), vector / length)
        placement = pin.SE3(rotation.toRotationMatrix(), (start + end) / 2)
        obj = pin.GeometryObject(name, parent_joint, placement, coal.Cylinder(radius, length))
        obj.meshColor = grey
        geometry.addGeometryObject(obj)

    for j in range(1, model.njoints):
        ball = pin.GeometryObject(
            f"joint_{model.names[j]}", j, pin.SE3.Identity(), coal.Sphere(1.6 * radius)
        )
        ball.meshColor = orange
        geometry.addGeometryObject(ball)
        segment(
            f"link_{model.names[j]}",
            model.parents[j],
            np.zeros(3),
            np.asarray(model.jointPlacements[j].translation),
        )
    # Tip segment: from each leaf joint to its farthest attached frame (flange, tool).
    leaves = set(range(1, model.njoints)) - set(model.parents[1:])
    for leaf in sorted(leaves):
        attached = [f for f in model.frames if f.parentJoint == leaf]
        if attached:
            tip = max(attached, key=lambda f: float(np.linalg.norm(f.placement.translation)))
            segment(f"tip_{tip.name}", leaf, np.zeros(3), np.asarray(tip.placement.translation))
    return geometry


def default_traced_frame(model: pin.Model) -> str:
    """Frame traced when none is given: ``flange``, ``tool0``, ... else the last frame."""
    for name in _PREFERRED_TRACED_FRAMES:
        if model.existFrame(name):
            return name
    return model.frames[len(model.frames) - 1].name


def _frame_id(model: pin.Model, name: str, urdf_path: Path) -> int:
    if model.existFrame(name):
        return int(model.getFrameId(name))
    names = [f.name for f in model.frames]
    close = difflib.get_close_matches(name, names, n=3)
    hint = f" Did you mean {close}?" if close else ""
    raise ModelError(f"{urdf_path}: no frame '{name}' to trace.{hint} Frames: {names}.")


def joint_configurations(
    model: pin.Model, trajectory: JointTrajectory, *, urdf_path: str | Path | None = None
) -> FloatArray:
    """Configurations of ``model`` along a trajectory whose columns are named joints.

    The trajectory's joints are matched to the model's by name (any column order).

    Parameters
    ----------
    model :
        Pinocchio model of a fixed-base robot (revolute, prismatic, continuous joints).
    trajectory :
        Joint positions [rad] or [m], shape (n_samples, n_joints). Its ``source`` (the CSV)
        is named in messages.
    urdf_path :
        The model's URDF, named in messages.

    Returns
    -------
    :
        Configurations, shape (n_samples, model.nq); a continuous joint's angle becomes
        its (cos, sin) pair.

    Raises
    ------
    DataError
        The trajectory's joint names are not exactly the model's 1-DoF joints.
    ModelError
        The model has a joint with more than one degree of freedom (floating base...).
    """
    model_joints = [model.names[j] for j in range(1, model.njoints)]
    multi = [model.names[j] for j in range(1, model.njoints) if model.joints[j].nv != 1]
    if multi:
        raise ModelError(
            f"replay supports 1-DoF joints only; joints {multi} have several degrees of freedom."
        )
    names = list(trajectory.joint_names)
    if sorted(names) != sorted(model_joints):
        missing = [j for j in model_joints if j not in names]
        extra = [j for j in names if j not in model_joints]
        csv = f"trajectory {trajectory.source}" if trajectory.source else "the trajectory"
        urdf = f"URDF {urdf_path}" if urdf_path is not None else "the URDF"
        if len(names) != len(model_joints):
            what = (
                f"{csv} has {len(names)} joints {names}, {urdf} has {len(model_joints)} "
                f"joints {model_joints}"
            )
        else:
            what = f"the joints of {csv} {names} do not match the joints of {urdf} {model_joints}"
        details = [f"missing from the trajectory: {missing}"] if missing else []
        details += [f"unknown to the URDF: {extra}"] if extra else []
        raise DataError(
            f"{what} ({'; '.join(details)}); the q_<joint> columns must name the URDF's "
            "joints (any order): rename the columns or use the URDF of the robot that made "
            "the trajectory."
        )
    q = np.tile(pin.neutral(model), (trajectory.n_samples, 1))
    for column, name in enumerate(names):
        joint = model.joints[model.getJointId(name)]
        angle = trajectory.q[:, column]
        if joint.nq == 1:
            q[:, joint.idx_q] = angle
        else:  # continuous joint: unit complex number (cos, sin)
            q[:, joint.idx_q] = np.cos(angle)
            q[:, joint.idx_q + 1] = np.sin(angle)
    return q


def _resample(trajectory: JointTrajectory, q: FloatArray, fps: float, speed: float) -> FloatArray:
    """Configurations at replay times ``k / fps``: trajectory times ``t0 + k * speed / fps``."""
    t = trajectory.t - trajectory.t[0]
    n_frames = int(math.floor(t[-1] / speed * fps + 1e-9)) + 1
    t_frames = np.arange(n_frames) * speed / fps
    out = np.empty((n_frames, q.shape[1]))
    for k in range(q.shape[1]):  # linear interpolation; keyframes are dense (fps >= 10)
        out[:, k] = np.interp(t_frames, t, q[:, k])
    return out


def _frame_positions(model: pin.Model, q: FloatArray, frame_id: int) -> FloatArray:
    """World positions [m] of a frame, shape (n_samples, 3)."""
    data = model.createData()
    out = np.empty((q.shape[0], 3))
    for k in range(q.shape[0]):  # Pinocchio evaluates one configuration at a time
        pin.framesForwardKinematics(model, data, q[k])
        out[k] = data.oMf[frame_id].translation
    return out


def _joint_positions(model: pin.Model, q: FloatArray) -> FloatArray:
    """World positions [m] of every joint origin, shape (n_samples, njoints, 3)."""
    data = model.createData()
    out = np.empty((q.shape[0], model.njoints, 3))
    for k in range(q.shape[0]):
        pin.forwardKinematics(model, data, q[k])
        out[k] = np.array([m.translation for m in data.oMi])
    return out


def _decimate(points: FloatArray, max_points: int) -> FloatArray:
    if points.shape[0] <= max_points:
        return points
    index = np.unique(np.linspace(0, points.shape[0] - 1, max_points).round().astype(int))
    return points[index]


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
    urdf_path: str | Path,
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
) -> ReplayScene:
    """Record a meshcat scene replaying one or more trajectories of the robot of a URDF.

    Parameters
    ----------
    urdf_path :
        Robot description; visuals from primitives or meshes (``package://`` URIs are looked
        up in ``package_dirs``).
    trajectories :
        Trajectories to replay; one robot each, side by side along world ``y``.
    traced_frame :
        Pinocchio frame whose Cartesian path is drawn (``None``: ``flange``, ``tool0``, ...,
        else the model's last frame).
    speed :
        Replay speed factor (1: true speed, 0.5: half speed).
    loop :
        Repeat the animation forever instead of playing it once.
    fps :
        Keyframes per second of replay time [1/s].
    spacing :
        Distance between robots [m] (``None``: 1.2 times the largest extent of the motion).
    labels :
        Name of each trajectory (default ``trajectory 0``, ...), shown in the page's caption.
    environment :
        Floor and obstacles (:class:`~ident.viz.environment.ReplayEnvironment`; ``None``: a
        floor at z = 0 and no obstacle).
    marks :
        Per trajectory, the moment of its smallest clearance (or ``None``): a sphere at the
        closest link at that time, and a caption line.

    Returns
    -------
    :
        The recorded scene.

    Raises
    ------
    DataError
        No trajectory, or joint names that do not match the URDF.
    ModelError
        Unreadable URDF or unknown traced frame.
    """
    urdf_path = Path(urdf_path)
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
    model, visual_model, fallback = load_visual_robot(urdf_path, package_dirs)
    frame_name = traced_frame if traced_frame is not None else default_traced_frame(model)
    frame_id = _frame_id(model, frame_name, urdf_path)
    configurations = [joint_configurations(model, t, urdf_path=urdf_path) for t in trajectories]

    keyframes = [
        _resample(traj, q, fps, speed) for traj, q in zip(trajectories, configurations, strict=True)
    ]
    paths = [
        _frame_positions(model, _decimate(q, _MAX_PATH_POINTS), frame_id) for q in configurations
    ]
    joints = [_joint_positions(model, q).reshape(-1, 3) for q in keyframes]
    extents = [np.ptp(np.vstack([j, p]), axis=0) for j, p in zip(joints, paths, strict=True)]
    if spacing is None:
        spacing = 1.2 * max(max(float(e.max()) for e in extents), 0.3)

    recorder = SceneRecorder()
    vis = meshcat.Visualizer(window=recorder)
    animation = Animation(default_framerate=fps)
    marker_radius = float(np.clip(0.015 * _characteristic_length(model), 0.004, 0.03))
    robot_paths = []
    camera_points = []
    notes: list[str] = []
    for k, (q_frames, path) in enumerate(zip(keyframes, paths, strict=True)):
        root = f"{_ROOT}/robot_{k}"
        offset = np.array([0.0, k * spacing, 0.0])
        viz = _BakedMeshVisualizer(model, None, visual_model)
        with warnings.catch_warnings():
            # Pinocchio warns through UserWarning for each unsupported geometry; keep them,
            # but not its meshcat-version notice about get_image.
            warnings.filterwarnings("ignore", message=".*get_image.*")
            viz.initViewer(viewer=vis)
            viz.loadViewerModel(rootNodeName=root)
        vis[root].set_transform(pin.SE3(np.eye(3), offset).homogeneous)
        _animate_robot(viz, animation, vis, root, q_frames)

        color = _PATH_COLORS[k % len(_PATH_COLORS)]
        vis[f"{root}/path"].set_object(
            mg.Line(mg.PointsGeometry(path.T.astype(np.float32)), mg.LineBasicMaterial(color=color))
        )
        vis[f"{root}/marker"].set_object(
            mg.Sphere(marker_radius), mg.MeshLambertMaterial(color=color)
        )
        marker_path = _frame_positions(model, q_frames, frame_id)
        for frame, position in enumerate(marker_path):
            with animation.at_frame(vis, frame) as frame_vis:
                frame_vis[f"{root}/marker"].set_transform(pin.SE3(np.eye(3), position).homogeneous)
        robot_paths.append(f"/meshcat/{root}")
        camera_points.append(np.vstack([joints[k], path]) + offset)
        mark = marks[k]
        if mark is not None:
            position = _mark_position(model, trajectories[k], configurations[k], mark)
            if position is not None:
                vis[f"{root}/closest"].set_object(
                    mg.Sphere(2.0 * marker_radius), mg.MeshLambertMaterial(color=CLOSEST_COLOR)
                )
                vis[f"{root}/closest"].set_transform(pin.SE3(np.eye(3), position).homogeneous)
            notes.append(f"robot {k}: {mark.describe()} (red sphere)")

    everything = np.vstack(camera_points)
    environment_paths = draw_environment(
        vis,
        _ROOT,
        [f"{_ROOT}/robot_{k}" for k in range(len(trajectories))],
        environment if environment is not None else ReplayEnvironment(),
        (everything.min(axis=0), everything.max(axis=0)),
    )

    vis.window.send(SetAnimation(animation, play=True, repetitions=math.inf if loop else 1))
    _set_camera(vis, np.vstack(camera_points), len(trajectories))
    duration = max((q.shape[0] - 1) / fps for q in keyframes)
    return ReplayScene(
        recorder=recorder,
        duration=duration,
        robot_paths=tuple(robot_paths),
        traced_frame=frame_name,
        n_visuals=len(visual_model.geometryObjects),
        fallback_geometry=fallback,
        labels=tuple(labels),
        colors=tuple(_PATH_COLORS[k % len(_PATH_COLORS)] for k in range(len(trajectories))),
        environment_paths=environment_paths,
        notes=tuple(notes),
    )


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
    urdf_path: Path,
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
) -> str:
    """Self-contained HTML page replaying trajectories of a robot (meshcat's static export).

    The page inlines meshcat's viewer and the scene (robot, animation, traced path, camera);
    it opens from disk, with no server and no network access. Arguments as in
    :func:`build_replay_scene`. Writing the file is the caller's job
    (``ident.fileio.atomic_write_text``). ``title`` is the page's title (default: ``ident
    replay: <urdf stem>``).
    """
    scene = build_replay_scene(
        urdf_path,
        trajectories,
        traced_frame=traced_frame,
        speed=speed,
        loop=loop,
        fps=fps,
        package_dirs=package_dirs,
        labels=labels,
        environment=environment,
        marks=marks,
    )
    title = title or f"ident replay: {Path(urdf_path).stem}"
    return scene.recorder.static_html(title=title, caption_html=scene.caption_html())
