"""The identification model: every parameter (rigid bodies and joint extras) and its base.

One parameter model serves ``ident identify`` and ``ident run`` with a simulated log: the
standard inertial parameters of every body (Pinocchio order, about the body frame origin),
then per joint the extra terms of :mod:`ident.dynamics.friction` (rotor inertia, viscous and
Coulomb friction, offset) and the coupled-wrist terms, reduced to base parameters on random
states with the *sequential* column choice in the priority order
``Ixx Ixy Ixz Iyy Iyz Izz mcx mcy mcz m Ia fv fs off`` per joint (the figaroh reference's
choice, so base parameters compare by name).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.dynamics.base_parameters import BaseParameters, compute_base_parameters
from ident.dynamics.chain import KinematicChain, chain_from_model, random_states
from ident.dynamics.friction import KINDS, ExtraTerms, extra_columns, extra_names
from ident.dynamics.parameters import parameter_names, parameters_from_model
from ident.dynamics.regressor import joint_torque_regressor

__all__ = [
    "PRIORITY_LABELS",
    "ParameterModel",
    "build_parameter_model",
    "model_regressors",
    "stage_parameter_model",
]

FloatArray = npt.NDArray[np.float64]

# Per-joint priority of the sequential base-parameter choice (figaroh's column order).
PRIORITY_LABELS = ("Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz", "mcx", "mcy", "mcz", "m")
_N_RANDOM_STATES = 200  # random states for the structural base parameters


@dataclass(frozen=True, eq=False)
class ParameterModel:
    """All parameters of the identification model and its base parameters.

    Attributes
    ----------
    names :
        Every parameter in priority order (see module docstring), length n_all.
    inertial_index :
        For each name, its column in the rigid-body regressor (Pinocchio order), or -1.
    extra_index :
        For each name, its column in :func:`~ident.dynamics.friction.extra_columns`, or -1.
    terms :
        The extra terms.
    base :
        :class:`~ident.dynamics.base_parameters.BaseParameters` over ``names``.
    nominal :
        Nominal values of ``names`` (URDF inertias, zero friction), shape (n_all,).
    rows :
        The joints (0-based) whose torques the model explains, or None for every joint; a
        stage of ``ident run`` explains the torques of its moving joints only
        (:func:`stage_parameter_model`).
    """

    names: tuple[str, ...]
    inertial_index: npt.NDArray[np.intp]
    extra_index: npt.NDArray[np.intp]
    terms: ExtraTerms
    base: BaseParameters
    nominal: FloatArray
    rows: tuple[int, ...] | None = None

    @property
    def base_names(self) -> tuple[str, ...]:
        """Names of the base parameters (independent name, ``R`` suffix when regrouped)."""
        return self.base.base_names

    def columns(self, Y_rigid: FloatArray, Y_extra: FloatArray, index: npt.ArrayLike) -> FloatArray:
        """Regressor columns of the parameters ``index`` (into :attr:`names`).

        ``Y_rigid`` (n, nv, 10 n) and ``Y_extra`` (n, nv, n_extra) -> (n, nv, len(index)).
        """
        return _gather_columns(self.inertial_index, self.extra_index, Y_rigid, Y_extra, index)


def _gather_columns(
    inertial_index: npt.NDArray[np.intp],
    extra_index: npt.NDArray[np.intp],
    Y_rigid: FloatArray,
    Y_extra: FloatArray,
    index: npt.ArrayLike,
) -> FloatArray:
    """Columns ``index`` of the parameter list from the rigid-body and extra regressors."""
    index = np.asarray(index, dtype=np.intp)
    out = np.empty((*Y_rigid.shape[:2], index.size))
    rigid = inertial_index[index] >= 0
    out[:, :, rigid] = Y_rigid[:, :, inertial_index[index[rigid]]]
    out[:, :, ~rigid] = Y_extra[:, :, extra_index[index[~rigid]]]
    return out


def model_regressors(
    chain: KinematicChain, terms: ExtraTerms, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> tuple[FloatArray, FloatArray]:
    return joint_torque_regressor(chain, q, dq, ddq), extra_columns(terms, dq, ddq)


def build_parameter_model(model: pin.Model, terms: ExtraTerms, *, rng: int = 0) -> ParameterModel:
    """Name, order and reduce to base parameters every parameter of the model.

    Parameters
    ----------
    model :
        Pinocchio model.
    terms :
        Extra (friction, offset, rotor, coupling) terms.
    rng :
        Seed of the random states used to find the structural base parameters.
    """
    chain = chain_from_model(model)
    rigid_names = parameter_names(chain.n_bodies)
    extras = extra_names(terms)
    names: list[str] = []
    # body b's parameters, then its joint's terms (a mimic joint's body has none: no motor)
    joint_of_body = {int(b): j for j, b in enumerate(chain.joint_bodies)}
    for b in range(chain.n_bodies):
        names += [f"{label}{b + 1}" for label in PRIORITY_LABELS]
        j = joint_of_body.get(b)
        if j is not None:
            names += [f"{kind}{j + 1}" for kind in KINDS if j in terms.per_joint[kind]]
    names += [e for e in extras if e.startswith(("Iam", "fvm", "fsm"))]
    inertial_index = np.array(
        [rigid_names.index(nm) if nm in rigid_names else -1 for nm in names], dtype=np.intp
    )
    extra_index = np.array(
        [extras.index(nm) if nm in extras else -1 for nm in names], dtype=np.intp
    )
    q, dq, ddq = random_states(chain, _N_RANDOM_STATES, rng=rng)
    Y_rigid, Y_extra = model_regressors(chain, terms, q, dq, ddq)
    W = _gather_columns(
        inertial_index, extra_index, Y_rigid, Y_extra, np.arange(len(names))
    ).reshape(-1, len(names))
    base = compute_base_parameters(W, names, method="sequential")
    rigid_nominal = parameters_from_model(model)
    nominal = np.where(inertial_index >= 0, rigid_nominal[np.maximum(inertial_index, 0)], 0.0)
    return ParameterModel(
        names=tuple(names),
        inertial_index=inertial_index,
        extra_index=extra_index,
        terms=terms,
        base=base,
        nominal=nominal,
    )


def stage_parameter_model(
    model: pin.Model,
    columns: tuple[int, ...],
    base: BaseParameters,
    rows: tuple[int, ...],
) -> ParameterModel:
    """The parameter model of a stage: some bodies' inertial parameters, some joints' torques.

    Parameters
    ----------
    model :
        Pinocchio model (its inertials are the nominal values).
    columns :
        The stage's unknown parameters: columns of the rigid-body regressor (Pinocchio order).
    base :
        Their base parameters (:class:`~ident.dynamics.base_parameters.BaseParameters` over
        the names of ``columns``, found on the stage's motion).
    rows :
        The joints (0-based) whose torques identify the stage.
    """
    n = model.nv
    rigid_names = parameter_names(model.njoints - 1)  # every body (mimic joints' too)
    names = tuple(rigid_names[c] for c in columns)
    if tuple(base.names) != names:
        raise ValueError("stage_parameter_model: the base parameters are not over the columns")
    no_terms = ExtraTerms.from_options(
        n, rotor_inertia=False, viscous=False, coulomb=False, offset=False
    )
    return ParameterModel(
        names=names,
        inertial_index=np.asarray(columns, dtype=np.intp),
        extra_index=np.full(len(columns), -1, dtype=np.intp),
        terms=no_terms,
        base=base,
        nominal=parameters_from_model(model)[list(columns)],
        rows=tuple(int(r) for r in rows),
    )
