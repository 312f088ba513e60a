"""Bounding ellipsoids of links from their URDF geometry, for the "mass inside" constraint.

An ellipsoid ``E = {x : (x - c)^T Q^-1 (x - c) <= 1}`` (link frame, metres) in homogeneous
form is ``Q_h = [[-Q^-1, Q^-1 c], [c^T Q^-1, 1 - c^T Q^-1 c]]``, so that
``[x; 1]^T Q_h [x; 1] = 1 - (x - c)^T Q^-1 (x - c)`` is >= 0 exactly inside ``E``. For a body
with pseudo-inertia ``J = integral [x; 1][x; 1]^T dm``
(:mod:`ident.identify.estimation.consistency`),

``tr(J Q_h) = integral (1 - (x - c)^T Q^-1 (x - c)) dm >= 0``

holds whenever the mass lies in ``E``: a linear constraint on the standard parameters that,
with ``J >= 0``, is the ellipsoidal density-realizability condition of Wensing, Kim and
Slotine (2017). It rejects, for example, a point mass outside ``E``.

The ellipsoid of a link is the minimum-volume ellipsoid (Khachiyan's algorithm, inflated to
contain every point exactly) of points whose convex hull holds the link's ``<collision>``
geometry (``<visual>`` when it has none): box corners, a prism circumscribing each cylinder,
the bounding-cube corners of a sphere (a lone sphere is its own ellipsoid), mesh vertices
(read and checked by :func:`ident.robot.meshes.mesh_vertices` when the file resolves: a bad
scale, NaN vertices or an unreadable file is a :class:`~ident.errors.ModelError`).
"""

from __future__ import annotations

# xml.etree: reads the links of the tree the robot loader parsed and checked (one parse, DTD
# refused); yourdfpy's reader cannot give the project's named errors: a non-number raises a bare
# ValueError ("could not convert string to float: 'abc'", no joint, no field; the same for xacro's
# "${-pi}"), and URDF.load re-parses malformed XML with lxml recover=True (checked: a truncated
# file loads) and expands DTD entities (checked), which the project refuses.
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ident.errors import ModelError
from ident.robot.meshes import mesh_vertices, resolve_mesh_path

__all__ = ["Ellipsoid", "link_ellipsoids", "link_geometry_points", "minimum_volume_ellipsoid"]

FloatArray = npt.NDArray[np.float64]

_CYLINDER_SIDES = 16  # prism sides circumscribing a cylinder


@dataclass(frozen=True, eq=False)
class Ellipsoid:
    """``{x : (x - center)^T shape^-1 (x - center) <= 1}`` in a link frame.

    Attributes
    ----------
    center :
        Centre [m], shape (3,).
    shape :
        Symmetric positive definite matrix [m^2], shape (3, 3); its eigenvalues are the
        squared semi-axes.
    """

    center: FloatArray
    shape: FloatArray

    def __post_init__(self) -> None:
        for name in ("center", "shape"):
            value = np.array(getattr(self, name), dtype=float, copy=True)
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def semi_axes(self) -> FloatArray:
        """Semi-axis lengths [m], increasing, shape (3,)."""
        return np.sqrt(np.linalg.eigvalsh(self.shape))

    def contains(self, points: npt.ArrayLike, *, rtol: float = 1e-9) -> npt.NDArray[np.bool_]:
        """Whether each point (..., 3) lies in the ellipsoid (boundary included, ``rtol``)."""
        d = np.asarray(points, dtype=float) - self.center
        inside = np.einsum("...i,ij,...j->...", d, np.linalg.inv(self.shape), d)
        return inside <= 1.0 + rtol

    def homogeneous_matrix(self) -> FloatArray:
        """``Q_h`` (4, 4) with ``[x; 1]^T Q_h [x; 1] >= 0`` exactly inside (module docstring)."""
        inverse = np.linalg.inv(self.shape)
        out = np.empty((4, 4))
        out[:3, :3] = -inverse
        out[:3, 3] = out[3, :3] = inverse @ self.center
        out[3, 3] = 1.0 - self.center @ inverse @ self.center
        return out


