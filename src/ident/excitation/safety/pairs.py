"""Which pairs a safety model checks: the rule, applied once when the model is built, on the
exact geometry (the meshes as loaded, coal BVH, and the URDF's primitives; never on a hull).

1. every pair of robot links except those **excluded**: adjacent (a joint and its parent;
   links welded by a fixed joint belong to the same joint in Pinocchio), named by the MoveIt
   SRDF given as ``safety.srdf`` (``<disable_collisions>``), in contact in the reference
   posture (0 clipped into the limits), or in contact in at least
   :data:`~ident.excitation.safety.config.ALWAYS_IN_CONTACT_FRACTION` of
   :data:`~ident.excitation.safety.config.N_EXCLUSION_POSTURES` random postures (the MoveIt
   setup assistant's rule, :mod:`ident.excitation.safety.exclusions`). A remaining pair
   closer than the margin in every sampled posture is an input error (no trajectory could
   keep the margin);
2. every robot geometry against the floor and every obstacle: **never excluded**. A pair
   whose distance no motion changes (the base on the floor, a first link turning about the
   vertical) is judged once (:mod:`ident.excitation.safety.environment`): partly inside is a
   mounting (the paper robot's joint-1 housing sunk into its pedestal), deeper than the
   geometry's bounding radius (and
   :data:`~ident.excitation.safety.config.MOUNT_TOLERANCE_M`) is an input error (a robot
   inside an obstacle or under the floor). Any other environment pair closer than the margin
   in every sampled posture, or at the home posture, is an input error, as are absurd sizes
   (validation).

Distances are reported per *link pair* (the URDF link names of the two geometries, or the
obstacle name): the minimum over the geometry pairs of the two links.
"""

from __future__ import annotations

# xml.etree: reads MoveIt's SRDF (<disable_collisions>), which yourdfpy does not read (URDF only)
# and MjSpec has no counterpart for.
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.config import file_problem
from ident.errors import ConfigError
from ident.excitation.safety.config import FLOOR, PAYLOAD

__all__ = ["ExcludedPair"]


@dataclass(frozen=True, eq=False)
class ExcludedPair:
    """A pair left out of the checks, and why."""

    pair: str
    reason: str


def _pair_key(a: str, b: str) -> tuple[str, str]:
    return (a, b) if a <= b else (b, a)


_MAX_SRDF_BYTES = 10_000_000


def _read_srdf(path: Path) -> list[tuple[str, str, str]]:
    """The ``<disable_collisions link1= link2= reason=/>`` entries of a MoveIt SRDF.

    Raises
    ------
    ConfigError
        If the file cannot be read or parsed, or is larger than 10 MB.
    """
    problem = file_problem(path)
    if problem is not None:
        raise ConfigError(f"safety.srdf: {path} {problem}; give MoveIt's .srdf file.")
    try:
        with path.open("rb") as f:  # bounded: never more than 10 MB, whatever the file
            data = f.read(_MAX_SRDF_BYTES + 1)
        if len(data) > _MAX_SRDF_BYTES:
            raise ConfigError(f"safety.srdf: {path} is larger than 10 MB; is it an SRDF?")
        root = ET.fromstring(data)
    except (OSError, ET.ParseError) as e:
        raise ConfigError(
            f"safety.srdf: cannot read {path} as an SRDF ({e}); give MoveIt's .srdf file."
        ) from e
    pairs = []
    for node in root.iter("disable_collisions"):
        a, b = node.get("link1"), node.get("link2")
        if not a or not b:
            raise ConfigError(
                f"safety.srdf: {path}: a <disable_collisions> lacks link1 or link2; "
                'write <disable_collisions link1="a" link2="b" reason="Adjacent"/>.'
            )
        pairs.append((a, b, node.get("reason") or "no reason given"))
    return pairs


def _add_srdf_exclusions(excluded: dict[tuple[str, str], str], srdf: Path, links: set[str]) -> None:
    """Add to ``excluded`` the pairs of ``links`` the SRDF disables (not already excluded)."""
    for first, second, reason in _read_srdf(srdf):
        key = _pair_key(first, second)
        if first in links and second in links and key not in excluded:
            excluded[key] = f"SRDF ({reason})"


