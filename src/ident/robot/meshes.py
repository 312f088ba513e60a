"""URDF meshes checked in Python before Pinocchio, coal or qhull see them.

Native code does not survive every mesh a URDF may name: qhull's convex hull of a collision
mesh whose triangles lie in one plane, of a mesh with ``<mesh scale="0 0 0">`` or of one with
NaN vertices kills the process (SIGSEGV, no message). :func:`check_urdf_meshes` resolves each
``<mesh>`` of a URDF the way Pinocchio does, loads its vertices (trimesh when installed;
coal's own loader, the one Pinocchio uses, for formats trimesh cannot read such as Collada)
and refuses, with one line naming the link, the file and the fix:

- a scale that is not three finite, non-zero numbers (a zero factor collapses the mesh;
  negative factors, a mirror or a half turn, are fine);
- a file without vertices, or that the loader cannot read;
- NaN or infinite vertex coordinates;
- a mesh more than :data:`MAX_EXTENT_M` across (wrong units);
- for collision meshes (whose convex hull the safety check builds): fewer than four vertices,
  or all vertices on one plane or one line (a zero-volume hull).

Visual meshes may be flat (a decal, a label): only the first three rules apply to them.
A mesh file that does not exist is left to Pinocchio, which reports it.
"""

from __future__ import annotations

import functools
import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ident.errors import ModelError

__all__ = [
    "FLATNESS_TOLERANCE",
    "MAX_EXTENT_M",
    "check_urdf_meshes",
    "mesh_problem",
    "mesh_vertices",
    "resolve_mesh_path",
]

FLATNESS_TOLERANCE = 1e-6
"""A collision mesh is flat when the smallest spread of its vertices (singular value of the
centred vertex array) is below this fraction of the largest. A plane stored in an STL's
single-precision floats spreads by about 2e-8 of its size, and qhull then still crashes;
a part 1e-6 as thick as it is long (1 micrometre per metre) is no part."""

MAX_EXTENT_M = 100.0
"""Largest size of a mesh [m] after its scale: beyond it the units are wrong (millimetres
read as metres, a scale typed in the wrong unit), and coal's arithmetic overflows for absurd
sizes."""

_FIX = (
    "repair the mesh file, or replace the <mesh> by a <box>, <cylinder> or <sphere> that "
    "encloses the part"
)


