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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import meshcat
import meshcat.geometry as mg
import numpy as np
import numpy.typing as npt
import pinocchio as pin
from meshcat.animation import Animation
from meshcat.commands import SetAnimation
from pinocchio.visualize import MeshcatVisualizer
from pinocchio.visualize.meshcat_visualizer import loadMesh

from ident.config import file_problem
from ident.errors import DataError, IdentWarning, ModelError
from ident.measure.timebase import find_segments
from ident.model.selection import RobotSelection, load_robot
from ident.robot.meshes import check_urdf_meshes, resolve_urdf_meshes
from ident.robot.urdf_load import build_model, prepare_urdf
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
    "replay_duration",
    "replay_html",
    "replay_segments",
    "run_robot_selection",
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
# Segments of a log drawn as lines of their own (more: one line through all of them).
_MAX_SEGMENT_LINES = 50


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
    robot: str | Path | RobotSelection,
    package_dirs: Sequence[str | Path] = (),
    *,
    package_hint: str = "--package-dir",
) -> tuple[pin.Model, pin.GeometryModel, bool]:
    """Load the kinematics and visual geometry of a robot selection (a URDF and its chain).

    The robot is chosen as for the identification (:func:`ident.model.selection.load_robot`:
    the chain ``base_link``..``tip_link``, the locked joints and their values); the visual
    geometry is the whole URDF's, with the links behind locked joints fixed at their lock
    values (Pinocchio's reduced model and geometry, ``pin.buildReducedModel``), so a hand
    locked half open is drawn half open and moves with the arm.

    Parameters
    ----------
    robot :
        A URDF file (nothing locked) or a :class:`~ident.model.selection.RobotSelection`
        with resolved paths. Meshes may be ``package://`` URIs or paths relative to the URDF.
    package_dirs :
        More folders that contain the ``package://`` roots, searched after the selection's
        ``package_dirs`` (the URDF's folder and its parent are always searched).
    package_hint :
        The option that gives mesh folders in the calling command, named in the warning
        when meshes are missing (``--package-dir``, or ``robot.package_dirs`` of a config).

    Returns
    -------
    model, visual_model, fallback :
        Pinocchio model of the moving joints (the selection's chain, locked joints removed;
        continuous joints as revolute), visual geometry model and whether the geometry is a
        stick figure built from the kinematics (URDF without visuals, or with meshes that
        cannot be found: an :class:`IdentWarning` names the missing file and the option).

    Raises
    ------
    ModelError
        The file does not exist, is not a URDF Pinocchio can parse, or the selection is not
        a serial chain (the message names the joints to lock).
    """
    selection = robot if isinstance(robot, RobotSelection) else RobotSelection(urdf=Path(robot))
    if selection.urdf is None:
        raise ModelError(f"{selection.path}: the replay needs a URDF (robot.urdf).")
    urdf_path = Path(selection.urdf)
    problem = file_problem(urdf_path)
    if problem is not None:
        raise ModelError(f"{urdf_path}: URDF file {problem}.")
    dirs = _mesh_folders(urdf_path, package_dirs, selection.package_dirs)
    # the identification's robot: its checks, chain and lock values (inertials not needed)
    robot_model = load_robot(selection.model_copy(update={"inertia_check": False}))
    text = robot_model.urdf_text  # xacro expanded
    pinocchio_text = prepare_urdf(text, str(urdf_path)).text
    model = build_model(pinocchio_text, str(urdf_path))
    visual_model = _urdf_geometry(model, urdf_path, pinocchio_text, dirs, package_hint)
    if visual_model is None:
        return robot_model.model, stick_figure(robot_model.model), True
    if robot_model.locked_joints:
        model, visual_model = _lock_joints(model, visual_model, dict(robot_model.locked_joints))
    if len(visual_model.geometryObjects) == 0:
        return model, stick_figure(model), True
    return model, visual_model, False


def _mesh_folders(
    urdf_path: Path, package_dirs: Sequence[str | Path], selection_dirs: Sequence[str | Path]
) -> list[str]:
    """Folders searched for ``package://`` meshes, in order: ``package_dirs``, the selection's
    ``package_dirs``, the URDF's folder and its parent (absolute)."""
    dirs = [str(Path(d)) for d in (*package_dirs, *selection_dirs)]
    return dirs + [str(urdf_path.parent.resolve()), str(urdf_path.parent.resolve().parent)]