def _adjacent_pairs(
    parents: Sequence[int], link_of: Sequence[str], joint_of: Sequence[int], n_robot: int
) -> tuple[dict[tuple[str, str], str], dict[tuple[str, str], list[tuple[int, int]]]]:
    """The robot's link pairs (keyed by the sorted link names) that are adjacent or hold a
    payload, with the reason, and the geometry object pairs ``(a, b)`` of every link pair
    (``link_of``, ``joint_of``: the link and parent joint of each of the ``n_robot`` robot
    objects; ``parents``: each joint's parent joint)."""
    excluded: dict[tuple[str, str], str] = {}
    geometry_pairs: dict[tuple[str, str], list[tuple[int, int]]] = {}
    for a in range(n_robot):
        for b in range(a + 1, n_robot):
            if link_of[a] == link_of[b]:
                continue
            key = _pair_key(link_of[a], link_of[b])
            ja, jb = joint_of[a], joint_of[b]
            # a payload's box is checked against the links next to it: only the links
            # it is fixed to (the same joint) are excluded
            next_to = PAYLOAD not in key and (parents[ja] == jb or parents[jb] == ja)
            if ja == jb and PAYLOAD in key:
                excluded.setdefault(key, "payload attached (fixed to this link)")
            elif ja == jb or next_to:
                excluded.setdefault(key, "adjacent")
            geometry_pairs.setdefault(key, []).append((a, b))
    return excluded, geometry_pairs


def _candidate_pairs(
    link_of: Sequence[str],
    environment: Sequence[str],
    excluded: Mapping[tuple[str, str], str],
    self_collision: bool,
) -> list[tuple[int, int, str, str]]:
    """``(geom a, geom b, pair name, kind)`` of every pair that may be checked: the robot's
    link pairs not ``excluded`` (with ``self_collision``), then every robot object against
    each environment object (numbered after the ``len(link_of)`` robot objects)."""
    n_robot = len(link_of)
    candidates: list[tuple[int, int, str, str]] = []
    if self_collision:
        for a in range(n_robot):
            for b in range(a + 1, n_robot):
                name = f"{link_of[a]}|{link_of[b]}"
                if link_of[a] != link_of[b] and _pair_key(link_of[a], link_of[b]) not in excluded:
                    candidates.append((a, b, name, "self"))
    for e, env_name in enumerate(environment):
        kind = "floor" if env_name == FLOOR else "obstacle"
        for a in range(n_robot):
            candidates.append((a, n_robot + e, f"{link_of[a]}|{env_name}", kind))
    return candidates


def _flat_pairs(
    tested: Sequence[tuple[str, str]],
    geometry_pairs: Mapping[tuple[str, str], list[tuple[int, int]]],
) -> tuple[list[tuple[int, int]], npt.NDArray[np.int64]]:
    """The geometry object pairs of the ``tested`` link pairs, in order, and the index in
    ``tested`` of the link pair each belongs to."""
    pairs = [ab for k in tested for ab in geometry_pairs[k]]
    owner = np.array([i for i, k in enumerate(tested) for _ in geometry_pairs[k]], dtype=int)
    return pairs, owner


def _mesh_pairs(
    geom: pin.GeometryModel, pairs: Sequence[tuple[int, int, str, str]]
) -> npt.NDArray[np.bool_]:
    """Per geometry pair, whether a mesh is on either side (where the hull and the geometry
    differ: the exact certificate measures them on the mesh).

    A mesh against a half-space (the floor, a plane) does not count: the point of a mesh
    nearest a plane is a vertex, one of its hull's, so apart they have the same distance;
    sunk in, :meth:`SafetyModel.clearances` keeps the deeper of the two, the hull's (its
    deepest vertex).
    """
    import coal

    is_mesh = [isinstance(o.geometry, coal.BVHModelBase) for o in geom.geometryObjects]
    plane = [isinstance(o.geometry, coal.Halfspace) for o in geom.geometryObjects]
    return np.array(
        [(is_mesh[a] or is_mesh[b]) and not (plane[a] or plane[b]) for a, b, _, _ in pairs],
        dtype=bool,
    )
