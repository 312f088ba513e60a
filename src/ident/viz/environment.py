"""What a replay shows around the robot: the floor, the obstacles, the moment of least clearance.

The replay draws plain data (:class:`ReplayEnvironment`, :class:`ClearanceMark`); the run's
``result.json`` (its ``config.safety`` section and the elites' ``safety_series``) is turned
into that data here, so the replay written with a run and ``ident replay RUN`` show the same
scene and trace the same frame (:func:`run_traced_frame`).

Drawing (meshcat paths, under the scene root ``/meshcat/replay``)::

    floor                          semi-opaque slab whose top is the floor height
    robot_<k>/environment/<name>   each obstacle, in robot k's base frame
    robot_<k>/closest              sphere at the closest link at the time of least clearance

A plane obstacle (a half-space) is drawn as a large thin slab on its boundary, on its solid
side.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin

from ident.errors import DataError

__all__ = [
    "ClearanceMark",
    "ReplayEnvironment",
    "draw_environment",
    "run_clearance_mark",
    "run_environment",
    "run_traced_frame",
]

FLOOR_COLOR = 0x868E96
OBSTACLE_COLOR = 0xE8590C
CLOSEST_COLOR = 0xE03131
# Size of the slab that stands for an unbounded plane obstacle [m].
_PLANE_SIZE = 4.0
_SLAB = 0.004  # thickness of the floor and plane slabs [m]


@dataclass(frozen=True)
class ClearanceMark:
    """The moment of smallest clearance of one replayed trajectory.

    Attributes
    ----------
    time :
        Time of the smallest clearance [s], on the trajectory's time axis.
    pair :
        ``<link>|<link or obstacle>``; the first name that is a frame of the robot is marked.
    clearance :
        The clearance [m].
    """

    time: float
    pair: str
    clearance: float

    def describe(self) -> str:
        """``smallest clearance 41.7 mm (link_4|flange) at t = 1.254 s``."""
        return (
            f"smallest clearance {1000.0 * self.clearance:.1f} mm ({self.pair}) at "
            f"t = {self.time:.3f} s"
        )


@dataclass(frozen=True)
class ReplayEnvironment:
    """The robot's surroundings as plain data.

    Attributes
    ----------
    floor_z :
        Height of the floor in the base frame [m], ``None``: no floor drawn.
    obstacles :
        Obstacles in the ``safety.obstacles`` form of a run config: mappings with an
        optional ``name`` and one of ``box`` ({size, position, rpy}), ``sphere`` ({radius,
        position}) or ``plane`` ({normal, offset}) [m, rad].
    """

    floor_z: float | None = 0.0
    obstacles: tuple[Mapping[str, Any], ...] = ()


def run_traced_frame(data: Mapping[str, Any]) -> str | None:
    """The frame a run's replay traces, from its ``result.json`` content.

    The excitation family's traced point (``excitation.traced_frame``, or a top-level
    ``traced_frame``); for a family without one, the wrist centre for the arm stage (the point
    the arm positions); else ``None`` (the replay's default, the flange).
    """
    excitation = data.get("excitation")
    frame = data.get("traced_frame") or (
        excitation.get("traced_frame") if isinstance(excitation, Mapping) else None
    )
    if isinstance(frame, str):
        return frame
    config = data.get("config")
    if isinstance(config, Mapping) and config.get("stage") == "arm":
        return "wrist_centre"
    return None


def _damaged(field: str, value: Any, expected: str) -> DataError:
    return DataError(
        f"result.json: {field} is {str(value)[:80]!r}, not {expected}; the run folder is "
        "damaged (replay it with --urdf and --trajectory, or run it again)."
    )


def _number(value: Any, field: str) -> float:
    """``value`` as a finite float, else :class:`DataError` naming ``field``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _damaged(field, value, "a number")
    number = float(value)
    if not math.isfinite(number):
        raise _damaged(field, value, "a finite number")
    return number


def _objects(value: Any, field: str) -> list[Mapping[str, Any]]:
    """``value`` as a list of JSON objects (``None``: empty), else :class:`DataError`."""
    if value is None:
        return []
    if not isinstance(value, list) or not all(isinstance(v, Mapping) for v in value):
        raise _damaged(field, value, "a list of objects")
    return value


def run_environment(data: Mapping[str, Any]) -> ReplayEnvironment:
    """The floor and obstacles of a run's ``config.safety`` (defaults: a floor at z = 0).

    Raises
    ------
    DataError
        A field of ``result.json`` that is not what ``ident run`` writes.
    """
    config = data.get("config")
    safety = config.get("safety") if isinstance(config, Mapping) else None
    if not isinstance(safety, Mapping):
        return ReplayEnvironment()
    floor = safety.get("floor")
    floor_z: float | None = 0.0
    if isinstance(floor, Mapping):
        enabled = floor.get("enabled", True)
        floor_z = _number(floor.get("z", 0.0), "config.safety.floor.z") if enabled else None
    obstacles = tuple(_objects(safety.get("obstacles"), "config.safety.obstacles"))
    for k, obstacle in enumerate(obstacles):
        try:
            made = obstacle_object(obstacle)
        except (TypeError, ValueError, KeyError, IndexError) as e:
            raise _damaged(f"config.safety.obstacles[{k}]", obstacle, f"an obstacle ({e})") from e
        if made is not None and not np.isfinite(made[1]).all():
            raise _damaged(f"config.safety.obstacles[{k}]", obstacle, "a finite pose")
    return ReplayEnvironment(floor_z=floor_z, obstacles=obstacles)


def run_clearance_mark(data: Mapping[str, Any], rank: int) -> ClearanceMark | None:
    """The smallest clearance of elite ``rank`` (its ``safety_series``), or ``None``.

    Raises
    ------
    DataError
        ``elites`` or the elite's ``safety_series`` is not what ``ident run`` writes.
    """
    for k, elite in enumerate(_objects(data.get("elites"), "elites")):
        if elite.get("rank") == rank:
            series = elite.get("safety_series")
            if not isinstance(series, Mapping):
                return None
            when, pair = series.get("closest_time"), series.get("closest_pair")
            value = series.get("closest_clearance")
            if isinstance(pair, str) and when is not None and value is not None:
                field = f"elites[{k}].safety_series"
                return ClearanceMark(
                    _number(when, f"{field}.closest_time"),
                    pair,
                    _number(value, f"{field}.closest_clearance"),
                )
    return None


def _material(color: int, opacity: float) -> mg.MeshLambertMaterial:
    return mg.MeshLambertMaterial(color=color, transparent=opacity < 1.0, opacity=opacity)


def _z_to(normal: np.ndarray) -> np.ndarray:
    """A rotation taking the z axis to the unit vector ``normal``."""
    rotation = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), normal)
    return np.asarray(rotation.toRotationMatrix())