def _urdf_geometry(
    model: pin.Model, urdf_path: Path, text: str, dirs: list[str], package_hint: str
) -> pin.GeometryModel | None:
    """The URDF's visual geometry of the full ``model``, else its collision geometry.

    The meshes are found by :func:`ident.robot.meshes.resolve_urdf_meshes` (the resolver of
    every loader) and checked before coal loads them (a broken file is never a segfault).
    When a visual mesh is missing, an :class:`IdentWarning` (attributed to the caller of
    :func:`load_visual_robot`) names the first missing files, their count and
    ``package_hint``, and the collision geometry is used when all of it is found; ``None``
    otherwise (or when it is empty): the caller shows a stick figure of the frames. A URDF
    without visuals gives an empty model. ``text``: the URDF as Pinocchio reads it
    (:func:`ident.robot.urdf_load.prepare_urdf`: a xacro file expanded).
    """
    resolved = resolve_urdf_meshes(text, dirs, urdf_path.parent)
    check_urdf_meshes(resolved.text, collision=False, name=str(urdf_path))  # before coal
    missing = resolved.missing_line("visual", str(urdf_path))
    if not missing:
        return pin.buildGeomFromUrdfString(model, resolved.text, pin.GeometryType.VISUAL)
    collision = pin.GeometryModel()
    if not resolved.missing_line("collision", str(urdf_path)):
        check_urdf_meshes(resolved.text, visual=False, name=str(urdf_path))  # before coal
        collision = pin.buildGeomFromUrdfString(model, resolved.text, pin.GeometryType.COLLISION)
    # stacklevel 3: the warning names the caller of load_visual_robot
    if len(collision.geometryObjects) == 0:
        warnings.warn(
            f"{missing}; showing a stick figure of the kinematic chain instead. Give the "
            f"folder that holds them with {package_hint}.",
            IdentWarning,
            stacklevel=3,
        )
        return None
    warnings.warn(
        f"{missing}; showing the collision geometry instead (the visual meshes' folder is "
        f"given with {package_hint}).",
        IdentWarning,
        stacklevel=3,
    )
    return collision


def _lock_joints(
    model: pin.Model, visual_model: pin.GeometryModel, locked: Mapping[str, float]
) -> tuple[pin.Model, pin.GeometryModel]:
    """Pinocchio's reduced model and geometry with the joints of ``locked`` held at their
    values [rad or m] (the other joints at their neutral configuration)."""
    reference = pin.neutral(model)
    for name, value in locked.items():
        reference[model.joints[model.getJointId(name)].idx_q] = value
    ids = [model.getJointId(name) for name in locked]
    return pin.buildReducedModel(model, visual_model, ids, reference)


def run_robot_selection(
    run_dir: str | Path,
    robot: Mapping[str, Any] | RobotSelection | None,
    package_dirs: Sequence[str | Path] = (),
) -> RobotSelection:
    """The robot selection of a run folder's ``robot.urdf`` (the copy of the run's URDF).

    Parameters
    ----------
    run_dir :
        The run folder; its ``robot.urdf`` is the file loaded.
    robot :
        The run config's ``robot`` section with resolved paths (``result.json``'s
        ``config.robot``, or the :class:`RobotSelection` itself), or ``None``.
    package_dirs :
        Folders searched first for ``package://`` meshes.

    Returns
    -------
    :
        The run's chain, locked joints and their values, on ``robot.urdf``; mesh folders:
        ``package_dirs``, the section's ``package_dirs``, then the original URDF's folder and
        its parent (meshes given relative to the original file). A DH description or no
        section: ``robot.urdf`` alone.

    Raises
    ------
    ModelError
        The section is not a valid robot selection (a damaged ``result.json``).
    """
    urdf = Path(run_dir) / "robot.urdf"
    dirs = [Path(d) for d in package_dirs]
    if robot is None:
        return RobotSelection(urdf=urdf, package_dirs=dirs)
    try:
        selection = (
            robot if isinstance(robot, RobotSelection) else RobotSelection.model_validate(robot)
        )
    except ValueError as e:  # pydantic's ValidationError is a ValueError
        raise ModelError(f"{run_dir}: the run's robot section is not valid ({e}).") from e
    if selection.urdf is None:  # a DH description: robot.urdf is generated, nothing locked
        return RobotSelection(urdf=urdf, package_dirs=dirs)
    original = Path(selection.urdf)
    dirs += [*selection.package_dirs, original.parent, original.parent.parent]
    return selection.model_copy(update={"urdf": urdf, "package_dirs": dirs})


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


