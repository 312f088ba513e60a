"""Rollout validation of a written MJCF: open-loop simulations over held-out windows of a log.

The inverse-dynamics fit says how well a model predicts the torques of a measured motion; a
simulator user needs the converse: given the measured torques, does MuJoCo reproduce the motion?
:func:`rollout_score` answers it on windows of the log (default :data:`WINDOW_S` = 0.5 s, at
most :data:`MAX_WINDOWS`, from its held-out part: the samples the identification kept aside,
:func:`held_out_windows`). In each window ``w`` (samples ``s_w .. s_w + L``), MuJoCo starts from
the measured state ``(q, dq)`` at ``s_w``, the measured joint torques are applied as
``qfrc_applied`` held over each sample period (zero-order hold; the model's actuators, a
position servo's ``<position>`` ones, are switched off: the measured torques stand for them),
with MuJoCo's timestep the sample period or a divisor of it (at most
:data:`MAX_TIMESTEP_S`), and the predicted ``q^, dq^`` are compared with the measured ones at
the ``L`` following samples. The objective (one formula, shown as "MJCF rollout")::

    J = 1/W sum_w 1/(2 n L) sum_{k=1..L} sum_{j=1..n}
          [ ((q^_wkj - q_wkj) / sd_q_j)^2 + ((dq^_wkj - dq_wkj) / sd_dq_j)^2 ]

with ``n`` joints and ``sd_q_j``, ``sd_dq_j`` the scale of joint ``j``: the standard deviations
of its ``q_j``, ``dq_j`` over the whole log, identification and held-out parts, as the
identification filters them (at least :data:`SD_FLOOR`; :func:`log_motion_scale`, carried by
the measurements as :attr:`RolloutMeasurements.scale`). One scale per identification: the
held-out score, the refinement's training and held-out objectives divide by the same numbers,
and a joint that barely moves in the scored windows does not weigh more there than in the log
(divided by its motion over the scored windows alone, a wrist at rest in the held-out part
would dominate ``J`` with errors a thousandth of the log's motion). ``J = 0``: the model
replays the log exactly; ``J ~ 1``: its errors are as large as the log's motion. The windows
are rolled out in one call of MuJoCo's :mod:`mujoco.rollout`.

Beside it, the same score of a reference model, written by the same MJCF writer
(:func:`ident.identify.model_files.mjcf.identified_mjcf`, so both share MuJoCo's friction-loss
and implicit-damping approximations and differ only in their parameters): in simulation
(``ident run``) the truth, i.e. the simulator's bodies (URDF inertials, payload) and its
armature, viscous and Coulomb friction, applied to the measured torque corrected by the
simulated gain and offset; on a log (``ident identify``) the URDF's nominal bodies without
joint extras. :func:`rollout_check` computes both once; the result's ``rollout`` entry
(``result.json``), the report's row and the terminal line (:func:`rollout_text`) show that
entry. A check that cannot run (no MJCF written, too few held-out samples, MuJoCo failing) says
so: ``rollout check not run: <why>``.
"""

from __future__ import annotations

import contextlib
import copy
import json
import math
import weakref
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt
from mujoco import rollout as mj_rollout

from ident.dynamics.parameters import payload_on_joint
from ident.errors import DataError, IdentError, ModelError
from ident.identify.estimation import preprocess
from ident.identify.estimation.accumulate import margin_samples
from ident.identify.model_files.fused_bodies import fused_bodies, parse_urdf
from ident.identify.model_files.mjcf import identified_mjcf
from ident.model import Robot
from ident.model.selection import load_robot

