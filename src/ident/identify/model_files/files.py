"""The identified model's files: URDF, MJCF and joint extras, from a robot and an estimate.

:func:`model_files` computes the three texts (nothing is written; any error is raised before a
file exists); :func:`write_model_files` writes them into a folder as
``<stem>_identified.urdf``, ``<stem>_identified.xml`` and ``<stem>_joint_extras.json``.
See :mod:`ident.identify.model_files.urdf_update` (URDF, links fused through fixed or locked joints)
and
:mod:`ident.identify.model_files.mjcf` (MJCF, the mapping of the joint extras to MuJoCo).
"""

from __future__ import annotations

import copy
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import IdentError
from ident.fileio import atomic_write_text
from ident.identify.friction.friction_law import (
    LAW_TORQUE_MODEL,
    WrittenFrictionLaw,
    friction_law_entry,
    friction_law_torque,
    native_theta,
)
from ident.identify.model_files.mjcf import identified_mjcf
from ident.identify.model_files.urdf_update import IdentifiedModel, identified_urdf
from ident.model import Robot
from ident.robot.inertia import PINOCCHIO_ORDER

__all__ = [
    "COVARIANCE_SUFFIX",
    "covariance_json",
    "ModelFiles",
    "ReloadParity",
    "model_files",
    "mujoco_inverse_dynamics",
    "reload_parity",
    "save_identified_model",
    "write_model_files",
]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ModelFiles:
    """The identified model as texts, and where they were written (if they were).

    Attributes
    ----------
    urdf :
        The identified URDF and its sidecar (:class:`IdentifiedModel`).
    mjcf :
        The MJCF text.
    extras_json :
        The joint-extras file's text (the sidecar as JSON).
    paths :
        ``{"urdf", "mjcf", "joint_extras": path}`` once written, else empty.
    """

    urdf: IdentifiedModel
    mjcf: str
    extras_json: str
    paths: dict[str, Path]

    @property
    def urdf_text(self) -> str:
        """The identified URDF."""
        return self.urdf.text


def _servo_extras(
    position_servos: Mapping[str, Mapping[str, float | None]] | None,
) -> dict[str, Any]:
    """The joint-extras entry of position servos (empty without)."""
    if not position_servos:
        return {}
    law = (
        "tau = clip(kp (q_cmd(t - d) - q) - kd dq, +-forcerange); kd is in the joint's viscous "
        "term (kd + fv, not separable)"
    )
    joints = {name: dict(values) for name, values in position_servos.items()}
    return {"position_servos": {"law": law, "joints": joints}}


def model_files(
    robot: Robot,
    theta: npt.ArrayLike,
    names: tuple[str, ...],
    *,
    nominal: npt.ArrayLike | None = None,
    coupled_pair: tuple[int, int] | None = None,
    friction_law: WrittenFrictionLaw | None = None,
    position_servos: Mapping[str, Mapping[str, float | None]] | None = None,
) -> ModelFiles:
    """The identified URDF, MJCF and joint-extras texts of a consistent estimate.

    Parameters
    ----------
    robot :
        The identified robot (URDF text, model without the locked joints, locks, gravity).
    theta, names :
        Standard parameters (per body ``m, mcx, ..., Izz`` about the joint frame, then the
        extras ``Ia{j}``, ``fv{j}``, ``fs{j}``, ``off{j}``, ``Iam{b}``...), shape (n_std,) [SI],
        and their names.
    nominal :
        Nominal parameters in the order of ``names`` (optional), checked against the file.
    coupled_pair :
        The joints (0-based) sharing the coupled motor if ``theta`` has ``Iam{b}``: a tendon.
    friction_law :
        A friction law the model carries instead of ``fv``/``fs``
        (:mod:`ident.identify.friction.friction_law`): the joint-extras file gets its
        ``"friction_law"``, the URDF's and MJCF's damping and friction its native part.
    position_servos :
        ``{joint: {"kp", "forcerange"}}`` of position servos (``ServoFit.mjcf_servos``): a
        ``<position>`` actuator per joint in the MJCF, ``"position_servos"`` in the extras.

    Raises :class:`ModelError` (an inconsistent estimate, a URDF not of the robot, MuJoCo).
    """
    source = str(robot.urdf_path or robot.name)
    theta = native_theta(theta, names, friction_law)
    urdf = identified_urdf(
        robot.urdf_text,
        robot.model,
        np.asarray(theta, dtype=float),
        names,
        nominal=None if nominal is None else np.asarray(nominal, dtype=float),
        coupled_pair=coupled_pair,
        source=source,
    )
    mjcf = identified_mjcf(
        robot.urdf_text,
        tuple(robot.joint_names),
        _link_parameters(theta, names, urdf.links),
        urdf.sidecar["joints"],
        coupled_motors=urdf.sidecar["coupled_motors"],
        locked_joints=robot.locked_joints,
        gravity=np.asarray(robot.model.gravity.linear, dtype=float),
        source=source,
        position_servos=position_servos,
    )
    extras = {**_joint_extras(urdf, robot, friction_law), **_servo_extras(position_servos)}
    return ModelFiles(
        urdf=urdf, mjcf=mjcf, extras_json=json.dumps(extras, indent=2) + "\n", paths={}
    )