def default_traced_frame(model: pin.Model, tip_link: str | None = None) -> str:
    """Frame traced when none is given: ``flange``, ``tool0``, ...; else the last frame on the
    body of ``tip_link`` (the chain's tip: its tool, a locked hand's centre), else the last
    frame."""
    for name in _PREFERRED_TRACED_FRAMES:
        if model.existFrame(name):
            return name
    if tip_link is not None and model.existFrame(tip_link):
        joint = model.frames[model.getFrameId(tip_link)].parentJoint
        return [f.name for f in model.frames if f.parentJoint == joint][-1]
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
        raise _joint_mismatch(names, model_joints, trajectory.source, urdf_path)
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


def _joint_mismatch(
    names: list[str], model_joints: list[str], source: str | None, urdf_path: str | Path | None
) -> DataError:
    """The error naming how the trajectory's joints (from the CSV ``source``) differ from the
    URDF's, and the fix."""
    missing = [j for j in model_joints if j not in names]
    extra = [j for j in names if j not in model_joints]
    csv = f"trajectory {source}" if source else "the trajectory"
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
    lock = (
        "; or hold the joints the trajectory does not move fixed (--lock NAME=VALUE, "
        "robot.lock in a config)"
        if missing and not extra
        else ""
    )
    return DataError(
        f"{what} ({'; '.join(details)}); the q_<joint> columns must name the URDF's "
        "joints (any order): rename the columns or use the URDF of the robot that made "
        f"the trajectory{lock}."
    )


def replay_segments(t: npt.ArrayLike) -> list[tuple[int, int]]:
    """Sample ranges of a trajectory that are replayed one after another.

    A log is split where its time stops increasing (a backwards jump: two runs appended, a
    clock reset) and at gaps (a step longer than :data:`ident.measure.timebase.GAP_FACTOR`
    median steps, the rule of the log readers, :func:`ident.measure.timebase.find_segments`):
    the replay shows each segment at its own speed and skips the time between them.

    Parameters
    ----------
    t :
        Time stamps [s], shape (n_samples,).

    Returns
    -------
    :
        ``[(start, stop), ...]`` index ranges covering ``0..n_samples`` in order.
    """
    t = np.asarray(t, dtype=float)
    backwards = np.flatnonzero(np.diff(t) <= 0.0) + 1
    bounds = [0, *backwards.tolist(), t.size]
    out: list[tuple[int, int]] = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        out += [(a + c, a + d) for c, d in find_segments(t[a:b])]
    return out


def replay_duration(t: npt.ArrayLike, speed: float = 1.0) -> float:
    """Replay time [s] of a trajectory with time stamps ``t`` [s]: its segments' spans / speed."""
    t = np.asarray(t, dtype=float)
    return sum(float(t[b - 1] - t[a]) for a, b in replay_segments(t)) / speed


def _resample(
    trajectory: JointTrajectory, q: FloatArray, fps: float, speed: float
) -> tuple[FloatArray, list[int]]:
    """Configurations at replay times ``k / fps``, segment after segment.

    Within a segment (:func:`replay_segments`) starting at ``t_s``, replay frame ``k`` shows
    trajectory time ``t_s + k * speed / fps``; the next segment starts at the next frame.
    Returns the configurations, shape (n_frames, nq), and the first frame of each segment.
    """
    parts, starts, n = [], [], 0
    for a, b in replay_segments(trajectory.t):
        t = trajectory.t[a:b] - trajectory.t[a]
        n_frames = int(math.floor(t[-1] / speed * fps + 1e-9)) + 1
        t_frames = np.arange(n_frames) * speed / fps
        out = np.empty((n_frames, q.shape[1]))
        for k in range(q.shape[1]):  # linear interpolation; keyframes are dense (fps >= 10)
            out[:, k] = np.interp(t_frames, t, q[a:b, k])
        parts.append(out)
        starts.append(n)
        n += n_frames
    return np.vstack(parts), starts


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


