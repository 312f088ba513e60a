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
A mesh file that does not exist is not checked here: :func:`resolve_urdf_meshes` finds the
meshes the way ROS does (:func:`resolve_mesh_path`, the one resolver of every loader) and
names the missing ones.
"""

from __future__ import annotations

import functools
import os
import urllib.parse

# xml.etree: rewrites mesh filenames in the user's URDF text (and stands in for missing meshes)
# before Pinocchio reads it, the rest left as it is; yourdfpy's round trip drops what it does not
# model (checked on example-robot-data's UR5: its 6 <transmission>, 8 <gazebo> blocks and 24
# comments are gone) and rewrites numbers (rpy "0 0 0" -> "0.0 -0.0 0.0").
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ident.errors import ModelError

__all__ = [
    "FLATNESS_TOLERANCE",
    "MAX_EXTENT_M",
    "MissingMesh",
    "ResolvedMeshes",
    "check_urdf_meshes",
    "mesh_problem",
    "mesh_vertices",
    "resolve_mesh_path",
    "resolve_urdf_meshes",
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


def resolve_mesh_path(
    filename: str, package_dirs: Sequence[str | Path], base: str | Path | None = None
) -> Path | None:
    """The file a URDF ``<mesh filename=...>`` names, found as ROS finds it; None if none exists.

    The one resolver of every mesh loader (safety geometry, replay, ellipsoids, mesh checks).
    In order:

    - ``package://pkg/rest`` (and ``model://``): ``rest`` in each folder of ``package_dirs``
      then of ``ROS_PACKAGE_PATH`` that is the package ``pkg`` itself (its name is ``pkg``)
      or holds it (``<dir>/pkg``, or a folder ``pkg`` up to :data:`_PACKAGE_DEPTH` levels
      down, as ROS crawls its package path);
    - a relative path: in the URDF's folder ``base``, then in the package folders (as
      Pinocchio does);
    - ``file://`` (percent-encoded or not) and plain absolute paths: as they are;
    - when still missing (a ``file:///root/...`` path of the author's machine, a package not
      given): the rest of the path after a folder named as a package of the package
      folders (``.../share/pkg/meshes/a.stl``: ``meshes/a.stl`` in ``pkg``), then the
      longest tail of the path, down to two parts (``meshes/base_link.STL``), under the
      package folders, ``base`` and its parent and grandparent.

    The extension may differ in case (``.STL`` for ``.stl``). Other schemes give None.
    """
    dirs = [Path(d) for d in package_dirs]
    dirs += [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    scheme, rest = filename.split("://", 1) if "://" in filename else ("", filename)
    if scheme not in ("", "file", "package", "model"):
        return None
    if scheme == "file":
        rest = rest if Path(rest).exists() else urllib.parse.unquote(rest)
    candidates: list[Path] = []
    if scheme in ("package", "model"):
        package, _, inside = rest.partition("/")
        for folder in dirs:
            candidates += [p / inside for p in _package_folders(folder, package)]
    elif Path(rest).is_absolute():
        candidates.append(Path(rest))
    else:
        candidates += [Path(d) / rest for d in ([base] if base is not None else [])]
        candidates += [folder / rest for folder in dirs]
    for path in candidates:
        found = _existing(path)
        if found is not None:
            return found
    parts = [p for p in Path(rest).parts if p not in ("/", ".", "..")]
    found = _in_named_package(parts, dirs)
    if found is not None:
        return found
    roots = list(dirs)
    if base is not None:
        roots += [Path(base), Path(base).parent, Path(base).parent.parent]
    return _tail_search(parts, roots)


_PACKAGE_DEPTH = 3
"""How deep under a package folder a ROS package is looked for (``ws/src/<repo>/<pkg>``)."""


def _package_folders(folder: Path, package: str) -> list[Path]:
    """The folders that may be ROS package ``package`` for a package-path entry ``folder``:
    the entry itself when so named, ``folder/package``, and folders so named below it."""
    found = [folder] if folder.name == package else []
    found.append(folder / package)
    return found + [p for p in _crawl(str(folder)).get(package, []) if p not in found]


@functools.lru_cache(maxsize=64)
def _crawl(folder: str) -> dict[str, list[Path]]:
    """Folder name -> folders of that name up to :data:`_PACKAGE_DEPTH` levels below
    ``folder`` (hidden folders skipped); cached per run."""
    out: dict[str, list[Path]] = {}
    level = [Path(folder)]
    for _ in range(_PACKAGE_DEPTH):
        below = []
        for parent in level:
            try:
                children = [c for c in parent.iterdir() if c.is_dir() and c.name[:1] != "."]
            except OSError:
                continue
            for child in sorted(children):
                out.setdefault(child.name, []).append(child)
            below += children
        level = below
    return out


def _in_named_package(parts: Sequence[str], dirs: Sequence[Path]) -> Path | None:
    """The file of a path of another machine (``/root/ws/install/pkg/share/pkg/meshes/a.stl``)
    in a package of ``dirs`` named by one of its folders, the last such folder first
    (``pkg`` then ``meshes/a.stl`` inside it)."""
    for i in range(len(parts) - 2, -1, -1):
        for folder in dirs:
            for package in _package_folders(folder, parts[i]):
                found = _existing(package.joinpath(*parts[i + 1 :]))
                if found is not None:
                    return found
    return None


def _existing(path: Path) -> Path | None:
    """``path`` if it is a file, else a file beside it whose name differs only in the case
    of its extension (``base.STL`` for ``base.stl``); None."""
    if path.is_file():
        return path
    try:
        siblings = list(path.parent.iterdir()) if path.suffix else []
    except OSError:
        return None
    for sibling in sorted(siblings):
        if (
            sibling.stem == path.stem
            and sibling.suffix.lower() == path.suffix.lower()
            and sibling.is_file()
        ):
            return sibling
    return None


def _tail_search(parts: Sequence[str], roots: Sequence[Path]) -> Path | None:
    """The first ``root / tail`` that exists, for the tails of ``parts`` longest first,
    down to two parts (a folder and the file name; one for a bare file name)."""
    if not parts:
        return None
    for n in range(len(parts), min(2, len(parts)) - 1, -1):
        tail = Path(*parts[len(parts) - n :])
        for root in roots:
            found = _existing(root / tail)
            if found is not None:
                return found
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
    name: str = "the URDF",
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
    name :
        What names the URDF in an error when ``urdf`` is its text (its file, usually).

    Raises
    ------
    ModelError
        On the first bad mesh: the URDF, the link, the file, what is wrong and the fix.
    """
    if urdf is None:
        return
    base = None
    if isinstance(urdf, Path) or not str(urdf).lstrip().startswith("<"):
        where, base = str(urdf), Path(urdf).parent
        try:
            text = Path(urdf).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            return  # the URDF loader reports an unreadable file
    else:
        where, text = name, str(urdf)
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return  # the URDF loader reports the syntax error
    for link in root.iter("link"):
        for kind in ("collision",) * collision + ("visual",) * visual:
            for element in link.iter(kind):
                for mesh in element.iter("mesh"):
                    _check_one(mesh, link.get("name", "?"), kind, where, package_dirs, base)


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
    mesh: ET.Element,
    link: str,
    kind: str,
    where: str,
    package_dirs: Sequence[str | Path],
    base: Path | None,
) -> None:
    filename = mesh.get("filename", "")
    head = f"{where}: link '{link}', <{kind}> mesh '{filename}'"
    path = resolve_mesh_path(filename, package_dirs, base)
    if path is None:
        return  # resolve_urdf_meshes names the missing files (a mesh not shipped, as TIAGo's)
    scale, problem = _scale(mesh.get("scale"))
    if scale is None:
        raise ModelError(f"{head}: {problem}.")
    vertices = mesh_vertices(path, mesh.get("scale"), where=head)
    found = mesh_problem(vertices, needs_volume=kind == "collision")
    if found is not None:
        raise ModelError(f"{head} ({path}): {found}; {_FIX}.")


