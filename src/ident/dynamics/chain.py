"""Kinematic chain arrays of a fixed-base serial robot, read from a Pinocchio model.

The regressor kernels work on plain arrays, not on ``pin.Model``: joint placements in the
parent joint frame, joint axes in the joint frame, and a prismatic flag. The frames are
Pinocchio's joint frames, so the regressor built on them uses the same parameter vector as
``pin.computeJointTorqueRegressor`` (inertia about each joint frame origin; fixed links are
already merged into the body of their parent joint by Pinocchio).

A chain may couple joints: a URDF mimic joint made a Pinocchio mimic joint
(:func:`ident.robot.mimic.coupled_model`) keeps its body and joint frame but has no coordinate;
it moves with its leader, ``q_f = m q_l + o``. The chain's ``q`` then holds the independent
joints only (``joint_names``, ``n_joints``) while the kinematic arrays have one row per body
(``body_names``, ``n_bodies``); :meth:`KinematicChain.body_states` expands a state to the bodies
and :meth:`KinematicChain.coupling` projects their torques back (``tau = G^T tau_bodies``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.errors import ModelError
from ident.robot.limits import (  # DEFAULT_Q_RANGE re-exported: the chain's guessed box
    DEFAULT_Q_RANGE,
    JointLimits,
    UnknownLimit,
    default_position_box,
)

__all__ = [
    "BoolArray",
    "FloatArray",
    "IntArray",
    "KinematicChain",
    "DEFAULT_DDQ_MAX",
    "DEFAULT_DQ_MAX",
    "DEFAULT_Q_RANGE",
    "chain_from_model",
    "model_limits",
    "random_states",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]
BoolArray = npt.NDArray[np.bool_]

# Fallback ranges where a model carries no limit (URDFs rarely give accelerations).
DEFAULT_DQ_MAX = 1.0  # [rad/s or m/s]
DEFAULT_DDQ_MAX = 10.0  # [rad/s^2 or m/s^2]

# Pinocchio joint types the chain accepts: 1-DoF, nq == nv == 1, axis in the joint frame.
_REVOLUTE_AXES = {
    "JointModelRX": (1.0, 0.0, 0.0),
    "JointModelRY": (0.0, 1.0, 0.0),
    "JointModelRZ": (0.0, 0.0, 1.0),
}
_PRISMATIC_AXES = {
    "JointModelPX": (1.0, 0.0, 0.0),
    "JointModelPY": (0.0, 1.0, 0.0),
    "JointModelPZ": (0.0, 0.0, 1.0),
}
_UNALIGNED = {"JointModelRevoluteUnaligned": False, "JointModelPrismaticUnaligned": True}

_FIX_HINT = (
    "a fixed-base serial chain of revolute and prismatic joints is needed; fix the URDF "
    "(no floating, planar or spherical joints) or lock the extra joints with "
    "pin.buildReducedModel (ident.Robot.from_urdf(path, lock_joints=...))"
)
_CONTINUOUS_HINT = (
    "load the URDF with ident.Robot.from_urdf, which reads continuous joints as revolute "
    "joints without position limit (nq = 1), or lock it with pin.buildReducedModel"
)


@dataclass(frozen=True, eq=False)  # arrays: no field-wise ==, made read-only
class KinematicChain:
    """Kinematic data of a fixed-base serial chain, in Pinocchio's joint frames.

    Attributes
    ----------
    joint_names :
        Names of the ``n`` independent joints (the coordinates of ``q``), base to tip.
    parents :
        Parent body index of each body, shape (nb,); -1 for the base (universe).
        For a serial chain ``parents[i] == i - 1``.
    placements :
        Placement of each body's joint frame in its parent's at q = 0
        (``model.jointPlacements``), homogeneous transforms [m], shape (nb, 4, 4).
    axes :
        Unit joint axis in the joint frame, shape (nb, 3).
    prismatic :
        True for prismatic joints, False for revolute ones, shape (nb,).
    gravity :
        Gravity vector in the base frame [m/s^2], shape (3,).
    q_lower, q_upper :
        Position limits [rad or m], shape (n,); ``-inf``/``inf`` where unknown.
    dq_max :
        Velocity limits [rad/s or m/s], shape (n,); ``inf`` where unknown.
    tau_max :
        Effort limits [N*m or N], shape (n,); ``inf`` where unknown.
    body_names :
        The joint of each of the ``nb`` bodies, base to tip: ``joint_names`` plus the mimic
        joints (followers); empty (the default) means ``joint_names``.
    coordinates :
        Index in ``q`` of the joint that moves each body, shape (nb,); default ``0..n-1``.
    scaling, offset :
        Each body's joint position is ``scaling * q[coordinates] + offset`` [rad or m],
        shape (nb,); default 1 and 0 (a mimic joint's multiplier and offset otherwise).
    unknown :
        The limits above that are ``inf`` because the model gives none (0 or an empty range),
        with the reason; a continuous joint's unlimited position is not listed.
    """

    joint_names: tuple[str, ...]
    parents: IntArray
    placements: FloatArray
    axes: FloatArray
    prismatic: BoolArray
    gravity: FloatArray
    q_lower: FloatArray
    q_upper: FloatArray
    dq_max: FloatArray
    tau_max: FloatArray
    body_names: tuple[str, ...] = ()
    coordinates: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    scaling: FloatArray = field(default_factory=lambda: np.zeros(0))
    offset: FloatArray = field(default_factory=lambda: np.zeros(0))
    unknown: tuple[UnknownLimit, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        if not self.body_names:  # no mimic joint: one body per coordinate, unscaled
            object.__setattr__(self, "body_names", tuple(self.joint_names))
            object.__setattr__(self, "coordinates", np.arange(n, dtype=np.intp))
            object.__setattr__(self, "scaling", np.ones(n))
            object.__setattr__(self, "offset", np.zeros(n))
        nb = len(self.body_names)
        shapes = {
            "parents": (nb,),
            "placements": (nb, 4, 4),
            "axes": (nb, 3),
            "prismatic": (nb,),
            "coordinates": (nb,),
            "scaling": (nb,),
            "offset": (nb,),
            "gravity": (3,),
            "q_lower": (n,),
            "q_upper": (n,),
            "dq_max": (n,),
            "tau_max": (n,),
        }
        for name, shape in shapes.items():
            value = np.array(getattr(self, name), copy=True)
            if value.shape != shape:
                raise ModelError(
                    f"KinematicChain.{name} must have shape {shape}, got {value.shape}"
                )
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def n_joints(self) -> int:
        """Number of independent joints (= nq = nv; = n_bodies without mimic joints)."""
        return len(self.joint_names)

    @property
    def n_bodies(self) -> int:
        """Number of moving bodies (10 parameters each), mimic joints' bodies included."""
        return len(self.body_names)

    @property
    def joint_bodies(self) -> IntArray:
        """The body of each independent joint, shape (n,) (``0..n-1`` without mimic joints)."""
        return np.array([self.body_names.index(name) for name in self.joint_names], dtype=np.intp)

    @property
    def coupled(self) -> bool:
        """True when some body moves with a mimic joint (``n_bodies > n_joints``)."""
        return self.n_bodies != self.n_joints

    def coupling(self) -> FloatArray:
        """``G`` of shape (nb, n): ``dq_bodies = G @ dq``, ``tau = G^T @ tau_bodies``."""
        out = np.zeros((self.n_bodies, self.n_joints))
        out[np.arange(self.n_bodies), self.coordinates] = self.scaling
        return out

    def body_states(
        self, q: FloatArray, dq: FloatArray, ddq: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Joint positions, velocities and accelerations of every body, (..., nb) each, from
        the independent joints' (..., n): ``q_b = s q[c] + o``, ``dq_b = s dq[c]``, ..."""
        c, s = self.coordinates, self.scaling
        return (
            self.body_positions(q),
            np.ascontiguousarray(dq[..., c] * s),
            np.ascontiguousarray(ddq[..., c] * s),
        )

    def body_positions(self, q: FloatArray) -> FloatArray:
        """Joint position of every body [rad or m], (..., nb), from ``q`` (..., n)."""
        return np.ascontiguousarray(q[..., self.coordinates] * self.scaling + self.offset)

    @property
    def nq(self) -> int:
        """Size of the configuration vector."""
        return self.n_joints

    @property
    def nv(self) -> int:
        """Size of the velocity vector."""
        return self.n_joints

    def position_box(self) -> tuple[FloatArray, FloatArray]:
        """Position limits with unknown ones replaced by ``DEFAULT_Q_RANGE`` (``[-pi, pi]`` rad,
        ``[-1, 1]`` m) [rad or m], shapes (n,)."""
        return default_position_box(self.q_lower, self.q_upper, self.prismatic[self.joint_bodies])


def _joint_axis(joint: pin.JointModel) -> tuple[np.ndarray, bool] | None:
    """Axis in the joint frame and prismatic flag, or None for unsupported joint types."""
    kind = joint.shortname()
    if kind in _REVOLUTE_AXES:
        return np.array(_REVOLUTE_AXES[kind]), False
    if kind in _PRISMATIC_AXES:
        return np.array(_PRISMATIC_AXES[kind]), True
    if kind in _UNALIGNED:
        # Pinocchio uses the stored axis as is (the URDF parser normalizes it)
        return np.array(joint.extract().axis, dtype=float), _UNALIGNED[kind]
    return None


def chain_from_model(model: pin.Model) -> KinematicChain:
    """Read the kinematic chain of a fixed-base serial Pinocchio model.

    Parameters
    ----------
    model :
        Pinocchio model whose joints 1..njoints-1 form a serial chain of 1-DoF revolute
        (about any axis) or prismatic joints, some of which may be Pinocchio mimic joints of an
        earlier one (:func:`ident.robot.mimic.coupled_model`).

    Returns
    -------
    :
        The chain arrays, in Pinocchio's joint frames and joint order; ``joint_names`` are the
        independent joints, ``body_names`` every joint (mimic joints with their leader's
        coordinate, multiplier and offset).

    Raises
    ------
    ModelError
        Naming the offending joint, for a floating-base, multi-DoF, spherical, planar or
        continuous (unbounded, nq = 2) joint, or a branched model. (A URDF ``<mimic>`` tag is
        no error: :meth:`ident.Robot.from_urdf` couples a follower on the chain to its leader
        or locks it with its leader, and names what it does not support.)
    """
    if model.njoints - 1 < 1:
        raise ModelError(f"model {model.name!r} has no joints; {_FIX_HINT}.")
    bodies = _body_arrays(model)
    n_joints = len(bodies["joint_names"])
    if model.nq != n_joints or model.nv != n_joints:
        raise ModelError(
            f"model {model.name!r} has nq={model.nq}, nv={model.nv} for {n_joints} joints; "
            f"{_FIX_HINT}."
        )
    limits = model_limits(model)
    return KinematicChain(
        **bodies,
        gravity=np.array(model.gravity.linear, dtype=float),
        q_lower=limits.q_lower,
        q_upper=limits.q_upper,
        dq_max=limits.dq_max,
        tau_max=limits.tau_max,
        unknown=limits.unknown,
        body_names=tuple(model.names[1:]),
    )


def _body_arrays(model: pin.Model) -> dict[str, Any]:
    """The per-body fields of :class:`KinematicChain` read from ``model`` (``n`` bodies):
    ``joint_names`` (the independent joints), ``parents`` (n,), ``placements`` (n, 4, 4),
    ``axes`` (n, 3), ``prismatic`` (n,) and each body's ``coordinates``, ``scaling`` and
    ``offset`` (n,) (a mimic joint's: its leader's coordinate, multiplier and offset); every
    joint checked by :func:`_serial_joint_axis`.

    Raises
    ------
    ModelError
        Naming the offending joint (:func:`chain_from_model`).
    """
    n = model.njoints - 1
    names: list[str] = []
    axes = np.zeros((n, 3))
    prismatic = np.zeros(n, dtype=bool)
    placements = np.zeros((n, 4, 4))
    parents = np.zeros(n, dtype=np.intp)
    coordinates, scaling, offset = np.zeros(n, dtype=np.intp), np.ones(n), np.zeros(n)
    for i in range(1, model.njoints):
        joint = model.joints[i]
        if joint.shortname() == "JointModelMimic":
            mimic = joint.extract()
            coordinates[i - 1] = joint.idx_q  # the leader's
            scaling[i - 1], offset[i - 1] = float(mimic.scaling), float(mimic.offset)
        else:
            coordinates[i - 1] = len(names)
            names.append(model.names[i])
        axes[i - 1], prismatic[i - 1] = _serial_joint_axis(model, i, int(coordinates[i - 1]))
        placements[i - 1] = model.jointPlacements[i].homogeneous
        parents[i - 1] = int(model.parents[i]) - 1
    return {
        "joint_names": tuple(names),
        "parents": parents,
        "placements": placements,
        "axes": axes,
        "prismatic": prismatic,
        "coordinates": coordinates,
        "scaling": scaling,
        "offset": offset,
    }


def _mimic_axis(model: pin.Model, i: int) -> tuple[np.ndarray, bool] | None:
    """Unit axis and ``prismatic`` of mimic joint ``i``: its motion subspace is the scaled
    axis of the joint it wraps (Pinocchio does not expose that joint)."""
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    motion = np.array(data.joints[i].S, dtype=float).reshape(6)
    scaling = float(model.joints[i].extract().scaling)
    linear, angular = motion[:3] / scaling, motion[3:] / scaling
    if np.any(linear) and np.any(angular):
        return None
    return (linear, True) if np.any(linear) else (angular, False)


# What chain_from_model names a joint it cannot take, by Pinocchio's joint short name.
_UNSUPPORTED_JOINTS = {
    "JointModelFreeFlyer": "a floating base (free-flyer)",
    "JointModelSpherical": "a spherical joint",
    "JointModelSphericalZYX": "a spherical joint",
    "JointModelPlanar": "a planar joint",
    "JointModelTranslation": "a 3-DoF translation joint",
    "JointModelRUBX": "a continuous (unbounded) joint",
    "JointModelRUBY": "a continuous (unbounded) joint",
    "JointModelRUBZ": "a continuous (unbounded) joint",
    "JointModelRevoluteUnboundedUnaligned": "a continuous (unbounded) joint",
}


def _serial_joint_axis(model: pin.Model, i: int, index: int) -> tuple[np.ndarray, bool]:
    """Unit axis (3,) in its joint frame and ``prismatic`` of joint ``i`` (1-based), after
    checking that it is a 1-DoF joint (or a mimic joint of one) of a serial chain with the
    configuration index ``index``.

    Raises :class:`ModelError` naming the joint.
    """
    joint = model.joints[i]
    name = model.names[i]
    kind = joint.shortname()
    mimic = kind == "JointModelMimic"
    found = _mimic_axis(model, i) if mimic else _joint_axis(joint)
    if found is None or (not mimic and (joint.nq != 1 or joint.nv != 1)):
        what = _UNSUPPORTED_JOINTS.get(
            kind, f"a joint of type {kind} (nq={joint.nq}, nv={joint.nv})"
        )
        hint = _CONTINUOUS_HINT if "continuous" in what else _FIX_HINT
        raise ModelError(f"joint {name!r} of model {model.name!r} is {what}; {hint}.")
    if joint.idx_q != index or joint.idx_v != index:
        raise ModelError(
            f"joint {name!r} of model {model.name!r} has configuration index {joint.idx_q} "
            f"(expected {index}); {_FIX_HINT}."
        )
    parent = int(model.parents[i]) - 1
    if parent != i - 2:
        raise ModelError(
            f"model {model.name!r} is branched: joint {name!r} is attached to "
            f"{model.names[parent + 1]!r}, not to the previous joint "
            f"{model.names[i - 1]!r}; {_FIX_HINT}."
        )
    if abs(np.linalg.norm(found[0]) - 1.0) > 1e-9:
        raise ModelError(
            f"joint {name!r} of model {model.name!r} has a non-unit axis {found[0]}; "
            "normalize the joint axis."
        )
    return found


def model_limits(model: pin.Model, source: str = "the model") -> JointLimits:
    """The position, velocity and effort limits of the 1-DoF joints of a Pinocchio model.

    Pinocchio turns a missing limit into 0 (an empty position range, a velocity or effort of
    0): those limits are **unknown**, ``inf`` (``-inf`` for a lower bound) in the arrays and
    listed in ``unknown`` with ``"<source> gives no ... limit"``. Pinocchio's ``+-max float``
    (a continuous joint) is ``+-inf`` and unlimited, not unknown. Accelerations are not in a
    model (``inf``, not listed: the robot lists them).

    Parameters
    ----------
    model :
        Pinocchio model; each joint that is not a mimic follower gives one entry, in order (its
        first configuration and velocity index).
    source :
        Who the reasons blame (``"the URDF"``, ``"the robot description"``).

    Returns
    -------
    :
        Limits of shape (n_independent_joints,) each [rad or m, /s, N*m or N].

    Raises
    ------
    ModelError
        For a joint whose lower position limit is above its upper one.
    """
    independent = [  # a mimic follower's q and v are its leader's
        i for i in range(1, model.njoints) if model.joints[i].shortname() != "JointModelMimic"
    ]
    names = tuple(model.names[i] for i in independent)
    iq = [model.joints[i].idx_q for i in independent]
    iv = [model.joints[i].idx_v for i in independent]

    def limits(values: np.ndarray, index: list[int], fill: float) -> np.ndarray:
        out = np.array(values, dtype=float).reshape(-1)[index]
        out[~np.isfinite(out) | (np.abs(out) >= 1e300)] = fill
        return out

    q_lower = limits(model.lowerPositionLimit, iq, -np.inf)
    q_upper = limits(model.upperPositionLimit, iq, np.inf)
    dq_max = limits(model.velocityLimit, iv, np.inf)
    tau_max = limits(model.effortLimit, iv, np.inf)
    unknown = _unknown_limits(names, (q_lower, q_upper, dq_max, tau_max), source)
    empty = q_upper == q_lower
    q_lower[empty], q_upper[empty] = -np.inf, np.inf
    dq_max[dq_max <= 0.0] = np.inf
    tau_max[tau_max <= 0.0] = np.inf
    axes = [_joint_axis(model.joints[i]) for i in independent]
    prismatic = np.array([axis is not None and axis[1] for axis in axes], dtype=bool)
    return JointLimits(
        names,
        q_lower,
        q_upper,
        dq_max,
        np.full(len(names), np.inf),
        tau_max,
        tuple(unknown),
        prismatic=prismatic,
    )


def _unknown_limits(
    names: tuple[str, ...],
    limits: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
    source: str,
) -> list[UnknownLimit]:
    """The limits Pinocchio's 0 leaves unknown (:func:`model_limits`): a position range of 0
    (a URDF without limits gives 0 and 0), a velocity or effort <= 0, in joint order, each
    blaming ``source``. ``limits`` is ``(q_lower, q_upper, dq_max, tau_max)``, shapes (n,).

    Raises
    ------
    ModelError
        For a joint whose lower position limit is above its upper one.
    """
    q_lower, q_upper, dq_max, tau_max = limits
    unknown = []
    for j, name in enumerate(names):
        if q_upper[j] < q_lower[j]:
            raise ModelError(
                f"joint {name!r}: lower position limit {q_lower[j]:g} is above the upper one "
                f"{q_upper[j]:g}; swap them."
            )
        if q_upper[j] == q_lower[j]:  # a URDF without limits gives 0 and 0
            unknown.append(UnknownLimit("position", name, f"{source} gives no position limit"))
        for kind, values in (("velocity", dq_max), ("torque", tau_max)):
            if values[j] <= 0.0:
                what = "effort" if kind == "torque" else kind
                unknown.append(UnknownLimit(kind, name, f"{source} gives no {what} limit"))
    return unknown


def random_states(
    chain: KinematicChain,
    n_samples: int,
    *,
    rng: np.random.Generator | int | None = None,
    ddq_max: npt.ArrayLike = DEFAULT_DDQ_MAX,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Uniformly random states within the chain's limits.

    Parameters
    ----------
    chain :
        Kinematic chain with its limits.
    n_samples :
        Number of states.
    rng :
        Generator or seed.
    ddq_max :
        Bound of the uniform accelerations [rad/s^2 or m/s^2], scalar or shape (n,) (models
        carry no limit); ``DEFAULT_DDQ_MAX`` where it is not finite.

    Returns
    -------
    :
        ``q`` in ``[q_lower, q_upper]`` (:meth:`KinematicChain.position_box`), ``dq`` in
        ``[-dq_max, dq_max]`` (``DEFAULT_DQ_MAX`` where unknown), ``ddq`` in
        ``[-ddq_max, ddq_max]``; each of shape (n_samples, n).
    """
    rng = np.random.default_rng(rng)
    n = chain.n_joints  # the independent joints (a mimic joint follows its leader)
    lower, upper = chain.position_box()
    dq_max = np.where(np.isfinite(chain.dq_max), chain.dq_max, DEFAULT_DQ_MAX)
    ddq_max = np.asarray(ddq_max, dtype=float)
    ddq_max = np.where(np.isfinite(ddq_max), ddq_max, DEFAULT_DDQ_MAX)
    q = rng.uniform(lower, upper, size=(n_samples, n))
    dq = rng.uniform(-dq_max, dq_max, size=(n_samples, n))
    ddq = rng.uniform(-ddq_max, ddq_max, size=(n_samples, n))
    return q, dq, ddq
