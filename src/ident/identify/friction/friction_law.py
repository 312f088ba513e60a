"""The friction law the written model carries, and its evaluation from the joint-extras file.

When ``model.friction`` names a law other than ``viscous_coulomb``, or ``auto`` picks one, the
identified model carries that law (:mod:`ident.dynamics.friction_models`):

- **Its parameters** are those of its separable least-squares fit with the rest of the model
  (:func:`ident.identify.friction.friction_fit.compare_friction_models`). The written rigid bodies,
  rotor inertias and offsets stay the consistent estimate's, which was fitted with viscous +
  Coulomb friction: the two were fitted separately (a consistent estimate with a nonlinear law
  is not implemented). Holding the consistent estimate and refitting only the law on what it
  leaves was tried and is worse: on a simulated Stribeck UR5 the consistent estimate's bodies
  had absorbed part of the Stribeck curve and the refit's ``fc`` came out 0.42-2.7 N*m for a
  true 1.0 (the separable fit: within 5 % on five joints). The file records the held-out fit of
  the written combination (consistent bodies + law) against the consistent bodies +
  ``viscous_coulomb`` fitted the same way.
- **``<stem>_joint_extras.json``** gains ``"friction_law"`` (:func:`friction_law_entry`): the
  law's name, formula, the unit of each parameter, the joint order, each joint's parameters by
  label, and how to apply it. Its ``"torque_model"`` says that the law replaces ``viscous`` and
  ``coulomb``.
- **URDF and MJCF** cannot hold a Stribeck or sigmoid law: their ``damping`` and
  ``friction``/``frictionloss`` (and the file's ``"joints"`` ``viscous``/``coulomb``) hold the
  law's closest viscous + Coulomb curve, per joint the non-negative least-squares fit of
  ``d dq + f sign(dq)`` to the law's torque at the identification samples' velocities (the
  "native part"). A MuJoCo user adds the rest, ``law(dq) - d dq - f sign(dq)``, as
  ``qfrc_applied`` every step (:func:`applied_friction_torque`, from the file alone).

:func:`friction_law_torque` evaluates the law from the file (by label, through the registry):
the reload check compares it with the fit's torques on the identification samples.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import nnls

from ident.dynamics.friction_models import get_friction_model
from ident.errors import DataError
from ident.identify.estimation.validation import prediction_metrics
from ident.identify.friction.friction_fit import FrictionFit, FrictionRows, fit_friction_model

__all__ = [
    "LAW_TORQUE_MODEL",
    "WrittenFrictionLaw",
    "applied_friction_torque",
    "friction_law_entry",
    "friction_law_torque",
    "native_theta",
    "written_friction_law",
]

FloatArray = npt.NDArray[np.float64]

#: The joint-extras file's ``"torque_model"`` when it carries a friction law.
LAW_TORQUE_MODEL = (
    "tau_j = rnea_j(q, dq, ddq) + rotor_inertia_j ddq_j + offset_j + law_j(dq_j, load_j), "
    "law and its parameters in 'friction_law' (it replaces viscous and coulomb of 'joints', "
    "which hold its closest viscous + Coulomb curve, as the URDF and MJCF do); coupled motors "
    "as listed"
)

#: How a user applies the law (the ``"apply"`` of ``"friction_law"``).
_APPLY = (
    "Pinocchio/URDF: add law_j(dq_j, load_j) to rnea (the URDF's damping/friction hold only "
    "its native part: do not add both). MuJoCo/MJCF: damping and frictionloss hold the native "
    "part; add qfrc_applied_j = law_j - native_damping_j dq_j - native_frictionloss_j "
    "sign(dq_j) every step (ident.identify.friction.friction_law.applied_friction_torque(file, dq, "
    "load)). load_j: the joint's torque without friction (rnea + rotor inertia + offset) "
    "[N*m], used by load-dependent laws only."
)


@dataclass(frozen=True, eq=False)
class WrittenFrictionLaw:
    """The friction law of the written model (module docstring).

    Attributes
    ----------
    model :
        Registry name of the law.
    joint_names :
        Every moving joint, the columns of ``dq`` (length nv).
    joints :
        0-based joints that have the law (those with friction terms).
    fit :
        The law's fit (``fit.linear`` (nv, n_linear), ``fit.nonlinear`` (nv, n_nonlinear),
        zero on joints without the law).
    native :
        Closest viscous + Coulomb curve per joint, shape (nv, 2): ``[damping, frictionloss]``
        [N*m*s/rad, N*m], both >= 0.
    dq, load :
        Identification samples' velocities [rad/s] and loads [N*m], shape (n, nv): where the
        reload check evaluates the written law.
    held_out_residual :
        Total relative residual of the written model (its rigid bodies, rotor inertias,
        offsets) with the law, on the held-out rows (the identification rows when none).
    baseline_held_out_residual :
        The same with ``viscous_coulomb`` fitted to the torque the written bodies leave.
    on_held_out :
        Whether the residuals are on held-out rows.
    """

    model: str
    joint_names: tuple[str, ...]
    joints: tuple[int, ...]
    fit: FrictionFit
    native: FloatArray
    dq: FloatArray
    load: FloatArray
    held_out_residual: float
    baseline_held_out_residual: float
    on_held_out: bool

    def torque(self, dq: FloatArray, load: FloatArray) -> FloatArray:
        """The law's torque [N*m], shape (n, nv) (zero on joints without it)."""
        law = get_friction_model(self.model)
        tau = law.torque(dq, load, self.fit.linear, self.fit.nonlinear)
        mask = np.zeros(len(self.joint_names), dtype=bool)
        mask[list(self.joints)] = True
        return np.where(mask, tau, 0.0)


