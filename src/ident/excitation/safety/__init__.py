"""Collision, environment and torque model of an excitation trajectory (what a robot can run).

A :class:`SafetyModel` holds, for one robot,

- its URDF **collision geometry** as a Pinocchio ``GeometryModel`` (coal computes the
  distances on the meshes as BVH, :meth:`SafetyModel.clearances`), and the same geometry with
  meshes replaced by their convex hulls, a conservative proxy (a hull contains its mesh) for
  the optimizer's cheap term and a broad phase;
- the **floor**, a half-space ``z <= floor.z`` in the base frame (on by default);
- the **obstacles** of the config: boxes, spheres and half-spaces (a table, a wall), fixed in
  the base frame;
- the **clearance margin** ``clearance_m`` (default 0.03 m) every checked pair must keep;
- the **torque limits**, the URDF ``effort`` of each joint with the nominal model's inverse
  dynamics (``pin.rnea``), next to the position, velocity and acceleration limits.

Which pairs are checked, and why the others are not, is the rule of
:mod:`~ident.excitation.safety.pairs`. The package's rooms, one concept each:

==================  ===========================================================================
``config``          the ``safety`` section (:class:`SafetyConfig`) and its bounds
``geometry``        the collision geometry loaded, its convex hulls and screenings cached
``environment``     the floor, the obstacles, a payload's box; environment pairs judged once
``pairs``           which link pairs are checked: adjacency, the SRDF, the candidates
``exclusions``      the sampled-posture rules: contact exclusions, the margin settled
``bounds``          cheap bounds: motion coefficients, reach, bounding spheres
``distances``       coal's distances and collisions of geometry pairs, the checked pairs
``certificate``     the exact clearances the dense check certifies
``fast``            the optimizer's cheap clearances (``primitives``: its compiled kernels)
``model``           :class:`SafetyModel`, :func:`build_safety_model`
``terms``           the cheap constraint terms of a swarm: clearances, torques
==================  ===========================================================================

References
----------
J. Carpentier et al., "The Pinocchio C++ library", SII 2019 (``GeometryModel``); coal
(formerly hpp-fcl) for GJK/EPA signed distances.
"""

from __future__ import annotations

# the private names (``x as x``) are re-exported for the tests and benchmarks that import them
from ident.excitation.safety.config import (
    ALWAYS_IN_CONTACT_FRACTION,
    DEFAULT_CLEARANCE_M,
    MAX_CLEARANCE_M,
    MAX_OBSTACLES,
    MAX_SIZE_M,
    MIN_LOWERED_CLEARANCE_M,
    N_EXCLUSION_POSTURES,
    PAYLOAD,
    BoxObstacle,
    FloorConfig,
    ObstacleConfig,
    PayloadBox,
    PlaneObstacle,
    SafetyConfig,
    SphereObstacle,
)
from ident.excitation.safety.geometry import _SCREENED as _SCREENED
from ident.excitation.safety.geometry import MESH_FIX, collision_geometry_problem
from ident.excitation.safety.geometry import (
    _kinematic_model_and_geometry as _kinematic_model_and_geometry,
)
from ident.excitation.safety.model import SafetyModel, build_safety_model, clearances
from ident.excitation.safety.pairs import _read_srdf as _read_srdf
from ident.excitation.safety.terms import _subsample as _subsample
from ident.excitation.safety.terms import collision_violations, joint_torques, torque_violations

__all__ = [
    "ALWAYS_IN_CONTACT_FRACTION",
    "DEFAULT_CLEARANCE_M",
    "MAX_CLEARANCE_M",
    "MAX_OBSTACLES",
    "MAX_SIZE_M",
    "MESH_FIX",
    "MIN_LOWERED_CLEARANCE_M",
    "N_EXCLUSION_POSTURES",
    "BoxObstacle",
    "FloorConfig",
    "ObstacleConfig",
    "PAYLOAD",
    "PayloadBox",
    "PlaneObstacle",
    "SafetyConfig",
    "SafetyModel",
    "SphereObstacle",
    "build_safety_model",
    "clearances",
    "collision_geometry_problem",
    "collision_violations",
    "joint_torques",
    "torque_violations",
]