__all__ = [
    "IDENTIFICATION_OVERLAP",
    "MAX_TIMESTEP_S",
    "MAX_WINDOWS",
    "NOT_RUN",
    "ReferenceModel",
    "SD_FLOOR",
    "WINDOW_S",
    "RolloutMeasurements",
    "RolloutScore",
    "held_out_windows",
    "identification_ranges",
    "identify_rollout",
    "reference_mjcf",
    "rollout_check",
    "identification_windows",
    "joint_addresses",
    "log_motion_scale",
    "motion_scale",
    "rollout_not_run",
    "rollout_residuals",
    "rollout_score",
    "rollout_text",
    "run_rollout",
    "spread_windows",
    "window_count",
    "written_offsets",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Length of a rollout window [s].
WINDOW_S = 0.5
#: Most windows scored (spread evenly over the held-out part): bounds the time (~L steps each).
MAX_WINDOWS = 64
#: Windows of the identification part (:func:`identification_windows`) start every
#: ``1 / IDENTIFICATION_OVERLAP`` of a window (0.1 s for 0.5 s windows), so they overlap. A
#: rollout's error is mostly the drift the torque noise drives from its start state; more
#: starts over the same samples average that drift instead of fitting it (the UR5's seed-1
#: MuJoCo-native log: on its 40 disjoint windows the refinement's first step lowered the
#: training objective 4 % and raised the objective on a fresh noise draw 1.6 %; on 64
#: overlapping ones it lowered both).
IDENTIFICATION_OVERLAP = 5
#: Longest MuJoCo timestep [s]: a slower log is integrated in several steps per sample.
MAX_TIMESTEP_S = 1e-3
#: Smallest standard deviation a joint's positions or velocities are divided by [rad or m,
#: rad/s or m/s]: a joint that does not move still has a finite weight.
SD_FLOOR = 1e-6
#: How every message of a check that did not run starts.
NOT_RUN = "rollout check not run"

# One Euler step per sample period within this relative tolerance of the sample times.
_UNIFORM_RTOL = 1e-6
# What a model or its data can fail with: named in the entry's note, never raised.
_FAILURES = (IdentError, ValueError, mujoco.FatalError)


@dataclass(frozen=True, eq=False)
class RolloutMeasurements:
    """Measured motion and torques on a uniform time grid (samples on axis 0).

    Attributes
    ----------
    t :
        Time [s], shape (n,); uniform within each window (a window never spans a gap).
    q, dq :
        Joint positions [rad or m] and velocities [rad/s or m/s], shape (n, nv).
    tau :
        Joint torques [N*m or N], shape (n, nv), each held from its sample to the next.
    joint_names :
        The joints, in column order (matched by name in the MJCF).
    scale :
        What the rollout errors are divided by: rows ``sd_q``, ``sd_dq`` [rad or m, rad/s or
        m/s], shape (2, nv), the log's motion (:func:`log_motion_scale`, set by
        :func:`held_out_windows` and :func:`identification_windows`); None: the motion of
        these samples, all of them (:func:`motion_scale` of ``q``, ``dq``).
    """

    t: FloatArray
    q: FloatArray
    dq: FloatArray
    tau: FloatArray
    joint_names: tuple[str, ...]
    scale: FloatArray | None = None

    def with_torque(self, tau: FloatArray) -> RolloutMeasurements:
        """The same motion (and scale) with other torques ``tau`` (n, nv)."""
        return RolloutMeasurements(self.t, self.q, self.dq, tau, self.joint_names, self.scale)

    def sd(self) -> FloatArray:
        """The scale the errors are divided by, shape (2, nv) (:attr:`scale`)."""
        return motion_scale(self.q, self.dq) if self.scale is None else np.asarray(self.scale)


def motion_scale(q: FloatArray, dq: FloatArray) -> FloatArray:
    """The standard deviations of positions ``q`` and velocities ``dq`` (n, nv) over their
    samples, each at least :data:`SD_FLOOR`: rows ``sd_q``, ``sd_dq``, shape (2, nv) [rad or
    m, rad/s or m/s]. The one formula of the rollout objective's scale."""
    return np.maximum(np.vstack([np.std(q, axis=0), np.std(dq, axis=0)]), SD_FLOOR)


@dataclass(frozen=True, eq=False)
class RolloutScore:
    """The rollout objective of a model (:func:`rollout_score`).

    Attributes
    ----------
    objective :
        ``J`` of the module docstring (dimensionless).
    per_window :
        Each window's term of the mean, shape (W,), in the order of ``windows``.
    timestep_s :
        MuJoCo's timestep [s] (the sample period over ``substeps``).
    substeps :
        MuJoCo steps per sample period.
    """

    objective: float
    per_window: FloatArray
    timestep_s: float
    substeps: int


def rollout_score(
    model: mujoco.MjModel | str | Path,
    measurements: RolloutMeasurements,
    windows: npt.ArrayLike,
    *,
    substeps: int | None = None,
) -> RolloutScore:
    """Score a MuJoCo model by open-loop rollouts over windows of measurements.

    Parameters
    ----------
    model :
        The model, or the path of its MJCF; copied, never changed. Its joints named
        ``measurements.joint_names`` are driven (hinge or slide, any order); its actuators
        (a position servo's) are switched off, the measured torques stand for them. Its
        options are kept but the timestep (and auto-reset: a diverging rollout must show as
        such, not restart from ``qpos0``).
    measurements :
        The measured motion and torques (:class:`RolloutMeasurements`).
    windows :
        ``[start, stop)`` sample ranges, shape (W, 2), all of the same length ``L + 1 >= 2``:
        the state at ``start`` is the initial state, ``L`` steps are compared.
    substeps :
        MuJoCo steps per sample period; default: the fewest with a timestep of at most
        :data:`MAX_TIMESTEP_S`.

    Returns
    -------
    :
        The objective ``J`` (module docstring) and its per-window terms.

    Raises
    ------
    DataError
        For malformed windows, non-uniform sample times in a window, a joint missing from
        the model, or a rollout that diverges (non-finite state).
    """
    e_q, e_dq, timestep, substeps = _scaled_errors(model, measurements, windows, substeps)
    per_window = 0.5 * (np.mean(e_q**2, axis=(1, 2)) + np.mean(e_dq**2, axis=(1, 2)))
    return RolloutScore(float(np.mean(per_window)), per_window, timestep, substeps)


def rollout_residuals(
    model: mujoco.MjModel | str | Path,
    measurements: RolloutMeasurements,
    windows: npt.ArrayLike,
    *,
    substeps: int | None = None,
) -> FloatArray:
    """The residuals of :func:`rollout_score`'s objective: ``r`` of shape (2 W L nv,) with
    ``sum(r**2) = J`` (the scaled ``q`` and ``dq`` errors over ``sqrt(2 W L nv)``); the
    parameters and errors as :func:`rollout_score`'s."""
    e_q, e_dq, _, _ = _scaled_errors(model, measurements, windows, substeps)
    return np.concatenate([e_q.ravel(), e_dq.ravel()]) / math.sqrt(2.0 * e_q.size)


def _scaled_errors(
    model: mujoco.MjModel | str | Path,
    measurements: RolloutMeasurements,
    windows: npt.ArrayLike,
    substeps: int | None,
) -> tuple[FloatArray, FloatArray, float, int]:
    """The rollout's ``q`` and ``dq`` errors over the measurements' scale
    (:meth:`RolloutMeasurements.sd`), shapes (W, L, nv), MuJoCo's timestep [s] and substeps
    (:func:`rollout_score`)."""
    mj = _model_copy(model)
    starts, length = _checked_windows(windows, measurements.t.shape[0])
    dt = _sample_period(measurements.t, starts, length)
    substeps = substeps or max(1, math.ceil(dt / MAX_TIMESTEP_S - 1e-9))
    mj.opt.timestep = dt / substeps
    mj.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
    # the measured torques stand for the actuators: a position servo's MJCF has <position>
    # actuators, which would otherwise pull toward ctrl = 0 on top of them
    mj.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_ACTUATION
    qpos, dof = joint_addresses(mj, measurements.joint_names)
    q_hat, dq_hat = _rollout(mj, measurements, starts, length, substeps, (qpos, dof))
    steps = starts[:, None] + np.arange(1, length)[None, :]  # (W, L) compared samples
    # the log's motion, not the scored windows' (module docstring)
    sd_q, sd_dq = measurements.sd()
    e_q = (q_hat - measurements.q[steps]) / sd_q
    e_dq = (dq_hat - measurements.dq[steps]) / sd_dq
    return e_q, e_dq, float(mj.opt.timestep), substeps


def _model_copy(model: mujoco.MjModel | str | Path) -> mujoco.MjModel:
    """A model this module may change: loaded from the MJCF path, or a copy of ``model``."""
    if isinstance(model, mujoco.MjModel):
        return copy.copy(model)  # MuJoCo's copy: its own arrays and options
    try:
        return mujoco.MjModel.from_xml_path(str(model))
    except ValueError as e:
        raise ModelError(f"{model}: MuJoCo cannot load the MJCF ({_first_line(e)}).") from e


def _checked_windows(windows: npt.ArrayLike, n_samples: int) -> tuple[IntArray, int]:
    """The windows' start samples (W,) and their common length ``L + 1`` (DataError)."""
    w = np.asarray(windows)
    if w.ndim != 2 or w.shape[0] == 0 or w.shape[1] != 2 or not np.issubdtype(w.dtype, np.integer):
        raise DataError(f"rollout windows: need integer [start, stop) rows (W, 2), got {w.shape}.")
    lengths = w[:, 1] - w[:, 0]
    if np.any(lengths != lengths[0]) or lengths[0] < 2:
        raise DataError("rollout windows: every window needs the same length of at least 2.")
    if w.min() < 0 or w.max() > n_samples:
        raise DataError(f"rollout windows: a window leaves the {n_samples} samples.")
    return w[:, 0].astype(np.int64), int(lengths[0])


def _sample_period(t: FloatArray, starts: IntArray, length: int) -> float:
    """The common sample period [s] of the windows (DataError when not uniform)."""
    steps = np.diff(t[starts[:, None] + np.arange(length)[None, :]], axis=1)
    dt = float(np.median(steps))
    if not dt > 0.0 or np.max(np.abs(steps - dt)) > _UNIFORM_RTOL * dt:
        raise DataError("rollout windows: the sample times are not uniform within the windows.")
    return dt


def joint_addresses(model: mujoco.MjModel, joint_names: Sequence[str]) -> tuple[IntArray, IntArray]:
    """``qpos`` and ``qvel`` addresses (nv,) of the named 1-DoF joints (DataError when one is
    missing, or not a hinge or slide)."""
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in joint_names]
    one_dof = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    bad = [
        n
        for n, i in zip(joint_names, ids, strict=True)
        if i < 0 or model.jnt_type[i] not in one_dof
    ]
    if bad:
        raise DataError(f"the model has no hinge or slide joint {', '.join(bad)}.")
    return (
        np.array([model.jnt_qposadr[i] for i in ids], dtype=np.int64),
        np.array([model.jnt_dofadr[i] for i in ids], dtype=np.int64),
    )


