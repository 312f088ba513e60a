"""The estimators of the identification core: problem set-up, weight choice, comparison.

:func:`consistent_identification_reduced` takes the identification rows reduced per joint (in
two parts, the later one for the choice of a prior weight) and returns

- the OLS and WLS estimates (once each) with the per-link consistency of the standard
  parameters they stand for (closest to the nominal ones);
- for any other registered estimator: its estimate on all identification rows, WLS-weighted,
  with the prior weight (``Contract.needs_prior``) either given or chosen on the later part
  (:func:`~ident.identify.estimators.regularization.choose_regularization`), so the core's own
  held-out part stays unseen.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.dynamics.chain import chain_from_model
from ident.dynamics.friction import extra_columns
from ident.dynamics.regressor import joint_torque_regressor
from ident.errors import ConfigError, ModelError
from ident.identify.estimation.estimate import METHODS as LEAST_SQUARES
from ident.identify.estimation.estimate import Estimate
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.estimators.problem import EstimationProblem, ParameterStructure
from ident.identify.estimators.registry import Contract, get_contract, get_estimator
from ident.identify.estimators.regularization import (
    DEFAULT_GRID,
    RegularizationChoice,
    choose_regularization,
)

__all__ = [
    "NONNEGATIVE_PREFIXES",
    "ConsistentIdentification",
    "body_link_names",
    "bounding_ellipsoids",
    "consistent_identification_reduced",
    "problem_from_states",
    "standard_regressor",
    "structure_from_parameter_model",
]

FloatArray = npt.NDArray[np.float64]

#: Extra parameters that must be >= 0: rotor inertia, viscous and Coulomb friction (also of a
#: coupled motor). Offsets (``off``) are free.
NONNEGATIVE_PREFIXES = ("Iam", "fvm", "fsm", "Ia", "fv", "fs")
#: Viscous and Coulomb friction (also of a coupled motor).
FRICTION_PREFIXES = ("fvm", "fsm", "fv", "fs")
_LABELS = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def body_link_names(model: pin.Model) -> tuple[str, ...]:
    """Name of the link carried by each joint 1..n (its first body frame)."""
    names = []
    for i in range(1, model.njoints):
        frames = [
            f.name for f in model.frames if f.parentJoint == i and f.type == pin.FrameType.BODY
        ]
        names.append(frames[0] if frames else model.names[i])
    return tuple(names)


def bounding_ellipsoids(
    model: pin.Model,
    urdf: str | Path,
    *,
    package_dirs: Sequence[str | Path] = (),
    source: str = "config",
) -> tuple[Any, ...]:
    """Bounding ellipsoid of each moving link of ``model`` from the URDF's geometry.

    For ``estimation.ellipsoids: true`` (:mod:`ident.robot.ellipsoids`): one
    :class:`~ident.robot.ellipsoids.Ellipsoid` per joint's link (:func:`body_link_names`).

    Raises
    ------
    ConfigError
        If the URDF cannot be read or a link has no ``<collision>`` or ``<visual>`` geometry
        that bounds a volume (the message names the link and the fix).
    """
    from ident.identify.model_files.urdf_update import parse_urdf
    from ident.robot.ellipsoids import link_ellipsoids

    urdf = Path(urdf)
    links = body_link_names(model)
    try:
        found = link_ellipsoids(
            parse_urdf(urdf.read_text(encoding="utf-8")),
            links,
            package_dirs=package_dirs,
            base=urdf.parent,
        )
    except (OSError, ModelError) as e:
        raise ConfigError(f"{source}: estimation.ellipsoids: {urdf}: {e}") from e
    missing = [link for link, e in zip(links, found, strict=True) if e is None]
    if missing:
        raise ConfigError(
            f"{source}: estimation.ellipsoids: {urdf} has no <collision> or <visual> geometry "
            f"bounding a volume for link(s) {', '.join(missing)} (box, cylinder, sphere, or a "
            "mesh found through robot.package_dirs); add it, or set estimation.ellipsoids: "
            "false."
        )
    return found


def structure_from_parameter_model(
    pm: Any, body_names: tuple[str, ...], ellipsoids: tuple[Any, ...] = ()
) -> ParameterStructure:
    """The :class:`ParameterStructure` of an identify parameter model.

    Parameters
    ----------
    pm :
        :class:`ident.identify.pipeline.real.ParameterModel` (names ``m1``, ``mcx1``, ..., extras).
    body_names :
        Link of each joint, in joint order.
    ellipsoids :
        Optional bounding ellipsoid per body.

    The bodies are those whose parameters ``pm`` holds (every one, or a stage's).
    """
    index = {name: i for i, name in enumerate(pm.names)}
    present = [b for b in range(len(body_names)) if f"m{b + 1}" in index]
    bodies = np.array(
        [[index[f"{label}{b + 1}"] for label in _LABELS] for b in present], dtype=np.intp
    ).reshape(len(present), len(_LABELS))

    def extras(prefixes: tuple[str, ...]) -> npt.NDArray[np.intp]:
        return np.array(
            [
                i
                for i, name in enumerate(pm.names)
                if pm.inertial_index[i] < 0 and name.rstrip("0123456789") in prefixes
            ],
            dtype=np.intp,
        )

    return ParameterStructure(
        names=tuple(pm.names),
        bodies=bodies,
        body_names=tuple(body_names[b] for b in present),
        nonnegative=extras(NONNEGATIVE_PREFIXES),
        nominal=np.asarray(pm.nominal, dtype=float),
        ellipsoids=tuple(ellipsoids[b] for b in present) if ellipsoids else (),
        friction=extras(FRICTION_PREFIXES),
    )


def standard_regressor(
    model: pin.Model, pm: Any, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> FloatArray:
    """Regressor of every standard parameter of ``pm`` (its ``names`` order).

    ``q, dq, ddq`` of shapes (n_samples, nv) give a regressor of shape
    (n_samples, nv, n_std) with ``Y @ theta`` the joint torques [N*m]: rigid bodies plus
    the extra (friction, rotor, offset) columns.
    """
    Y_rigid = joint_torque_regressor(chain_from_model(model), q, dq, ddq)
    Y_extra = extra_columns(pm.terms, dq, ddq)
    return pm.columns(Y_rigid, Y_extra, np.arange(len(pm.names)))


def problem_from_states(
    model: pin.Model,
    pm: Any,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    tau: FloatArray,
    **fields: Any,
) -> EstimationProblem:
    """The base-coordinate :class:`EstimationProblem` of states and measured torques.

    Parameters
    ----------
    model, pm :
        The robot and its parameter model
        (:func:`ident.identify.pipeline.real.build_parameter_model`).
    q, dq, ddq, tau :
        States and torques [SI], shapes (n_samples, nv).
    **fields :
        Further :class:`EstimationProblem` fields (``regularization``, ``options``, ...).
    """
    Y = standard_regressor(model, pm, q, dq, ddq)
    obs = ReducedObservations.from_samples(Y[:, :, pm.base.independent], tau)
    structure = structure_from_parameter_model(pm, body_link_names(model))
    return _problem_of_rows(pm, obs, structure, **fields)


def _problem_of_rows(
    pm: Any, obs: ReducedObservations, structure: ParameterStructure, **fields: Any
) -> EstimationProblem:
    """The base-coordinate :class:`EstimationProblem` of the reduced rows ``obs`` with the
    parameter model ``pm`` (base names and map), its ``structure``
    (:func:`structure_from_parameter_model`) and further ``fields``."""
    return EstimationProblem(
        observations=obs,
        names=tuple(pm.base_names),
        structure=structure,
        base_map=pm.base.projection,
        **fields,
    )


@dataclass(frozen=True, eq=False)
class ConsistentIdentification:
    """Constrained estimate and the consistency of every estimator, for the report.

    Attributes
    ----------
    method :
        The configured estimator.
    contract :
        Its :class:`~ident.identify.estimators.registry.Contract`.
    estimates :
        ``{"ols": ..., "wls": ..., method: ...}`` on the identification rows, each with
        ``theta`` and per-link ``consistency``.
    constrained :
        The configured estimator's estimate when it is not a least-squares one
        (``contract.least_squares`` false), else None; physically consistent only when
        ``contract.consistent``.
    regularization :
        The weight choice when ``weight: auto``, else None.
    structure :
        The standard parameters.
    seconds :
        Wall time of the constrained estimate (weight choice included) [s].
    problem :
        The reduced problem of the identification rows (WLS weights set for a constrained
        method).
    """

    method: str
    contract: Contract
    estimates: dict[str, Estimate]
    constrained: Estimate | None
    regularization: RegularizationChoice | None
    structure: ParameterStructure
    seconds: float
    problem: EstimationProblem


def consistent_identification_reduced(
    model: pin.Model,
    pm: Any,
    first: ReducedObservations,
    last: ReducedObservations,
    *,
    method: str,
    weight: float | str = "auto",
    grid: tuple[float, ...] = DEFAULT_GRID,
    ellipsoids: tuple[Any, ...] = (),
    options: dict[str, Any] | None = None,
) -> ConsistentIdentification:
    """OLS, WLS and the configured estimator on reduced identification rows (module docstring).

    Parameters
    ----------
    model :
        The robot (link names).
    pm :
        The parameter model (standard names, base map, nominal values).
    first, last :
        The identification rows reduced in two parts: ``last`` (the later rows) chooses the
        prior weight when ``weight == "auto"``; the estimate uses both (merged).
    method :
        Registered estimator name.
    weight :
        Prior weight, or ``"auto"`` (estimators whose contract needs a prior).
    grid :
        Weights tried when ``weight == "auto"``.
    ellipsoids :
        Optional bounding ellipsoid per body (None entries for none).
    options :
        Options of the estimator (e.g. ``friction``).
    """
    structure = structure_from_parameter_model(pm, body_link_names(model), ellipsoids)
    problem = _problem_of_rows(pm, first.merge(last), structure)
    # the two least-squares estimates, once each (the report compares every estimator)
    estimates = {name: get_estimator(name)(problem) for name in LEAST_SQUARES}
    contract = get_contract(method)
    constrained = None
    choice = None
    seconds = 0.0
    if not contract.least_squares:
        t0 = time.perf_counter()
        problem, choice = _configured_problem(
            problem, estimates["wls"], (first, last), method, weight, grid, options
        )
        constrained = get_estimator(method)(problem)
        estimates[method] = constrained
        seconds = time.perf_counter() - t0
    return ConsistentIdentification(
        method=method,
        contract=contract,
        estimates=estimates,
        constrained=constrained,
        regularization=choice,
        structure=structure,
        seconds=seconds,
        problem=problem,
    )


def _configured_problem(
    problem: EstimationProblem,
    wls: Estimate,
    parts: tuple[ReducedObservations, ReducedObservations],
    method: str,
    weight: float | str,
    grid: tuple[float, ...],
    options: dict[str, Any] | None,
) -> tuple[EstimationProblem, RegularizationChoice | None]:
    """The problem of the configured (not least-squares) estimator ``method``: ``problem``'s rows
    WLS-weighted (``1 / sigma_j`` of ``wls``, 0 for a joint without rows), with ``options``, and
    with the prior weight when the contract needs a prior (``weight``, or chosen on ``grid`` with
    the later rows of ``parts`` held out when ``"auto"``); and that choice, or None."""
    contract = get_contract(method)
    first, last = parts
    weights = 1.0 / np.asarray(wls.sigma)
    n_rows = problem.observations.n_rows
    problem = dataclasses.replace(problem, weights=np.where(n_rows > 0, weights, 0.0))
    if options:
        problem = dataclasses.replace(problem, options=dict(options))
    choice = None
    if contract.needs_prior and weight == "auto":
        first_problem = dataclasses.replace(problem, observations=first)
        choice = choose_regularization(first_problem, last, method=method, grid=grid)
        weight = choice.weight
    if contract.needs_prior:
        problem = dataclasses.replace(problem, regularization=float(weight))
    return problem, choice
