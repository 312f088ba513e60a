"""The robot a replay draws: its kinematics and visual geometry, and the frame whose path is
traced.

:func:`load_visual_robot` loads the chain of a robot selection as the identification does,
with the URDF's visual geometry (its collision geometry, or a :func:`stick_figure` of the
kinematics, when meshes are missing); :func:`run_robot_selection` is the selection of a run
folder's ``robot.urdf``; :func:`default_traced_frame` picks the frame traced when none is
given.
"""

from __future__ import annotations

import difflib
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.config import file_problem
from ident.errors import IdentWarning, ModelError
from ident.model.selection import RobotSelection, load_robot
from ident.robot.meshes import check_urdf_meshes, resolve_urdf_meshes
from ident.robot.urdf_load import build_model, prepare_urdf

__all__ = [
    "default_traced_frame",
    "load_visual_robot",
    "run_robot_selection",
    "stick_figure",
]

FloatArray = npt.NDArray[np.float64]

# Frames tried, in order, when no traced frame is given (the paper robot's flange first).
_PREFERRED_TRACED_FRAMES = ("flange", "tool0", "tool", "ee_link", "wrist_centre")


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
    selection, urdf_path = _selected_urdf(robot)
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


def _selected_urdf(robot: str | Path | RobotSelection) -> tuple[RobotSelection, Path]:
    """The robot selection of ``robot`` (a URDF file: nothing locked) and its URDF file.

    Raises
    ------
    ModelError
        The selection has no URDF (a DH description), or the file cannot be read.
    """
    selection = robot if isinstance(robot, RobotSelection) else RobotSelection(urdf=Path(robot))
    if selection.urdf is None:
        raise ModelError(f"{selection.path}: the replay needs a URDF (robot.urdf).")
    urdf_path = Path(selection.urdf)
    problem = file_problem(urdf_path)
    if problem is not None:
        raise ModelError(f"{urdf_path}: URDF file {problem}.")
    return selection, urdf_path


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