def _rollout(
    model: mujoco.MjModel,
    measurements: RolloutMeasurements,
    starts: IntArray,
    length: int,
    substeps: int,
    addresses: tuple[IntArray, IntArray],
) -> tuple[FloatArray, FloatArray]:
    """Predicted ``q^``, ``dq^`` at the ``length - 1`` samples after each start, shapes
    (W, L, nv): every window in one :func:`mujoco.rollout.rollout` call, the torque of sample
    ``k`` held (``qfrc_applied``) over the ``substeps`` steps up to sample ``k + 1``."""
    qpos, dof = addresses
    data = mujoco.MjData(model)
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
    initial = np.empty((starts.size, mujoco.mj_stateSize(model, full)))
    for w, s in enumerate(starts):
        mujoco.mj_resetData(model, data)
        data.qpos[qpos], data.qvel[dof] = measurements.q[s], measurements.dq[s]
        mujoco.mj_getState(model, data, initial[w], full)
    held = measurements.tau[starts[:, None] + np.arange(length - 1)[None, :]]  # (W, L, nv)
    control = np.zeros((starts.size, length - 1, model.nv))
    control[:, :, dof] = held
    control = np.repeat(control, substeps, axis=1)  # zero-order hold over the substeps
    state, _ = mj_rollout.rollout(
        model,
        data,
        initial,
        control,
        control_spec=mujoco.mjtState.mjSTATE_QFRC_APPLIED.value,
    )
    state = state[:, substeps - 1 :: substeps]  # the state at each following sample
    if not np.all(np.isfinite(state)):
        raise DataError("MuJoCo's rollout diverged (non-finite state) in a window.")
    q0 = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_TIME.value)
    v0 = q0 + model.nq
    return state[:, :, q0 + qpos], state[:, :, v0 + dof]


