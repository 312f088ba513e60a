"""Schema of a run config's ``measurement:`` section for the MuJoCo simulator.

Example (every key optional except ``source``; SI units unless a key says otherwise)::

    measurement:
      source: mujoco
      rate_hz: 1000.0            # controller and log rate [Hz]
      substeps: 1                # MuJoCo steps per controller period
      controller: {kind: computed_torque, kp: 10000.0, kd: 200.0}
      friction: {viscous: [0.5, 0.5, 0.4, 0.1, 0.1, 0.1], coulomb: 1.0}
      # MuJoCo's native joint friction (dof_frictionloss, constraint solver) for the Coulomb term:
      # friction: {semantics: mujoco, viscous: 0.5, coulomb: 1.0}
      actuator: {kind: motor, forcerange: null, delay_steps: 0}
      # or a position servo, the reference as its command (no controller section then):
      # actuator: {kind: position, kp: 2000.0, kv: 50.0, forcerange: 150.0, delay_steps: 2}
      # or another law of the friction-model registry, applied on top:
      # friction: {law: {model: stribeck, values: {fv: 0.5, fc: 1.0, fst: 0.5, vs: 0.05}}}
      signals: {delay_s: 0.0, torque_gain: 1.0, torque_offset: 0.0}
      armature: [0.3, 0.3, 0.2, 0.05, 0.05, 0.05]
      encoder_counts_per_rev: 524288
      torque_noise_std: 0.2
      current: null              # or {torque_constants: [...]}: log currents instead of torques
      settle_periods: 1
      n_periods: 2
      payload: null              # or {mass: 2.0, com: [0, 0, 0.05], inertia: [...], link: null}

A scalar where a list is allowed applies to every joint. The schema checks what it can alone
(finite values, signs, ranges); :func:`check_joint_counts` checks the list lengths against the
robot. :func:`load_mujoco_measurement` turns validation failures into one-line
:class:`~ident.errors.ConfigError` messages naming the key.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import numpy.typing as npt
from pydantic import AfterValidator, Field, field_validator, model_validator

from ident.config import StrictModel, validate_config
from ident.dynamics.friction_models import get_friction_model
from ident.errors import ConfigError
from ident.robot.inertia import consistency_problems, parameters_from_com

__all__ = [
    "DEFAULT_DAMPING_RATIO",
    "DEFAULT_NATURAL_FREQUENCY_RAD_S",
    "ActuatorConfig",
    "ControllerConfig",
    "CurrentConfig",
    "FrictionConfig",
    "FrictionLawConfig",
    "MujocoMeasurement",
    "PayloadConfig",
    "SignalConfig",
    "check_joint_counts",
    "load_mujoco_measurement",
    "per_joint",
]

FloatArray = npt.NDArray[np.float64]

#: Closed-loop natural frequency [rad/s] of the default gains (16 Hz). Chosen on UR5 and Panda
#: excitations at 1 kHz with friction and a rotor inertia of 0.1 kg*m^2 the controller ignores:
#: 50 rad/s left 30-70 mrad RMS errors on the last wrist joint, 100 rad/s leaves 8-20 mrad (below
#: 5 mrad elsewhere); 200 rad/s tracks 4x better again but doubles the torque jitter that the
#: velocity estimate of a 2^19-count encoder feeds through ``kd`` (2-5 N*m RMS at 100 rad/s on
#: the shoulders). The loop delay (velocity estimate plus zero-order hold, about 1 ms) costs
#: about 0.1 rad of phase at 100 rad/s.
DEFAULT_NATURAL_FREQUENCY_RAD_S = 100.0
#: Damping ratio of the default gains (critically damped: no overshoot on the error dynamics).
DEFAULT_DAMPING_RATIO = 1.0


def _per_joint_check(
    *, unit: str, positive: bool = False
) -> AfterValidator:  # one validator per quantity, so that messages carry its unit
    def check(value: float | list[float]) -> float | list[float]:
        values = value if isinstance(value, list) else [value]
        if isinstance(value, list) and not value:
            raise ValueError("give one value for every joint or one per joint, not an empty list")
        bound = "> 0" if positive else ">= 0"
        for v in values:
            if not math.isfinite(v) or (v <= 0.0 if positive else v < 0.0):
                raise ValueError(f"values must be finite and {bound} {unit}, got {value}")
        return value

    return AfterValidator(check)


NonNegativeNm = Annotated[float | list[float], _per_joint_check(unit="N*m")]
NonNegativeViscous = Annotated[float | list[float], _per_joint_check(unit="N*m*s/rad")]
NonNegativeInertia = Annotated[float | list[float], _per_joint_check(unit="kg*m^2")]
PositiveGain = Annotated[float | list[float], _per_joint_check(unit="(see kind)", positive=True)]
PositiveTorqueConstant = Annotated[
    float | list[float], _per_joint_check(unit="N*m/A", positive=True)
]
PositiveStiffness = Annotated[float | list[float], _per_joint_check(unit="N*m/rad", positive=True)]
PositiveNm = Annotated[float | list[float], _per_joint_check(unit="N*m", positive=True)]


class ControllerConfig(StrictModel):
    """The joint controller that tracks the reference, run at ``rate_hz``.

    Both kinds feed back the encoder position ``q_m`` (quantized when an encoder is set) and the
    velocity estimate ``dq_m = (q_m[k] - q_m[k-1]) * rate_hz`` (backward difference), and hold
    their torque over the controller period (zero-order hold).

    Attributes
    ----------
    kind :
        ``computed_torque``: ``tau = RNEA_nominal(q_m, dq_m, ddq_ref + kp e + kd de)`` with
        ``e = q_ref - q_m``, ``de = dq_ref - dq_m``, on the nominal rigid-body model (the URDF's
        inertials; no friction, no armature), so ``kp`` [1/s^2] and ``kd`` [1/s] are
        acceleration gains. ``pd``: ``tau = g_nominal(q_m) + kp e + kd de`` (PD plus gravity
        compensation), ``kp`` [N*m/rad], ``kd`` [N*m*s/rad].
    kp, kd :
        Gains, one for all joints or one per joint; ``null`` takes the defaults: natural frequency
        ``w = 100 rad/s``, damping ratio 1, i.e. ``kp = w^2``, ``kd = 2 w`` for computed torque and
        ``kp = w^2 m_j``, ``kd = 2 w m_j`` for PD, with ``m_j`` the smallest effective inertia
        ``1 / (M^-1)_jj`` of joint ``j`` of the nominal model along the reference (the diagonal
        of ``M`` would make the coupled loop unstable at 1 kHz on a 7-joint arm: the stability of
        the discrete loop needs the eigenvalues of ``h M^-1 Kd`` below 2, and their sum is
        ``h sum_j (M^-1)_jj kd_j <= 2 w h n_joints`` with this choice).
    """

    kind: Literal["computed_torque", "pd"] = "computed_torque"
    kp: PositiveGain | None = None
    kd: PositiveGain | None = None


class FrictionLawConfig(StrictModel):
    """A friction law of the registry (:mod:`ident.dynamics.friction_models`) with its values.

    Attributes
    ----------
    model :
        A registered model name, e.g. ``stribeck``.
    values :
        Every linear and nonlinear parameter of the model by its label (one value for all
        joints or one per joint), e.g. ``{fv: 0.5, fc: 1.0, fst: 0.5, vs: 0.05}``.
    """

    model: str
    values: dict[str, float | list[float]]

    @field_validator("model")
    @classmethod
    def _registered(cls, value: str) -> str:
        try:
            get_friction_model(value)
        except ConfigError as e:
            raise ValueError(str(e)) from e
        return value

    @model_validator(mode="after")
    def _labels(self) -> FrictionLawConfig:
        model = get_friction_model(self.model)
        wanted = {*model.linear, *model.nonlinear}
        if set(self.values) != wanted:
            raise ValueError(
                f"friction.law.values of {self.model!r} takes exactly "
                f"{', '.join(sorted(wanted))}; got {', '.join(sorted(self.values)) or 'none'}"
            )
        for label, value in self.values.items():
            values = value if isinstance(value, list) else [value]
            if not values or not all(math.isfinite(v) for v in values):
                raise ValueError(f"friction.law.values.{label}: finite numbers, got {value}")
        return self


class FrictionConfig(StrictModel):
    """Joint friction of the simulated robot (the controller does not know it).

    ``tau_friction = viscous * dq + coulomb * sign(dq)`` per joint while the joint slides, plus
    the torque of ``law`` when given (``semantics: ident`` only; applied like the Coulomb term;
    the load of ``load_dependent`` is the commanded torque minus the friction).

    Attributes
    ----------
    semantics :
        How MuJoCo realizes the friction. ``ident``: the identification's own law, the Coulomb
        term ``coulomb * sign(dq)`` (``sign(0) = 0``) applied as a generalized force from the
        velocity at the start of every MuJoCo step (a joint that should stick chatters about
        zero velocity). ``mujoco``: MuJoCo's native joint friction, ``coulomb`` as
        ``dof_frictionloss`` solved by MuJoCo's constraint solver (a joint sticks while the
        other forces stay within ``coulomb``, then slides against exactly ``coulomb``), not
        the identification's model class.
    viscous :
        Viscous coefficients [N*m*s/rad] (MuJoCo's ``dof_damping``), >= 0.
    coulomb :
        Coulomb levels [N*m], >= 0.
    law :
        Another friction law of the registry, applied on top (``semantics: ident``).
    """

    semantics: Literal["ident", "mujoco"] = "ident"
    viscous: NonNegativeViscous = 0.0
    coulomb: NonNegativeNm = 0.0
    law: FrictionLawConfig | None = None

    @model_validator(mode="after")
    def _law_is_ident_semantics(self) -> FrictionConfig:
        if self.semantics == "mujoco" and self.law is not None:
            raise ValueError(
                "friction.law is applied as ident's own force law and MuJoCo has no such joint "
                "friction; remove law, or use friction.semantics: ident"
            )
        return self


class ActuatorConfig(StrictModel):
    """The joint actuators MuJoCo simulates, one per robot joint (added to the model's spec).

    Attributes
    ----------
    kind :
        ``motor``: the force is the control, the controller's torque (MuJoCo's ``<motor>``).
        ``position``: the control is a joint position ``q_cmd`` (the reference, sent at
        ``rate_hz`` and held) and the force is ``kp (q_cmd - q) - kv dq`` (MuJoCo's
        ``<position>``); the actuator is then the only controller (no ``controller`` section).
    kp :
        Position gain [N*m/rad], > 0; ``kind: position`` only, and required there.
    kv :
        Velocity gain [N*m*s/rad], >= 0; ``kind: position`` only (default 0, as MuJoCo's).
    forcerange :
        Saturation [N*m], > 0: the actuator force is clipped to ``[-forcerange, forcerange]``
        (MuJoCo's ``forcerange``). ``null``: unlimited.
    delay_steps :
        Transport delay of the control, a whole number of MuJoCo timesteps
        ``1 / (rate_hz * substeps)`` [s], >= 0: the force of a step uses the control set
        ``delay_steps`` steps earlier (MuJoCo's actuator ``delay`` with a history buffer).
    """

    kind: Literal["motor", "position"] = "motor"
    kp: PositiveStiffness | None = None
    kv: NonNegativeViscous | None = None
    forcerange: PositiveNm | None = None
    delay_steps: int = Field(default=0, ge=0, le=10_000)

    @model_validator(mode="after")
    def _gains_of_the_kind(self) -> ActuatorConfig:
        if self.kind == "position" and self.kp is None:
            raise ValueError(
                "actuator.kind: position needs actuator.kp [N*m/rad] (and kv [N*m*s/rad], "
                "default 0); add them"
            )
        if self.kind == "motor" and (self.kp is not None or self.kv is not None):
            raise ValueError(
                "actuator.kp and kv are the gains of kind: position; remove them, or set "
                "actuator.kind: position"
            )
        return self


class SignalConfig(StrictModel):
    """Errors of the measured torque signal: ``tau_measured(t) = gain * tau(t - delay_s) + offset``
    (plus noise), ``tau`` the commanded torque, linearly interpolated (held at the ends).

    Attributes
    ----------
    delay_s :
        Delay [s] of the torque behind the positions, >= 0.
    torque_gain :
        Gain per joint (1: exact), > 0.
    torque_offset :
        Offset per joint [N*m].
    """

    delay_s: float = Field(default=0.0, ge=0.0, allow_inf_nan=False)
    torque_gain: PositiveGain = 1.0
    torque_offset: float | list[float] = 0.0


class CurrentConfig(StrictModel):
    """Log joint-side currents ``i = tau_measured / torque_constants`` instead of torques.

    Attributes
    ----------
    torque_constants :
        Joint-side torque constants [N*m/A] (motor constant times gear ratio), > 0.
    """

    torque_constants: PositiveTorqueConstant


class PayloadConfig(StrictModel):
    """A rigid payload welded to a link of the simulated robot (the controller ignores it).

    Attributes
    ----------
    mass :
        Mass [kg], > 0.
    com :
        Centre of mass in the frame of ``link`` [m], 3 values.
    inertia :
        Inertia about the centre of mass, axes of ``link``'s frame [kg*m^2], Pinocchio order
        ``[Ixx, Ixy, Iyy, Ixz, Iyz, Izz]``; positive semi-definite. Default: a point mass.
    link :
        URDF link the payload is welded to; ``null``: the child link of the last moving joint.
    """

    mass: float = Field(gt=0.0)
    com: list[float] = Field(min_length=3, max_length=3)
    inertia: list[float] = Field(default=[0.0] * 6, min_length=6, max_length=6)
    link: str | None = None

    @model_validator(mode="after")
    def _physical(self) -> PayloadConfig:
        problems = consistency_problems(self.parameters())
        if problems:
            raise ValueError(
                f"payload: not a rigid body ({'; '.join(problems)}); give a positive "
                "semi-definite inertia about the centre of mass that meets the triangle "
                "inequality"
            )
        return self

    def parameters(self) -> FloatArray:
        """Standard parameters about ``link``'s origin, shape (10,), Pinocchio order."""
        xx, xy, yy, xz, yz, zz = self.inertia
        inertia = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        return parameters_from_com(np.asarray(self.mass), np.asarray(self.com), inertia)


class MujocoMeasurement(StrictModel):
    """``measurement: {source: mujoco, ...}``: closed-loop MuJoCo simulation writing a log.

    Attributes
    ----------
    source :
        ``mujoco``.
    rate_hz :
        Controller and log rate [Hz], > 0 (default 1 kHz).
    substeps :
        MuJoCo steps per controller period; the MuJoCo timestep is ``1 / (rate_hz * substeps)``
        [s]. The command is held over the period, the Coulomb force is updated every step.
    controller :
        The tracking controller (:class:`ControllerConfig`).
    friction :
        Viscous and Coulomb friction, their semantics, and another law (:class:`FrictionConfig`).
    actuator :
        The joint actuators: torque motors (default) or position servos, their saturation and
        command delay (:class:`ActuatorConfig`).
    armature :
        Rotor inertia reflected to the joint [kg*m^2] (MuJoCo's ``dof_armature``), >= 0.
    encoder_counts_per_rev :
        Encoder counts per joint revolution; logged (and fed back) positions are rounded to
        multiples of ``2 pi / counts`` [rad]. ``null``: exact positions.
    torque_noise_std :
        Standard deviation [N*m] of the zero-mean Gaussian noise added to the commanded torque to
        make the measured torque, >= 0.
    current :
        ``null`` logs torques [N*m]; a :class:`CurrentConfig` logs currents [A].
    signals :
        Delay, gain and offset of the measured torque (:class:`SignalConfig`).
    settle_periods :
        Periods simulated before logging starts (transients of the start from the reference's
        initial state), >= 0.
    n_periods :
        Periods logged, >= 1.
    payload :
        A rigid payload welded to a link (:class:`PayloadConfig`), or ``null``.
    """

    source: Literal["mujoco"] = "mujoco"
    rate_hz: float = Field(default=1000.0, gt=0.0, allow_inf_nan=False)
    substeps: int = Field(default=1, ge=1, le=100)
    controller: ControllerConfig = ControllerConfig()
    friction: FrictionConfig = FrictionConfig()
    actuator: ActuatorConfig = ActuatorConfig()
    armature: NonNegativeInertia = 0.0
    encoder_counts_per_rev: int | None = Field(default=None, ge=2)
    torque_noise_std: NonNegativeNm = 0.0
    current: CurrentConfig | None = None
    signals: SignalConfig = SignalConfig()
    settle_periods: int = Field(default=1, ge=0)
    n_periods: int = Field(default=2, ge=1)
    payload: PayloadConfig | None = None

    @model_validator(mode="after")
    def _actuator_fits(self) -> MujocoMeasurement:
        position = self.actuator.kind == "position"
        if position and "controller" in self.model_fields_set:
            raise ValueError(
                "controller: a position actuator tracks the reference itself with its kp, kv; "
                "remove the controller section, or use actuator.kind: motor"
            )
        law = self.friction.law
        changed = position or self.actuator.forcerange is not None or self.actuator.delay_steps
        if law is not None and get_friction_model(law.model).uses_load and changed:
            raise ValueError(
                f"friction.law {law.model!r} takes the commanded torque as its load, which "
                "only a motor actuator without forcerange and delay_steps applies as commanded; "
                "use such an actuator, or a law without load"
            )
        return self


def load_mujoco_measurement(
    data: Mapping[str, Any], source: str | Path = "measurement"
) -> MujocoMeasurement:
    """Validate a ``measurement:`` mapping.

    Raises
    ------
    ConfigError
        Naming ``source`` and the key, for unknown keys, wrong types and out-of-range values.
    """
    return validate_config(MujocoMeasurement, data, source)


def per_joint(value: float | Sequence[float], n_joints: int) -> FloatArray:
    """One value per joint: a scalar repeated, or the list as given, shape (n_joints,).

    Raises
    ------
    ConfigError
        If a list does not have ``n_joints`` entries.
    """
    array = np.atleast_1d(np.asarray(value, dtype=float))
    if array.size == 1 and not isinstance(value, Sequence):
        return np.full(n_joints, float(array[0]))
    if array.shape != (n_joints,):
        raise ConfigError(f"expected one value or {n_joints} values, got {array.size}")
    return array.copy()


def check_joint_counts(
    cfg: MujocoMeasurement,
    n_joints: int,
    *,
    joint_names: Sequence[str] | None = None,
    source: str | Path = "config",
) -> None:
    """Check that every per-joint list of ``cfg`` has one entry per robot joint.

    Parameters
    ----------
    cfg :
        The validated section.
    n_joints :
        Number of joints of the robot (``Robot.nv``).
    joint_names :
        Their names, for the message.
    source :
        Config file name for the message.

    Raises
    ------
    ConfigError
        ``<source>: measurement.<key> has <k> entries, the robot has <n> joints (...); give one
        value for all joints or one per joint.``
    """
    entries = {
        "controller.kp": cfg.controller.kp,
        "controller.kd": cfg.controller.kd,
        "friction.viscous": cfg.friction.viscous,
        "friction.coulomb": cfg.friction.coulomb,
        "actuator.kp": cfg.actuator.kp,
        "actuator.kv": cfg.actuator.kv,
        "actuator.forcerange": cfg.actuator.forcerange,
        "armature": cfg.armature,
        "torque_noise_std": cfg.torque_noise_std,
        "current.torque_constants": None if cfg.current is None else cfg.current.torque_constants,
        "signals.torque_gain": cfg.signals.torque_gain,
        "signals.torque_offset": cfg.signals.torque_offset,
    }
    if cfg.friction.law is not None:
        entries.update({f"friction.law.values.{k}": v for k, v in cfg.friction.law.values.items()})
    names = f" ({', '.join(joint_names)})" if joint_names else ""
    for key, value in entries.items():
        if isinstance(value, list) and len(value) != n_joints:
            raise ConfigError(
                f"{source}: measurement.{key} has {len(value)} entries, the robot has "
                f"{n_joints} joints{names}; give one value for all joints or one per joint."
            )
