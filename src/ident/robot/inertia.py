"""Standard inertial parameter vectors: construction, frame changes, physical consistency.

A rigid body's standard parameters are, in Pinocchio's ``Inertia.toDynamicParameters()`` order,

``pi = [m, m*cx, m*cy, m*cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]``

with the first moment ``m*c`` [kg*m] and the inertia tensor [kg*m^2] both expressed in, and
taken about the origin of, the body frame. The paper (eq. 14) orders them
``[m, mcx, mcy, mcz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]``; :data:`PAPER_TO_PINOCCHIO` is the one
permutation between the two (``pi_pinocchio = PAPER_TO_PINOCCHIO @ pi_paper``). Products of
inertia are tensor entries in both (``I = [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]]``),
so no signs change.

All functions take stacked arrays: the body axis (or any leading axes) comes first.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import numpy.typing as npt

__all__ = [
    "PAPER_ORDER",
    "PAPER_TO_PINOCCHIO",
    "PINOCCHIO_ORDER",
    "URDF_INERTIA_ENTRIES",
    "com_and_inertia",
    "consistency_problems",
    "inertia_about_origin",
    "paper_to_pinocchio",
    "parameters_from_com",
    "pinocchio_to_paper",
    "transform_matrix",
    "transform_parameters",
    "urdf_inertia_tensor",
]

FloatArray = npt.NDArray[np.float64]

PINOCCHIO_ORDER: tuple[str, ...] = (
    "m",
    "mcx",
    "mcy",
    "mcz",
    "Ixx",
    "Ixy",
    "Iyy",
    "Ixz",
    "Iyz",
    "Izz",
)
PAPER_ORDER: tuple[str, ...] = ("m", "mcx", "mcy", "mcz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")

#: Permutation with ``pi_pinocchio = PAPER_TO_PINOCCHIO @ pi_paper`` (its inverse is its transpose).
PAPER_TO_PINOCCHIO: FloatArray = np.array(
    [[1.0 if p == q else 0.0 for q in PAPER_ORDER] for p in PINOCCHIO_ORDER]
)
PAPER_TO_PINOCCHIO.setflags(write=False)

#: URDF ``<inertia>`` attribute -> (row, column) of the 3x3 inertia tensor.
URDF_INERTIA_ENTRIES: dict[str, tuple[int, int]] = {
    "ixx": (0, 0),
    "ixy": (0, 1),
    "ixz": (0, 2),
    "iyy": (1, 1),
    "iyz": (1, 2),
    "izz": (2, 2),
}


def urdf_inertia_tensor(attributes: Mapping[str, str] | None) -> FloatArray:
    """The symmetric 3x3 tensor [kg*m^2] of a URDF ``<inertia>`` element's attributes
    (``element.attrib``; a missing attribute or element is 0), shape (3, 3).

    Raises
    ------
    ValueError
        An attribute that is not a number.
    """
    tensor = np.zeros((3, 3))
    for key, (i, j) in URDF_INERTIA_ENTRIES.items():
        tensor[i, j] = tensor[j, i] = float((attributes or {}).get(key, "0"))
    return tensor


# Indices of the tensor entries in a Pinocchio-ordered vector.
_TENSOR_INDEX = np.array([[4, 5, 7], [5, 6, 8], [7, 8, 9]])


def paper_to_pinocchio(params_paper: npt.ArrayLike) -> FloatArray:
    """Reorder parameters from the paper's eq. 14 order to Pinocchio's, shape (..., 10)."""
    return np.asarray(params_paper, dtype=float) @ PAPER_TO_PINOCCHIO.T


def pinocchio_to_paper(params: npt.ArrayLike) -> FloatArray:
    """Reorder parameters from Pinocchio's order to the paper's eq. 14 order, shape (..., 10)."""
    return np.asarray(params, dtype=float) @ PAPER_TO_PINOCCHIO


def _skew_square(v: FloatArray) -> FloatArray:
    """``S(v)^T S(v) = |v|^2 I - v v^T`` for v of shape (..., 3)."""
    eye = np.eye(3)
    return (
        np.einsum("...i,...i->...", v, v)[..., None, None] * eye - v[..., :, None] * v[..., None, :]
    )


def parameters_from_com(
    mass: npt.ArrayLike, com: npt.ArrayLike, inertia_com: npt.ArrayLike
) -> FloatArray:
    """Standard parameters about the frame origin from mass, centre of mass and inertia at it.

    Parameters
    ----------
    mass :
        Masses [kg], shape (...,).
    com :
        Centres of mass in the body frame [m], shape (..., 3).
    inertia_com :
        Inertia tensors about the centre of mass, axes of the body frame [kg*m^2], (..., 3, 3).

    Returns
    -------
    :
        Pinocchio-ordered parameters, shape (..., 10); parallel axis theorem
        ``I_O = I_C + m (|c|^2 E - c c^T)``.
    """
    mass = np.asarray(mass, dtype=float)
    com = np.asarray(com, dtype=float)
    inertia_com = np.asarray(inertia_com, dtype=float)
    inertia_origin = inertia_com + mass[..., None, None] * _skew_square(com)
    out = np.empty(mass.shape + (10,))
    out[..., 0] = mass
    out[..., 1:4] = mass[..., None] * com
    out[..., 4:] = inertia_origin[..., [0, 0, 1, 0, 1, 2], [0, 1, 1, 2, 2, 2]]
    return out


def inertia_about_origin(params: npt.ArrayLike) -> FloatArray:
    """Inertia tensor about the frame origin [kg*m^2], shape (..., 3, 3), from (..., 10)."""
    params = np.asarray(params, dtype=float)
    return params[..., _TENSOR_INDEX]


def com_and_inertia(params: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Mass [kg], centre of mass [m] and inertia about it [kg*m^2] from parameters (..., 10).

    The centre of mass of a zero-mass body is returned as NaN.
    """
    params = np.asarray(params, dtype=float)
    mass = params[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        com = params[..., 1:4] / mass[..., None]
    first_moment = params[..., 1:4]
    with np.errstate(divide="ignore", invalid="ignore"):
        # I_C = I_O - (|h|^2 E - h h^T) / m, h = m c
        inertia_com = (
            inertia_about_origin(params) - _skew_square(first_moment) / mass[..., None, None]
        )
    return mass, com, inertia_com


def transform_parameters(
    params: npt.ArrayLike, rotation: npt.ArrayLike, translation: npt.ArrayLike
) -> FloatArray:
    """Express parameters given in frame B in frame A.

    Parameters
    ----------
    params :
        Parameters in frame B (about B's origin, B's axes), shape (..., 10).
    rotation, translation :
        Pose of B in A: ``x_A = rotation @ x_B + translation``; shapes (..., 3, 3) and (..., 3)
        [m].

    Returns
    -------
    :
        The same rigid body's parameters about A's origin in A's axes, shape (..., 10):
        ``h_A = m t + R h_B`` and
        ``I_A = R I_B R^T + m S(t)^T S(t) + S(t)^T S(R h_B) + S(R h_B)^T S(t)``.
    """
    params = np.asarray(params, dtype=float)
    rotation = np.asarray(rotation, dtype=float)
    translation = np.asarray(translation, dtype=float)
    mass = params[..., 0]
    h_rotated = np.einsum("...ij,...j->...i", rotation, params[..., 1:4])
    inertia_b = inertia_about_origin(params)
    inertia_rotated = rotation @ inertia_b @ np.swapaxes(rotation, -1, -2)
    # S(t)^T S(u) + S(u)^T S(t) = 2 (t.u) E - t u^T - u t^T, the cross term of the shift
    t, u = translation, h_rotated
    cross = (
        2.0 * np.einsum("...i,...i->...", t, u)[..., None, None] * np.eye(3)
        - t[..., :, None] * u[..., None, :]
        - u[..., :, None] * t[..., None, :]
    )
    inertia_a = inertia_rotated + mass[..., None, None] * _skew_square(t) + cross
    out = np.empty(np.broadcast_shapes(params.shape, translation.shape[:-1] + (10,)))
    out[..., 0] = mass
    out[..., 1:4] = mass[..., None] * t + u
    out[..., 4:] = inertia_a[..., [0, 0, 1, 0, 1, 2], [0, 1, 1, 2, 2, 2]]
    return out


def consistency_problems(params: npt.ArrayLike, *, rtol: float = 1e-9) -> list[str]:
    """Physical-consistency problems of one body's parameters; an empty list means consistent.

    Checks that the mass is positive, that the inertia about the centre of mass is positive
    semi-definite, and that its principal moments satisfy the triangle inequality
    ``I1 + I2 >= I3`` (a body's mass cannot lie farther from an axis than from the other two).
    Tolerances are relative to the largest principal moment.

    Parameters
    ----------
    params :
        Pinocchio-ordered parameters of one body, shape (10,).

    Returns
    -------
    :
        Human-readable problems, each naming the failing quantity and its values.
    """
    params = np.asarray(params, dtype=float)
    if params.shape != (10,):
        raise ValueError(f"expected one body's 10 parameters, got shape {params.shape}")
    mass = params[0]
    if not np.all(np.isfinite(params)):
        return [f"parameters are not finite: {params.tolist()}"]
    if not mass > 0.0:
        return [f"mass = {mass:.6g} kg must be > 0"]
    _, _, inertia_com = com_and_inertia(params)
    moments = np.linalg.eigvalsh(0.5 * (inertia_com + inertia_com.T))
    scale = max(float(np.max(np.abs(moments))), np.finfo(float).tiny)
    tol = rtol * scale
    problems = []
    if moments[0] < -tol:
        problems.append(
            "inertia about the centre of mass is not positive semi-definite "
            f"(principal moments {', '.join(f'{x:.6g}' for x in moments)} kg*m^2)"
        )
    elif moments[0] + moments[1] < moments[2] - tol:
        problems.append(
            "principal moments about the centre of mass violate the triangle inequality "
            f"I1 + I2 >= I3 ({moments[0]:.6g} + {moments[1]:.6g} < {moments[2]:.6g} kg*m^2)"
        )
    return problems


def transform_matrix(rotation: npt.ArrayLike, translation: npt.ArrayLike) -> FloatArray:
    """The linear map of :func:`transform_parameters` for one pose, as a (10, 10) matrix.

    ``transform_matrix(R, t) @ params_b == transform_parameters(params_b, R, t)``: a change of
    frame is linear in the parameters, so regressors change by the same matrix
    (``Y_b = Y_a @ transform_matrix(R, t)``).
    """
    return transform_parameters(np.eye(10), rotation, translation).T