def reference_mjcf(
    robot: Robot,
    extras: Mapping[str, Mapping[str, float]] | None = None,
    payload: tuple[str | None, FloatArray] | None = None,
) -> str:
    """The MJCF of the robot's own bodies (its URDF inertials, fused as Pinocchio fuses them)
    with the joint ``extras``, written by the identified model's writer.

    Parameters
    ----------
    robot :
        The robot (URDF text, Pinocchio model, locked joints, gravity).
    extras :
        ``{joint: {"rotor_inertia", "viscous", "coulomb"}}`` [SI] (the simulator's truth), or
        None: no joint extras (the URDF's nominal model).
    payload :
        ``(link, parameters (10,))``: a rigid payload about ``link``'s origin [SI], Pinocchio
        order, added to the body that carries ``link`` (None: the last moving joint's child
        link, as the simulator's ``measurement.payload``), or None.

    Raises
    ------
    ModelError
        If the URDF's structure does not match the model, the payload's link is not a link of
        the model, or MuJoCo cannot compile the bodies.
    """
    model = robot.model
    source = str(robot.urdf_path or robot.name)
    carriers = [
        body.carrier for body in fused_bodies(parse_urdf(robot.urdf_text, source), model, source)
    ]
    bodies = {c: model.inertias[j].toDynamicParameters() for j, c in enumerate(carriers, start=1)}
    if payload is not None:
        link, parameters = payload
        try:
            joint, phi = payload_on_joint(model, link, parameters)
        except ValueError:
            raise ModelError(
                f"{source}: the payload's link {link!r} is not a link of the robot."
            ) from None
        bodies[carriers[joint - 1]] = bodies[carriers[joint - 1]] + phi
    return identified_mjcf(
        robot.urdf_text,
        tuple(robot.joint_names),
        bodies,
        extras or {},
        locked_joints=robot.locked_joints,
        gravity=np.asarray(model.gravity.linear, dtype=float),
        source=source,
    )


def spread_windows(n_candidates: int, max_windows: int = MAX_WINDOWS) -> IntArray:
    """Indices of at most ``max_windows`` of ``n_candidates`` windows, spread evenly (first and
    last included), increasing, shape (min(n, max),)."""
    if n_candidates <= max_windows:
        return np.arange(n_candidates, dtype=np.int64)
    return np.round(np.linspace(0, n_candidates - 1, max_windows)).astype(np.int64)


