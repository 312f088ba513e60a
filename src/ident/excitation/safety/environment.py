"""The robot's surroundings in its collision geometry: the floor, the obstacles and a
payload's box, and the environment pairs judged before any motion.

The floor is the half-space ``z <= floor.z`` of the base frame; obstacles (boxes, spheres,
half-spaces) are fixed in the base frame (:func:`_add_environment`); a payload's box moves
with its link (:func:`_attach_payload_box`). Every robot geometry is checked against each of
them; a pair whose distance no motion changes is judged once (:func:`_judge_candidates`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.errors import ConfigError
from ident.excitation.family import FloatArray
from ident.excitation.safety.config import (
    _SCREEN_SLACK_M,
    FLOOR,
    MOUNT_TOLERANCE_M,
    PAYLOAD,
    ObstacleConfig,
    PayloadBox,
    SafetyConfig,
)
from ident.excitation.safety.distances import _collisions, _exact_distances
from ident.excitation.safety.geometry import _Hulls
from ident.excitation.safety.pairs import ExcludedPair

__all__: list[str] = []  # the package's own steps, imported by name


def _rpy_matrix(rpy: Sequence[float]) -> FloatArray:
    return np.asarray(pin.rpy.rpyToMatrix(*[float(v) for v in rpy]))


def _obstacle_geometry(obstacle: ObstacleConfig) -> tuple[Any, pin.SE3]:
    import coal

    if obstacle.box is not None:
        box = obstacle.box
        pose = pin.SE3(_rpy_matrix(box.rpy), np.asarray(box.position, dtype=float))
        return coal.Box(*[float(s) for s in box.size]), pose
    if obstacle.sphere is not None:
        sphere = obstacle.sphere
        return coal.Sphere(float(sphere.radius)), pin.SE3(
            np.eye(3), np.asarray(sphere.position, dtype=float)
        )
    plane = obstacle.plane
    assert plane is not None  # by ObstacleConfig's validator
    normal = np.asarray(plane.normal, dtype=float)
    norm = float(np.linalg.norm(normal))
    return coal.Halfspace(normal / norm, float(plane.offset) / norm), pin.SE3.Identity()


def _attach_payload_box(model: pin.Model, geom: pin.GeometryModel, box: PayloadBox) -> None:
    """Add the payload's box to ``geom`` on a new frame :data:`PAYLOAD` of ``model``.

    The frame sits at the box centre, on ``box.link``'s joint (``null``: the last joint), so
    the box moves rigidly with that link and its pairs are named ``payload|...``.

    Raises
    ------
    ConfigError
        If ``box.link`` is not a frame of the model (the message lists the frames of the
        last joint), or the model already has a frame named :data:`PAYLOAD`.
    """
    import coal

    if model.existFrame(PAYLOAD):
        raise ConfigError(
            f"safety.payload_box: the robot already has a link or frame named {PAYLOAD!r}; "
            "rename it in the URDF or leave payload_box out."
        )
    if box.link is None:
        joint = model.njoints - 1
        parent = model.getFrameId(model.names[joint], pin.FrameType.JOINT)
        link_in_joint = pin.SE3.Identity()
    else:
        if not model.existFrame(box.link):
            last = model.njoints - 1
            frames = [f.name for f in model.frames if f.parentJoint == last]
            raise ConfigError(
                f"safety.payload_box.link: {box.link!r} is not a link or frame of the robot; "
                f"frames of the last link: {', '.join(frames)} (null: the last joint's frame)."
            )
        parent = model.getFrameId(box.link)
        frame = model.frames[parent]
        joint, link_in_joint = int(frame.parentJoint), frame.placement
    box_in_link = pin.SE3(_rpy_matrix(box.rpy), np.asarray(box.position, dtype=float))
    placement = link_in_joint * box_in_link  # box centre in the parent joint's frame
    frame_id = model.addFrame(pin.Frame(PAYLOAD, joint, parent, placement, pin.FrameType.OP_FRAME))
    shape = coal.Box(*[float(s) for s in box.size])
    geom.addGeometryObject(pin.GeometryObject(PAYLOAD, joint, frame_id, placement, shape))


def _add_environment(geom: pin.GeometryModel, config: SafetyConfig) -> list[str]:
    """Add the floor and the obstacles of ``config`` to ``geom``; their names, in order.

    Obstacles are attached to the universe (joint 0, frame 0), fixed in the base frame.
    """
    import coal

    environment: list[str] = []
    if config.floor.enabled:
        floor = coal.Halfspace(np.array([0.0, 0.0, 1.0]), float(config.floor.z))
        geom.addGeometryObject(pin.GeometryObject(FLOOR, 0, 0, pin.SE3.Identity(), floor))
        environment.append(FLOOR)
    for k, obstacle in enumerate(config.obstacles):
        name = obstacle.name or f"obstacle_{k + 1}_{obstacle.kind}"
        shape, pose = _obstacle_geometry(obstacle)
        geom.addGeometryObject(pin.GeometryObject(name, 0, 0, pose, shape))
        environment.append(name)
    return environment


def _estimate_environment(n_robot: int, n_environment: int) -> None:
    """Warn with an estimate of the time when many environment pairs are checked."""
    n_pairs = n_robot * n_environment
    if n_pairs <= 200:
        return
    import warnings

    from ident.errors import IdentWarning

    seconds = n_pairs * 101 * 5e-6  # collision tests of the environment pairs, then distances
    warnings.warn(
        f"safety: {n_environment} environment objects (floor, obstacles) x {n_robot} robot "
        f"geometries = {n_pairs} pairs: "
        f"about {seconds:.0f} s to judge them, then about {n_pairs * 10e-6 * 1000:.0f} s per "
        "1000 postures the optimizer or the check measures (the run's estimate includes it).",
        IdentWarning,
        stacklevel=3,
    )


def _constant_pairs(
    objects: Sequence[pin.GeometryObject],
    candidates: Sequence[tuple[int, int, str, str]],
    constant: Mapping[int, float],
) -> tuple[ExcludedPair, ...]:
    """The ``candidates`` no motion changes (``constant``: candidate index -> distance [m]),
    named by the robot object and the environment object."""
    return tuple(
        ExcludedPair(
            f"{objects[candidates[k][0]].name}|{candidates[k][2].split('|', 1)[1]}",
            f"constant distance {d:.4f} m (no joint moves one relative to the other); judged once",
        )
        for k, d in constant.items()
    )


def _judge_candidates(
    model: pin.Model,
    geom: pin.GeometryModel,
    hulls: _Hulls,
    candidates: list[tuple[int, int, str, str]],
    postures: FloatArray,
    clearance_m: float,
    home_q: npt.ArrayLike | None,
) -> dict[int, float]:
    """Check the environment pairs before any motion; return those of constant distance.

    A robot geometry fixed to the base, or one whose distance to an obstacle no joint
    changes (a first link turning on the floor), has one distance: below
    ``-MOUNT_TOLERANCE_M`` (inside the floor or an obstacle) it is an input error;
    otherwise the pair is judged once and not checked along trajectories. Any other
    environment pair closer than the margin ``clearance_m`` [m] in every sampled posture (the
    first 101 ``postures``), or at the home posture when one is given, is an input error.
    ``hulls``: ``geom`` with meshes as their hulls, which screen the postures.
    """
    env = [k for k, c in enumerate(candidates) if c[3] != "self"]
    constant: dict[int, float] = {}
    if not env:
        return constant
    pairs = [(candidates[k][0], candidates[k][1]) for k in env]
    n_env = min(postures.shape[0], 101)
    # the hulls screen: hulls apart by the margin are meshes apart by it
    hull = _exact_distances(model, hulls.get(), pairs, postures[:n_env])
    near = hull < clearance_m + _SCREEN_SLACK_M
    within = _collisions(model, geom, pairs, postures[:n_env], clearance_m, near)
    always = [env[i] for i in np.flatnonzero(within.all(axis=0))]
    if always:
        probe = postures[: min(n_env, 6)]
        constant = _constant_or_close(model, geom, candidates, always, probe, clearance_m, n_env)
    if home_q is not None:
        rest = [k for k in env if k not in constant]
        _check_home(model, geom, candidates, rest, home_q, clearance_m)
    return constant


def _constant_or_close(
    model: pin.Model,
    geom: pin.GeometryModel,
    candidates: list[tuple[int, int, str, str]],
    always: list[int],
    probe: FloatArray,
    clearance_m: float,
    n_env: int,
) -> dict[int, float]:
    """The distances [m] of the ``candidates`` numbered ``always`` (closer than the margin
    ``clearance_m`` in every one of ``n_env`` sampled postures): constant over the ``probe``
    postures (no joint moves one relative to the other) and not inside the obstacle; any
    other is a :class:`ConfigError`."""
    constant: dict[int, float] = {}
    d = _exact_distances(model, geom, [(candidates[k][0], candidates[k][1]) for k in always], probe)
    for i, k in enumerate(always):
        a, _, name, _ = candidates[k]
        link, obstacle = name.split("|", 1)
        if np.ptp(d[:, i]) <= 1e-6:
            shape = geom.geometryObjects[a].geometry
            shape.computeLocalAABB()
            if d[0, i] < -max(MOUNT_TOLERANCE_M, float(shape.aabb_radius)):
                raise ConfigError(
                    f"safety: the robot's {link} is {-d[0, i]:.3f} m inside "
                    f"{'the floor' if obstacle == FLOOR else repr(obstacle)} whatever "
                    "its joints do; check the obstacle's position and size (and "
                    "safety.floor.z) in metres."
                )
            constant[k] = float(d[0, i])
        else:
            raise ConfigError(
                f"safety: the robot's {link} is closer than clearance_m = "
                f"{clearance_m:g} m to "
                f"{'the floor' if obstacle == FLOOR else repr(obstacle)} in every one "
                f"of {n_env} sampled postures (e.g. {d[0, i]:.3f} m in the reference "
                "posture); move the obstacle (positions in metres, base frame) or "
                "lower the margin."
            )
    return constant


def _check_home(
    model: pin.Model,
    geom: pin.GeometryModel,
    candidates: list[tuple[int, int, str, str]],
    rest: list[int],
    home_q: npt.ArrayLike,
    clearance_m: float,
) -> None:
    """Raise a :class:`ConfigError` if a robot geometry of the ``candidates`` numbered
    ``rest`` is closer than ``clearance_m`` [m] to its obstacle at ``home_q`` [rad]."""
    home = np.asarray(home_q, dtype=float)[None, :]
    pairs = [(candidates[k][0], candidates[k][1]) for k in rest]
    d = _exact_distances(model, geom, pairs, home)[0]
    for i, k in enumerate(rest):
        if d[i] < clearance_m:
            link, obstacle = candidates[k][2].split("|", 1)
            raise ConfigError(
                f"controller.home: the robot's {link} is {d[i]:.3f} m from "
                f"{'the floor' if obstacle == FLOOR else repr(obstacle)}, below "
                f"safety.clearance_m = {clearance_m:g} m; choose another home "
                "posture or move the obstacle."
            )