def resolve_mesh_path(filename: str, package_dirs: Sequence[str | Path]) -> Path | None:
    """The file Pinocchio loads for a URDF ``<mesh filename=...>``, or None if none exists.

    ``package://`` and ``model://`` paths and relative paths are searched in
    ``package_dirs`` then in ``ROS_PACKAGE_PATH`` (in that order, as Pinocchio does);
    ``file://`` and absolute paths are taken as they are. Other schemes give None
    (Pinocchio refuses them itself).
    """
    dirs = [str(d) for d in package_dirs]
    dirs += [p for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    if "://" in filename:
        scheme, rest = filename.split("://", 1)
        if scheme == "file":
            candidates = [Path(rest)]
        elif scheme in ("package", "model"):
            candidates = [Path(d + "/" + rest) for d in dirs]
        else:
            return None
    elif Path(filename).is_absolute():
        candidates = [Path(filename)]
    else:
        candidates = [Path(d + "/" + filename) for d in dirs]
    for path in candidates:
        if path.is_file():
            return path
    return None


@functools.lru_cache(maxsize=256)
def _vertices(path: str, mtime_ns: int, size: int) -> np.ndarray:
    """Vertices [file units] of a mesh file, shape (n_vertices, 3); cached per file version."""
    del mtime_ns, size  # part of the cache key only
    vertices: np.ndarray | None
    try:
        import trimesh  # optional: without it, coal's loader reads every format

        mesh: Any = trimesh.load(path, force="mesh", process=False)
        vertices = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
    except Exception:  # noqa: BLE001 - no trimesh, or a format it lacks (Collada): coal's
        vertices = None
    if vertices is None or (len(vertices) == 0 and not path.lower().endswith((".stl", ".obj"))):
        import coal

        model = coal.MeshLoader().load(path, np.ones(3))
        vertices = np.asarray(model.vertices(), dtype=np.float64).reshape(-1, 3)
    return vertices


def mesh_problem(vertices: np.ndarray, *, needs_volume: bool) -> str | None:
    """What is wrong with a mesh for Pinocchio and coal, or None.

    Parameters
    ----------
    vertices :
        Vertex coordinates [m] after the URDF's scale, shape (n_vertices, 3).
    needs_volume :
        True for collision meshes, whose convex hull is built (qhull).
    """
    if len(vertices) == 0:
        return "the file has no vertices"
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        return f"{int(bad.sum())} of its {len(vertices)} vertices are NaN or infinite"
    extent = float(np.max(vertices.max(axis=0) - vertices.min(axis=0)))
    if not extent <= MAX_EXTENT_M:
        return (
            f"it is {extent:.3g} m across, more than the {MAX_EXTENT_M:g} m of any robot part "
            '(millimetres read as metres? set <mesh scale="0.001 0.001 0.001">)'
        )
    if not needs_volume:
        return None
    if len(vertices) < 4:
        return f"it has {len(vertices)} vertices, too few to enclose a volume"
    spread = np.linalg.svd(vertices - vertices.mean(axis=0), compute_uv=False)
    if spread[0] == 0.0:
        return "all its vertices are one point (a hull of zero volume)"
    if spread[1] <= FLATNESS_TOLERANCE * spread[0]:
        return "all its vertices lie on one line (a hull of zero volume)"
    if spread[2] <= FLATNESS_TOLERANCE * spread[0]:
        return "all its vertices lie in one plane (a hull of zero volume)"
    return None


def _scale(text: str | None) -> tuple[np.ndarray | None, str]:
    if text is None:
        return np.ones(3), ""
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError:
        return None, f'scale="{text}" is not three numbers'
    if values.shape != (3,):
        return None, f'scale="{text}" is not three numbers'
    # Negative factors are accepted: two are a half turn (TIAGo writes "-1 -1 1"), one mirrors
    # (Centauro's left arm is its right arm's meshes at "0.001 -0.001 0.001"); distances and
    # hulls do not depend on the triangles' winding.
    if not np.isfinite(values).all() or (values == 0.0).any():
        return None, (
            f'scale="{text}": each factor must be finite and non-zero (zero collapses the mesh)'
        )
    return values, ""


def check_urdf_meshes(
    urdf: str | Path | None,
    package_dirs: Sequence[str | Path] = (),
    *,
    collision: bool = True,
    visual: bool = True,
) -> None:
    """Refuse the URDF meshes that would crash Pinocchio, coal or qhull.

    Parameters
    ----------
    urdf :
        URDF file path, or its XML text (a string starting with ``<``); None does nothing.
    package_dirs :
        Folders searched for ``package://`` and relative mesh paths, as given to Pinocchio.
    collision, visual :
        Which elements to check: ``<collision>`` meshes (flat ones refused too: their hull
        is built) and/or ``<visual>`` meshes.

    Raises
    ------
    ModelError
        On the first bad mesh: the URDF, the link, the file, what is wrong and the fix.
    """
    if urdf is None:
        return
    if isinstance(urdf, Path) or not str(urdf).lstrip().startswith("<"):
        where = str(urdf)
        try:
            text = Path(urdf).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            return  # the URDF loader reports an unreadable file
    else:
        where, text = "the URDF", str(urdf)
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return  # the URDF loader reports the syntax error
    for link in root.iter("link"):
        for kind in ("collision",) * collision + ("visual",) * visual:
            for element in link.iter(kind):
                for mesh in element.iter("mesh"):
                    _check_one(mesh, link.get("name", "?"), kind, where, package_dirs)


def mesh_vertices(path: str | Path, scale: str | None, *, where: str) -> np.ndarray:
    """Vertices [m] of a mesh file after a URDF ``scale`` attribute, checked.

    Parameters
    ----------
    path :
        The resolved mesh file (:func:`resolve_mesh_path`).
    scale :
        The ``<mesh scale="...">`` text, or None (no scale).
    where :
        What names the mesh in an error (URDF, link, element, file name).

    Returns
    -------
    :
        Vertex coordinates, shape (n_vertices, 3), every one finite, the mesh at most
        :data:`MAX_EXTENT_M` across.

    Raises
    ------
    ModelError
        A bad scale, an unreadable or empty file, NaN or infinite vertices, a huge mesh.
    """
    factors, problem = _scale(scale)
    if factors is None:
        raise ModelError(f"{where}: {problem}.")
    path = Path(path)
    stat = path.stat()
    try:
        vertices = _vertices(str(path), stat.st_mtime_ns, stat.st_size)
    except Exception as e:  # noqa: BLE001 - any loader failure is the file's fault
        lines = [x.strip() for x in str(e).strip().splitlines()] or [type(e).__name__]
        # coal's message: "From file: ... message: Could not load resource ... Hint: ..."
        said = next((x for x in lines if x.startswith("message:")), lines[0])
        raise ModelError(f"{where} ({path}): cannot be read as a mesh ({said}); {_FIX}.") from e
    scaled = vertices * factors
    found = mesh_problem(scaled, needs_volume=False)
    if found is not None:
        raise ModelError(f"{where} ({path}): {found}; {_FIX}.")
    return scaled


def _check_one(
    mesh: ET.Element, link: str, kind: str, where: str, package_dirs: Sequence[str | Path]
) -> None:
    filename = mesh.get("filename", "")
    head = f"{where}: link '{link}', <{kind}> mesh '{filename}'"
    path = resolve_mesh_path(filename, package_dirs)
    if path is None:
        return  # Pinocchio names the missing file (a mesh not shipped, as TIAGo's)
    scale, problem = _scale(mesh.get("scale"))
    if scale is None:
        raise ModelError(f"{head}: {problem}.")
    vertices = mesh_vertices(path, mesh.get("scale"), where=head)
    found = mesh_problem(vertices, needs_volume=kind == "collision")
    if found is not None:
        raise ModelError(f"{head} ({path}): {found}; {_FIX}.")