def _link_parameters(
    theta: npt.ArrayLike, names: tuple[str, ...], links: Sequence[str]
) -> dict[str, FloatArray]:
    """Each link's 10 parameters (10,) in Pinocchio's order, from ``theta`` (n_std,) by name."""
    theta = np.asarray(theta, dtype=float)
    index = {name: i for i, name in enumerate(names)}
    return {
        link: theta[[index[f"{label}{j}"] for label in PINOCCHIO_ORDER]]
        for j, link in enumerate(links, start=1)
    }


def _joint_extras(
    urdf: IdentifiedModel, robot: Robot, friction_law: WrittenFrictionLaw | None
) -> dict[str, Any]:
    """Content of the joint-extras file: the URDF's sidecar, the locked joints, the welded
    links' scales and the friction law when there are any."""
    extras = dict(urdf.sidecar)
    if robot.locked_joints:
        extras["locked_joints"] = dict(robot.locked_joints)
    if urdf.welded_scale:
        extras["welded_links_scaled"] = dict(urdf.welded_scale)
    if friction_law is not None:
        extras["torque_model"] = LAW_TORQUE_MODEL
        extras["friction_law"] = friction_law_entry(friction_law)
    return extras


def write_model_files(
    robot: Robot,
    theta: npt.ArrayLike,
    names: tuple[str, ...],
    out_dir: str | Path,
    stem: str,
    *,
    nominal: npt.ArrayLike | None = None,
    coupled_pair: tuple[int, int] | None = None,
    suffix: str = "identified",
    friction_law: WrittenFrictionLaw | None = None,
    position_servos: Mapping[str, Mapping[str, float | None]] | None = None,
) -> ModelFiles:
    """Write ``<stem>_identified.urdf``, ``<stem>_identified.xml``, ``<stem>_joint_extras.json``.

    Everything is computed first (:func:`model_files`); on an error nothing is written. Each
    file is written atomically into the existing folder ``out_dir``. ``suffix`` replaces
    ``identified`` in the model files' names (e.g. ``consistent``, where the cautious copy is
    ``<stem>_identified.urdf``).

    Returns
    -------
    :
        The texts and their ``paths``.
    """
    files = model_files(
        robot,
        theta,
        names,
        nominal=nominal,
        coupled_pair=coupled_pair,
        friction_law=friction_law,
        position_servos=position_servos,
    )
    folder = Path(out_dir)
    paths = {
        "urdf": atomic_write_text(folder / f"{stem}_{suffix}.urdf", files.urdf.text),
        "mjcf": atomic_write_text(folder / f"{stem}_{suffix}.xml", files.mjcf),
        "joint_extras": atomic_write_text(folder / f"{stem}_joint_extras.json", files.extras_json),
    }
    return ModelFiles(urdf=files.urdf, mjcf=files.mjcf, extras_json=files.extras_json, paths=paths)


@dataclass(frozen=True)
class ReloadParity:
    """How well the written files reproduce the estimate (see :func:`reload_parity`).

    Attributes
    ----------
    urdf_relative_error :
        ``max |tau_urdf - tau_estimate| / max |tau_estimate|``, Pinocchio RNEA of the
        reloaded URDF against the rigid-body part of the estimate.
    mjcf_relative_error :
        The same for MuJoCo's inverse dynamics of the MJCF (constraints off, so no friction
        loss) against rigid body + rotor inertia + viscous friction.
    n_states :
        Number of random states compared.
    friction_law_relative_error :
        With a friction law: ``max |law_file - law_fit| / max |law_fit|``, the law evaluated
        from the written joint-extras file (:func:`friction_law_torque`) against the fit's
        torques, on the identification samples; None without a law.
    """

    urdf_relative_error: float
    mjcf_relative_error: float
    n_states: int
    friction_law_relative_error: float | None = None