def written_friction_law(
    fit: FrictionFit,
    rows: FrictionRows,
    held_out: FrictionRows | None,
    rest: FloatArray,
    joint_names: tuple[str, ...],
) -> WrittenFrictionLaw:
    """The law of ``fit`` as the written model carries it (module docstring).

    Parameters
    ----------
    fit :
        The law's separable least-squares fit (:func:`~ident.identify.friction.friction_fit.
        compare_friction_models`' fit of the chosen model): its parameters are written.
    rows, held_out :
        Identification and held-out rows
        (:func:`~ident.identify.friction.friction_fit.friction_rows`).
    rest :
        The written model's parameters of the columns of ``rows.W_rest``, shape (p,): the
        residuals of the written model with the law, and with ``viscous_coulomb`` fitted to
        the torque that ``rest`` leaves, are computed with them.
    joint_names :
        The moving joints (length nv).
    """
    base = fit_friction_model("viscous_coulomb", rows, rest=rest)
    val = held_out if held_out is not None else rows
    rest_val = val.W_rest @ rest

    def residual(f: FrictionFit) -> float:
        law = get_friction_model(f.model)
        friction = law.torque(val.dq, rest_val, f.linear, f.nonlinear)
        mask = np.zeros(val.tau.shape[1], dtype=bool)
        mask[list(val.joints)] = True
        pred = rest_val + np.where(mask, friction, 0.0)
        return float(prediction_metrics(val.tau, pred, val.keep).total_relative_residual)

    load = rows.W_rest @ fit.rest  # the load the fit used
    law = get_friction_model(fit.model)
    tau = law.torque(rows.dq, load, fit.linear, fit.nonlinear)
    native = np.zeros((rows.tau.shape[1], 2))
    for j in rows.joints:  # the closest d dq + f sign(dq), d, f >= 0, at the kept samples
        k = rows.keep[:, j]
        A = np.stack([rows.dq[k, j], np.sign(rows.dq[k, j])], axis=1)
        if A.shape[0] >= 2:
            native[j] = nnls(A, tau[k, j])[0]
    return WrittenFrictionLaw(
        model=fit.model,
        joint_names=tuple(joint_names),
        joints=tuple(rows.joints),
        fit=fit,
        native=native,
        dq=rows.dq,
        load=load,
        held_out_residual=residual(fit),
        baseline_held_out_residual=residual(base),
        on_held_out=held_out is not None,
    )


def native_theta(
    theta: npt.ArrayLike, names: tuple[str, ...], law: WrittenFrictionLaw | None
) -> FloatArray:
    """``theta`` with each law joint's ``fv{j}``, ``fs{j}`` replaced by the law's native part
    (what the URDF's ``<dynamics>`` and the MJCF's ``damping``/``frictionloss`` hold); a copy,
    unchanged without a law."""
    theta = np.array(theta, dtype=float)
    if law is None:
        return theta
    index = {name: i for i, name in enumerate(names)}
    for j in law.joints:
        for label, value in zip(("fv", "fs"), law.native[j], strict=True):
            if f"{label}{j + 1}" in index:
                theta[index[f"{label}{j + 1}"]] = value
    return theta


