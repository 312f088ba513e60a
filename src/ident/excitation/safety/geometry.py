"""The robot's collision geometry: loaded once, its convex hulls made once, screened once.

- :func:`_kinematic_model_and_geometry`: the URDF's collision geometry as a Pinocchio
  ``GeometryModel`` on the robot's joints (meshes found by :func:`ident.robot.meshes.
  resolve_urdf_meshes`; :func:`collision_geometry_problem` says why it cannot be checked);
- the caches: :data:`_LOADED` (the last robot's geometry, :func:`_loaded_geometry`),
  :data:`_LOADED_HULLS` (its meshes as convex hulls, :func:`_loaded_hulls`, per model
  :class:`_Hulls`) and :data:`_SCREENED` (the last screening of the exclusion postures,
  :func:`_screen`): ``ident init`` builds three safety models of one robot, and reading,
  convexifying and screening large meshes took seconds each time.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from ident.errors import ModelError
from ident.excitation.family import FloatArray
from ident.excitation.safety.bounds import _sphere_bounds
from ident.excitation.safety.config import _SCREEN_SLACK_M
from ident.excitation.safety.distances import _geometry_data
from ident.robot.meshes import check_urdf_meshes, resolve_urdf_meshes
from ident.robot.mimic import coupled_model
from ident.robot.urdf_load import prepare_urdf

__all__ = ["MESH_FIX", "collision_geometry_problem"]


def _revolute_text(text: str) -> str:
    """The text Pinocchio reads, rewritten as :meth:`ident.Robot.from_urdf` does."""
    return prepare_urdf(text, "the URDF").text


MESH_FIX = (
    "give the folder that holds them with --package-dir / robot.package_dirs, or set "
    "safety.self_collision: false to design without self-collision checks"
)
"""The fix named when collision meshes are missing (every command that builds a safety model)."""


def _urdf_source(robot: Any, urdf: str | Path | None) -> tuple[str, Path | None, str]:
    """The URDF text, its folder (None for text) and the name that locates it in messages."""
    if urdf is None:
        text = getattr(robot, "urdf_text", None)
        if text is None:
            raise ModelError("the robot has no URDF text; pass urdf= (a path or the text).")
        path = getattr(robot, "urdf_path", None)
        return str(text), None if path is None else Path(path).parent, str(path or "the URDF")
    if isinstance(urdf, Path) or (isinstance(urdf, str) and not urdf.lstrip().startswith("<")):
        return Path(urdf).read_text(encoding="utf-8"), Path(urdf).parent, str(urdf)
    return str(urdf), None, "the URDF"


def collision_geometry_problem(robot: Any, package_dirs: Sequence[str | Path] = ()) -> str:
    """Why self-collision cannot be checked for ``robot`` (empty when it can): the missing
    collision meshes (the first three and their count), or a URDF without geometry.

    ``ident init`` asks before it writes ``safety.self_collision``; a safety model with
    self-collision on raises it, with its fix (:data:`MESH_FIX` for missing meshes).
    """
    return _collision_urdf(robot, None, package_dirs)[2][0]


def _collision_urdf(
    robot: Any, urdf: str | Path | None, package_dirs: Sequence[str | Path]
) -> tuple[str, tuple[tuple[str, str], ...], tuple[str, str]]:
    """The URDF text with its collision meshes found (absolute paths; a link's visual geometry
    where its collision geometry is absent or missing), the notes the certificate shows
    (``(link, what)``), and why self-collision cannot be checked and the fix (``('', '')``
    when it can).

    Raises
    ------
    ModelError
        A mesh that would crash coal (:func:`ident.robot.meshes.check_urdf_meshes`).
    """
    text, base, where = _urdf_source(robot, urdf)
    resolved = resolve_urdf_meshes(text, package_dirs, base, visual_for_collision=True)
    check_urdf_meshes(resolved.text, visual=False, name=where)  # before coal: no segfault
    notes = [(link, "visual mesh used for collision") for link in resolved.visual_for_collision]
    lost = dict.fromkeys(m.link for m in resolved.missing if m.kind == "collision")
    notes += [
        (link, "not checked against the floor and obstacles: its collision mesh is missing")
        for link in lost
    ]
    problem = resolved.missing_line("collision", where)
    if problem:
        return resolved.text, tuple(notes), (problem, MESH_FIX)
    if "<collision" not in resolved.text:
        problem = f"{where} has no <collision> or <visual> geometry"
        fix = (
            "add <collision> geometry to its links, or set safety.self_collision: false to "
            "design without self-collision checks"
        )
        return resolved.text, tuple(notes), (problem, fix)
    return resolved.text, tuple(notes), ("", "")


def _kinematic_model_and_geometry(
    robot: Any,
    urdf: str | Path | None,
    package_dirs: Sequence[str | Path],
    self_collision: bool = True,
) -> tuple[pin.Model, pin.GeometryModel, tuple[tuple[str, str], ...]]:
    """Pinocchio model (same joints as ``robot.model``), its collision GeometryModel and the
    geometry notes of :func:`_collision_urdf` (``(link, what)``).

    The meshes reach Pinocchio as absolute paths in the URDF text (:func:`ident.robot.meshes.
    resolve_urdf_meshes`), not through Pinocchio's ``package_dirs``: its own lookup knows
    neither the URDF's folder nor ``file://`` paths of another machine, and one resolver for
    every loader keeps the safety model, the mesh checks and the replay on the same files.
    """
    text, notes, (problem, fix) = _collision_urdf(robot, urdf, package_dirs)
    if problem and self_collision:
        raise ModelError(f"{problem}; {fix}.")
    text = _revolute_text(text)
    full = pin.buildModelFromXML(text)
    try:
        geom = pin.buildGeomFromUrdfString(full, text, pin.GeometryType.COLLISION, None, [])
    except (RuntimeError, ValueError) as e:
        raise ModelError(
            f"cannot load the URDF's collision geometry ({str(e).splitlines()[0]}); {MESH_FIX}."
        ) from e
    names = tuple(robot.model.names[1:])
    if tuple(full.names[1:]) != names:
        locked = dict(getattr(robot, "locked_joints", {}) or {})
        reference = pin.neutral(full)
        for name, value in locked.items():
            reference[full.joints[full.getJointId(name)].idx_q] = value
        ids = [full.getJointId(name) for name in full.names[1:] if name not in names]
        full, geom = pin.buildReducedModel(full, geom, ids, reference)
        if tuple(full.names[1:]) != names:
            raise ModelError(
                f"the URDF's joints {list(full.names[1:])} do not match the robot's {list(names)}"
            )
    # the robot's mimic joints move with their leaders here too (the same q as robot.model)
    mimics = getattr(robot, "mimic_joints", ())
    return (
        coupled_model(full, mimics, str(getattr(robot, "urdf_path", None) or "URDF")),
        geom,
        notes,
    )


_LOADED: dict[
    tuple[Any, ...], tuple[pin.Model, pin.GeometryModel, tuple[tuple[str, str], ...]]
] = {}
_LOADED_HULLS: dict[tuple[Any, ...], pin.GeometryModel] = {}  # the same, meshes as hulls
# the last screening of SafetyModel._screen: its threshold [m] and its bounds
_SCREENED: dict[tuple[Any, ...], tuple[float, FloatArray]] = {}


def _loaded_geometry(
    robot: Any,
    urdf: str | Path | None,
    package_dirs: Sequence[str | Path],
    self_collision: bool = True,
) -> tuple[pin.Model, pin.GeometryModel, tuple[tuple[str, str], ...], tuple[Any, ...]]:
    """:func:`_kinematic_model_and_geometry`, remembered for the last robot (its URDF text,
    joints, locked joints and mesh folders): ``ident init`` builds three safety models of one
    robot, and reading large meshes took seconds each time. Returns copies (the caller adds
    the environment and a payload to them) and the geometry notes."""
    if urdf is None:
        source = getattr(robot, "urdf_text", None)
    elif isinstance(urdf, Path) or not urdf.lstrip().startswith("<"):
        source = Path(urdf).read_text(encoding="utf-8")
    else:
        source = urdf
    key = (
        source,
        tuple(robot.model.names),
        tuple(sorted((getattr(robot, "locked_joints", {}) or {}).items())),
        tuple(str(d) for d in package_dirs),
        self_collision,
    )
    if key not in _LOADED:
        _LOADED.clear()
        _LOADED_HULLS.clear()
        _LOADED[key] = _kinematic_model_and_geometry(robot, urdf, package_dirs, self_collision)
    model, geom, notes = _LOADED[key]
    return model.copy(), geom.clone(), notes, key


def _loaded_hulls(key: tuple[Any, ...], geom: pin.GeometryModel) -> pin.GeometryModel:
    """A copy of ``geom`` with its meshes replaced by their hulls (:func:`_convexify`); the
    first objects, those :func:`_loaded_geometry` loaded under ``key``, from the hulls made
    once per robot, the others (environment, payload: primitives) as they are."""
    if key not in _LOADED_HULLS:
        hulls = _LOADED[key][1].clone()
        _convexify(hulls)
        _LOADED_HULLS[key] = hulls
    out = _LOADED_HULLS[key].clone()
    for obj in list(geom.geometryObjects)[out.ngeoms :]:
        out.addGeometryObject(obj)
    return out


class _Hulls:
    """A model's geometry ``geom`` (robot and environment, before any pair is chosen) with
    every mesh replaced by its convex hull (:func:`_convexify`), made on first use (by
    :func:`_loaded_hulls`, the robot's hulls once per robot ``key``), once per model."""

    def __init__(self, key: tuple[Any, ...], geom: pin.GeometryModel) -> None:
        self.key = key
        self._geom = geom
        self._hull_geometry: pin.GeometryModel | None = None

    def get(self) -> pin.GeometryModel:
        """The hull geometry (made on the first call)."""
        if self._hull_geometry is None:
            self._hull_geometry = _loaded_hulls(self.key, self._geom)
        return self._hull_geometry


def _with_pairs(geom: pin.GeometryModel, pairs: Sequence[tuple[Any, ...]]) -> pin.GeometryModel:
    """``geom`` with exactly the collision pairs ``(a, b, ...)`` of ``pairs`` (in place)."""
    geom.removeAllCollisionPairs()
    for pair in pairs:
        geom.addCollisionPair(pin.CollisionPair(pair[0], pair[1]))
    return geom


def _convexify(geom: pin.GeometryModel) -> None:
    """Replace mesh geometry by its convex hull (GJK/EPA then give penetration depths).

    The hull is computed (qhull through ``buildConvexHull``, facets not triangulated: a
    triangulated hull of a finely tessellated cylinder gives one vertex more neighbours than
    coal stores, "Too many neighbors"). ``buildConvexRepresentation`` would only relabel the
    mesh as convex: for a non-convex mesh the support function's hill climbing then stops at
    local extrema, and distances come out too large (by up to 0.44 m on the UR5's upper arm
    against the floor plane), i.e. unsafe.

    Raises
    ------
    ModelError
        If qhull cannot build a mesh's hull.
    """
    import coal

    for obj in geom.geometryObjects:
        shape = obj.geometry
        if isinstance(shape, coal.BVHModelBase):
            try:
                shape.buildConvexHull(False, "")
            except RuntimeError as e:
                raise ModelError(
                    f"collision mesh of {obj.name}: its convex hull cannot be built "
                    f"({str(e).splitlines()[-1].strip()}); simplify the mesh or give the link a "
                    "primitive <collision> (box, cylinder, sphere)."
                ) from e
            obj.geometry = shape.convex


def _screen(
    model: pin.Model,
    postures: FloatArray,
    clearance_m: float,
    geom: pin.GeometryModel,
    pairs: list[tuple[int, int]],
    hulls: _Hulls,
) -> FloatArray:
    """Lower bounds of the exact distances of the geometry ``pairs`` at the exclusion
    ``postures`` [m], shape (n_postures, n_pairs): their convex hulls' signed distance (meshes
    replaced by their hulls, primitives as they are; a hull contains its mesh) wherever
    the bounding spheres (:func:`_sphere_bounds`, containing the geometry) are within
    the margin ``clearance_m`` (and :data:`_SCREEN_SLACK_M`), the spheres' distance
    elsewhere. ``hulls``: ``geom``'s hulls, made only if a sphere is within the margin."""
    threshold = clearance_m + _SCREEN_SLACK_M
    key = (hulls.key, tuple(pairs), postures.tobytes())
    if key in _SCREENED and _SCREENED[key][0] >= threshold:
        # the same robot, pairs and postures screened at a margin at least as large (init
        # builds three models): every bound there is exact below this one's threshold
        return _SCREENED[key][1].copy()
    out = _sphere_bounds(model, geom, pairs, postures)
    near = out < threshold
    if near.any():
        hull = hulls.get()
        hull.removeAllCollisionPairs()
        for a, b in pairs:
            hull.addCollisionPair(pin.CollisionPair(a, b))
        data, gdata = model.createData(), _geometry_data(hull)
        for s in np.flatnonzero(near.any(axis=1)).tolist():  # coal: one posture at a time
            pin.updateGeometryPlacements(model, data, hull, gdata, postures[s])
            for p in np.flatnonzero(near[s]).tolist():
                out[s, p] = pin.computeDistance(hull, gdata, p).min_distance
        hull.removeAllCollisionPairs()
    _SCREENED.clear()
    _SCREENED[key] = (threshold, out.copy())
    return out
