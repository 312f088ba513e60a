"""Cheap bounds of the robot's geometry, measured once when a safety model is built.

- how far a geometry's points can move per unit of joint motion (:func:`_motion_coefficients`,
  per checked pair :func:`_pair_motion_coefficients`): the dense check bounds a pair's
  distance between two samples with them;
- the robot's reach (:func:`_reach`): a margin beyond it cannot be kept;
- the distance of the spheres around two geometries (:func:`_sphere_bounds`), a lower bound of
  theirs: the first screening of the exclusion postures.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.dynamics.chain import chain_from_model
from ident.excitation.family import FloatArray

__all__: list[str] = []


def _bounding_radius(obj: pin.GeometryObject) -> float:
    """Radius [m] of a ball about the parent joint's origin that holds the geometry."""
    shape = obj.geometry
    shape.computeLocalAABB()
    centre = obj.placement.act(np.asarray(shape.aabb_center, dtype=float))
    return float(np.linalg.norm(centre) + float(shape.aabb_radius))


def _motion_coefficients(model: pin.Model, geom: pin.GeometryModel, n_robot: int) -> FloatArray:
    """Per robot geometry, how far its points can move per unit of each joint's motion.

    Row ``g``, column ``v``: for a revolute ancestor joint, a bound on the distance of the
    geometry's points from the joint's origin [m] (the joint offsets along the chain plus the
    geometry's bounding radius, whatever the posture); 1 for a prismatic ancestor; 0 for
    joints that do not move it. A point's displacement over a step is at most
    ``row . |dq| dt``. Shape (n_robot, nv).
    """
    out = np.zeros((n_robot, model.nv))
    offsets = [
        float(np.linalg.norm(model.jointPlacements[j].translation)) for j in range(model.njoints)
    ]
    chain = chain_from_model(model)  # a mimic joint moves with its leader: |m| per unit of it
    for g in range(n_robot):
        obj = geom.geometryObjects[g]
        reach = _bounding_radius(obj)
        j = int(obj.parentJoint)
        while j > 0:
            scale = abs(float(chain.scaling[j - 1]))
            out[g, chain.coordinates[j - 1]] += scale * (1.0 if chain.prismatic[j - 1] else reach)
            reach += offsets[j]
            j = int(model.parents[j])
    return out


def _reach(
    model: pin.Model,
    objects: Sequence[pin.GeometryObject],
    joint_of: Sequence[int],
    coefficients: FloatArray,
) -> float:
    """A bound [m] on the distance of any point of the robot from its base: for each of the
    robot's objects (``joint_of``: its parent joint), the first joint's offset plus the
    object's motion coefficient about it, or its bounding radius when fixed to the base."""
    offsets = [float(np.linalg.norm(p.translation)) for p in model.jointPlacements]
    return max(
        (
            float(coefficients[g, model.joints[1].idx_v]) + offsets[1]
            if joint_of[g] > 0
            else _bounding_radius(objects[g])
            for g in range(len(joint_of))
        ),
        default=0.0,
    )


def _pair_motion_coefficients(
    coefficients: FloatArray,
    n_environment: int,
    pairs: Sequence[tuple[int, int, str, str]],
    group: npt.NDArray[np.int64],
    n_pairs: int,
    nv: int,
) -> FloatArray:
    """Read-only shape (n_pairs, nv): per checked pair, the largest over its geometry
    ``pairs`` (row ``group[p]``) of the robot objects' ``coefficients`` (shape
    (n_robot, nv); 0 for the environment) of the joints that move one side but not both."""
    out = np.zeros((n_pairs, nv))
    padded = np.vstack([coefficients, np.zeros((n_environment, nv))])
    for p, (a, b, _, _) in enumerate(pairs):
        # the joints above both bodies move them together: only the others change the
        # pair's relative posture (for an environment pair, every joint above the link)
        common = (padded[a] > 0.0) & (padded[b] > 0.0)
        row = out[group[p]]
        np.maximum(row, np.where(common, 0.0, padded[a] + padded[b]), out=row)
    out.setflags(write=False)
    return out


def _sphere_bounds(
    model: pin.Model,
    geom: pin.GeometryModel,
    pairs: Sequence[tuple[int, int]],
    postures: FloatArray,
) -> FloatArray:
    """Distances of the spheres around the geometry ``pairs`` (each about its local bounding
    box's centre, of the box's half-diagonal: it holds the geometry) at ``postures`` [m],
    shape (n_postures, n_pairs): a lower bound of the geometries' distance."""
    objects = geom.geometryObjects
    used = sorted({g for pair in pairs for g in pair})
    centre = np.zeros((len(objects), 3))
    radius = np.zeros(len(objects))
    joint = np.zeros(len(objects), dtype=int)
    for g in used:
        shape = objects[g].geometry
        shape.computeLocalAABB()
        centre[g] = objects[g].placement.act(np.asarray(shape.aabb_center, dtype=float))
        radius[g] = float(shape.aabb_radius)
        joint[g] = int(objects[g].parentJoint)
    data = model.createData()
    rotation = np.empty((postures.shape[0], model.njoints, 3, 3))
    translation = np.empty((postures.shape[0], model.njoints, 3))
    for s, q in enumerate(postures):
        pin.forwardKinematics(model, data, q)
        for j in range(model.njoints):
            rotation[s, j] = data.oMi[j].rotation
            translation[s, j] = data.oMi[j].translation
    world = np.einsum("sgij,gj->sgi", rotation[:, joint], centre) + translation[:, joint]
    a, b = (np.array([pair[k] for pair in pairs], dtype=int) for k in (0, 1))
    gap = np.linalg.norm(world[:, a] - world[:, b], axis=2)
    return np.asarray(gap - radius[a] - radius[b])