def minimum_volume_ellipsoid(
    points: npt.ArrayLike, *, tol: float = 1e-4, max_iter: int = 10_000
) -> Ellipsoid:
    """Minimum-volume ellipsoid enclosing points (Khachiyan's algorithm with away steps).

    Parameters
    ----------
    points :
        Points [m], shape (n_points, 3), not all in one plane.
    tol :
        Stop when every point is within ``1 + tol`` of the rim and every supporting point
        within ``1 - tol`` (in the lifted norm): the ellipsoid's volume is then within about
        ``d * tol`` of the minimum.

    Returns
    -------
    :
        The ellipsoid, scaled up where needed so that every point is inside.

    References
    ----------
    L. G. Khachiyan, "Rounding of polytopes in the real number model of computation",
    Mathematics of Operations Research 21(2), 1996. M. J. Todd and E. A. Yildirim, "On
    Khachiyan's algorithm for the computation of minimum-volume enclosing ellipsoids",
    Discrete Applied Mathematics 155(13), 2007.
    """
    P = np.asarray(points, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 4:
        raise ModelError(f"need at least 4 points of shape (n, 3), got {P.shape}.")
    P = _hull_vertices(P)  # the same ellipsoid; a mesh's 10^4 vertices made it take minutes
    n, d = P.shape
    lifted = np.column_stack([P, np.ones(n)])
    u = np.full(n, 1.0 / n)
    for _ in range(max_iter):
        try:
            M = ((lifted @ np.linalg.inv(lifted.T @ (lifted * u[:, None]))) * lifted).sum(axis=1)
        except np.linalg.LinAlgError as e:
            raise ModelError("the geometry points lie in a plane: no bounding ellipsoid.") from e
        # Todd and Yildirim's away steps: move weight off the innermost supporting point as
        # well as onto the outermost one (Khachiyan's steps alone crawl: 10^4 iterations)
        j = int(np.argmax(M))
        k = int(np.flatnonzero(u > 0)[np.argmin(M[u > 0])])
        if M[j] - (d + 1) <= tol * (d + 1) and (d + 1) - M[k] <= tol * (d + 1):
            break  # tol-optimal: every point within (1 + tol), every support on the rim
        if M[j] - (d + 1) >= (d + 1) - M[k]:
            step = (M[j] - d - 1.0) / ((d + 1.0) * (M[j] - 1.0))
            u = (1.0 - step) * u
            u[j] += step
        else:
            step = min((d + 1.0 - M[k]) / ((d + 1.0) * (M[k] - 1.0)), u[k] / (1.0 - u[k]))
            u = (1.0 + step) * u
            u[k] -= step
            u[k] = max(u[k], 0.0)
    center = P.T @ u
    scatter = (P * u[:, None]).T @ P - np.outer(center, center)
    shape = d * scatter
    diff = P - center
    reach = np.einsum("ij,jk,ik->i", diff, np.linalg.inv(shape), diff).max()
    return Ellipsoid(center=center, shape=shape * max(1.0, float(reach)))


def _hull_vertices(points: FloatArray) -> FloatArray:
    """The vertices of the points' convex hull (the minimum-volume ellipsoid touches only
    those), or all points when Qhull cannot build a hull (flat or degenerate sets: the
    caller's rank check then names them)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        return points


def _origin(element: ET.Element) -> tuple[FloatArray, FloatArray]:
    """Rotation (3, 3) and translation (3,) of an element's ``<origin>`` (link frame)."""
    import pinocchio as pin

    origin = element.find("origin")
    if origin is None:
        return np.eye(3), np.zeros(3)
    xyz = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
    rpy = np.array([float(v) for v in origin.get("rpy", "0 0 0").split()])
    return pin.rpy.rpyToMatrix(rpy), xyz


def _shape_points(
    geometry: ET.Element, package_dirs: Sequence[str | Path], base: Path | None
) -> tuple[FloatArray, float | None] | None:
    """Points whose hull holds the shape, and the radius when it is a sphere; None if unknown."""
    box = geometry.find("box")
    if box is not None:
        half = 0.5 * np.array([float(v) for v in box.get("size", "0 0 0").split()])
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return corners * half, None
    cylinder = geometry.find("cylinder")
    if cylinder is not None:
        radius = float(cylinder.get("radius", 0.0)) / np.cos(np.pi / _CYLINDER_SIDES)
        half_length = 0.5 * float(cylinder.get("length", 0.0))
        angles = 2.0 * np.pi * np.arange(_CYLINDER_SIDES) / _CYLINDER_SIDES
        ring = np.column_stack([radius * np.cos(angles), radius * np.sin(angles)])
        ends = (-half_length, half_length)
        return np.vstack([np.column_stack([ring, np.full(len(ring), z)]) for z in ends]), None
    sphere = geometry.find("sphere")
    if sphere is not None:
        r = float(sphere.get("radius", 0.0))
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return r * corners, r
    mesh = geometry.find("mesh")
    if mesh is not None:
        path = resolve_mesh_path(mesh.get("filename", ""), package_dirs, base)
        if path is None:
            return None
        where = f"URDF mesh '{mesh.get('filename', '')}'"
        return mesh_vertices(path, mesh.get("scale"), where=where), None
    return None


def link_geometry_points(
    link: ET.Element, *, package_dirs: Sequence[str | Path] = (), base: Path | None = None
) -> tuple[FloatArray, list[tuple[FloatArray, float]]] | None:
    """Points (n, 3) in the link frame holding its collision (else visual) geometry.

    Also returns the spheres ``(center, radius)``; None when a shape cannot be read (an
    unresolved mesh) or the link has no geometry.
    """
    elements = link.findall("collision") or link.findall("visual")
    if not elements:
        return None
    points, spheres = [], []
    for element in elements:
        geometry = element.find("geometry")
        shape = None if geometry is None else _shape_points(geometry, package_dirs, base)
        if shape is None:
            return None
        local, radius = shape
        rotation, translation = _origin(element)
        points.append(local @ rotation.T + translation)
        if radius is not None:
            spheres.append((translation, radius))
    return np.vstack(points), spheres


def link_ellipsoids(
    urdf: ET.Element,
    link_names: Sequence[str],
    *,
    package_dirs: Sequence[str | Path] = (),
    base: str | Path | None = None,
) -> tuple[Ellipsoid | None, ...]:
    """Bounding ellipsoid of each named link (None where its geometry is unknown).

    Parameters
    ----------
    urdf :
        The parsed URDF's ``<robot>`` element (parse with
        :func:`ident.identify.model_files.urdf_update.parse_urdf`, which refuses DTDs).
    link_names :
        Links, e.g. the bodies of the identified joints.
    package_dirs :
        Folders holding the ``package://`` mesh packages.
    base :
        Folder of the URDF, for relative mesh paths.
    """
    links = {link.get("name"): link for link in urdf.iter("link")}
    out: list[Ellipsoid | None] = []
    for name in link_names:
        if name not in links:
            known = ", ".join(str(k) for k in links)
            raise ModelError(f"URDF: link {name!r} not found (links: {known}).")
        found = link_geometry_points(
            links[name], package_dirs=package_dirs, base=None if base is None else Path(base)
        )
        if found is None:
            out.append(None)
            continue
        points, spheres = found
        if len(spheres) == 1 and len(points) == 8:  # a lone sphere is its own ellipsoid
            center, radius = spheres[0]
            out.append(Ellipsoid(center=center, shape=radius**2 * np.eye(3)))
            continue
        try:
            out.append(minimum_volume_ellipsoid(points))
        except ModelError:
            out.append(None)  # flat geometry (a plane): no bounded constraint
    return tuple(out)
