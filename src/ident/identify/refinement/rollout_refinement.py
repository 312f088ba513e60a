"""Refinement of the written MJCF's joint extras on MuJoCo rollouts (``refinement: rollout``).

Inverse dynamics fits ``tau = Y(q, dq, ddq) theta``; MuJoCo integrates the model forward, with
Coulomb friction as a constraint (``frictionloss``) and damping integrated implicitly, so small
errors that the torque fit does not see grow over an open-loop rollout
(:mod:`ident.identify.assessment.rollout`). The refinement adjusts only what the regressor
cannot express in MuJoCo's own terms, per moving joint ``j``: ``frictionloss_j``,
``damping_j`` and ``armature_j`` (``x``, 3 n values, through
:func:`ident.measure.mujoco_model.set_joint_parameters`, ident's ``fs``, ``fv``, ``Ia``); the
link inertials stay the regressor's consistent estimate. In scaled variables
``z = x / s`` (``s``: the regressor's value, at least :data:`SCALE_FLOOR` of the largest of its
kind), starting from the regressor's ``z0``, :func:`scipy.optimize.least_squares` (trust region,
``z >= 0``, forward differences of step :data:`DIFF_STEP`) minimises::

    F(z) = J_train(z) / J_train(z0) + w / (3 n) * ||z - z0||^2

``J_train``: the rollout objective (:func:`~ident.identify.assessment.rollout.rollout_score`)
over windows of the identification part (:func:`identification_windows`, disjoint from the
held-out ones; its errors divided by the same scale as the held-out ``J``'s, the whole log's
motion, :func:`~ident.identify.assessment.rollout.log_motion_scale`), ``w``:
``refinement.prior_weight`` (default 0.01: moving every value by 100 %
costs 1 % of the starting objective). After each iteration the held-out objective ``J_held``
(the rollout check's windows, :func:`held_out_windows`) is computed; the iterate with the best
``J_held`` is kept (early stopping: the search stops after :data:`PATIENCE` iterations without
a better one, or at ``refinement.max_iterations``).

The refined values are accepted only if ``J_held`` improves on the regressor's AND the held-out
torque error (:func:`torque_error`) is no worse; otherwise the MJCF keeps the regressor's values
and the entry says why. Accepted, the MJCF file (``<stem>_identified.xml``) carries them; the
URDF and the joint-extras file keep the regressor's (the torque model). :func:`refinement_text`
is the one line the terminal and the report show of ``result.json``'s ``refinement`` entry.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from ident.errors import IdentError
from ident.fileio import atomic_write_text
from ident.identify.assessment.rollout import (
    MAX_TIMESTEP_S,
    WINDOW_S,
    RolloutMeasurements,
    held_out_windows,
    identification_windows,
    joint_addresses,
    rollout_residuals,
    rollout_score,
    written_offsets,
)
from ident.identify.model_files.files import mujoco_inverse_dynamics
from ident.identify.model_files.mjcf import with_joint_values
from ident.measure.mujoco_model import JOINT_PARAMETER_FIELDS, MujocoRobot, set_joint_parameters

__all__ = [
    "DIFF_STEP",
    "NOT_RUN",
    "KINDS",
    "MJCF_ATTRIBUTES",
    "PATIENCE",
    "SCALE_FLOOR",
    "Refinement",
    "estimated_cpu_s",
    "joint_values",
    "refine_joint_extras",
    "refinement_entry",
    "refinement_off",
    "refinement_text",
    "rejection_reasons",
    "torque_error",
    "with_values",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
Windows = tuple[RolloutMeasurements, IntArray]

#: ident's per-joint parameters refined, in the rows of ``x`` (3, nv): Coulomb, viscous, rotor.
KINDS = ("fs", "fv", "Ia")
#: Their MJCF ``<joint>`` attributes.
MJCF_ATTRIBUTES = {"fs": "frictionloss", "fv": "damping", "Ia": "armature"}
#: Smallest scale of a value, as a fraction of the largest regressor value of its kind.
SCALE_FLOOR = 0.05
#: Relative forward-difference step of the Jacobian (in scaled variables).
DIFF_STEP = 1e-3
#: Iterations without a better held-out objective before the search stops.
PATIENCE = 2
#: CPU seconds of one MuJoCo step of a rollout, per ``1 + nv`` (measured on a shared 2-core
#: machine: 21 us per step of the UR5 with friction loss, 11 us of a 2-joint arm); only for
#: the estimate printed before a refinement.
STEP_CPU_S = 3.5e-6


@dataclass(frozen=True, eq=False)
class Refinement:
    """A refinement's course (:func:`refine_joint_extras`); values (3, nv) in :data:`KINDS` rows.

    Attributes
    ----------
    initial, refined :
        The regressor's values and the kept iterate's [SI, joint side].
    held_out, train :
        ``J_held`` and ``J_train`` per iterate (index 0: ``initial``).
    best :
        Index of the kept iterate (0: none improved the held-out objective).
    cpu_s, estimate_s :
        CPU seconds used, and estimated from the first training rollout's.
    stop :
        Why the search stopped.
    """

    initial: FloatArray
    refined: FloatArray
    held_out: tuple[float, ...]
    train: tuple[float, ...]
    best: int
    cpu_s: float
    estimate_s: float
    stop: str

    @property
    def iterations(self) -> int:
        """Iterations done."""
        return len(self.held_out) - 1


def _robot(model: mujoco.MjModel, joint_names: Sequence[str]) -> MujocoRobot:
    """The map of the named joints of an MJCF's model (for :func:`set_joint_parameters`)."""
    qpos, dof = joint_addresses(model, joint_names)
    return MujocoRobot(model, tuple(joint_names), qpos, dof)


