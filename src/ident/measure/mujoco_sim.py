"""Closed-loop MuJoCo simulation of an excitation, logged as a robot controller would.

The simulated robot is the URDF's rigid bodies (:mod:`ident.measure.mujoco_model`) plus, per
joint ``j``, what the ``measurement:`` config adds (:mod:`ident.measure.mujoco_config`), written
into MuJoCo's model by the one map of ident's parameters to MuJoCo's fields
(:func:`~ident.measure.mujoco_model.set_joint_parameters`):

- rotor inertia ``Ia_j`` reflected to the joint (MuJoCo's ``dof_armature``);
- viscous friction ``fv_j dq_j`` (``dof_damping``, integrated explicitly);
- Coulomb friction ``fs_j``: with ``friction.semantics: ident`` (the default) the
  identification's own law ``fs_j sign(dq_j)`` (``sign(0) = 0``), the velocity taken at the
  start of every MuJoCo step, applied through ``qfrc_applied``; with ``semantics: mujoco``
  MuJoCo's ``dof_frictionloss``, solved by its constraint solver (stiction, then exactly
  ``fs_j`` against the sliding direction);
- optionally (``semantics: ident``) a friction law of the registry
  (:mod:`ident.dynamics.friction_models`, e.g. Stribeck), applied like the Coulomb term; a
  load-dependent law's load is the torque through the gear, the command minus the friction;
- one actuator per joint (``measurement.actuator``): a torque motor fed by the controller, or a
  position servo ``kp (q_cmd - q) - kv dq`` fed the reference; either saturated at
  ``forcerange`` and delayed by ``delay_steps`` MuJoCo steps;
- and on the measured torque a delay, a gain and an offset (``measurement.signals``).

So at every MuJoCo step, with ``dq`` the velocity before the step, ``ddq`` the acceleration
MuJoCo integrates (``qacc``) and ``tau_act`` the actuators' force (``actuator_force``)::

    tau_act = RNEA_urdf(q, dq, ddq) + Ia * ddq + fv * dq + fs * sign(dq)      (the truth)

exactly with ``semantics: ident``, and while the joint slides with ``semantics: mujoco`` (to
the constraint solver's tolerance; a stuck joint's friction is whatever holds it, within
``fs``); then the semi-implicit Euler step ``dq' = dq + h ddq``, ``q' = q + h dq'``. With one
MuJoCo step per controller period (the default) the second central difference of the logged
true positions is exactly ``h^2 ddq``, and their backward difference exactly ``h dq``.

With a motor actuator a controller (computed torque on the nominal model, or PD plus gravity; see
:class:`~ident.measure.mujoco_config.ControllerConfig`) tracks the reference at ``rate_hz`` from
the encoder positions, its torque held over the period. It knows neither friction nor armature,
so it tracks imperfectly, as on a real robot. With a position actuator the reference position is
the command, held over the period. The log holds, from the end of the settle periods on, one
sample per controller period: the time stamp, the encoder positions, the measured torque (the
actuator force plus Gaussian noise) or current (measured torque over the torque constant), the
commanded torque and, for a position actuator, the commanded position. :func:`write_log` writes
it as a CSV file with the ``log:`` section that ``ident identify`` reads.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import numpy.typing as npt
import pinocchio as pin
import yaml
from scipy.interpolate import BPoly

from ident.dynamics.friction_models import get_friction_model
from ident.errors import DataError
from ident.measure.ideal import quantize
from ident.measure.mujoco_config import (
    DEFAULT_DAMPING_RATIO,
    DEFAULT_NATURAL_FREQUENCY_RAD_S,
    MujocoMeasurement,
    check_joint_counts,
    per_joint,
)
from ident.measure.mujoco_log import route_mujoco_warnings
from ident.measure.mujoco_model import MujocoRobot, load_mujoco, set_joint_parameters
from ident.model import Robot

route_mujoco_warnings()  # MuJoCo warnings as Python warnings, no MUJOCO_LOG.TXT

__all__ = [
    "LOG_CSV",
    "LOG_YAML",
    "LogFiles",
    "SimulatedLog",
    "controller_gains",
    "coulomb_law",
    "log_columns",
    "reference_at_rate",
    "simulate",
    "write_log",
]

FloatArray = npt.NDArray[np.float64]
RngLike = np.random.Generator | int | None

LOG_CSV = "log.csv"
LOG_YAML = "log.yaml"

# Relative tolerance on "the period is a whole number of controller periods" and "the reference
# is already sampled at the controller rate" (time stamps printed with ~12 digits pass).
_RATE_RTOL = 1e-9
# Tracking error [rad or m] past which the simulation stops: a diverging loop reaches it long
# before MuJoCo's own instability warning (which also writes MUJOCO_LOG.TXT into the folder).
_MAX_TRACKING_ERROR = 1.0
# Fixed-point rounds of a load-dependent friction law (error ~ fl^rounds).
_LOAD_ROUNDS = 40


def coulomb_law(dq: FloatArray) -> FloatArray:
    """The simulator's Coulomb friction shape: ``sign(dq)``, 0 at ``dq == 0``, any shape."""
    return np.sign(dq)


