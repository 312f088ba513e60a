"""The ``safety`` section of a run config: the floor, the obstacles, a payload's box, the
clearance margin and the other switches (:class:`SafetyConfig`), with the bounds that keep
their sizes sane and the names the checked pairs use for the floor and the payload.
"""

from __future__ import annotations

import math
from pathlib import Path

from pydantic import Field, field_validator, model_validator

from ident.config import StrictModel

__all__ = [
    "ALWAYS_IN_CONTACT_FRACTION",
    "DEFAULT_CLEARANCE_M",
    "FLOOR",
    "MAX_CLEARANCE_M",
    "MAX_OBSTACLES",
    "MAX_SIZE_M",
    "MIN_LOWERED_CLEARANCE_M",
    "N_EXCLUSION_POSTURES",
    "PAYLOAD",
    "BoxObstacle",
    "FloorConfig",
    "ObstacleConfig",
    "PayloadBox",
    "PlaneObstacle",
    "SafetyConfig",
    "SphereObstacle",
]

DEFAULT_CLEARANCE_M = 0.03
# the default margin is halved down to this while a link pair cannot keep it [m]
MIN_LOWERED_CLEARANCE_M = 0.002
# a hull distance above this (or above a margin by this) proves the meshes apart: GJK's
# tolerance (1e-6 m) with room to spare [m]
_SCREEN_SLACK_M = 1e-4
N_EXCLUSION_POSTURES = 1000  # random postures of the "always in contact" rule (MoveIt: 1000+)
ALWAYS_IN_CONTACT_FRACTION = 0.95  # MoveIt setup assistant's default
MAX_SIZE_M = 100.0  # obstacle sizes and positions, floor height [m]
MAX_CLEARANCE_M = 10.0  # the margin [m]; also below the robot's reach
MAX_OBSTACLES = 256
MAX_PAYLOAD_SIZE_M = 5.0  # payload box edges and offset from its link [m]
MOUNT_TOLERANCE_M = 0.01  # a base (or a link turning in place) may sink this deep [m] ...
# ... or, for a larger geometry, up to its bounding radius: deeper, it is inside the obstacle
FLOOR = "floor"
PAYLOAD = "payload"  # the link name of the payload's box in pair names ("payload|floor")

Vector3 = tuple[float, float, float]


def _near_robot(value: Vector3) -> Vector3:
    if max(abs(v) for v in value) > MAX_SIZE_M:
        raise ValueError(
            f"position {list(value)} is more than {MAX_SIZE_M:g} m from the robot's base "
            "(millimetres typed as metres?)"
        )
    return value


def _box_edges(value: Vector3, limit: float, what: str) -> Vector3:
    """``value``, a box's edge lengths [m], each in ``(0, limit]``."""
    if min(value) <= 0.0 or max(value) > limit:
        raise ValueError(
            f"every {what} edge must be in (0, {limit:g}] m, got {list(value)} "
            "(millimetres typed as metres?)"
        )
    return value


# ---------------------------------------------------------------------- config schema
class FloorConfig(StrictModel):
    """The floor: the half-space ``z <= z`` of the base frame [m]."""

    enabled: bool = True
    z: float = Field(default=0.0, ge=-MAX_SIZE_M, le=MAX_SIZE_M)


class BoxObstacle(StrictModel):
    """A box: edge lengths ``size`` [m], centre ``position`` [m], orientation ``rpy`` [rad]."""

    size: Vector3
    position: Vector3 = (0.0, 0.0, 0.0)
    rpy: Vector3 = (0.0, 0.0, 0.0)

    @field_validator("size")
    @classmethod
    def _positive(cls, value: Vector3) -> Vector3:
        return _box_edges(value, MAX_SIZE_M, "box")

    @field_validator("position")
    @classmethod
    def _near(cls, value: Vector3) -> Vector3:
        return _near_robot(value)


class SphereObstacle(StrictModel):
    """A sphere of ``radius`` [m] centred at ``position`` [m]."""

    radius: float = Field(gt=0.0, le=MAX_SIZE_M)
    position: Vector3 = (0.0, 0.0, 0.0)

    @field_validator("position")
    @classmethod
    def _near(cls, value: Vector3) -> Vector3:
        return _near_robot(value)