def joint_values(model: mujoco.MjModel, joint_names: Sequence[str]) -> FloatArray:
    """The named joints' ``frictionloss``, ``damping``, ``armature``, shape (3, nv) [SI]."""
    dof = _robot(model, joint_names).dof_index
    return np.array([getattr(model, JOINT_PARAMETER_FIELDS[k])[dof] for k in KINDS])


def with_values(model: mujoco.MjModel, joint_names: Sequence[str], x: FloatArray) -> Any:
    """A copy of ``model`` with the named joints' values ``x`` (3, nv) [SI] set, and the
    constants MuJoCo's compiler derives from them recomputed (``mj_setConst``: the dofs'
    ``invweight0``, which sets the friction-loss constraint's softness, includes the armature),
    so the copy simulates as the MJCF file carrying ``x`` does once reloaded."""
    out = copy.copy(model)
    set_joint_parameters(_robot(out, joint_names), dict(zip(KINDS, np.asarray(x), strict=True)))
    mujoco.mj_setConst(out, mujoco.MjData(out))
    return out


def estimated_cpu_s(
    n_train: int, n_held: int, sampling_rate_hz: float, nv: int, iterations: int
) -> float:
    """CPU seconds of a refinement [s], before any rollout: ``iterations`` of ``3 nv + 2``
    rollouts of the ``n_train`` training windows and one of the ``n_held`` held-out windows
    (the counts :func:`~ident.identify.assessment.rollout.window_count` gives), each window
    :data:`WINDOW_S` long in MuJoCo steps of at most
    :data:`~ident.identify.assessment.rollout.MAX_TIMESTEP_S` (the sample period or a divisor
    of it), :data:`STEP_CPU_S` per step and ``1 + nv``."""
    substeps = max(1, math.ceil(1.0 / (sampling_rate_hz * MAX_TIMESTEP_S) - 1e-9))
    steps = substeps * round(WINDOW_S * sampling_rate_hz)
    per_iteration = (3 * nv + 2) * n_train + n_held
    return float(iterations * per_iteration * steps * (1 + nv) * STEP_CPU_S)