@dataclass(frozen=True, eq=False)
class SimulatedLog:
    """What the simulated controller logged, and the truth behind it.

    Attributes
    ----------
    t :
        Time stamps [s] of the simulation clock (0 at the start of the settle periods),
        shape (n_samples,).
    q :
        Measured (encoder) joint positions [rad], shape (n_samples, nq).
    tau_cmd :
        Commanded joint torques [N*m], shape (n_samples, nv): the controller's torque, held
        over each controller period (motor actuator), or the servo's force ``tau_actuator``
        (position actuator, which has no other torque command).
    tau_measured :
        Measured joint torques [N*m]: ``tau_actuator`` with the signal errors and Gaussian
        noise, shape (n_samples, nv).
    current :
        Logged currents [A] ``tau_measured / torque_constants``, shape (n_samples, nv), or
        ``None`` when torques are logged.
    torque_constants :
        Joint-side torque constants [N*m/A], shape (nv,), or ``None``.
    joint_names :
        The robot's joint names, in column order.
    rate_hz :
        Controller and log rate [Hz].
    truth :
        ``viscous`` [N*m*s/rad], ``coulomb`` [N*m], ``armature`` [kg*m^2],
        ``torque_noise_std`` [N*m], ``delay_s`` [s], ``torque_gain``, ``torque_offset`` [N*m]
        and ``law.<label>`` (the friction law's parameters) per joint, each shape (nv,).
    q_true, dq_true, ddq_true :
        Simulated state at each time stamp before the step, and MuJoCo's acceleration of that
        step [rad, rad/s, rad/s^2], shapes (n_samples, nq), (n_samples, nv), (n_samples, nv).
    q_reference, dq_reference, ddq_reference :
        The reference tracked at each time stamp, same shapes.
    tau_actuator :
        The actuators' force on the joints at each time stamp [N*m] (MuJoCo's
        ``actuator_force`` of the step from it): the command after ``forcerange`` and
        ``delay_steps``, shape (n_samples, nv). Equals ``tau_cmd`` for a motor without them.
    q_cmd :
        Commanded joint positions [rad] sent at each time stamp (before the actuator's delay),
        shape (n_samples, nq), for a position actuator; ``None`` for a motor.
    """

    t: FloatArray
    q: FloatArray
    tau_cmd: FloatArray
    tau_measured: FloatArray
    current: FloatArray | None
    torque_constants: FloatArray | None
    joint_names: tuple[str, ...]
    rate_hz: float
    truth: dict[str, FloatArray]
    q_true: FloatArray
    dq_true: FloatArray
    ddq_true: FloatArray
    q_reference: FloatArray
    dq_reference: FloatArray
    ddq_reference: FloatArray
    tau_actuator: FloatArray
    q_cmd: FloatArray | None = None

    def __post_init__(self) -> None:
        arrays = [
            self.t,
            self.q,
            self.tau_cmd,
            self.tau_measured,
            self.q_true,
            self.dq_true,
            self.ddq_true,
            self.q_reference,
            self.dq_reference,
            self.ddq_reference,
            self.tau_actuator,
            *self.truth.values(),
        ]
        for a in (self.current, self.torque_constants, self.q_cmd):
            if a is not None:
                arrays.append(a)
        for a in arrays:
            a.setflags(write=False)

    @property
    def n_samples(self) -> int:
        """Number of logged samples."""
        return int(self.t.shape[0])

    def tracking_rms(self) -> FloatArray:
        """RMS of the true tracking error ``q_true - q_reference`` per joint [rad], (nq,)."""
        return np.sqrt(np.mean((self.q_true - self.q_reference) ** 2, axis=0))