@dataclass(frozen=True)
class MissingMesh:
    """A ``<mesh>`` of a URDF that :func:`resolve_mesh_path` cannot find."""

    link: str
    kind: str  # "collision" or "visual"
    filename: str  # as the URDF writes it


@dataclass(frozen=True)
class ResolvedMeshes:
    """A URDF whose meshes are found (see :func:`resolve_urdf_meshes`).

    Attributes
    ----------
    text :
        The URDF text, every found mesh at its absolute path, every ``<visual>`` or
        ``<collision>`` whose mesh is missing removed: Pinocchio, coal and meshcat load it as
        it is, whatever the machine the file was written on.
    missing :
        The meshes not found (their elements were removed), in file order.
    visual_for_collision :
        Links whose ``<visual>`` elements became their ``<collision>`` ones (with
        ``visual_for_collision=True``: no ``<collision>``, or a collision mesh missing).
    """

    text: str
    missing: tuple[MissingMesh, ...]
    visual_for_collision: tuple[str, ...] = ()

    def missing_line(self, kind: str, where: str) -> str:
        """``<where>: N <kind> mesh(es) not found: a, b, c (and N-3 more)`` (empty if none)."""
        names = list(dict.fromkeys(m.filename for m in self.missing if m.kind == kind))
        if not names:
            return ""
        more = f" (and {len(names) - 3} more)" if len(names) > 3 else ""
        plural = "es" if len(names) > 1 else ""
        return f"{where}: {len(names)} {kind} mesh{plural} not found: {', '.join(names[:3])}{more}"