def _scales(x0: FloatArray) -> FloatArray:
    """Scale of each value (3, nv): its regressor value, at least :data:`SCALE_FLOOR` of the
    largest of its kind (and 1e-9, for a kind that is zero everywhere)."""
    largest = np.max(np.abs(x0), axis=1, keepdims=True)
    return np.maximum(np.abs(x0), np.maximum(SCALE_FLOOR * largest, 1e-9))


def refine_joint_extras(
    model: mujoco.MjModel,
    train: Windows,
    held: Windows,
    *,
    max_iterations: int,
    prior_weight: float,
) -> Refinement:
    """Refine the joints' ``frictionloss``, ``damping``, ``armature`` on rollouts (module
    docstring): ``least_squares`` on the ``train`` windows, the iterate with the best objective
    on the ``held`` windows kept.

    Parameters
    ----------
    model :
        The MuJoCo model (copied, never changed); its values of the joints named in the
        windows' measurements are the start and the prior.
    train, held :
        Measurements and ``[start, stop)`` windows (W, 2) (:func:`identification_windows`,
        :func:`held_out_windows`), with the same sample period.
    max_iterations, prior_weight :
        The most iterations; ``w`` of the module docstring.

    Raises
    ------
    DataError
        When a rollout fails (a window, a joint missing, divergence).
    """
    start = time.process_time()
    p = _Problem(model, train, held, prior_weight)
    course = _Course(p.z0, float(np.sum(p.score(p.z0, held) ** 2)), p.j0)
    estimate = p.one_s * max_iterations * (p.z0.size + 2) + (time.process_time() - start)

    def callback(intermediate_result: Any) -> None:  # the name scipy's introspection wants
        z = np.asarray(intermediate_result.x, dtype=float)
        course.record(z, float(np.sum(p.score(z, held) ** 2)), p.train_objective(z))
        course.check(max_iterations)

    stop = "converged (least_squares' tolerances)"
    if p.j0 > 0.0:
        out = least_squares(
            p.residuals, p.z0, bounds=(0.0, np.inf), method="trf", diff_step=DIFF_STEP,
            max_nfev=4 * max_iterations, callback=callback, x_scale=1.0,
        )  # fmt: skip
        stop = course.stop or ("converged" if out.status > 0 else str(out.message))
    return Refinement(
        initial=p.x0,
        refined=p.values(course.best_z),
        held_out=tuple(course.held),
        train=tuple(course.train),
        best=course.best,
        cpu_s=time.process_time() - start,
        estimate_s=estimate,
        stop=stop,
    )


class _Problem:
    """The scaled least-squares problem of :func:`refine_joint_extras` (module docstring)."""

    def __init__(
        self, model: mujoco.MjModel, train: Windows, held: Windows, prior_weight: float
    ) -> None:
        self.model, self.train, self.names = model, train, train[0].joint_names
        self.substeps = rollout_score(model, held[0], held[1]).substeps
        # MuJoCo's values are never negative; the scales: module docstring
        self.x0 = np.maximum(joint_values(model, self.names), 0.0)
        self.scale = _scales(self.x0)
        self.z0 = (self.x0 / self.scale).ravel()
        self.prior = math.sqrt(prior_weight / self.z0.size)
        t0 = time.process_time()
        r0 = self.score(self.z0, train)
        self.one_s = time.process_time() - t0  # CPU of one rollout of the training windows
        self.j0 = float(r0 @ r0)
        # the training residuals of the latest evaluations (the callback's iterate among them)
        self.seen = {self.z0.tobytes(): r0}

    def values(self, z: FloatArray) -> FloatArray:
        """The joint values (3, nv) [SI] of scaled variables ``z`` (3 nv,)."""
        return z.reshape(self.x0.shape) * self.scale

    def score(self, z: FloatArray, windows: Windows) -> FloatArray:
        """Rollout residuals of ``z`` on ``windows`` (:func:`rollout_residuals`)."""
        mj = with_values(self.model, self.names, self.values(z))
        return rollout_residuals(mj, windows[0], windows[1], substeps=self.substeps)

    def train_residuals(self, z: FloatArray) -> FloatArray:
        """:meth:`score` on the training windows, remembered for an iteration's evaluations."""
        r = self.seen.get(z.tobytes())
        if r is None:
            r = self.score(z, self.train)
            if len(self.seen) > 2 * z.size + 4:
                del self.seen[next(iter(self.seen))]
            self.seen[z.tobytes()] = r
        return r

    def train_objective(self, z: FloatArray) -> float:
        """``J_train(z)``."""
        r = self.train_residuals(z)
        return float(r @ r)

    def residuals(self, z: FloatArray) -> FloatArray:
        """The residuals of ``F`` (module docstring): data over ``sqrt(J_train(z0))``, prior."""
        r = self.train_residuals(z) / math.sqrt(max(self.j0, 1e-300))
        return np.concatenate([r, self.prior * (z - self.z0)])


