"""Standard inertial parameters per body, in Pinocchio's order, and their labels.

Per body (joint frame ``i``): ``[m, m*cx, m*cy, m*cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` with the
inertia tensor about the joint frame origin, axes of joint frame ``i``
(``pin.Inertia.toDynamicParameters``). Units: kg, kg*m, kg*m^2. The per-body labels are
:data:`ident.robot.inertia.PINOCCHIO_ORDER`.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ident.dynamics.chain import FloatArray
from ident.robot.inertia import PINOCCHIO_ORDER

__all__ = ["parameter_names", "parameters_from_model"]


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
    return tuple(f"{label}{body + 1}" for body in range(n_bodies) for label in PINOCCHIO_ORDER)


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