def reference_at_rate(
    t: FloatArray, q: FloatArray, dq: FloatArray, ddq: FloatArray, rate_hz: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """One period of a periodic reference, sampled at the controller rate.

    The period is ``T = n_samples * dt`` (samples at ``t_0 + k dt``, ``k = 0..n_samples-1``, the
    end point excluded, as :func:`ident.excitation.family.sample_times` gives them). A reference
    already at ``rate_hz`` is returned as given; otherwise it is interpolated by the periodic
    quintic Hermite spline through the samples' positions, velocities and accelerations (exact
    for quintic polynomials, C2).

    Parameters
    ----------
    t :
        Uniform sample times [s], shape (n_samples,).
    q, dq, ddq :
        Positions [rad], velocities [rad/s], accelerations [rad/s^2], each
        shape (n_samples, n_joints).
    rate_hz :
        Controller rate [Hz]; ``T * rate_hz`` must be a whole number.

    Returns
    -------
    q, dq, ddq :
        At ``k / rate_hz`` after ``t_0``, ``k = 0..T*rate_hz - 1``, shape (T*rate_hz, n_joints).

    Raises
    ------
    DataError
        For non-uniform or too few samples, mismatched shapes, non-finite values, or a period
        that is not a whole number of controller periods.
    """
    t = np.asarray(t, dtype=float)
    q, dq, ddq = (np.asarray(a, dtype=float) for a in (q, dq, ddq))
    dt, n_ctrl = _sample_step(t, q, dq, ddq, rate_hz)
    n, period = t.shape[0], t.shape[0] * dt
    if n_ctrl == n:
        return q.copy(), dq.copy(), ddq.copy()
    knots = np.append(np.arange(n) * dt, period)
    tc = np.arange(n_ctrl) / rate_hz
    out = [np.empty((n_ctrl, q.shape[1])) for _ in range(3)]
    for j in range(q.shape[1]):  # BPoly interpolates one scalar signal at a time
        derivatives = np.stack([q[:, j], dq[:, j], ddq[:, j]], axis=1)
        spline = BPoly.from_derivatives(knots, np.vstack([derivatives, derivatives[:1]]))
        for order in range(3):
            out[order][:, j] = spline(tc, nu=order)
    return out[0], out[1], out[2]


def _sample_step(
    t: FloatArray, q: FloatArray, dq: FloatArray, ddq: FloatArray, rate_hz: float
) -> tuple[float, int]:
    """The reference's sample step dt [s] and the controller samples per period; raises the
    :class:`DataError` of :func:`reference_at_rate`."""
    n = t.shape[0] if t.ndim == 1 else 0
    if n < 2 or any(a.ndim != 2 or a.shape[0] != n or a.shape != q.shape for a in (q, dq, ddq)):
        raise DataError(
            f"reference: need t of shape (n,), n >= 2, and q, dq, ddq of one shape (n, n_joints); "
            f"got t {t.shape}, q {q.shape}, dq {dq.shape}, ddq {ddq.shape}."
        )
    if not all(np.all(np.isfinite(a)) for a in (t, q, dq, ddq)):
        raise DataError("reference: the trajectory contains NaN or infinite values.")
    steps = np.diff(t)
    dt = (t[-1] - t[0]) / (n - 1)
    if not dt > 0.0 or np.max(np.abs(steps - dt)) > 1e-6 * dt:
        raise DataError("reference: sample times must be increasing and uniformly spaced.")
    period = n * dt
    n_ctrl = int(round(period * rate_hz))
    if n_ctrl < 2 or abs(n_ctrl - period * rate_hz) > _RATE_RTOL * period * rate_hz:
        raise DataError(
            f"reference: the period {period:g} s is not a whole number of controller periods "
            f"(1 / {rate_hz:g} Hz); choose a period that is a multiple of {1.0 / rate_hz:g} s."
        )
    return dt, n_ctrl


def controller_gains(
    robot: Robot, config: MujocoMeasurement, q_reference: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The controller's ``kp``, ``kd`` per joint, shape (nv,) each (defaults filled in).

    Defaults (``null`` in the config), with ``w`` = :data:`DEFAULT_NATURAL_FREQUENCY_RAD_S` and
    ``z`` = :data:`DEFAULT_DAMPING_RATIO`: ``kp = w^2`` [1/s^2], ``kd = 2 z w`` [1/s] for computed
    torque; ``kp = w^2 m_j`` [N*m/rad], ``kd = 2 z w m_j`` [N*m*s/rad] for PD, where
    ``m_j = min_k 1 / (M^-1(q_k))_jj`` is the smallest effective inertia of joint ``j`` (the
    inertia it shows when the other joints move freely) of the nominal model along ``q_reference``
    (shape (n_samples, nq), at most 200 samples of it are used).
    """
    w, z = DEFAULT_NATURAL_FREQUENCY_RAD_S, DEFAULT_DAMPING_RATIO
    scale = np.ones(robot.nv)
    if config.controller.kind == "pd":
        data = robot.model.createData()
        stride = max(1, q_reference.shape[0] // 200)
        inverse_diagonal = [
            np.diag(pin.computeMinverse(robot.model, data, q)).copy() for q in q_reference[::stride]
        ]
        scale = 1.0 / np.max(inverse_diagonal, axis=0)
    kp = scale * w**2 if config.controller.kp is None else per_joint(config.controller.kp, robot.nv)
    kd = (
        scale * 2.0 * z * w
        if config.controller.kd is None
        else per_joint(config.controller.kd, robot.nv)
    )
    return kp, kd


def simulate(
    robot: Robot,
    t: FloatArray,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    config: MujocoMeasurement,
    *,
    rng: RngLike = None,
) -> SimulatedLog:
    """Simulate the robot tracking a periodic reference in closed loop and log it: it starts in
    the reference's initial state (position and velocity), is simulated for
    ``settle_periods + n_periods`` periods and logged over the last ``n_periods``.

    Parameters
    ----------
    robot :
        The robot (URDF inertials; its locked joints are fixed in MuJoCo at their values).
    t, q, dq, ddq :
        One period of the reference: uniform times [s], shape (n_samples,); positions [rad],
        velocities [rad/s], accelerations [rad/s^2], shape (n_samples, nq); at ``config.rate_hz``
        (used as is) or coarser (interpolated, see :func:`reference_at_rate`).
    config, rng :
        The ``measurement:`` section; generator or seed of the torque noise (the only random
        draw; the motion itself is deterministic).

    Returns the log and the truth. Raises ConfigError (a per-joint list without one entry per
    joint), DataError (a malformed reference; tracking error reaching 1 rad), ModelError.
    """
    nv = robot.nv
    check_joint_counts(config, nv, joint_names=robot.joint_names)
    rate = float(config.rate_hz)
    reference = reference_at_rate(t, _checked_positions(robot, q), dq, ddq, rate)
    n_ctrl = reference[0].shape[0]
    truth = _truth(config, nv)
    k0 = config.settle_periods * n_ctrl
    n_total = k0 + config.n_periods * n_ctrl
    run = _run_closed_loop(robot, config, reference, truth, k0, n_total)
    t_log, index = np.arange(k0, n_total) / rate, np.arange(k0, n_total) % n_ctrl
    tau_measured = _measured_torque(t_log, run.tau_actuator, config, nv, rng)
    current, torque_constants = _motor_current(tau_measured, config, nv)
    return SimulatedLog(
        t=t_log,
        q=run.q_measured,
        tau_cmd=run.tau_cmd,
        tau_measured=tau_measured,
        current=current,
        torque_constants=torque_constants,
        joint_names=tuple(robot.joint_names),
        rate_hz=rate,
        truth=truth,
        q_true=run.q_true,
        dq_true=run.dq_true,
        ddq_true=run.ddq_true,
        q_reference=reference[0][index],
        dq_reference=reference[1][index],
        ddq_reference=reference[2][index],
        tau_actuator=run.tau_actuator,
        q_cmd=run.q_cmd,
    )


def _motor_current(
    tau_measured: FloatArray, config: MujocoMeasurement, nv: int
) -> tuple[FloatArray | None, FloatArray | None]:
    """Logged motor current [A] (n_samples, nv) and torque constants [N*m/A] (nv,) when the
    config logs currents, else (None, None)."""
    if config.current is None:
        return None, None
    torque_constants = per_joint(config.current.torque_constants, nv)
    return tau_measured / torque_constants, torque_constants


def _checked_positions(robot: Robot, q: FloatArray) -> FloatArray:
    """``q`` as floats, shape (n_samples, nq) checked against the robot (DataError)."""
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != robot.nq:
        raise DataError(
            f"reference: q has shape {q.shape}, the robot {robot.name!r} has nq = {robot.nq}."
        )
    return q


def _truth(config: MujocoMeasurement, nv: int) -> dict[str, FloatArray]:
    """Per-joint truth of the simulated robot and signals, each shape (nv,).

    ``viscous``, ``coulomb``, ``armature``, ``torque_noise_std``, ``delay_s`` (repeated),
    ``torque_gain``, ``torque_offset``, and ``law.<label>`` for every parameter of the
    friction law when one is configured.
    """
    truth = {
        "viscous": per_joint(config.friction.viscous, nv),
        "coulomb": per_joint(config.friction.coulomb, nv),
        "armature": per_joint(config.armature, nv),
        "torque_noise_std": per_joint(config.torque_noise_std, nv),
        "delay_s": np.full(nv, float(config.signals.delay_s)),
        "torque_gain": per_joint(config.signals.torque_gain, nv),
        "torque_offset": per_joint(config.signals.torque_offset, nv),
    }
    law = config.friction.law
    if law is not None:
        truth.update({f"law.{k}": per_joint(v, nv) for k, v in law.values.items()})
    return truth


def _friction_law_torque(
    config: MujocoMeasurement, truth: dict[str, FloatArray]
) -> Callable[[FloatArray, FloatArray], FloatArray]:
    """``torque(dq, tau)`` [N*m], shapes (nv,): the Coulomb term and the friction law, for the
    motor torque ``tau`` (the law's load: ``tau`` minus the friction)."""
    coulomb = truth["coulomb"]
    law = config.friction.law
    if law is None:
        return lambda dq, load: coulomb * coulomb_law(dq)
    model = get_friction_model(law.model)
    nv = len(coulomb)
    linear = np.column_stack([truth[f"law.{k}"] for k in model.linear])
    nonlinear = np.zeros((nv, len(model.nonlinear)))
    for i, k in enumerate(model.nonlinear):
        nonlinear[:, i] = truth[f"law.{k}"]

    def torque(dq: FloatArray, tau: FloatArray) -> FloatArray:
        # the load is what passes the gear, tau - friction: a fixed point (contracts by the
        # load coefficients), exact to round-off after a few rounds for |fl| < 0.5
        base = coulomb * coulomb_law(dq)
        friction = base
        for _ in range(_LOAD_ROUNDS if model.uses_load else 1):
            law = model.torque(dq[None, :], (tau - friction)[None, :], linear, nonlinear)[0]
            friction, previous = base + law, friction
            if np.max(np.abs(friction - previous)) <= 1e-14 * (1.0 + np.max(np.abs(tau))):
                break
        return friction

    return torque


@dataclass(frozen=True, eq=False)
class _LoopRun:
    """Logged samples of the closed loop (see :class:`SimulatedLog`)."""

    q_true: FloatArray
    dq_true: FloatArray
    ddq_true: FloatArray
    q_measured: FloatArray
    tau_cmd: FloatArray
    tau_actuator: FloatArray
    q_cmd: FloatArray | None


def _simulator(
    robot: Robot, config: MujocoMeasurement, truth: dict[str, FloatArray]
) -> MujocoRobot:
    """The MuJoCo model of the simulated robot: its actuators, and ident's true joint
    parameters written by :func:`set_joint_parameters` (``fs`` as ``dof_frictionloss`` only
    with ``friction.semantics: mujoco``)."""
    native = config.friction.semantics == "mujoco"
    mj = load_mujoco(
        robot,
        timestep_s=1.0 / (float(config.rate_hz) * config.substeps),
        payload=config.payload,
        actuator=config.actuator,
        native_friction=native,
    )
    values = {"fv": truth["viscous"], "Ia": truth["armature"]}
    if native:
        values["fs"] = truth["coulomb"]
    set_joint_parameters(mj, values)
    # A diverging simulation must fail loudly, not restart from qpos0.
    mj.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
    return mj


def _run_closed_loop(
    robot: Robot,
    config: MujocoMeasurement,
    reference: tuple[FloatArray, FloatArray, FloatArray],
    truth: dict[str, FloatArray],
    k0: int,
    n_total: int,
) -> _LoopRun:
    """Step the controller and MuJoCo for ``n_total`` periods, logging from period ``k0`` on."""
    q_ref, dq_ref = reference[0], reference[1]
    nv, rate, n_ctrl = robot.nv, float(config.rate_hz), q_ref.shape[0]
    position = config.actuator.kind == "position"
    command = _command(robot, config, reference)
    native = config.friction.semantics == "mujoco"
    friction = None if native else _friction_law_torque(config, truth)
    mj = _simulator(robot, config, truth)
    data = mujoco.MjData(mj.model)
    mj.set_state(data, q_ref[0], dq_ref[0])  # mimic joints on their leaders
    n_log = n_total - k0
    out = _LoopRun(
        q_true=np.empty((n_log, robot.nq)),
        dq_true=np.empty((n_log, nv)),
        ddq_true=np.empty((n_log, nv)),
        q_measured=np.empty((n_log, robot.nq)),
        tau_cmd=np.empty((n_log, nv)),
        tau_actuator=np.empty((n_log, nv)),
        q_cmd=np.empty((n_log, robot.nq)) if position else None,
    )
    q_prev = None
    for k in range(n_total):
        q_now = data.qpos[mj.qpos_index]
        counts = config.encoder_counts_per_rev
        q_m = quantize(q_now, counts) if counts is not None else q_now.copy()
        dq_m = dq_ref[0] if q_prev is None else (q_m - q_prev) * rate
        _check_tracking(robot, q_ref[k % n_ctrl] - q_m, k / rate)
        ctrl = command(k % n_ctrl, q_m, dq_m)
        if k == 0:
            mj.start_control(data, ctrl)  # a delayed actuator's history holds it
        data.ctrl[mj.actuator_index] = ctrl
        i = k - k0
        if i >= 0:
            out.q_true[i], out.dq_true[i], out.q_measured[i] = q_now, data.qvel[mj.dof_index], q_m
            if out.q_cmd is not None:
                out.q_cmd[i] = ctrl
        ddq, force = _step_period(mj, data, config.substeps, ctrl, friction)
        if i >= 0:
            out.ddq_true[i], out.tau_actuator[i] = ddq, force
            out.tau_cmd[i] = force if position else ctrl
        q_prev = q_m
    return out


def _command(
    robot: Robot, config: MujocoMeasurement, reference: tuple[FloatArray, FloatArray, FloatArray]
) -> Callable[[int, FloatArray, FloatArray], FloatArray]:
    """``ctrl(j, q_m, dq_m)``, shape (nv,), the actuators' control for reference sample ``j``
    from the encoder position and velocity estimate: the controller's torque [N*m] for motors,
    the reference position [rad] itself for position servos."""
    q_ref, dq_ref, ddq_ref = reference
    if config.actuator.kind == "position":
        return lambda j, q_m, dq_m: np.array(q_ref[j])
    controller = _controller(robot, config, q_ref)
    return lambda j, q_m, dq_m: controller(q_m, dq_m, q_ref[j] - q_m, dq_ref[j] - dq_m, ddq_ref[j])


def _step_period(
    mj: MujocoRobot,
    data: mujoco.MjData,
    substeps: int,
    ctrl: FloatArray,
    friction: Callable[[FloatArray, FloatArray], FloatArray] | None,
) -> tuple[FloatArray, FloatArray]:
    """Step MuJoCo ``substeps`` times with the control held (the ident-semantics friction
    ``friction(dq, ctrl)`` [N*m] applied against the motion at every step, when given).

    Returns the first step's acceleration ``qacc`` [rad/s^2] and actuator force [N*m] (nv,):
    those of the state before the period.
    """
    first: tuple[FloatArray, FloatArray] | None = None
    for _ in range(substeps):
        if friction is not None:
            data.qfrc_applied[mj.dof_index] = -friction(data.qvel[mj.dof_index], ctrl)
        mujoco.mj_step(mj.model, data)
        if first is None:
            first = (data.qacc[mj.dof_index].copy(), data.actuator_force[mj.actuator_index].copy())
    assert first is not None  # substeps >= 1 (the schema)
    return first


def _controller(
    robot: Robot, config: MujocoMeasurement, q_ref: FloatArray
) -> Callable[[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray], FloatArray]:
    """``tau(q_m, dq_m, error, derror, ddq_ref)`` [N*m], (nv,), of the configured controller."""
    kp, kd = controller_gains(robot, config, q_ref)
    nominal = robot.model.copy()  # the controller's model: URDF inertials only
    nominal.armature[:] = 0.0
    nominal_data = nominal.createData()
    computed_torque = config.controller.kind == "computed_torque"

    def torque(
        q_m: FloatArray, dq_m: FloatArray, error: FloatArray, derror: FloatArray, ddq: FloatArray
    ) -> FloatArray:
        if computed_torque:
            tau = pin.rnea(nominal, nominal_data, q_m, dq_m, ddq + kp * error + kd * derror)
        else:
            tau = pin.computeGeneralizedGravity(nominal, nominal_data, q_m) + kp * error
            tau += kd * derror
        return np.array(tau)  # Pinocchio returns a view of its data

    return torque


def _check_tracking(robot: Robot, error: FloatArray, t: float) -> None:
    """Raise DataError when a tracking error [rad] reaches :data:`_MAX_TRACKING_ERROR`."""
    if not np.max(np.abs(error)) < _MAX_TRACKING_ERROR:  # also catches NaN
        joint = robot.joint_names[int(np.argmax(~(np.abs(error) < _MAX_TRACKING_ERROR)))]
        raise DataError(
            f"MuJoCo simulation of {robot.name!r}: the tracking error of joint {joint!r} "
            f"reached {_MAX_TRACKING_ERROR:g} rad at t = {t:g} s (unstable or too weak "
            "control); change measurement.controller.kp/kd, raise measurement.substeps or "
            "slow the excitation down."
        )


def _measured_torque(
    t: FloatArray, tau_cmd: FloatArray, config: MujocoMeasurement, nv: int, rng: RngLike
) -> FloatArray:
    """``gain * tau_cmd(t - delay) + offset + noise`` [N*m], shape (n_samples, nv).

    The delayed torque is linearly interpolated between samples, held at the first one.
    """
    signals = config.signals
    delayed = tau_cmd
    if signals.delay_s > 0.0:
        delayed = np.column_stack(
            [np.interp(t - signals.delay_s, t, tau_cmd[:, j]) for j in range(nv)]
        )
    gain = per_joint(signals.torque_gain, nv)
    offset = per_joint(signals.torque_offset, nv)
    noise_std = per_joint(config.torque_noise_std, nv)
    rng = np.random.default_rng(rng)
    # Draw even for zero std so that the random stream does not depend on the noise level.
    return gain * delayed + offset + rng.standard_normal(tau_cmd.shape) * noise_std


@dataclass(frozen=True)
class LogFiles:
    """The files :func:`write_log` wrote."""

    csv: Path  # t, q_<joint>..., tau_<joint>... (or current_<joint>...), tau_cmd_..., [q_cmd_...]
    yaml: Path  # the ``log:`` (and, for currents, ``transmission:``) sections for identify


def log_columns(log: SimulatedLog) -> tuple[list[str], list[str], list[str]]:
    """Column names of the position, measured-signal and commanded-torque blocks."""
    measured = "current" if log.current is not None else "tau"
    return (
        [f"q_{name}" for name in log.joint_names],
        [f"{measured}_{name}" for name in log.joint_names],
        [f"tau_cmd_{name}" for name in log.joint_names],
    )


def write_log(folder: str | Path, log: SimulatedLog) -> LogFiles:
    """Write the log as ``log.csv`` and its ``log:`` section as ``log.yaml`` into ``folder``.

    ``log.csv``: a header ``t,q_<joint>...,tau_<joint>...,tau_cmd_<joint>...`` (``current_<joint>``
    [A] in place of ``tau_<joint>`` [N*m] when currents are logged; then ``q_cmd_<joint>...``
    [rad], the commanded positions, for a position actuator), then one row per sample; every
    value is printed with 17 significant digits, so reading it back gives the same floats
    bit for bit. ``log.yaml``: the ``log:`` section of an ``ident identify`` config for this file
    (time column ``t``, joint-side positions in rad, torques in N*m or currents in A), plus
    ``transmission: {torque_constants: [...]}`` for currents; its paths are relative to
    ``folder``, so the YAML is valid where it lies.

    Returns
    -------
    :
        The two paths.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    q_cols, measured_cols, cmd_cols = log_columns(log)
    measured = log.current if log.current is not None else log.tau_measured
    blocks = [log.t, log.q, measured, log.tau_cmd]
    if log.q_cmd is not None:
        cmd_cols = cmd_cols + [f"q_cmd_{name}" for name in log.joint_names]
        blocks.append(log.q_cmd)
    table = np.column_stack(blocks)
    csv_path = folder / LOG_CSV
    np.savetxt(
        csv_path,
        table,
        fmt="%.17g",
        delimiter=",",
        header=",".join(["t", *q_cols, *measured_cols, *cmd_cols]),
        comments="",
    )
    section: dict = {
        "log": {
            "time": {"path": LOG_CSV, "column": "t"},
            "position": {"path": LOG_CSV, "columns": q_cols},
            "torque": {"path": LOG_CSV, "columns": measured_cols},
            "position_unit": "rad",
            "torque_unit": "A" if log.current is not None else "N*m",
            "side": "joint",
        }
    }
    if log.torque_constants is not None:
        section["transmission"] = {"torque_constants": log.torque_constants.tolist()}
    yaml_path = folder / LOG_YAML
    header = (
        f"# Simulated controller log ({log.n_samples} samples at {log.rate_hz:g} Hz, "
        f"MuJoCo {mujoco.__version__}); paths relative to this file.\n"
    )
    yaml_path.write_text(header + yaml.safe_dump(section, sort_keys=False), encoding="utf-8")
    return LogFiles(csv=csv_path, yaml=yaml_path)