class _Course:
    """The iterates' objectives, the best held-out one, and the early stop."""

    def __init__(self, z0: FloatArray, held0: float, train0: float) -> None:
        self.held, self.train = [held0], [train0]
        self.best, self.best_z, self.stop = 0, z0, ""
        self.last, self.moves, self.best_move = z0, 0, 0

    def record(self, z: FloatArray, held: float, train: float) -> None:
        if not np.array_equal(z, self.last):  # an iteration whose step was refused: no move
            self.moves += 1
        self.last = z.copy()
        self.held.append(held)
        self.train.append(train)
        if held < self.held[self.best]:
            self.best, self.best_z, self.best_move = len(self.held) - 1, z.copy(), self.moves

    def check(self, max_iterations: int) -> None:
        """Raise StopIteration (least_squares' stop) at the cap or after :data:`PATIENCE`
        moves (iterations whose step was taken) without a better held-out objective."""
        done = len(self.held) - 1
        if done >= max_iterations:
            self.stop = f"iteration cap ({max_iterations}, refinement.max_iterations)"
        elif self.moves - self.best_move >= PATIENCE:
            self.stop = f"early stop: no better held-out objective in {PATIENCE} iterations"
        if self.stop:
            raise StopIteration


def torque_error(
    model: mujoco.MjModel, measurements: RolloutMeasurements, windows: IntArray
) -> float:
    """Held-out relative torque error of a model's joint values: ``||tau - tau^|| / ||tau||``.

    ``tau^`` is ident's torque model with the MJCF's values: MuJoCo's inverse dynamics without
    constraints (bodies, ``armature ddq``, ``damping dq``) plus ``frictionloss sign(dq)``, at
    the windows' interior samples (``ddq``: central differences of ``dq``); ``tau``: the
    measured torques the rollouts are driven with. Dimensionless.
    """
    w = np.asarray(windows)
    rows = np.concatenate([np.arange(a + 1, b - 1) for a, b in w])
    m = measurements
    dt = float(np.median(np.diff(m.t[w[0, 0] : w[0, 1]])))
    ddq = (m.dq[rows + 1] - m.dq[rows - 1]) / (2.0 * dt)
    names = m.joint_names
    tau_hat = mujoco_inverse_dynamics(model, names, m.q[rows], m.dq[rows], ddq)
    tau_hat = tau_hat + joint_values(model, names)[0] * np.sign(m.dq[rows])
    size = max(float(np.linalg.norm(m.tau[rows])), 1e-300)
    return float(np.linalg.norm(m.tau[rows] - tau_hat)) / size


#: What every message of a refinement that could not run starts with.
NOT_RUN = "refinement not run"
# What a model or its data can fail with: named in the entry's note, never raised.
_FAILURES = (IdentError, ValueError, OSError, KeyError, TypeError, mujoco.FatalError)


