"""The :class:`Robot` facade: a Pinocchio model with names, limits and true parameters.

A ``Robot`` is built from a URDF (:meth:`Robot.from_urdf`) or from a DH robot description
(:meth:`Robot.from_config`, which generates the URDF in memory). It offers the regressor
(hand-derived Newton-Euler from :mod:`ident.dynamics`), inverse dynamics and forward kinematics
through Pinocchio, and random states within the limits. Everything is SI; samples are on axis 0.

Parameters are Pinocchio's standard parameters per body, ``[m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz,
Iyz, Izz]``, about the origin of each body's (URDF link / Pinocchio joint) frame. For a robot
built from a standard-DH config those frames are *not* the DH frames the paper uses;
:meth:`Robot.parameters_dh` and :meth:`Robot.dh_to_model_parameters` give the DH-frame vector and
the linear map between the two.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools

# xml.etree: only the type of the parsed <robot> that robot/urdf_load.prepare_urdf hands over
# (its parsing and the reason for it are there).
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.config import file_problem
from ident.dynamics.chain import chain_from_model, model_limits, random_states
from ident.dynamics.parameters import parameter_names, parameters_from_model
from ident.dynamics.pinocchio_check import pinocchio_rnea
from ident.dynamics.regressor import joint_torque_regressor
from ident.errors import DataError, ModelError
from ident.robot.dh import DHTable
from ident.robot.inertia import transform_matrix
from ident.robot.limits import UnknownLimit
from ident.robot.mimic import (
    Mimic,
    coupled_model,
    follower_limits,
    read_mimics,
    resolve_mimic_locks,
)
from ident.robot.robot_config import RobotDescription, load_robot_config
from ident.robot.urdf import dh_frame_in_link, urdf_from_description
from ident.robot.urdf_load import (
    URDF_INERTIA_RTOL,
    PreparedURDF,
    build_model,
    chain_locks,
    check_inertials,
    continuous_as_revolute,
    lock_values,
    locked_model,
    moving_links,
    prepare_urdf,
    suggested_locks,
    urdf_file_text,
)

__all__ = ["URDF_INERTIA_RTOL", "Robot", "continuous_as_revolute", "suggested_locks"]

FloatArray = npt.NDArray[np.float64]


#: Why a robot has no acceleration limit, per origin (URDFs carry none).
_NO_ACCELERATION = {
    "the URDF": "the URDF gives no acceleration limit (URDFs have none): set "
    "robot.acceleration_limits",
    "the robot description": "the robot description gives no acceleration limit",
}


class Robot:
    """A fixed-base serial robot: Pinocchio model, names, limits and true parameters.

    Attributes
    ----------
    name :
        Robot name.
    model :
        The Pinocchio model (fixed base, serial chain of 1-DoF joints).
    urdf_text :
        The URDF text: generated from the config, or the file as written (continuous joints
        stay continuous and locked joints stay in it, so a copy of it is the user's robot).
    urdf_path :
        The URDF file, or ``None`` when the URDF was generated from a config.
    dh :
        The DH table when built from a config, else ``None``.
    description :
        The full robot description when built from a config, else ``None``.
    joint_names :
        Names of the independent joints (the coordinates of ``q``), base to tip.
    continuous_joints :
        URDF joints declared continuous, modelled as revolute joints without position limit.
    locked_joints :
        URDF joints held fixed (name -> position [rad or m]); not in the model. A mimic joint
        whose leader is locked is locked at its mimic value.
    mimic_joints :
        URDF mimic joints on the chain, each moving with its leader (a Pinocchio mimic joint
        of the model: its body moves, it has no coordinate; see :mod:`ident.robot.mimic`).
    nq, nv, n_bodies :
        Configuration and velocity sizes, number of moving bodies.
    q_lower, q_upper :
        Position limits [rad or m], shape (nq,); ``-inf``/``inf`` where unknown or unlimited
        (a continuous joint).
    dq_max, ddq_max, tau_max :
        Velocity [rad/s or m/s], acceleration [rad/s^2 or m/s^2] and effort [N*m or N]
        limits, shape (nv,); ``inf`` where unknown (URDFs carry no acceleration limits).
    unknown_limits :
        The limits above that nobody gave (:class:`ident.robot.limits.UnknownLimit`: kind,
        joint, reason); every check that needs one names it instead of passing.
    """

    def __init__(
        self,
        model: pin.Model,
        urdf_text: str,
        *,
        urdf_path: Path | None = None,
        description: RobotDescription | None = None,
        ddq_max: npt.ArrayLike | None = None,
    ) -> None:
        self.model = model
        self.urdf_text = urdf_text
        self.urdf_path = urdf_path
        self.description = description
        self.dh: DHTable | None = description.dh if description is not None else None
        self.name: str = description.name if description is not None else model.name
        # the independent joints: a mimic joint (nv = 0) moves with its leader
        self.joint_names: tuple[str, ...] = tuple(
            model.names[i] for i in range(1, model.njoints) if model.nvs[i] > 0
        )
        self.nq: int = model.nq
        self.nv: int = model.nv
        self.n_bodies: int = model.njoints - 1
        source = "the URDF" if description is None else "the robot description"
        limits = model_limits(model, source)  # unknown (0 in Pinocchio) -> inf, with a reason
        self.q_lower: FloatArray = np.array(limits.q_lower)
        self.q_upper: FloatArray = np.array(limits.q_upper)
        self.dq_max: FloatArray = np.array(limits.dq_max)
        self.tau_max: FloatArray = np.array(limits.tau_max)
        self.ddq_max: FloatArray = (
            np.full(self.nv, np.inf) if ddq_max is None else np.array(ddq_max, dtype=float)
        )
        for array in (self.q_lower, self.q_upper, self.dq_max, self.ddq_max, self.tau_max):
            array.setflags(write=False)
        no_acceleration = [
            UnknownLimit("acceleration", name, _NO_ACCELERATION[source])
            for name, value in zip(limits.joint_names, self.ddq_max, strict=False)
            if not np.isfinite(value)
        ]
        self.unknown_limits: tuple[UnknownLimit, ...] = (*limits.unknown, *no_acceleration)
        self.continuous_joints: tuple[str, ...] = ()
        self.locked_joints: dict[str, float] = {}
        self.mimic_joints: tuple[Mimic, ...] = ()
        self.package_dirs: tuple[str, ...] = ()

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_urdf(
        cls,
        path: str | Path,
        *,
        lock_joints: Mapping[str, float] | Sequence[str] | None = None,
        base_link: str | None = None,
        tip_link: str | None = None,
        package_dirs: Sequence[str | Path] = (),
        inertia_check: bool = True,
    ) -> Robot:
        """Load the fixed-base serial chain of a URDF file.

        Continuous joints (``type="continuous"``, which Pinocchio would model with the
        unit-complex configuration ``(cos q, sin q)``, nq = 2) are read as revolute joints without
        a position limit (:func:`ident.robot.urdf_load.continuous_as_revolute`), so every joint
        has nq = nv = 1 and the same dynamics. The inertial of every link that moves is checked
        for physical consistency (positive mass, inertia about the centre of mass positive
        semi-definite with ``I1 + I2 >= I3``, relative tolerance
        :data:`~ident.robot.urdf_load.URDF_INERTIA_RTOL`); links that never move (fixed to the
        world, or behind locked joints only) cannot change the torques and are not checked.
        A mimic joint moves with its leader, ``q_f = m q_l + o``: on the chain it has no
        coordinate (the leader's torque is ``tau_l + m tau_f``, see :mod:`ident.robot.mimic`);
        with its leader locked it is locked at ``m q_lock + o``.

        Parameters
        ----------
        path :
            The URDF file.
        lock_joints :
            Joints to hold fixed, as names (locked at 0) or a mapping name -> position [rad or m]:
            the robot is Pinocchio's reduced model (``pin.buildReducedModel``) without them, so a
            branched URDF (an arm with gripper fingers) becomes a serial chain.
        base_link, tip_link :
            The chain to identify: the joints between these links move, every other joint is
            locked (at its ``lock_joints`` value, else at 0 clipped into its limits).
        package_dirs :
            Folders in which ``package://`` mesh URIs are looked up (visuals and replay only).
        inertia_check :
            ``False`` loads a file whose moving links have impossible inertials (their
            parameters are then whatever the file says).

        Raises
        ------
        ModelError
            Naming the file, if it is missing or malformed, has a physically inconsistent
            inertial on a moving link, names an unknown joint or link, or is not a fixed-base
            serial chain of revolute and prismatic joints once the locked joints are removed,
            or has a mimic joint in a case :mod:`ident.robot.mimic` does not support.
        """
        path = Path(path)
        where = str(path)
        text, prepared, model = _read_urdf(path, package_dirs, where)
        model, locked, coupled = _moving_chain(
            model, prepared.root, lock_joints, (base_link, tip_link), inertia_check, where
        )
        robot = cls(model, text, urdf_path=path)
        robot._keep_urdf_facts(prepared, locked, coupled, package_dirs, where)
        return robot

    @classmethod
    def from_config(cls, path: str | Path) -> Robot:
        """Build a robot from a DH description file (see :mod:`ident.robot.robot_config`).

        The URDF is generated in memory (:func:`ident.robot.urdf.urdf_from_description`), the
        model's gravity is set from the file, and the acceleration limits come from the file.

        Raises
        ------
        ConfigError
            For a missing, malformed or inconsistent description file.
        """
        return cls.from_description(load_robot_config(path))

    @classmethod
    def from_description(cls, description: RobotDescription) -> Robot:
        """Build a robot from an already loaded :class:`RobotDescription`."""
        text = urdf_from_description(description)
        model = build_model(text, str(description.source or description.name))
        model.gravity.linear = np.array(description.gravity, dtype=float)
        robot = cls(model, text, description=description, ddq_max=description.ddq_max)
        robot._check_serial(str(description.source or description.name))
        return robot

    def _keep_urdf_facts(
        self,
        prepared: PreparedURDF,
        locked: dict[str, float],
        coupled: tuple[Mimic, ...],
        package_dirs: Sequence[str | Path],
        where: str,
    ) -> None:
        """What :meth:`from_urdf` learnt from the file ``where``: why a limit is unknown (the
        file says; Pinocchio only has the 0), the continuous, locked and mimic joints and the
        mesh folders; then the chain is checked to be serial."""
        self.unknown_limits = tuple(
            UnknownLimit(u.kind, u.joint, prepared.unknown.get((u.kind, u.joint), u.reason))
            for u in self.unknown_limits
        )
        self.continuous_joints = prepared.continuous
        self.locked_joints = locked
        self._follow_mimics(coupled, where)
        self.package_dirs = tuple(str(p) for p in package_dirs)
        self._check_serial(where)

    def _follow_mimics(self, coupled: tuple[Mimic, ...], where: str) -> None:
        """Keep the chain's mimic joints; narrow their leaders' limits to keep them in range."""
        self.mimic_joints = coupled
        if not coupled:
            return
        limits = follower_limits(
            self.joint_names, self.q_lower, self.q_upper, self.dq_max, coupled, where
        )
        for key, value in zip(("q_lower", "q_upper", "dq_max"), limits, strict=True):
            value.setflags(write=False)
            setattr(self, key, value)

    def _check_serial(self, where: str) -> None:
        try:
            self.chain  # noqa: B018 - builds and validates the chain
        except ModelError as e:
            message = f"{where}: {e}"
            locks = suggested_locks(self.model)
            if locks and "branched" in message:
                flags = " ".join(f"--lock {name}" for name in locks)
                message = (
                    f"{message.rstrip('.')}; with ident verify: {flags} "
                    "(--lock NAME=VALUE holds a joint elsewhere than 0)."
                )
            raise ModelError(message) from e

    def __repr__(self) -> str:
        source = self.urdf_path or (self.description.source if self.description else None)
        return f"Robot({self.name!r}, nq={self.nq}, source={str(source)!r})"

    # ------------------------------------------------------------------ dynamics
    @functools.cached_property
    def chain(self) -> Any:
        """Kinematic chain arrays for the regressor (``ident.dynamics.chain.chain_from_model``)."""
        return chain_from_model(self.model)

    def parameters(self) -> FloatArray:
        """True standard parameters of the model, shape (10 * n_bodies,).

        Pinocchio order per body, about the origin of each body (joint) frame, in its axes
        [kg, kg*m, kg*m^2]; the labels are :meth:`parameter_names`.
        """
        return parameters_from_model(self.model)

    def parameter_names(self) -> tuple[str, ...]:
        """Labels of :meth:`parameters`: ``m1, mcx1, mcy1, mcz1, Ixx1, ..., Izz<n>``."""
        return parameter_names(self.n_bodies)

    def dh_to_model_parameters(self) -> FloatArray:
        """Linear map from DH-frame parameters to model-frame parameters.

        Returns
        -------
        :
            Block-diagonal matrix ``M`` of shape (10 * n_bodies, 10 * n_bodies) with
            ``parameters() == M @ parameters_dh()``; a regressor in the DH parameterization is
            ``regressor(...) @ M``. For modified DH, ``M`` is the identity.

        Raises
        ------
        ModelError
            If the robot was not built from a DH description.
        """
        dh = self._require_description("dh_to_model_parameters").dh
        out = np.zeros((10 * self.n_bodies, 10 * self.n_bodies))
        for i in range(self.n_bodies):
            pose = dh_frame_in_link(dh, i)
            out[10 * i : 10 * i + 10, 10 * i : 10 * i + 10] = transform_matrix(
                pose[:3, :3], pose[:3, 3]
            )
        return out

    def parameters_dh(self) -> FloatArray:
        """True parameters about the DH frame origins, in DH axes (the paper's frames).

        Pinocchio order per link, shape (10 * n_bodies,). Reorder with
        :func:`ident.robot.inertia.pinocchio_to_paper` for the paper's eq. 14 order.
        """
        description = self._require_description("parameters_dh")
        return np.asarray(description.parameters_dh, dtype=float).reshape(-1).copy()

    def _require_description(self, what: str) -> RobotDescription:
        if self.description is None:
            raise ModelError(
                f"Robot {self.name!r} was loaded from a URDF and has no DH table; {what} needs "
                "a robot built with Robot.from_config."
            )
        return self.description

    def regressor(self, q: npt.ArrayLike, dq: npt.ArrayLike, ddq: npt.ArrayLike) -> FloatArray:
        """Joint-torque regressor (hand-derived Newton-Euler), vectorized over samples.

        Parameters
        ----------
        q, dq, ddq :
            Positions [rad or m], velocities, accelerations; shapes (n_samples, nq),
            (n_samples, nv), (n_samples, nv).

        Returns
        -------
        :
            Shape (n_samples, nv, 10 * n_bodies); ``regressor @ parameters()`` gives the joint
            torques [N*m or N] of :meth:`rnea`.
        """
        q, dq, ddq = self._states(q, dq, ddq)
        return joint_torque_regressor(self.chain, q, dq, ddq)

    def rnea(self, q: npt.ArrayLike, dq: npt.ArrayLike, ddq: npt.ArrayLike) -> FloatArray:
        """Inverse dynamics with Pinocchio's RNEA (gravity of the model included).

        Parameters
        ----------
        q, dq, ddq :
            Shapes (n_samples, nq), (n_samples, nv), (n_samples, nv) (one state of shape
            (nq,) is one sample).

        Returns
        -------
        :
            Joint torques [N*m or N], shape (n_samples, nv).
        """
        return pinocchio_rnea(self.model, *self._states(q, dq, ddq))

    # ------------------------------------------------------------------ kinematics
    def frame_placements(self, q: npt.ArrayLike, frame: str) -> FloatArray:
        """World poses of a named frame (``"flange"``, ``"wrist_centre"``, a link or joint).

        Parameters
        ----------
        q :
            Positions, shape (n_samples, nq) or (nq,).
        frame :
            Frame name in the model.

        Returns
        -------
        :
            Homogeneous transforms, shape (n_samples, 4, 4) [m].

        Raises
        ------
        ModelError
            If the frame does not exist; the message lists the available frames.
        """
        frame_id = self._frame_id(frame)
        q = self._positions(q)
        data = self.model.createData()
        out = np.empty((q.shape[0], 4, 4))
        for k in range(q.shape[0]):
            pin.forwardKinematics(self.model, data, q[k])
            out[k] = pin.updateFramePlacement(self.model, data, frame_id).homogeneous
        return out

    def frame_positions(self, q: npt.ArrayLike, frame: str) -> FloatArray:
        """World positions of a named frame [m], shape (n_samples, 3)."""
        return self.frame_placements(q, frame)[:, :3, 3]

    def frame_names(self) -> tuple[str, ...]:
        """Names of all frames of the model (links, joints, ``flange``, ...)."""
        return tuple(f.name for f in self.model.frames)

    def _frame_id(self, frame: str) -> int:
        if not self.model.existFrame(frame):
            names = [n for n in dict.fromkeys(self.frame_names()) if n != "universe"]
            close = difflib.get_close_matches(frame, names, n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ModelError(
                f"frame {frame!r} not found in robot {self.name!r}; {hint}"
                f"available frames: {', '.join(names)}."
            )
        return int(self.model.getFrameId(frame))

    # ------------------------------------------------------------------ sampling
    def random_configurations(
        self, n_samples: int, rng: np.random.Generator | int | None = None
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Uniformly random states within the limits.

        Parameters
        ----------
        n_samples :
            Number of states.
        rng :
            Generator or seed; the same seed gives the same states.

        Returns
        -------
        q, dq, ddq :
            Each of shape (n_samples, nq or nv). ``q`` in ``[q_lower, q_upper]`` (``+-pi`` rad or
            ``+-1`` m where unknown), ``dq`` in ``[-dq_max, dq_max]`` (``+-1`` where unknown),
            ``ddq`` in ``[-ddq_max, ddq_max]`` (``+-10`` where unknown).
        """
        # The robot's limits (a one-sided unknown position limit makes both sides unknown here,
        # while chain_from_model keeps the known side).
        limited = dataclasses.replace(
            self.chain, q_lower=self.q_lower, q_upper=self.q_upper, dq_max=self.dq_max
        )
        return random_states(limited, n_samples, rng=rng, ddq_max=self.ddq_max)

    # ------------------------------------------------------------------ input checks
    def _positions(self, q: npt.ArrayLike) -> FloatArray:
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != self.nq:
            raise DataError(
                f"q must have shape (n_samples, {self.nq}) for robot {self.name!r}, got {q.shape}."
            )
        return q

    def _states(
        self, q: npt.ArrayLike, dq: npt.ArrayLike, ddq: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        q = self._positions(q)
        out = [q]
        for name, value in (("dq", dq), ("ddq", ddq)):
            array = np.asarray(value, dtype=float)
            if array.ndim == 1:
                array = array[None, :]
            if array.shape != (q.shape[0], self.nv):
                raise DataError(
                    f"{name} must have shape ({q.shape[0]}, {self.nv}) to match q for robot "
                    f"{self.name!r}, got {array.shape}."
                )
            out.append(array)
        return out[0], out[1], out[2]


def _read_urdf(
    path: Path, package_dirs: Sequence[str | Path], where: str
) -> tuple[str, PreparedURDF, pin.Model]:
    """The URDF file ``path`` as written (xacro expanded), as Pinocchio reads it
    (:func:`~ident.robot.urdf_load.prepare_urdf`) and its whole Pinocchio model, the continuous
    joints without position limit.

    Raises
    ------
    ModelError
        Naming the file, if it is missing or malformed.
    """
    problem = file_problem(path)
    if problem is not None:
        raise ModelError(f"{path}: URDF file {problem}; check the path.")
    # UTF-8, bounded, no DTD: what every parser of ident (Pinocchio, the write-back) reads
    text = urdf_file_text(path, package_dirs, where)  # xacro expanded
    prepared = prepare_urdf(text, where)
    model = build_model(prepared.text, where)
    _unbounded(model, prepared.continuous)
    return text, prepared, model


def _moving_chain(
    model: pin.Model,
    root: ET.Element,
    lock_joints: Mapping[str, float] | Sequence[str] | None,
    ends: tuple[str | None, str | None],
    inertia_check: bool,
    where: str,
) -> tuple[pin.Model, dict[str, float], tuple[Mimic, ...]]:
    """The model of the joints that move, ``(model, locked, coupled)``: ``model`` (the whole
    URDF's, ``root`` its parsed ``<robot>``) without the ``lock_joints``, the joints off the
    chain ``ends = (base_link, tip_link)`` and the mimic joints of locked leaders
    (``locked``: name -> position [rad or m]), with the chain's mimic joints ``coupled``; the
    moving links' inertials checked when ``inertia_check``.

    Raises
    ------
    ModelError
        Naming the file ``where``: an unknown joint or link, an inconsistent inertial, a mimic
        joint :mod:`ident.robot.mimic` does not support.
    """
    locked = lock_values(model, lock_joints, where)
    given = tuple(locked)
    _lock_off_chain(model, locked, *ends, where)
    locked, coupled = resolve_mimic_locks(read_mimics(root, model, where), locked, given, where)
    if inertia_check:
        check_inertials(root, where, moving_links(model, locked))
    return coupled_model(locked_model(model, locked, where), coupled, where), locked, coupled


def _lock_off_chain(
    model: pin.Model,
    locked: dict[str, float],
    base_link: str | None,
    tip_link: str | None,
    where: str,
) -> None:
    """Add to ``locked`` every joint off the chain ``base_link -> tip_link`` not locked yet, at 0
    clipped into its position limits (0 where the range is empty)."""
    for name in chain_locks(model, base_link, tip_link, where):
        if name not in locked:
            index = model.joints[model.getJointId(name)].idx_q
            low, high = model.lowerPositionLimit[index], model.upperPositionLimit[index]
            locked[name] = float(np.clip(0.0, low, high)) if high > low else 0.0


def _unbounded(model: pin.Model, continuous: Sequence[str]) -> None:
    """Give the ``continuous`` joints no position limit (Pinocchio's convention for unbounded:
    ``-+max float``), in place."""
    for name in continuous:
        index = model.joints[model.getJointId(name)].idx_q
        model.lowerPositionLimit[index] = -np.finfo(float).max
        model.upperPositionLimit[index] = np.finfo(float).max