def resolve_urdf_meshes(
    text: str,
    package_dirs: Sequence[str | Path] = (),
    base: str | Path | None = None,
    *,
    visual_for_collision: bool = False,
) -> ResolvedMeshes:
    """The URDF ``text`` with its meshes resolved by :func:`resolve_mesh_path`.

    Resolving here, once, and handing Pinocchio absolute paths is what makes every loader
    agree: Pinocchio's own lookup knows neither the URDF's folder (it gets text), nor
    ``file://`` paths of another machine, nor package folders that are the package itself.

    Parameters
    ----------
    text :
        URDF XML text (unparsable text is returned as it is: the URDF loader reports it).
    package_dirs :
        Folders of (or holding) the ROS packages the meshes name.
    base :
        The URDF's folder (relative mesh paths, and the tail search).
    visual_for_collision :
        Let a link's visual geometry stand in for its collision geometry where it has no
        ``<collision>`` or a collision mesh is missing (the safety model's geometry).
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return ResolvedMeshes(text, ())
    missing: list[MissingMesh] = []
    stand_ins: list[str] = []
    for link in root.iter("link"):
        name = link.get("name", "?")
        lost = {
            kind: _resolve_elements(link, kind, package_dirs, base)
            for kind in ("collision", "visual")
        }
        has_visual = link.find("visual") is not None and not lost["visual"]
        no_collision = bool(lost["collision"]) or link.find("collision") is None
        if visual_for_collision and has_visual and no_collision:
            for element in link.findall("collision"):
                link.remove(element)
            for element in link.findall("visual"):
                copy = ET.fromstring(ET.tostring(element))
                copy.tag = "collision"
                link.append(copy)
            stand_ins.append(name)
            lost["collision"] = []
        missing += [MissingMesh(name, kind, f) for kind in lost for f in lost[kind]]
    return ResolvedMeshes(ET.tostring(root, encoding="unicode"), tuple(missing), tuple(stand_ins))


def _not_a_file(filename: str, base: str | Path | None) -> str:
    """`` (a folder)`` or `` (not a regular file)`` when the path a mesh names as it is
    (absolute, or relative to the URDF's folder ``base``) exists as no file (a folder, a
    device), so that "not found" names the cause; else ''."""
    rest = filename.split("://", 1)[1] if filename.startswith("file://") else filename
    if "://" in rest:
        return ""
    path = Path(rest) if Path(rest).is_absolute() or base is None else Path(base) / rest
    if not path.exists() or path.is_file():
        return ""
    return " (a folder)" if path.is_dir() else " (not a regular file: a device or a pipe)"


def _resolve_elements(
    link: ET.Element, kind: str, package_dirs: Sequence[str | Path], base: str | Path | None
) -> list[str]:
    """Set the absolute path of every mesh of ``link``'s ``kind`` elements; remove the
    elements whose mesh is missing and return its file names as the URDF writes them."""
    lost = []
    for element in link.findall(kind):
        for mesh in element.iter("mesh"):
            filename = mesh.get("filename", "")
            path = resolve_mesh_path(filename, package_dirs, base)
            if path is None:
                lost.append(filename + _not_a_file(filename, base))
                link.remove(element)
                break
            mesh.set("filename", str(path.resolve()))
    return lost
