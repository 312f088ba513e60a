"""Standard inertial parameters per body, in Pinocchio's order, and their labels.

Per body (joint frame ``i``): ``[m, m*cx, m*cy, m*cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` with the
inertia tensor about the joint frame origin, axes of joint frame ``i``
(``pin.Inertia.toDynamicParameters``). Units: kg, kg*m, kg*m^2.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ident.dynamics.chain import FloatArray

__all__ = ["PARAMETER_LABELS", "parameter_names", "parameters_from_model"]

PARAMETER_LABELS: tuple[str, ...] = (
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


def parameter_names(n_bodies: int) -> tuple[str, ...]:
    """Labels of the standard parameter vector, 1-based body numbers.

    Parameters
    ----------
    n_bodies :
        Number of bodies (= joints of a serial chain).

    Returns
    -------
    :
        ``("m1", "mcx1", ..., "Izz1", "m2", ...)``, length ``10 * n_bodies``.
    """
    return tuple(f"{label}{body + 1}" for body in range(n_bodies) for label in PARAMETER_LABELS)


def parameters_from_model(model: pin.Model) -> FloatArray:
    """Standard parameter vector of a Pinocchio model.

    Parameters
    ----------
    model :
        Pinocchio model; body ``i`` is the inertia attached to joint ``i`` (1-based).

    Returns
    -------
    :
        Parameters [kg, kg*m, kg*m^2], shape (10 * (njoints - 1),), in the order of
        :func:`parameter_names`.
    """
    return np.concatenate(
        [np.asarray(model.inertias[i].toDynamicParameters()) for i in range(1, model.njoints)]
    )