def _path_lines(
    model: pin.Model, q: FloatArray, segments: list[tuple[int, int]], frame_id: int
) -> list[FloatArray]:
    """The traced frame's positions [m], one (n_points, 3) array per segment (a single one,
    across the segments, beyond :data:`_MAX_SEGMENT_LINES` segments)."""
    if len(segments) == 1 or len(segments) > _MAX_SEGMENT_LINES:
        return [_frame_positions(model, _decimate(q, _MAX_PATH_POINTS), frame_id)]
    budget = max(2, _MAX_PATH_POINTS // len(segments))
    return [_frame_positions(model, _decimate(q[a:b], budget), frame_id) for a, b in segments]


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


@dataclass(frozen=True, eq=False)
class _SceneRobot:
    """The replayed robot: kinematics, visual geometry and traced frame.

    Attributes
    ----------
    model, geometry, fallback :
        As returned by :func:`load_visual_robot`.
    frame_name, frame_id :
        The frame whose path is drawn: its name and Pinocchio id.
    """

    model: pin.Model
    geometry: pin.GeometryModel
    fallback: bool
    frame_name: str
    frame_id: int


def _scene_robot(
    selection: RobotSelection,
    traced_frame: str | None,
    package_dirs: Sequence[str | Path],
    package_hint: str,
) -> _SceneRobot:
    """Load the robot of ``selection`` (:func:`load_visual_robot`) and find the traced frame
    (``None``: :func:`default_traced_frame`). Raises :class:`ModelError`."""
    model, geometry, fallback = load_visual_robot(
        selection, package_dirs, package_hint=package_hint
    )
    name = (
        traced_frame
        if traced_frame is not None
        else default_traced_frame(model, selection.tip_link)
    )
    frame_id = _frame_id(model, name, Path(selection.path))
    return _SceneRobot(model, geometry, fallback, name, frame_id)


@dataclass(frozen=True, eq=False)
class _Motion:
    """One trajectory as the scene draws it.

    Attributes
    ----------
    trajectory, q :
        The trajectory and the model's configurations at its samples, shape (n_samples, nq).
    keyframes :
        Configurations at the replay's keyframes (one per ``1 / fps`` s of replay time),
        shape (n_frames, nq).
    segment_starts :
        First keyframe of each segment of the log (:func:`replay_segments`).
    path_lines :
        The traced frame's positions [m], one (n_points, 3) array per line drawn.
    points :
        Joint origins at every keyframe, then the traced path's points [m], shape (n, 3),
        in the robot's own frame: what the spacing and the camera must show.
    """

    trajectory: JointTrajectory
    q: FloatArray
    keyframes: FloatArray
    segment_starts: list[int]
    path_lines: list[FloatArray]
    points: FloatArray


def _replay_motions(
    robot: _SceneRobot,
    trajectories: Sequence[JointTrajectory],
    fps: float,
    speed: float,
    urdf_path: Path,
) -> list[_Motion]:
    """Keyframes, traced path and extent of each trajectory, replayed at ``fps`` keyframes
    per second [1/s] and ``speed``. Raises :class:`DataError` (joints that do not match the
    URDF at ``urdf_path``: :func:`joint_configurations`, every trajectory checked first)."""
    model = robot.model
    configurations = [joint_configurations(model, t, urdf_path=urdf_path) for t in trajectories]
    motions = []
    for trajectory, q in zip(trajectories, configurations, strict=True):
        keyframes, starts = _resample(trajectory, q, fps, speed)
        # the traced path, one line per segment (at most _MAX_SEGMENT_LINES, else one line)
        lines = _path_lines(model, q, replay_segments(trajectory.t), robot.frame_id)
        joints = _joint_positions(model, keyframes).reshape(-1, 3)
        points = np.vstack([joints, np.vstack(lines)])
        motions.append(_Motion(trajectory, q, keyframes, starts, lines, points))
    return motions


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