def reload_parity(
    robot: Robot,
    files: ModelFiles,
    theta: npt.ArrayLike,
    names: tuple[str, ...],
    *,
    n_states: int = 50,
    seed: int = 0,
    friction_law: WrittenFrictionLaw | None = None,
) -> ReloadParity:
    """Reload the written URDF (Pinocchio) and MJCF (MuJoCo) and compare with the estimate.

    The estimate's prediction is the robot's regressor times ``theta``'s body parameters
    (plus ``Ia_j ddq_j + fv_j dq_j`` and the coupled motors' inertia and viscous terms for
    MuJoCo) on ``n_states`` random states within the
    robot's limits (:meth:`Robot.random_configurations`). Both errors are about 1e-15 for a
    correct file; the tests hold them below 1e-9. With ``friction_law`` the files hold its
    native part as ``fv``/``fs`` (the MJCF's damping is compared with it), and the law read
    back from the joint-extras file is compared with the fit on its samples
    (``friction_law_relative_error``, 0 to rounding for a correct file).
    """
    import pinocchio as pin

    from ident.identify.model_files.urdf_update import model_of_urdf

    theta = native_theta(theta, names, friction_law)
    index = {name: i for i, name in enumerate(names)}
    n = robot.n_bodies
    q, dq, ddq = robot.random_configurations(n_states, rng=seed)
    # the bodies' parameters by name, in the regressor's (Pinocchio's) order: ``names`` may
    # interleave them with the extras (the identification's priority order)
    bodies = theta[[index[f"{label}{j}"] for j in range(1, n + 1) for label in PINOCCHIO_ORDER]]
    rigid = robot.regressor(q, dq, ddq) @ bodies
    scale = max(float(np.abs(rigid).max()), np.finfo(float).tiny)

    reloaded = model_of_urdf(files.urdf.text, robot.locked_joints)
    reloaded.gravity = robot.model.gravity
    data = reloaded.createData()
    tau = np.array([pin.rnea(reloaded, data, q[k], dq[k], ddq[k]) for k in range(n_states)])
    urdf_error = float(np.abs(tau - rigid).max()) / scale

    def extra(prefix: str) -> FloatArray:
        return np.array(
            [
                theta[index[f"{prefix}{j}"]] if f"{prefix}{j}" in index else 0.0
                for j in range(1, n + 1)
            ]
        )

    expected = rigid + extra("Ia") * ddq + extra("fv") * dq
    for motor in files.urdf.sidecar["coupled_motors"]:  # a tendon q_a + q_b in the MJCF
        a, b = (robot.joint_names.index(name) for name in motor["joints"])
        shared = motor["rotor_inertia"] * (ddq[:, a] + ddq[:, b])
        shared = shared + motor["viscous"] * (dq[:, a] + dq[:, b])
        expected[:, a] += shared
        expected[:, b] += shared
    got = mujoco_inverse_dynamics(files.mjcf, robot.joint_names, q, dq, ddq)
    mjcf_error = float(np.abs(got - expected).max()) / max(float(np.abs(expected).max()), scale)
    law_error = None if friction_law is None else _law_reload_error(files, friction_law)
    return ReloadParity(urdf_error, mjcf_error, n_states, law_error)