def friction_law_entry(law: WrittenFrictionLaw) -> dict[str, Any]:
    """The joint-extras file's ``"friction_law"`` section (JSON-ready, SI)."""
    model = get_friction_model(law.model)
    labels = (*model.linear, *model.nonlinear)
    values = np.concatenate([law.fit.linear, law.fit.nonlinear], axis=1)
    return {
        "model": law.model,
        "formula": model.formula,
        "variables": {
            "dq": "joint velocity [rad/s]",
            "load": "joint torque without friction (rnea + rotor inertia + offset) [N*m]",
            "sign(0)": 0,
        },
        "units": {label: model.units.get(label, "SI") for label in labels},
        "joint_order": list(law.joint_names),
        "parameters": {
            law.joint_names[j]: {
                label: float(v) for label, v in zip(labels, values[j], strict=True)
            }
            for j in law.joints
        },
        "native": {
            law.joint_names[j]: {
                "damping": float(law.native[j, 0]),
                "frictionloss": float(law.native[j, 1]),
            }
            for j in law.joints
        },
        "apply": _APPLY,
        "fitted": (
            "separable least squares with a least-squares rigid-body estimate; the written "
            "rigid bodies are the consistent estimate's (fitted with viscous + Coulomb)"
        ),
        "held_out_relative_residual": {
            law.model: law.held_out_residual,
            "viscous_coulomb": law.baseline_held_out_residual,
            "rows": "held out" if law.on_held_out else "identification",
        },
    }


def _section(extras: Mapping[str, Any] | str | Path) -> Mapping[str, Any]:
    content: Mapping[str, Any] = (
        json.loads(Path(extras).read_text()) if isinstance(extras, str | Path) else extras
    )
    if "friction_law" not in content:
        raise DataError("joint extras: no 'friction_law' section (the model has no such law).")
    section: Mapping[str, Any] = content["friction_law"]
    return section


def friction_law_torque(
    extras: Mapping[str, Any] | str | Path, dq: npt.ArrayLike, load: npt.ArrayLike | None = None
) -> FloatArray:
    """The written friction law's torque [N*m] from a joint-extras file.

    Parameters
    ----------
    extras :
        The ``<stem>_joint_extras.json`` file (path) or its parsed content.
    dq :
        Joint velocities [rad/s], shape (n, nv), columns in ``friction_law.joint_order``.
    load :
        The joints' torque without friction [N*m], shape (n, nv); needed by a load-dependent
        law only (None: zero).

    Returns
    -------
    :
        Shape (n, nv); zero on joints without the law.
    """
    section = _section(extras)
    model = get_friction_model(section["model"])
    order = list(section["joint_order"])
    dq = np.atleast_2d(np.asarray(dq, dtype=float))
    if dq.shape[1] != len(order):
        raise DataError(f"friction law: dq has {dq.shape[1]} columns, joint_order {len(order)}.")
    load = np.zeros_like(dq) if load is None else np.atleast_2d(np.asarray(load, dtype=float))
    nv = len(order)
    linear = np.zeros((nv, len(model.linear)))
    nonlinear = np.ones((nv, len(model.nonlinear)))  # finite placeholders off the law's joints
    mask = np.zeros(nv, dtype=bool)
    for name, params in section["parameters"].items():
        j = order.index(name)
        mask[j] = True
        linear[j] = [params[label] for label in model.linear]
        nonlinear[j] = [params[label] for label in model.nonlinear]
    return np.where(mask, model.torque(dq, load, linear, nonlinear), 0.0)


def applied_friction_torque(
    extras: Mapping[str, Any] | str | Path, dq: npt.ArrayLike, load: npt.ArrayLike | None = None
) -> FloatArray:
    """What a MuJoCo user of the written MJCF adds as ``qfrc_applied`` [N*m], shape (n, nv):
    the law minus its native part (``damping dq + frictionloss sign(dq)``, which the MJCF
    holds). Arguments as :func:`friction_law_torque`; map the columns to MuJoCo's dofs by
    joint name."""
    section = _section(extras)
    dq = np.atleast_2d(np.asarray(dq, dtype=float))
    tau = friction_law_torque(extras, dq, load)
    order = list(section["joint_order"])
    for name, native in section["native"].items():
        j = order.index(name)
        tau[:, j] -= native["damping"] * dq[:, j] + native["frictionloss"] * np.sign(dq[:, j])
    return tau
