"""Physical consistency of standard inertial parameters: pseudo-inertia, eigenvalues, checks.

A rigid body's standard parameters about its frame origin,
``theta_b = [m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` (Pinocchio order), belong to a
body with a non-negative mass density exactly when its 4x4 *pseudo-inertia*

``J = [[Sigma, h], [h^T, m]]``,  ``Sigma = tr(I)/2 * E - I``,  ``h = m c``

is positive semi-definite (``J = integral of [x; 1][x; 1]^T dm``; Wensing, Kim and Slotine
2017). ``J`` is linear in ``theta_b``: ``J = sum_k theta_b[k] M_k`` with the constant matrices
:data:`PSEUDO_INERTIA_BASIS`, which is what makes it a linear matrix inequality.
``J`` positive definite is equivalent to a positive mass with an inertia about the centre of
mass that is positive definite and satisfies the strict triangle inequalities.

References
----------
P. M. Wensing, S. Kim and J.-J. E. Slotine, "Linear matrix inequalities for physically
consistent inertial parameter identification: a statistical perspective on the mass
distribution", IEEE Robotics and Automation Letters 3(1), 2017.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.robot.inertia import consistency_problems

__all__ = [
    "PSEUDO_INERTIA_BASIS",
    "BodyConsistency",
    "body_consistency",
    "parameters_from_pseudo_inertia",
    "pseudo_inertia",
    "pseudo_inertia_min_eigenvalue",
    "triangle_inequality_margin",
]

FloatArray = npt.NDArray[np.float64]


def _basis() -> FloatArray:
    """``M_k`` with ``J(theta) = sum_k theta[k] M_k``, shape (10, 4, 4)."""
    basis = np.zeros((10, 4, 4))
    basis[0, 3, 3] = 1.0  # m
    for k in range(3):  # h = m c
        basis[1 + k, k, 3] = basis[1 + k, 3, k] = 1.0
    # Sigma = tr(I)/2 E - I: diagonal Sigma_xx = (-Ixx + Iyy + Izz)/2, off-diagonal -Ixy, ...
    for k, (i, j) in zip((4, 6, 9), ((0, 0), (1, 1), (2, 2)), strict=True):
        basis[k] += 0.5 * np.eye(4)
        basis[k, 3, 3] = 0.0
        basis[k, i, j] -= 1.0
    for k, (i, j) in zip((5, 7, 8), ((0, 1), (0, 2), (1, 2)), strict=True):
        basis[k, i, j] = basis[k, j, i] = -1.0
    basis.setflags(write=False)
    return basis


#: ``M_k`` of ``J(theta_b) = sum_k theta_b[k] M_k``, shape (10, 4, 4), Pinocchio order.
PSEUDO_INERTIA_BASIS: FloatArray = _basis()


def pseudo_inertia(theta: npt.ArrayLike) -> FloatArray:
    """Pseudo-inertia ``J`` [kg*m^2 / kg*m / kg entries] of parameters, (..., 10) -> (..., 4, 4)."""
    return np.einsum("...k,kij->...ij", np.asarray(theta, dtype=float), PSEUDO_INERTIA_BASIS)


def parameters_from_pseudo_inertia(J: npt.ArrayLike) -> FloatArray:
    """Inverse of :func:`pseudo_inertia`: standard parameters (..., 10) of ``J`` (..., 4, 4)."""
    J = np.asarray(J, dtype=float)
    sigma = J[..., :3, :3]
    trace = np.trace(sigma, axis1=-2, axis2=-1)
    # I = tr(Sigma) E - Sigma
    inertia = trace[..., None, None] * np.eye(3) - sigma
    out = np.empty(J.shape[:-2] + (10,))
    out[..., 0] = J[..., 3, 3]
    out[..., 1:4] = J[..., :3, 3]
    out[..., 4:] = inertia[..., [0, 0, 1, 0, 1, 2], [0, 1, 1, 2, 2, 2]]
    return out


def pseudo_inertia_min_eigenvalue(theta: npt.ArrayLike) -> FloatArray:
    """Smallest eigenvalue of the pseudo-inertia of parameters (..., 10), shape (...)."""
    return np.asarray(np.linalg.eigvalsh(pseudo_inertia(theta))[..., 0], dtype=np.float64)


def triangle_inequality_margin(theta: npt.ArrayLike) -> FloatArray:
    """``min(I1 + I2 - I3)`` over the principal moments about the centre of mass [kg*m^2].

    Negative when the triangle inequality fails; NaN for a non-positive mass. Shape (...).
    """
    from ident.robot.inertia import com_and_inertia

    theta = np.asarray(theta, dtype=float)
    mass, _, inertia_com = com_and_inertia(theta)
    with np.errstate(invalid="ignore"):
        moments = np.linalg.eigvalsh(np.nan_to_num(inertia_com))
    margin = moments[..., 0] + moments[..., 1] - moments[..., 2]
    return np.where(mass > 0, margin, np.nan)


@dataclass(frozen=True)
class BodyConsistency:
    """Consistency of one body's parameters.

    Attributes
    ----------
    body :
        Label of the body (link name).
    consistent :
        Positive mass, inertia about the centre of mass positive semi-definite, triangle
        inequality: :func:`ident.robot.inertia.consistency_problems` finds nothing.
    min_eigenvalue :
        Smallest eigenvalue of the pseudo-inertia (>= 0 for a realizable density) [SI].
    mass :
        Mass [kg].
    triangle_margin :
        :func:`triangle_inequality_margin` [kg*m^2].
    problems :
        What is wrong, in words; empty when consistent.
    """

    body: str
    consistent: bool
    min_eigenvalue: float
    mass: float
    triangle_margin: float
    problems: tuple[str, ...] = ()


def body_consistency(
    theta: npt.ArrayLike, bodies: npt.ArrayLike, labels: tuple[str, ...] | None = None
) -> tuple[BodyConsistency, ...]:
    """Check every body of a standard parameter vector.

    Parameters
    ----------
    theta :
        Standard parameters, shape (n_std,).
    bodies :
        Indices into ``theta`` of each body's 10 parameters in Pinocchio order,
        shape (n_bodies, 10).
    labels :
        Body labels (default ``"body 1"``, ...).

    Returns
    -------
    :
        One :class:`BodyConsistency` per body.
    """
    theta = np.asarray(theta, dtype=float)
    bodies = np.asarray(bodies, dtype=np.intp)
    labels = labels or tuple(f"body {b + 1}" for b in range(bodies.shape[0]))
    out = []
    for label, index in zip(labels, bodies, strict=True):
        phi = theta[index]
        problems = tuple(consistency_problems(phi))
        out.append(
            BodyConsistency(
                body=label,
                consistent=not problems,
                min_eigenvalue=float(pseudo_inertia_min_eigenvalue(phi)),
                mass=float(phi[0]),
                triangle_margin=float(triangle_inequality_margin(phi)),
                problems=problems,
            )
        )
    return tuple(out)