def mujoco_inverse_dynamics(
    mjcf: str | Any, joint_names: Sequence[str], q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> FloatArray:
    """MuJoCo's inverse dynamics of the MJCF text (or a copy of an ``MjModel``) with
    constraints off (no friction loss): joint torques [N*m or N] (n_states, n) at the states
    (n_states, n) of the named joints."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(mjcf) if isinstance(mjcf, str) else copy.copy(mjcf)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joint_names]
    qpos = np.array([model.jnt_qposadr[i] for i in ids])
    dof = np.array([model.jnt_dofadr[i] for i in ids])
    mj_data = mujoco.MjData(model)
    got = np.empty_like(np.asarray(dq, dtype=float))
    for k in range(q.shape[0]):
        mj_data.qpos[qpos], mj_data.qvel[dof], mj_data.qacc[dof] = q[k], dq[k], ddq[k]
        mujoco.mj_inverse(model, mj_data)
        got[k] = mj_data.qfrc_inverse[dof]
    return got


def _law_reload_error(files: ModelFiles, friction_law: WrittenFrictionLaw) -> float:
    """``max |law_file - law_fit| / max |law_fit|`` on the fit's samples, the law read back
    from the joint-extras file."""
    fitted = friction_law.torque(friction_law.dq, friction_law.load)
    read = friction_law_torque(json.loads(files.extras_json), friction_law.dq, friction_law.load)
    law_scale = max(float(np.abs(fitted).max()), np.finfo(float).tiny)
    return float(np.abs(read - fitted).max()) / law_scale


def save_identified_model(result: Any, out_dir: str | Path) -> dict[str, Any]:
    """Write the identified model of an identification and return its ``result.json`` entry.

    The model is ``result.model`` (:class:`~ident.identify.pipeline.core.IdentifyResult`): the
    physically consistent estimate of every link. Its files are
    ``<stem>_identified.urdf``, ``<stem>_identified.xml`` and ``<stem>_joint_extras.json``
    (``<stem>``: the robot file's name, :func:`write_model_files`); once written, both model
    files are reloaded and compared with the estimate (:func:`reload_parity`).

    Returns
    -------
    :
        JSON-ready: ``written`` (bool), ``method``, ``files`` (``urdf``, ``mjcf``,
        ``joint_extras``: names in ``out_dir``), ``reload_parity`` (``urdf``, ``mjcf``: the
        largest relative torque difference; ``n_states``; ``friction_law`` with a law),
        ``friction_law`` (with a law: its name and held-out residuals),
        ``held_out_relative_residual`` (the model's and the least-squares fit's, rows above
        the velocity threshold) and ``note`` (why nothing was written, or None). A model the
        files cannot represent (a :class:`~ident.errors.IdentError` from the write-back or
        MuJoCo) is a ``note``, not an exception: the estimate is saved before, the report
        says what happened.
    """
    from ident.identify.estimators.summary import model_identification
    from ident.model.selection import load_robot

    model = model_identification(result)
    ls_method = result.config.estimation.least_squares_method
    method = None if result.model is None else result.model.method
    entry: dict[str, Any] = {"written": False, "method": method, "files": None}
    entry.update(reload_parity=None, held_out_relative_residual=None, note=None)
    if model is None:
        entry["note"] = _not_written(result)
        return entry
    entry["held_out_relative_residual"] = {
        label: _finite(result.predictions[key].metrics.total_relative_residual)
        for label, key in ((model.method, model.method), (ls_method, "identified"))
        if key in result.predictions
    }
    law = getattr(result, "friction_law", None)
    if law is not None:
        entry["friction_law"] = _law_entry(law)
    try:
        robot = load_robot(result.config.robot)  # the identified chain, its locked joints
        files = _write_model(result, model, robot, out_dir, law)
    except IdentError as e:
        entry["note"] = f"no model written: {e}"
        return entry
    entry.update(written=True, files={key: path.name for key, path in files.paths.items()})
    _write_covariance(result, out_dir, entry["files"])
    try:  # the files are written: a reload that fails is reported, never loses them
        theta, names = model.constrained.theta, model.structure.names
        parity = reload_parity(robot, files, theta, names, friction_law=law)
    except IdentError as e:
        entry["note"] = f"written, but not reloaded: {e}"
        return entry
    entry["reload_parity"] = _parity_entry(parity)
    return entry


#: The file beside ``<stem>_identified.urdf`` holding its base parameters' covariance.
COVARIANCE_SUFFIX = "_identified_covariance.json"


def _write_covariance(result: Any, out_dir: str | Path, files: dict[str, str]) -> None:
    """Write :func:`covariance_json` as ``<stem>_identified_covariance.json`` beside the model
    (for ``ident payload``) and name it in ``files``; nothing when there is none."""
    text = covariance_json(result)
    if text is not None:
        stem = Path(result.config.robot.path).stem
        path = atomic_write_text(Path(out_dir) / f"{stem}{COVARIANCE_SUFFIX}", text)
        files["covariance"] = path.name


def covariance_json(result: Any) -> str | None:
    """The identification's base-parameter covariance, for a later user of the written model
    (``ident payload`` propagates the arm's uncertainty into the payload's intervals).

    ``{"parameter_names": (n_all,), "projection": T (n_base, n_all), "covariance": C (n_base,
    n_base), "method": ...}``: ``beta = T theta`` over every parameter (inertial, SI, and the
    extra terms), ``C`` the covariance of the least-squares ``beta`` by the identification's
    one interval method (block bootstrap, or ordinary). The written model is the consistent
    estimate, whose constraints can hold it tighter than the least-squares spread (a light
    last link): with the model's bootstrap re-solves, ``model_bootstrap`` holds their
    covariance over the standard parameters (:func:`_model_bootstrap`), the written model's
    own spread.
    None when the estimate is not over the base parameters or its covariance is not finite.
    """
    pm, sd = result.parameters, result.parameter_std
    covariance = np.asarray(sd.covariance, dtype=float)
    if tuple(result.estimate.names) != tuple(pm.base_names) or not np.all(np.isfinite(covariance)):
        return None
    return (
        json.dumps(
            {
                "description": "covariance of the identification's base parameters beta = T theta",
                "method": sd.method,
                "parameter_names": list(pm.names),
                "base_names": list(pm.base_names),
                "projection": np.asarray(pm.base.projection, dtype=float).tolist(),
                "covariance": covariance.tolist(),
                **_model_bootstrap(result),
            },
            allow_nan=False,
        )
        + "\n"
    )


def _model_bootstrap(result: Any) -> dict[str, Any]:
    """``{"model_bootstrap": {...}}``: the covariance of the written model's own bootstrap
    re-estimates (:mod:`ident.identify.assessment.model_intervals`) over its standard
    parameters, ``{}`` without them (switched off, fewer than 10 re-solves, not finite)."""
    intervals = getattr(result, "model_intervals", None)
    if intervals is None or intervals.samples.shape[0] < 10:
        return {}
    covariance = np.cov(np.asarray(intervals.samples, dtype=float), rowvar=False)
    if not np.all(np.isfinite(covariance)):
        return {}
    return {
        "model_bootstrap": {
            "method": intervals.method,
            "n_samples": int(intervals.samples.shape[0]),
            "parameter_names": list(intervals.names),
            "covariance": covariance.tolist(),
        }
    }


def _write_model(
    result: Any, model: Any, robot: Robot, out_dir: str | Path, law: Any
) -> ModelFiles:
    """:func:`write_model_files` of the identification's model (its consistent estimate)."""
    return write_model_files(
        robot,
        model.constrained.theta,
        model.structure.names,
        out_dir,
        Path(result.config.robot.path).stem,
        nominal=model.structure.nominal,
        coupled_pair=result.parameters.terms.coupled_wrist,
        friction_law=law,
        position_servos=_position_servos(result),
    )


def _position_servos(result: Any) -> dict[str, dict[str, float | None]] | None:
    """The MJCF's ``<position>`` actuators of an identification of position servos, or None."""
    fit = getattr(result, "actuator", None)
    return None if fit is None else fit.mjcf_servos()


def _parity_entry(parity: ReloadParity) -> dict[str, Any]:
    """The ``reload_parity`` entry of :func:`save_identified_model`."""
    entry: dict[str, Any] = {
        "urdf": parity.urdf_relative_error,
        "mjcf": parity.mjcf_relative_error,
        "n_states": parity.n_states,
    }
    if parity.friction_law_relative_error is not None:
        entry["friction_law"] = parity.friction_law_relative_error
    return entry


def _not_written(result: Any) -> str:
    """Why no model is written: switched off, or the consistent estimator did not converge."""
    if result.model is None:
        return "no model written: urdf_update.model is none"
    why = result.model.constrained.message if result.model.constrained is not None else None
    return f"no model written: {result.model.method} did not give a consistent estimate" + (
        f" ({why})" if why is not None else ""
    )


def _law_entry(law: Any) -> dict[str, Any]:
    """The written friction law's ``result.json`` entry: its name and held-out residuals."""
    return {
        "model": law.model,
        "held_out_relative_residual": {
            law.model: law.held_out_residual,
            "viscous_coulomb": law.baseline_held_out_residual,
        },
    }


def _finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None