def held_out_windows(
    result: Any, window_s: float = WINDOW_S, max_windows: int = MAX_WINDOWS
) -> tuple[RolloutMeasurements, IntArray]:
    """The rollout windows of an identification's held-out part, and their measurements.

    The held-out part is, per segment of ``result.log``, the raw samples between the first
    and the last held-out time stamp (``result.t_validate``, the identification's time split;
    the identification part itself when ``validation.identify_fraction`` is 1). It is cut in
    windows of ``round(window_s * fs) + 1`` samples (consecutive windows share one sample), of
    which at most ``max_windows`` are kept, spread evenly (:func:`spread_windows`). Each
    window's ``q``, ``dq`` and ``tau`` are the identification's: low-pass and central
    differences of ``preprocess`` (or the log's measured ``dq``), computed on the window with
    the chunks' filter margins on both sides (:func:`margin_samples`).

    Parameters
    ----------
    result :
        An :class:`~ident.identify.pipeline.core.IdentifyResult` (``log``, ``t_validate``,
        ``config.preprocess`` resolved).
    window_s, max_windows :
        Window length [s] and the most windows.

    Returns
    -------
    :
        The windows' samples, one after another (shape (W * (L + 1), nv)), and their
        ``[start, stop)`` rows, shape (W, 2).

    Raises
    ------
    DataError
        When the held-out part is shorter than one window.
    """
    ranges = _held_out_ranges(result.log, np.asarray(result.t_validate))
    return _part_windows(result, ranges, "held-out", window_s, max_windows)


def identification_windows(
    result: Any, window_s: float = WINDOW_S, max_windows: int = MAX_WINDOWS
) -> tuple[RolloutMeasurements, IntArray]:
    """Rollout windows of the identification part, disjoint from :func:`held_out_windows`'.

    Per segment of ``result.log``, the raw samples before its held-out range (the whole
    segment when it has none; a segment's samples after it too), without the
    ``preprocess.trim_samples`` at each end of the segment; cut in windows that start every
    ``1 / IDENTIFICATION_OVERLAP`` of a window (overlapping, unlike the held-out ones: see
    :data:`IDENTIFICATION_OVERLAP`), spread and processed as :func:`held_out_windows` does
    (same parameters, returns and errors). No window shares a sample with a held-out window.
    """
    ranges = identification_ranges(result)
    return _part_windows(
        result, ranges, "identification", window_s, max_windows, IDENTIFICATION_OVERLAP
    )


def window_count(
    result: Any, part: str, window_s: float = WINDOW_S, max_windows: int = MAX_WINDOWS
) -> int:
    """How many windows :func:`identification_windows` (``part="identification"``) or
    :func:`held_out_windows` (``"held-out"``) return with these parameters, counted from the
    log's time stamps alone (nothing filtered); 0 where they would raise."""
    if part == "held-out":
        ranges, overlap = _held_out_ranges(result.log, np.asarray(result.t_validate)), 1
    else:
        ranges, overlap = identification_ranges(result), IDENTIFICATION_OVERLAP
    starts = _window_starts(ranges, _window_length(result.log, window_s), overlap)
    return min(len(starts), max_windows)


def identification_ranges(result: Any) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """The identification part's raw samples: per segment ``(a, b)`` of ``result.log``, the
    ``[r0, r1)`` ranges before and after its held-out range (the whole segment when it has
    none), without the ``preprocess.trim_samples`` at each end of the segment; no range shares
    a sample with the held-out range (:func:`held_out_windows`)."""
    log = result.log
    trim = int(result.config.preprocess.trim_samples)
    held = dict(_held_out_ranges(log, np.asarray(result.t_validate)))
    ranges = []
    for a, b in log.segments:
        lo, hi = held.get((a, b), (b, b))
        for r0, r1 in ((a + trim, lo - 1), (hi + 1, b - trim)):
            if r1 > r0:
                ranges.append(((a, b), (r0, r1)))
    return ranges


def _window_length(log: Any, window_s: float) -> int:
    """Samples of a window of ``window_s`` [s] (its last one the next window's first)."""
    return int(round(window_s * log.sampling_rate_hz)) + 1