def refinement_off() -> dict[str, Any]:
    """The ``refinement`` entry of an identification that did not ask for one."""
    return {"method": "none", "accepted": None, "note": "refinement: none (the default)"}


def _not_run(cfg: Any, reason: str) -> dict[str, Any]:
    return {"method": cfg.method, "accepted": None, "note": f"{NOT_RUN}: {reason}"}


def refinement_entry(
    result: Any, folder: Path, model: Mapping[str, Any], rollout: Mapping[str, Any]
) -> dict[str, Any]:
    """Refine the written MJCF as ``result.config.refinement`` asks; its ``result.json`` entry.

    Parameters
    ----------
    result :
        The identification (:class:`~ident.identify.pipeline.core.IdentifyResult`).
    folder, model :
        The run folder and :func:`~ident.identify.model_files.files.save_identified_model`'s
        entry (its MJCF and joint-extras file).
    rollout :
        The MJCF's rollout entry (its reference, the truth or the nominal model, and that
        reference's held-out objective).

    Returns
    -------
    :
        JSON-ready (module docstring, :func:`_done_entry`), or with ``method: none`` when not
        asked for; a refinement that cannot run says why in ``note`` (never raises for the
        data or the model). Accepted, the MJCF file is rewritten with the refined values.
    """
    cfg = result.config.refinement
    if cfg.method == "none":
        return refinement_off()
    if not model.get("written"):
        return _not_run(cfg, f"no MJCF written ({model.get('note')})")
    if rollout.get("objective") is None:
        return _not_run(cfg, f"the MJCF's rollout check did not run ({rollout.get('note')})")
    files = model["files"]
    try:
        mj = mujoco.MjModel.from_xml_path(str(folder / files["mjcf"]))
        offsets = np.asarray(written_offsets(folder, files, result.joint_names), dtype=float)
        train, held = (
            _driven(windows, offsets)
            for windows in (
                identification_windows(result, max_windows=cfg.max_windows),
                held_out_windows(result),
            )
        )
        fit = refine_joint_extras(
            mj, train, held, max_iterations=cfg.max_iterations, prior_weight=cfg.prior_weight
        )
        entry = _done_entry(cfg, mj, fit, train, held, rollout)
        if entry["accepted"]:
            _write_refined(folder / files["mjcf"], result.joint_names, fit.refined)
            entry["file"] = files["mjcf"]
    except _FAILURES as e:
        return _not_run(cfg, str(e).strip().splitlines()[0] if str(e).strip() else repr(e))
    return entry


def _driven(windows: Windows, offsets: FloatArray) -> Windows:
    """The windows' measurements driven by the measured torque minus the offsets (nv,)."""
    m, w = windows
    return m.with_torque(m.tau - offsets), w


def _done_entry(
    cfg: Any,
    model: mujoco.MjModel,
    fit: Refinement,
    train: Windows,
    held: Windows,
    rollout: Mapping[str, Any],
) -> dict[str, Any]:
    """The entry of a refinement that ran: ``objective_before``/``_after`` (held-out ``J``),
    ``reference``/``reference_objective`` (the rollout entry's), ``torque_error_before``/
    ``_after`` (:func:`torque_error`), ``parameters`` (``{joint: {attribute: [before, after]}}``
    [SI]), ``iterations``, ``best_iteration``, ``stop``, ``held_out_objectives`` (per
    iterate), windows, settings, ``cpu_s``, ``cpu_estimate_s``, ``accepted`` and ``note``
    (why not accepted), ``file`` (the MJCF that carries the refined values, or None)."""
    names = train[0].joint_names
    before = torque_error(model, *held)
    after = torque_error(with_values(model, names, fit.refined), *held)
    j_before, j_after = fit.held_out[0], fit.held_out[fit.best]
    why = rejection_reasons(fit, before, after)
    return {
        "method": cfg.method,
        "accepted": not why,
        "note": "; ".join(why) or None,
        "objective_before": j_before,
        "objective_after": j_after if not why else j_before,
        "objective_best_iterate": j_after,
        "reference": rollout.get("reference"),
        "reference_objective": rollout.get("reference_objective"),
        "torque_error_before": before,
        "torque_error_after": after if not why else before,
        "torque_error_best_iterate": after,
        "parameters": {
            name: {
                MJCF_ATTRIBUTES[k]: [float(fit.initial[i, j]), float(fit.refined[i, j])]
                for i, k in enumerate(KINDS)
            }
            for j, name in enumerate(names)
        },
        "iterations": fit.iterations,
        "best_iteration": fit.best,
        "stop": fit.stop,
        "held_out_objectives": list(fit.held_out),
        "train_windows": int(train[1].shape[0]),
        "held_out_windows": int(held[1].shape[0]),
        "window_s": WINDOW_S,
        "max_windows": cfg.max_windows,
        "max_iterations": cfg.max_iterations,
        "prior_weight": cfg.prior_weight,
        "cpu_s": fit.cpu_s,
        "cpu_estimate_s": fit.estimate_s,
        "file": None,
    }