def obstacle_object(obstacle: Mapping[str, Any]) -> tuple[mg.Geometry, np.ndarray] | None:
    """Geometry and pose (4x4, base frame) of one obstacle; ``None`` for an unknown kind."""
    box, sphere, plane = (obstacle.get(k) for k in ("box", "sphere", "plane"))
    if isinstance(box, Mapping):
        pose = pin.SE3(
            np.asarray(pin.rpy.rpyToMatrix(*[float(v) for v in box.get("rpy", (0, 0, 0))])),
            np.asarray(box.get("position", (0, 0, 0)), dtype=float),
        )
        return mg.Box([float(v) for v in box["size"]]), pose.homogeneous
    if isinstance(sphere, Mapping):
        pose = pin.SE3(np.eye(3), np.asarray(sphere.get("position", (0, 0, 0)), dtype=float))
        return mg.Sphere(float(sphere["radius"])), pose.homogeneous
    if isinstance(plane, Mapping):
        normal = np.asarray(plane["normal"], dtype=float)
        length = float(np.linalg.norm(normal))
        normal = normal / length
        offset = float(plane.get("offset", 0.0)) / length
        # the solid side is normal . p <= offset: the slab lies just below the boundary
        centre = normal * (offset - _SLAB / 2)
        pose = pin.SE3(_z_to(normal), centre)
        return mg.Box([_PLANE_SIZE, _PLANE_SIZE, _SLAB]), pose.homogeneous
    return None


def draw_environment(
    vis: meshcat.Visualizer,
    root: str,
    robot_roots: Sequence[str],
    environment: ReplayEnvironment,
    extent: tuple[np.ndarray, np.ndarray],
) -> tuple[str, ...]:
    """Draw the floor (one slab under every robot) and each robot's obstacles.

    Parameters
    ----------
    vis :
        The recording visualizer.
    root :
        Scene root (``replay``); the floor goes to ``<root>/floor``.
    robot_roots :
        Root of each robot (its base frame); obstacles go to ``<robot>/environment/<name>``.
    environment :
        Floor height and obstacles.
    extent :
        Lower and upper corner of everything shown [m], shape (3,) each: the floor covers it.

    Returns
    -------
    :
        meshcat paths of the drawn objects.
    """
    drawn = []
    if environment.floor_z is not None and math.isfinite(environment.floor_z):
        lower, upper = extent
        margin = 0.5 + 0.25 * float(np.max(upper[:2] - lower[:2]))
        size = [float(upper[0] - lower[0]) + 2 * margin, float(upper[1] - lower[1]) + 2 * margin]
        centre = [(lower[0] + upper[0]) / 2, (lower[1] + upper[1]) / 2]
        # top just under the floor height: meshcat's grid (z = 0) stays visible on it
        z = environment.floor_z - _SLAB / 2 - 1e-3
        vis[f"{root}/floor"].set_object(mg.Box([*size, _SLAB]), _material(FLOOR_COLOR, 0.35))
        vis[f"{root}/floor"].set_transform(
            pin.SE3(np.eye(3), np.array([centre[0], centre[1], z])).homogeneous
        )
        drawn.append(f"/meshcat/{root}/floor")
    for robot in robot_roots:
        for k, obstacle in enumerate(environment.obstacles):
            made = obstacle_object(obstacle)
            if made is None:
                continue
            name = str(obstacle.get("name") or f"obstacle_{k}").replace("/", "_")
            path = f"{robot}/environment/{name}"
            vis[path].set_object(made[0], _material(OBSTACLE_COLOR, 0.5))
            vis[path].set_transform(made[1])
            drawn.append(f"/meshcat/{path}")
    return tuple(drawn)