def _window_starts(
    ranges: Sequence[tuple[tuple[int, int], tuple[int, int]]], length: int, overlap: int = 1
) -> list[tuple[tuple[int, int], int]]:
    """Every window that fits in the ranges, one every ``(length - 1) / overlap`` samples (1:
    consecutive windows share one sample): its segment and first raw sample."""
    step = max(1, (length - 1) // overlap)
    return [(segment, s) for segment, (lo, hi) in ranges for s in range(lo, hi - length + 1, step)]


def _part_windows(
    result: Any,
    ranges: Sequence[tuple[tuple[int, int], tuple[int, int]]],
    part: str,
    window_s: float,
    max_windows: int,
    overlap: int = 1,
) -> tuple[RolloutMeasurements, IntArray]:
    """The windows of the raw ranges ``(segment, [lo, hi))`` of a part of the log
    (:func:`held_out_windows`; ``overlap``: :func:`_window_starts`); DataError naming ``part``
    when none fits."""
    log, pp = result.log, result.config.preprocess
    length = _window_length(log, window_s)
    candidates = _window_starts(ranges, length, overlap)
    if not candidates:
        raise DataError(
            f"the {part} part of the log is shorter than one window of {window_s:g} s "
            f"({length} samples at {log.sampling_rate_hz:g} Hz)."
        )
    margin = margin_samples(pp, log.sampling_rate_hz)[0]
    pieces = [
        _window_signals(log, candidates[i][0], candidates[i][1], length, pp, margin)
        for i in spread_windows(len(candidates), max_windows)
    ]
    starts = np.arange(len(pieces), dtype=np.int64) * length
    t, q, dq, tau = (np.concatenate([p[k] for p in pieces]) for k in range(4))
    scale = log_motion_scale(result)
    measurements = RolloutMeasurements(t, q, dq, tau, tuple(log.joint_names), scale)
    return measurements, np.column_stack([starts, starts + length])


#: Raw samples filtered at a time by :func:`log_motion_scale` (with the chunks' margins on
#: both sides): an hour at 1 kHz is never filtered as one array beside the log itself.
SCALE_BLOCK_SAMPLES = 1 << 16

#: Each identification's scale, computed once (held-out and identification windows share it).
_SCALES: weakref.WeakKeyDictionary[Any, FloatArray] = weakref.WeakKeyDictionary()


def log_motion_scale(result: Any) -> FloatArray:
    """The scale of the rollout objective of an identification: :func:`motion_scale` of the
    whole log's ``q`` and ``dq`` (every segment, identification and held-out parts, without
    the ``preprocess.trim_samples`` at each end), low-passed and differentiated as the
    identification does (:func:`held_out_windows`). Shape (2, nv) [rad or m, rad/s or m/s]; a
    segment too short to filter is left out (a DataError when none is left).

    Filtered by blocks of :data:`SCALE_BLOCK_SAMPLES` with the chunks' filter margins on both
    sides (equal to filtering the whole segment, as the chunked identification relies on),
    their moments combined: the memory is a block's, whatever the log's length. Computed
    once per ``result``.
    """
    try:
        return _SCALES[result]
    except (KeyError, TypeError):  # not computed yet; an object without weak references
        pass
    log, pp = result.log, result.config.preprocess
    trim = int(pp.trim_samples)
    margin = margin_samples(pp, log.sampling_rate_hz)[0]
    moments = _Moments()
    for a, b in log.segments:
        lo, hi = a + trim, b - trim
        if hi - lo < 2:
            continue
        for c0 in range(lo, hi, SCALE_BLOCK_SAMPLES):
            c1 = min(hi, c0 + SCALE_BLOCK_SAMPLES)
            r0, r1 = max(a, c0 - margin), min(b, c1 + margin)
            try:
                q, dq = _states(log, r0, r1, pp)
            except DataError:  # a segment too short to filter
                break
            moments.add(np.stack([q[c0 - r0 : c1 - r0], dq[c0 - r0 : c1 - r0]]))
    if moments.n == 0:
        raise DataError("the log has no segment long enough to filter: no rollout scale.")
    scale = np.maximum(np.sqrt(moments.variance()), SD_FLOOR)
    with contextlib.suppress(TypeError):
        _SCALES[result] = scale
    return scale


class _Moments:
    """Count, mean and sum of squared deviations of samples added block by block (Chan's
    pairwise combination: no cancellation of a large mean against a small spread)."""

    def __init__(self) -> None:
        self.n, self.mean, self.m2 = 0, 0.0, 0.0

    def add(self, x: FloatArray) -> None:
        """Add the samples of ``x`` (2, m, nv) (rows ``q``, ``dq``)."""
        m = x.shape[1]
        if m == 0:
            return
        mean = x.mean(axis=1)
        m2 = ((x - mean[:, None, :]) ** 2).sum(axis=1)
        n = self.n + m
        delta = mean - self.mean
        self.mean = self.mean + delta * (m / n)
        self.m2 = self.m2 + m2 + delta**2 * (self.n * m / n)
        self.n = n

    def variance(self) -> FloatArray:
        """The population variance (2, nv), as ``np.std``'s."""
        return np.asarray(self.m2 / self.n, dtype=float)


def _held_out_ranges(
    log: Any, t_validate: FloatArray
) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """Per segment with held-out samples: the segment and its held-out raw range [lo, hi)."""
    out = []
    for a, b in log.segments:
        t = log.t[a:b]
        inside = t_validate[(t_validate >= t[0]) & (t_validate <= t[-1])]
        if inside.size:
            lo = a + int(np.searchsorted(t, inside.min()))
            out.append(((a, b), (lo, a + int(np.searchsorted(t, inside.max(), side="right")))))
    return out


def _window_signals(
    log: Any, segment: tuple[int, int], start: int, length: int, pp: Any, margin: int
) -> tuple[FloatArray, ...]:
    """``t, q, dq, tau`` of the samples ``[start, start + length)`` processed as the
    identification processes them, on the window plus ``margin`` samples each side."""
    fs = log.sampling_rate_hz
    r0, r1 = max(segment[0], start - margin), min(segment[1], start + length + margin)
    q, dq = _states(log, r0, r1, pp)
    tau = log.tau[r0:r1]
    if pp.torque_lowpass is not None:
        flt = pp.torque_lowpass
        tau, _ = preprocess.lowpass(tau, fs, flt.cutoff_hz, flt.order, what="tau")
    keep = slice(start - r0, start - r0 + length)
    return log.t[start : start + length], q[keep], dq[keep], tau[keep]


def _states(log: Any, r0: int, r1: int, pp: Any) -> tuple[FloatArray, FloatArray]:
    """``q``, ``dq`` (r1 - r0, nv) of the raw samples ``[r0, r1)`` of one segment, filtered
    on them as the identification does: the log's measured ``dq``, else the low-passed
    positions' central differences."""
    q = log.q[r0:r1]
    if log.dq is not None:
        return q, log.dq[r0:r1]
    position = preprocess.position_filter(pp)
    if position is not None:
        q, _ = preprocess.lowpass(q, log.sampling_rate_hz, position.cutoff_hz, position.order)
    return q, preprocess.differentiate(q, log.sampling_rate_hz)[0]


#: Builds a reference model for a robot: its MJCF text and the map of the measured torque to
#: the torque it is driven with, ``(tau - offset) / gain`` (offset, gain: (nv,) or scalars).
ReferenceModel = Callable[[Robot], tuple[str, npt.ArrayLike, npt.ArrayLike]]


def rollout_check(
    result: Any,
    mjcf: Path,
    reference: str,
    reference_model: ReferenceModel,
    *,
    offsets: npt.ArrayLike = 0.0,
) -> dict[str, Any]:
    """The rollout entry of an identification's written MJCF and of a reference model.

    Parameters
    ----------
    result :
        The identification (:func:`held_out_windows`; ``config.robot`` for the reference).
    mjcf :
        The written MJCF; driven by the measured torque minus ``offsets`` (nv,) [N*m or N],
        the identified torque offsets (which the MJCF cannot hold).
    reference, reference_model :
        The reference's name (``"truth"``, ``"nominal"``) and how to build it.

    Returns
    -------
    :
        JSON-ready: ``objective`` (``J`` of the MJCF, module docstring), ``reference_objective``
        (the reference's, on the same windows), ``reference``, ``windows`` (W), ``window_s``,
        ``max_windows``, ``timestep_s``, ``held_out`` (False: no held-out part, the windows
        are identification samples), ``note`` (``"rollout check not run: ..."``, else None)
        and ``reference_note`` (why the reference was not scored, else None). Never raises
        for the data or the model: what failed is the note.
    """
    try:
        measurements, windows = held_out_windows(result)
        driven = measurements.with_torque(measurements.tau - np.asarray(offsets, dtype=float))
        score = rollout_score(mjcf, driven, windows)
    except _FAILURES as e:
        return rollout_not_run(reference, _first_line(e))
    entry = _entry(reference, windows=int(windows.shape[0]), timestep_s=score.timestep_s)
    entry.update(objective=score.objective)
    entry["held_out"] = bool(result.config.validation.identify_fraction < 1.0)
    try:
        text, offset, gain = reference_model(load_robot(result.config.robot))
        tau = (measurements.tau - np.asarray(offset, dtype=float)) / np.asarray(gain, dtype=float)
        model = mujoco.MjModel.from_xml_string(text)
        ref = rollout_score(model, measurements.with_torque(tau), windows, substeps=score.substeps)
        entry["reference_objective"] = ref.objective
    except _FAILURES as e:
        entry["reference_note"] = f"the {reference} model was not scored: {_first_line(e)}"
    return entry


def _first_line(error: BaseException) -> str:
    """The first line of an error's message (MuJoCo's can run over several)."""
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


def _entry(reference: str, **values: Any) -> dict[str, Any]:
    """A rollout entry with every key (see :func:`rollout_check`), ``values`` set."""
    entry: dict[str, Any] = {
        "objective": None,
        "reference_objective": None,
        "reference": reference,
        "windows": 0,
        "window_s": WINDOW_S,
        "max_windows": MAX_WINDOWS,
        "timestep_s": None,
        "held_out": None,
        "note": None,
        "reference_note": None,
    }
    entry.update(values)
    return entry


def rollout_not_run(reference: str, reason: str) -> dict[str, Any]:
    """The rollout entry of a check that could not run: its ``note`` says why."""
    return _entry(reference, note=f"{NOT_RUN}: {reason}")


def rollout_text(entry: Mapping[str, Any] | None) -> str:
    """The one line every place shows of a rollout entry (:func:`rollout_check`)."""
    if entry is None:
        return (
            f"{NOT_RUN}: no rollout entry in result.json (an interrupted run, or one written "
            "before the check existed)"
        )
    if entry["objective"] is None:
        return str(entry["note"])
    reference = entry["reference"]
    ref = (
        f"{reference} model {entry['reference_objective']:.3g}"
        if entry["reference_objective"] is not None
        else str(entry["reference_note"])
    )
    part = "held-out part" if entry["held_out"] else "identification part (no held-out part)"
    return (
        f"MJCF rollout error {entry['objective']:.3g} ({ref}): open-loop MuJoCo rollouts "
        f"driven by the measured torques, {entry['windows']} windows of {entry['window_s']:g} s "
        f"(at most {entry['max_windows']}) of the log's {part}, timestep "
        f"{1e3 * entry['timestep_s']:.3g} ms; mean squared error of q and dq over their std in "
        "the whole log (0: exact)"
    )


def identify_rollout(result: Any, folder: Path, model: Mapping[str, Any]) -> dict[str, Any]:
    """The rollout entry of ``ident identify``: the MJCF written into ``folder`` (``model``:
    :func:`~ident.identify.model_files.files.save_identified_model`'s entry) against the
    URDF's nominal model (no joint extras)."""
    return _written_check(
        result, Path(folder), model, "nominal", lambda robot: (reference_mjcf(robot), 0.0, 1.0)
    )


def run_rollout(
    outcome: Any, payload: Any, folder: Path, model: Mapping[str, Any] | None
) -> dict[str, Any]:
    """The rollout entry of ``ident run``: the MJCF of the executed elite's simulated log
    (``outcome``: its :class:`~ident.run.log_measurement.LogOutcome`, None for an ideal
    measurement) against the simulator's truth: bodies (with ``payload``, the
    ``measurement.payload`` config or None), armature, viscous and Coulomb friction, driven by
    the measured torque corrected by the simulated gain and offset."""
    if outcome is None:
        return rollout_not_run(
            "truth", "no simulated log (measurement.source: ideal), so no MJCF is written"
        )
    truth, names = outcome.log.truth, outcome.log.joint_names
    extras = {
        name: {
            "rotor_inertia": float(truth["armature"][j]),
            "viscous": float(truth["viscous"][j]),
            "coulomb": float(truth["coulomb"][j]),
        }
        for j, name in enumerate(names)
    }
    mass = None if payload is None else (payload.link, payload.parameters())

    def truth_model(robot: Robot) -> tuple[str, FloatArray, FloatArray]:
        return reference_mjcf(robot, extras, mass), truth["torque_offset"], truth["torque_gain"]

    return _written_check(outcome.result, Path(folder), model or {}, "truth", truth_model)


def _written_check(
    result: Any,
    folder: Path,
    model: Mapping[str, Any],
    reference: str,
    reference_model: ReferenceModel,
) -> dict[str, Any]:
    """:func:`rollout_check` of the model files of ``model`` in ``folder``, or why not."""
    if result is None:
        return rollout_not_run(reference, "the log did not identify, so no MJCF is written")
    if not model.get("written"):
        return rollout_not_run(reference, f"no MJCF written ({model.get('note')})")
    files = model["files"]
    try:
        offsets = written_offsets(folder, files, result.joint_names)
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
        return rollout_not_run(reference, f"cannot read {files['joint_extras']} ({e})")
    return rollout_check(
        result, folder / files["mjcf"], reference, reference_model, offsets=offsets
    )


def written_offsets(
    folder: Path, files: Mapping[str, str], joint_names: Sequence[str]
) -> list[float]:
    """The identified torque offsets [N*m or N] (nv,) of the joint-extras file ``files
    ["joint_extras"]`` in ``folder`` (0 for a joint without one), which the MJCF cannot hold:
    its rollouts are driven by the measured torque minus them. Raises OSError, ValueError,
    KeyError, TypeError or AttributeError for a file that is missing or malformed."""
    sidecar = json.loads((folder / files["joint_extras"]).read_text(encoding="utf-8"))
    joints = sidecar["joints"]
    return [float(joints.get(name, {}).get("offset", 0.0)) for name in joint_names]