def rejection_reasons(fit: Refinement, torque_before: float, torque_after: float) -> list[str]:
    """Why the refined values are not accepted (empty: accepted): no iterate improved the
    held-out rollout objective, or the held-out torque error (:func:`torque_error`, before and
    after) would rise."""
    if fit.best == 0:
        return [
            f"no iterate improved the held-out rollout objective ({fit.iterations} iterations, "
            f"{fit.stop})"
        ]
    if torque_after > torque_before:
        return [
            f"the held-out torque error would rise from {torque_before:.4g} to {torque_after:.4g}"
        ]
    return []


def _write_refined(path: Path, joint_names: Sequence[str], refined: FloatArray) -> None:
    """Rewrite the MJCF at ``path`` with the refined joint values (3, nv) [SI]."""
    values = {
        name: {MJCF_ATTRIBUTES[k]: float(refined[i, j]) for i, k in enumerate(KINDS)}
        for j, name in enumerate(joint_names)
    }
    note = (
        "Refined on MuJoCo rollouts (result.json: refinement): the joints' frictionloss, "
        "damping and armature below are the refinement's; the URDF and the joint-extras file "
        "keep the regressor's values (the torque model)."
    )
    text = with_joint_values(path.read_text(encoding="utf-8"), values, note)
    atomic_write_text(path, text)


def refinement_text(entry: Mapping[str, Any] | None) -> str | None:
    """The one line the terminal and the report show of a ``refinement`` entry, or None when
    none was asked for (:func:`refinement_entry`)."""
    if entry is None or entry.get("method") in (None, "none"):
        return None
    if entry.get("accepted") is None:
        return str(entry["note"])
    ref = entry["reference_objective"]
    ref_text = f", {entry['reference']} model {ref:.4g}" if ref is not None else ""
    verdict = (
        f"accepted, {entry['file']} carries the refined values (URDF: the regressor's)"
        if entry["accepted"]
        else f"not accepted ({entry['note']}), the MJCF keeps the regressor's values"
    )
    n = len(entry["parameters"])
    return (
        f"MJCF refinement on rollouts: {verdict}; held-out rollout error "
        f"{entry['objective_before']:.4g} -> {entry['objective_best_iterate']:.4g}{ref_text}; "
        f"held-out torque error {entry['torque_error_before']:.4g} -> "
        f"{entry['torque_error_best_iterate']:.4g}; frictionloss, damping, armature of {n} "
        f"joints, {entry['iterations']} iterations (best {entry['best_iteration']}; "
        f"{entry['stop']}), {entry['train_windows']} training / {entry['held_out_windows']} "
        f"held-out windows of {entry['window_s']:g} s, prior weight {entry['prior_weight']:g}, "
        f"CPU {entry['cpu_s']:.1f} s (at most {entry['cpu_estimate_s']:.1f} s: every iteration "
        "allowed, timed on one rollout)"
    )