class PlaneObstacle(StrictModel):
    """A half-space: the solid side is ``normal . p <= offset`` [m].

    ``normal`` points into the free space (it is normalized on use): a wall 1 m in front of
    the robot along x is ``{normal: [-1, 0, 0], offset: -1.0}``; a table top at 0.2 m under the
    base is ``{normal: [0, 0, 1], offset: -0.2}``.
    """

    normal: Vector3
    offset: float = Field(ge=-MAX_SIZE_M, le=MAX_SIZE_M)

    @field_validator("normal")
    @classmethod
    def _nonzero(cls, value: Vector3) -> Vector3:
        if math.hypot(*value) < 1e-12:
            raise ValueError("plane normal must not be the zero vector")
        return value


class ObstacleConfig(StrictModel):
    """One obstacle: exactly one of ``box``, ``sphere``, ``plane``; optional ``name``."""

    name: str | None = None
    box: BoxObstacle | None = None
    sphere: SphereObstacle | None = None
    plane: PlaneObstacle | None = None

    @model_validator(mode="after")
    def _exactly_one(self) -> ObstacleConfig:
        given = [k for k in ("box", "sphere", "plane") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(
                "an obstacle is exactly one of box, sphere, plane, e.g. "
                "{box: {size: [1.0, 0.6, 0.05], position: [0.8, 0.0, 0.3]}}; "
                f"got {', '.join(given) or 'none'}"
            )
        return self

    @property
    def kind(self) -> str:
        """``"box"``, ``"sphere"`` or ``"plane"``."""
        return next(k for k in ("box", "sphere", "plane") if getattr(self, k) is not None)


class PayloadBox(StrictModel):
    """The bounding box of a payload (a tool, a grasped object) rigidly attached to a link.

    ``size``: edge lengths [m]; ``position``: the box centre and ``rpy``: its orientation [rad],
    both in the frame of ``link`` (a URDF link or frame name; ``null``: the last moving joint's
    frame, the frame of the last link). The box joins the robot's collision geometry as a link
    named ``payload``: it is checked against the floor, the obstacles and every robot link
    except those rigidly attached to it (the same joint); a link adjacent to it is checked too.
    """

    size: Vector3
    position: Vector3 = (0.0, 0.0, 0.0)
    rpy: Vector3 = (0.0, 0.0, 0.0)
    link: str | None = None

    @field_validator("size")
    @classmethod
    def _positive(cls, value: Vector3) -> Vector3:
        return _box_edges(value, MAX_PAYLOAD_SIZE_M, "payload box")

    @field_validator("position")
    @classmethod
    def _near(cls, value: Vector3) -> Vector3:
        if max(abs(v) for v in value) > MAX_PAYLOAD_SIZE_M:
            raise ValueError(
                f"payload box centre {list(value)} is more than {MAX_PAYLOAD_SIZE_M:g} m from "
                "its link (millimetres typed as metres?)"
            )
        return value


class SafetyConfig(StrictModel):
    """The ``safety`` section of a run config.

    ```yaml
    safety:
      floor: {enabled: true, z: 0.0}
      obstacles:
        - {name: table, box: {size: [1.0, 0.6, 0.05], position: [0.8, 0.0, 0.3]}}
        - {sphere: {radius: 0.1, position: [0.5, 0.5, 0.8]}}
        - {name: wall, plane: {normal: [-1.0, 0.0, 0.0], offset: -1.2}}
      clearance_m: 0.03
      self_collision: true
      torque_limits: true
      check_rate_hz: 1000
      check_samples: 16
      payload_box: {size: [0.1, 0.1, 0.2], position: [0.0, 0.0, 0.1], link: tool0}
    ```

    ``check_samples`` is the number of samples per period at which the optimization's cheap
    constraint term measures the clearances; ``check_rate_hz`` (>= 1000) the rate of the
    dense check of the chosen trajectories. ``srdf`` is a MoveIt SRDF whose
    ``<disable_collisions link1= link2= reason=/>`` pairs are not checked (relative to the
    config file). Sizes are bounded: obstacles and the floor within :data:`MAX_SIZE_M` of the
    base, at most :data:`MAX_OBSTACLES` obstacles, ``clearance_m`` at most
    :data:`MAX_CLEARANCE_M` (and below the robot's reach, checked with the robot).
    """

    floor: FloorConfig = FloorConfig()
    obstacles: tuple[ObstacleConfig, ...] = Field(default=(), max_length=MAX_OBSTACLES)
    clearance_m: float = Field(default=DEFAULT_CLEARANCE_M, ge=0.0, le=MAX_CLEARANCE_M)
    self_collision: bool = True
    srdf: Path | None = None
    torque_limits: bool = True
    check_rate_hz: float = Field(default=1000.0, ge=1000.0)
    check_samples: int = Field(default=16, ge=1)
    payload_box: PayloadBox | None = None
