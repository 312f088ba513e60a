"""The URDF links that make up each body of a Pinocchio model, and how to split a body back.

Pinocchio (and MuJoCo) fuse the links behind fixed joints, and behind the joints locked for the
identification, into the body of the nearest moving joint above them: that body's parameters
are the sum of the links' inertials, in the moving joint's frame. :func:`fused_bodies` finds
which links (from the model's body frames), :func:`compose_body` splits an identified body back
between the joint's child link and the welded links, exactly and without a negative mass.
Only the top-level ``<robot>/<link>`` and ``<robot>/<joint>`` elements are read, as urdfdom
does (a ``<joint>`` inside a ``<transmission>`` is not a joint).
"""

from __future__ import annotations

# xml.etree: the tree parsed by the robot loader's parse_xml (its errors, DTD refused), read as
# urdfdom does (top-level <link>/<joint> only); the nominal inertials are read with Pinocchio's
# rpyToMatrix, so a link that is not written back is bit-identical in the reloaded model; yourdfpy
# turns <origin rpy> into a matrix with its own code (checked: rpy 0.3 -1.2 2.1 differs from
# pin.rpy.rpyToMatrix by 1.1e-16).
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ident.errors import ModelError
from ident.inputs import refuse_dtd
from ident.robot.urdf_load import parse_xml

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "FusedBody",
    "compose_body",
    "fused_bodies",
    "link_inertial",
    "model_of_urdf",
    "parse_urdf",
]

FloatArray = npt.NDArray[np.float64]


def parse_urdf(urdf_text: str, source: str = "URDF") -> ET.Element:
    """Parse URDF text into an element tree, refusing what the robot loader would not read.

    Raises
    ------
    ModelError
        For a document type declaration (entities), malformed XML, or a root other than
        ``<robot>``; nothing has been changed then.
    """
    refuse_dtd(urdf_text, source)  # the rule of every URDF reader (ident.inputs)
    return parse_xml(urdf_text, source)  # the robot loader's parser and its errors


def link_inertial(link: ET.Element) -> FloatArray:
    """The link's own ``<inertial>`` as parameters about its frame origin (10,) [SI]."""
    import pinocchio as pin

    from ident.robot.inertia import parameters_from_com, urdf_inertia_tensor

    inertial = link.find("inertial")
    if inertial is None:
        return np.zeros(10)
    mass_el = inertial.find("mass")
    mass = float(mass_el.get("value", 0.0)) if mass_el is not None else 0.0
    origin = inertial.find("origin")
    xyz = np.zeros(3)
    rotation = np.eye(3)
    if origin is not None:
        xyz = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
        rpy = np.array([float(v) for v in origin.get("rpy", "0 0 0").split()])
        rotation = pin.rpy.rpyToMatrix(rpy)
    el = inertial.find("inertia")
    inertia = urdf_inertia_tensor(el.attrib if el is not None else None)
    return parameters_from_com(mass, xyz, rotation @ inertia @ rotation.T)


@dataclass(frozen=True)
class FusedBody:
    """One body of the Pinocchio model and the URDF links fused into it.

    Pinocchio (and MuJoCo) fuse the links behind fixed joints, and the robot's locked joints,
    into the body of the nearest moving joint above them; that body's parameters are the sum of
    the links' inertials, expressed in the moving joint's frame.

    Attributes
    ----------
    joint :
        The moving joint.
    carrier :
        Its child link, whose frame is the joint frame.
    welded :
        The other links of the body with their inertial about the joint frame origin, in
        the joint axes, shape (10,) each [SI].
    """

    joint: str
    carrier: str
    welded: tuple[tuple[str, FloatArray], ...]

    @property
    def welded_sum(self) -> FloatArray:
        """Sum of the welded links' parameters in the joint frame, shape (10,) [SI]."""
        return np.sum([p for _, p in self.welded], axis=0) if self.welded else np.zeros(10)


