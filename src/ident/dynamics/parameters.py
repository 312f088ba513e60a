"""Standard inertial parameters per body, in Pinocchio's order, and their labels.

Per body (joint frame ``i``): ``[m, m*cx, m*cy, m*cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` with the
inertia tensor about the joint frame origin, axes of joint frame ``i``
(``pin.Inertia.toDynamicParameters``). Units: kg, kg*m, kg*m^2. The per-body labels are
:data:`ident.robot.inertia.PINOCCHIO_ORDER`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.dynamics.chain import FloatArray
from ident.robot.inertia import PINOCCHIO_ORDER, transform_parameters

__all__ = ["parameter_names", "parameters_from_model", "payload_on_joint"]


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


def payload_on_joint(
    model: pin.Model, link: str | None, parameters: npt.ArrayLike
) -> tuple[int, FloatArray]:
    """The joint whose body carries a payload welded to ``link``, and the payload's parameters
    in that joint's frame.

    Parameters
    ----------
    model :
        Pinocchio model (its frames name the URDF's links).
    link :
        The link the payload is welded to; None: the child link of the last joint (its frame
        is the joint's), as the MuJoCo source's ``measurement.payload``.
    parameters :
        The payload's standard parameters about ``link``'s origin, ``link``'s axes, shape (10,)
        [kg, kg*m, kg*m^2], Pinocchio order.

    Returns
    -------
    :
        ``(joint, phi)``: the 1-based joint (``model.inertias[joint]`` carries the payload) and
        the parameters about its frame, shape (10,): ``transform_parameters`` by the link's
        placement in the joint's frame.

    Raises
    ------
    ValueError
        If ``link`` is not a frame of the model.
    """
    parameters = np.asarray(parameters, dtype=float)
    if link is None:
        return model.njoints - 1, parameters.copy()
    if not model.existFrame(link):
        raise ValueError(f"the payload's link {link!r} is not a link of the robot")
    frame = model.frames[model.getFrameId(link)]
    rotation, translation = frame.placement.rotation, frame.placement.translation
    return int(frame.parentJoint), transform_parameters(parameters, rotation, translation)
