"""The one problem every estimator solves, and the parts of a result they share.

Observation rows ``y = W_b beta + e`` are reduced per row group (joint) to triangular factors
(:class:`~ident.identify.estimation.observations.ReducedObservations`), so that for any ``beta``

``||W_b beta - y||^2 = sum_j ||R_j beta - z_j||^2 + rho_j``.

The columns are the *base* parameters ``beta = K theta`` of the *standard* parameters
``theta`` (every body's 10 inertial parameters plus per-joint friction, rotor inertia and
offsets); ``K`` is the ``projection`` of
:class:`~ident.dynamics.base_parameters.BaseParameters`. Unconstrained estimators (OLS, WLS)
solve for ``beta``; constrained ones (LMI, log-Cholesky) for ``theta``, through
``R_j K theta``. The cost of the reduced problem does not depend on the log length.

Scaled distance to the nominal parameters: ``||D (theta - theta_nominal)||`` with
``D = diag(1 / scale)`` (:meth:`ParameterStructure.scales`): per body, the mass by its nominal
mass ``m``, first moments by ``m L``, inertias by ``m L^2`` with ``L`` the body's radius of
gyration about its frame origin (``sqrt(tr(I_O) / (2 m))``, at least 1 cm); the extras have
``D = 0`` (friction, rotor inertia and offsets are left to the data).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import DataError
from ident.identify.estimation.consistency import body_consistency
from ident.identify.estimation.estimate import Estimate
from ident.identify.estimation.observations import ReducedObservations

__all__ = ["EstimationProblem", "ParameterStructure", "result_from_theta"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]

_MIN_LENGTH = 0.01  # [m] floor of a body's length scale (point masses at the origin)
_MIN_MASS = 1e-3  # [kg] floor of a body's mass scale (massless URDF links)


@dataclass(frozen=True, eq=False)
class ParameterStructure:
    """What the standard parameters ``theta`` are.

    Attributes
    ----------
    names :
        Names of ``theta``, length n_std.
    bodies :
        Indices into ``theta`` of each identified body's 10 parameters in Pinocchio order
        ``[m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` (about the body frame origin),
        shape (n_bodies, 10).
    body_names :
        Label of each body (its link name), length n_bodies.
    nonnegative :
        Indices of parameters that must be >= 0 (viscous and Coulomb friction, rotor
        inertia); the rest of the extras (offsets) are free.
    nominal :
        Nominal ``theta`` (URDF inertials, zero extras), shape (n_std,).
    ellipsoids :
        Optional bounding ellipsoid per body (:class:`~ident.robot.ellipsoids.Ellipsoid`
        or None), empty for none.
    friction :
        Indices of the viscous and Coulomb friction parameters (a subset of
        ``nonnegative``), empty for none: the constrained estimators keep those that the
        least-squares fit finds positive at its values (see
        :mod:`ident.identify.estimators.constrained`).
    """

    names: tuple[str, ...]
    bodies: IntArray
    body_names: tuple[str, ...]
    nonnegative: IntArray
    nominal: FloatArray
    ellipsoids: tuple[Any, ...] = ()
    friction: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))

    def __post_init__(self) -> None:
        object.__setattr__(self, "friction", np.asarray(self.friction, dtype=np.intp))
        for name in ("bodies", "nonnegative", "nominal", "friction"):
            value = np.array(getattr(self, name), copy=True)
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        n = len(self.names)
        if self.nominal.shape != (n,):
            raise DataError(f"nominal has shape {self.nominal.shape}, expected ({n},).")
        if self.bodies.ndim != 2 or self.bodies.shape[1] != 10:
            raise DataError(f"bodies must have shape (n_bodies, 10), got {self.bodies.shape}.")
        if len(self.body_names) != self.bodies.shape[0]:
            raise DataError("one body name per body is needed.")
        if self.ellipsoids and len(self.ellipsoids) != self.bodies.shape[0]:
            raise DataError("ellipsoids: one entry (or None) per body is needed.")
        if not np.isin(self.friction, self.nonnegative).all():
            raise DataError("friction: every friction index must also be in nonnegative.")

    @property
    def n_std(self) -> int:
        """Number of standard parameters."""
        return len(self.names)

    def scales(self) -> FloatArray:
        """Typical magnitude of every parameter, shape (n_std,) [SI] (see module docstring).

        Extras get 1 (their unit); use :meth:`prior_weights` for the prior.
        """
        scale = np.ones(self.n_std)
        for index in self.bodies:
            phi = self.nominal[index]
            mass = max(float(phi[0]), _MIN_MASS)
            trace = float(phi[4] + phi[6] + phi[9])
            length = max(np.sqrt(max(trace, 0.0) / (2.0 * mass)), _MIN_LENGTH)
            scale[index] = mass * np.array([1.0] + [length] * 3 + [length**2] * 6)
        return scale

    def prior_weights(self) -> FloatArray:
        """Diagonal of ``D``: ``1 / scale`` on inertial parameters, 0 on extras, (n_std,)."""
        weights = np.zeros(self.n_std)
        index = self.bodies.reshape(-1)
        weights[index] = 1.0 / self.scales()[index]
        return weights

    def distance_to_nominal(self, theta: npt.ArrayLike) -> float:
        """``||D (theta - nominal)||`` (dimensionless)."""
        return float(np.linalg.norm(self.prior_weights() * (np.asarray(theta) - self.nominal)))


@dataclass(frozen=True, eq=False)
class EstimationProblem:
    """Reduced observations plus what a constrained estimator needs to know.

    Attributes
    ----------
    observations :
        Reduced rows in the coordinates ``names`` (base parameters, or ``theta`` when
        ``base_map`` is None).
    names :
        Names of the observation columns, length n.
    structure :
        The standard parameters (needed by the constrained estimators; optional for OLS/WLS,
        which then also report the consistency of the standard parameters closest to the
        nominal ones among those with the estimated base values).
    base_map :
        ``K`` of ``beta = K theta``, shape (n, n_std), or None when the columns are ``theta``.
    weights :
        Per-group row weights ``1 / sigma_j`` for the constrained estimators, shape
        (n_groups,); None: take them from a WLS fit of the same problem.
    regularization :
        Weight ``lambda`` of the prior ``lambda ||G D (theta - nominal)||^2`` added to the
        mean weighted squared residual (constrained estimators; ``G`` and the fixed floor:
        :mod:`ident.identify.estimators.constrained`).
    wls_passes :
        Weighted solves of WLS (see :func:`~ident.identify.estimation.estimate.least_squares`).
    options :
        Estimator-specific options (see each estimator).
    """

    observations: ReducedObservations
    names: tuple[str, ...]
    structure: ParameterStructure | None = None
    base_map: FloatArray | None = None
    weights: FloatArray | None = None
    regularization: float = 0.0
    wls_passes: int = 2
    options: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))

    def __post_init__(self) -> None:
        n = self.observations.n_params
        if len(self.names) != n:
            raise DataError(f"{len(self.names)} names for {n} observation columns.")
        if self.structure is not None:
            K = self.K
            if K.shape != (n, self.structure.n_std):
                raise DataError(
                    f"base_map has shape {K.shape}, expected ({n}, {self.structure.n_std})."
                )
        if not self.regularization >= 0.0:
            raise DataError(f"regularization = {self.regularization} must be >= 0.")

    @property
    def K(self) -> FloatArray:
        """``beta = K theta``, shape (n, n_std) (identity when the columns are ``theta``)."""
        if self.base_map is not None:
            return np.asarray(self.base_map, dtype=float)
        return np.eye(self.observations.n_params)

    @property
    def n_rows(self) -> int:
        """Number of observation rows."""
        return int(self.observations.n_rows.sum())

    def require_structure(self, method: str) -> ParameterStructure:
        """The structure, or a DataError naming the estimator that needs it."""
        if self.structure is None:
            raise DataError(
                f"estimator {method!r} works on the standard parameters: give the problem a "
                "ParameterStructure (bodies, extras, nominal values) and its base_map."
            )
        return self.structure

    def standard_completion(self, beta: npt.ArrayLike) -> FloatArray:
        """The ``theta`` with ``K theta = beta`` closest to the nominal in the scaled norm.

        ``theta = nominal + S (K S)^+ (beta - K nominal)``, ``S = diag(scale)``: the standard
        parameters an unconstrained base estimate stands for when every direction the data
        do not see is kept at its nominal value.
        """
        structure = self.require_structure("standard_completion")
        S = structure.scales()
        K = self.K
        delta = np.asarray(beta, dtype=float) - K @ structure.nominal
        return structure.nominal + S * (np.linalg.pinv(K * S[None, :]) @ delta)


def result_from_theta(
    problem: EstimationProblem,
    theta: FloatArray,
    *,
    method: str,
    sigma: FloatArray,
    success: bool,
    message: str,
    regularization: float = 0.0,
) -> Estimate:
    """An :class:`~ident.identify.estimation.estimate.Estimate` of standard parameters ``theta``.

    ``x = K theta`` (base values, comparable with OLS/WLS), residuals from the reduced rows,
    per-body consistency, distance to the nominal. Standard deviations are not defined for a
    constrained estimate: ``std`` and ``relative_std`` are NaN, ``covariance`` is empty.
    """
    structure = problem.require_structure(method)
    obs = problem.observations
    x = problem.K @ theta
    ss = obs.residual_ss(x)
    n_rows = obs.n_rows.astype(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        residual_rms = np.sqrt(ss / n_rows)
    tau_norm = float(np.sqrt(obs.yty.sum()))
    s = np.linalg.svd(obs.stacked()[0], compute_uv=False)
    nan = np.full(x.shape, np.nan)
    return Estimate(
        x=x,
        names=problem.names,
        std=nan,
        relative_std=nan.copy(),
        method=method,
        residual_rms=residual_rms,
        relative_residual=float(np.sqrt(ss.sum()) / tau_norm) if tau_norm > 0 else float("inf"),
        sigma=np.asarray(sigma, dtype=float),
        condition_number=float(s[0] / s[-1]) if s[-1] > 0 else float("inf"),
        n_samples=problem.n_rows,
        success=success,
        message=message,
        n_observations=problem.n_rows,
        theta=np.asarray(theta, dtype=float),
        consistency=body_consistency(theta, structure.bodies, structure.body_names),
        group_residual_ss=ss,
        regularization=float(regularization),
        distance_to_nominal=structure.distance_to_nominal(theta),
    )