def fused_bodies(root: ET.Element, model: pin.Model, source: str = "URDF") -> list[FusedBody]:
    """The URDF links fused into each body of ``model``, in joint order.

    Parameters
    ----------
    root :
        The parsed URDF (only its top-level ``<link>`` and ``<joint>`` elements are read).
    model :
        The Pinocchio model built from it (continuous joints as revolute, locked joints
        removed: :meth:`ident.model.Robot.from_urdf`); its body frames say which link is fused
        into which joint's body, and where.

    Raises
    ------
    ModelError
        If a joint of the model or its child link is not a top-level element of the URDF.
    """
    import pinocchio as pin

    from ident.robot.inertia import transform_parameters

    links = {link.get("name"): link for link in root.findall("link")}
    child = {}
    for joint in root.findall("joint"):
        element = joint.find("child")
        if element is not None:
            child[joint.get("name")] = element.get("link")
    bodies: dict[int, list[tuple[str, FloatArray]]] = {j: [] for j in range(1, model.njoints)}
    carriers = {}
    for j in range(1, model.njoints):
        name = model.names[j]
        carrier = child.get(name)
        if carrier is None or carrier not in links:
            raise ModelError(f"{source}: joint {name!r} or its child link not found.")
        carriers[j] = carrier
    for frame in model.frames:
        j = int(frame.parentJoint)
        if frame.type != pin.FrameType.BODY or j == 0 or frame.name not in links:
            continue
        if frame.name == carriers[j]:
            if not frame.placement.isIdentity(1e-12):
                raise ModelError(
                    f"{source}: link {frame.name!r} is not at the frame of its joint "
                    f"{model.names[j]!r} in Pinocchio's model; cannot write it back."
                )
            continue
        own = link_inertial(links[frame.name])
        if not own.any():
            continue
        placed = transform_parameters(own, frame.placement.rotation, frame.placement.translation)
        bodies[j].append((str(frame.name), placed))
    return [
        FusedBody(joint=str(model.names[j]), carrier=str(carriers[j]), welded=tuple(bodies[j]))
        for j in range(1, model.njoints)
    ]


#: When the welded links must be scaled down (:func:`compose_body`), the carrying link keeps at
#: least this fraction of the body's smallest pseudo-inertia eigenvalue: strictly consistent.
_MARGIN = 1e-6


def compose_body(body: FloatArray, welded: FloatArray) -> tuple[FloatArray, float]:
    """Split an identified body between its carrying link and its welded links, exactly.

    The carrying link gets ``body - s * welded`` and the welded links their nominal inertials
    times ``s`` (same centres of mass, masses and inertias scaled), so the sum is ``body``
    whatever ``s``. ``s = 1`` (the welded links unchanged) when the carrying link is then
    physically consistent; otherwise ``s`` is the largest value in [0, 1) for which the carrying
    link's pseudo-inertia keeps a small positive margin (bisection: the set of such ``s`` is an
    interval containing 0, because pseudo-inertias are linear in the parameters and
    ``body`` is consistent). ``s = 0`` puts the whole body on the carrying link.

    Parameters
    ----------
    body :
        Identified body about the joint frame origin, shape (10,) [SI]; must be consistent.
    welded :
        Sum of the welded links' nominal parameters in the same frame, shape (10,).

    Returns
    -------
    own, scale :
        The carrying link's parameters (10,) and ``s``; never a negative mass.
    """
    from ident.identify.estimation.consistency import pseudo_inertia_min_eigenvalue
    from ident.robot.inertia import consistency_problems

    body = np.asarray(body, dtype=float)
    welded = np.asarray(welded, dtype=float)
    if not welded.any() or not consistency_problems(body - welded):
        return body - welded, 1.0
    margin = _MARGIN * max(float(pseudo_inertia_min_eigenvalue(body)), 0.0)

    def feasible(s: float) -> bool:
        own = body - s * welded
        return bool(own[0] > 0 and float(pseudo_inertia_min_eigenvalue(own)) >= margin)

    low, high = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if feasible(mid) else (low, mid)
    return body - low * welded, low


def model_of_urdf(
    urdf_text: str, locked: Mapping[str, float] | None = None, source: str = "URDF"
) -> pin.Model:
    """Pinocchio's model of a URDF as :meth:`ident.model.Robot.from_urdf` builds it.

    Continuous joints as revolute ones, missing limits as 0 (unknown), the joints ``locked``
    held at their values; no inertial check (the write-back reads the file's own values).
    """
    from ident.robot.urdf_load import locked_model, model_from_text

    parse_urdf(urdf_text, source)  # the write-back's own XML errors first
    return locked_model(model_from_text(urdf_text, source), dict(locked or {}), source)
