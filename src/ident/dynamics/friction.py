"""Per-joint parameters beyond the rigid bodies, as extra regressor columns.

Column order (documented once, used everywhere): for each joint ``j = 1..n`` in joint order, the
enabled ones of

- ``Ia{j}``  rotor (actuator) inertia reflected to the joint [kg*m^2]: column ``ddq_j``;
- ``fv{j}``  viscous friction [N*m*s/rad]: column ``dq_j``;
- ``fs{j}``  Coulomb friction [N*m]: column ``sign(dq_j)``;
- ``off{j}`` torque offset [N*m]: column ``1``;

each entering only row ``j``; then, for a coupled wrist whose motor ``b`` turns with joints
``a`` and ``b`` (``q_motor_b = N_b (q_a + q_b)``, the TX40 wrist ``a = 5, b = 6``), the motor's
own terms

- ``Iam{b}`` coupled-motor inertia: column ``ddq_a + ddq_b``;
- ``fvm{b}`` coupled-motor viscous friction: column ``dq_a + dq_b``;
- ``fsm{b}`` coupled-motor Coulomb friction: column ``sign(dq_a + dq_b)``.

Derivation of the coupled rows: the motor torque ``t_m = J_m ddq_m + f_v dq_m + f_s sign(dq_m)``
with ``dq_m = N (dq_a + dq_b)`` reaches the joints through ``tau = Rq^T t``, whose column ``b``
has ``N`` in rows ``a`` and ``b``. So the three columns enter rows ``a`` and ``b`` alike, with
joint-side values ``Iam = N^2 J_m``, ``fvm = N^2 f_v``, ``fsm = N f_s``.

The reference script of the TX40 data (figaroh) uses another, equivalent, basis: row ``a`` gets
``ddq_b, dq_b`` and row ``b`` gets ``ddq_a, dq_a`` (plus the common ``sign(dq_a + dq_b)``). Both
span the same columns once ``Ia``, ``fv`` of joints ``a`` and ``b`` are present, with
``fv_a(figaroh) = fv_a + fvm``, ``fv_b(figaroh) = fv_b + fvm``, ``Ia_a(figaroh) = Ia_a + Iam``,
``Ia_b(figaroh) = Ia_b + Iam``; ``Iam``, ``fvm``, ``fsm`` and the ``fs`` are the same.
:func:`figaroh_coupling_columns` gives that basis for comparisons.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.errors import ConfigError

__all__ = [
    "KINDS",
    "ExtraTerms",
    "extra_columns",
    "extra_names",
    "figaroh_coupling_columns",
]

FloatArray = npt.NDArray[np.float64]

KINDS = ("Ia", "fv", "fs", "off")  # per-joint order within a joint


@dataclass(frozen=True)
class ExtraTerms:
    """Which extra terms a model has.

    Attributes
    ----------
    n_joints :
        Number of joints.
    per_joint :
        For each kind of :data:`KINDS`, the 0-based joints that have it.
    coupled_wrist :
        0-based ``(a, b)`` joints sharing motor ``b``, or None.
    """

    n_joints: int
    per_joint: dict[str, tuple[int, ...]]
    coupled_wrist: tuple[int, int] | None = None

    @classmethod
    def from_options(
        cls,
        n_joints: int,
        *,
        rotor_inertia: bool | Sequence[int] = True,
        viscous: bool | Sequence[int] = True,
        coulomb: bool | Sequence[int] = True,
        offset: bool | Sequence[int] = True,
        coupled_wrist: Sequence[int] | None = None,
    ) -> ExtraTerms:
        """Build from per-kind options: True (all joints), False, or 1-based joint lists.

        Raises
        ------
        ConfigError
            If a joint number is out of range.
        """

        def joints(key: str, value: bool | Sequence[int]) -> tuple[int, ...]:
            if value is True:
                return tuple(range(n_joints))
            if value is False:
                return ()
            out = []
            for j in value:
                if not 1 <= int(j) <= n_joints:
                    raise ConfigError(
                        f"model.{key}: joint {j} out of range; joints are 1..{n_joints}."
                    )
                out.append(int(j) - 1)
            return tuple(sorted(set(out)))

        per_joint = {
            "Ia": joints("rotor_inertia", rotor_inertia),
            "fv": joints("viscous", viscous),
            "fs": joints("coulomb", coulomb),
            "off": joints("offset", offset),
        }
        pair = None
        if coupled_wrist is not None:
            a, b = (int(j) for j in coupled_wrist)
            if not (1 <= a <= n_joints and 1 <= b <= n_joints and a != b):
                raise ConfigError(
                    f"model.coupled_wrist = {list(coupled_wrist)}: two distinct joints in "
                    f"1..{n_joints}."
                )
            pair = (a - 1, b - 1)
        return cls(n_joints=n_joints, per_joint=per_joint, coupled_wrist=pair)


def extra_names(terms: ExtraTerms) -> tuple[str, ...]:
    """Names of the extra columns in the documented order (1-based joint numbers)."""
    names = [
        f"{kind}{j + 1}"
        for j in range(terms.n_joints)
        for kind in KINDS
        if j in terms.per_joint[kind]
    ]
    if terms.coupled_wrist is not None:
        b = terms.coupled_wrist[1] + 1
        names += [f"Iam{b}", f"fvm{b}", f"fsm{b}"]
    return tuple(names)


def extra_columns(terms: ExtraTerms, dq: FloatArray, ddq: FloatArray) -> FloatArray:
    """Extra regressor columns for every sample.

    Parameters
    ----------
    terms :
        The model's extra terms.
    dq, ddq :
        Joint velocities [rad/s] and accelerations [rad/s^2], shape (n_samples, nv).

    Returns
    -------
    :
        Shape (n_samples, nv, n_extra) in the order of :func:`extra_names`, so that
        ``Y_extra @ params`` is the torque [N*m] they add.
    """
    dq = np.asarray(dq, dtype=float)
    ddq = np.asarray(ddq, dtype=float)
    n_samples, nv = dq.shape
    names = extra_names(terms)
    out = np.zeros((n_samples, nv, len(names)))
    source = {"Ia": ddq, "fv": dq, "fs": np.sign(dq), "off": np.ones_like(dq)}
    col = 0
    for j in range(terms.n_joints):
        for kind in KINDS:
            if j in terms.per_joint[kind]:
                out[:, j, col] = source[kind][:, j]
                col += 1
    if terms.coupled_wrist is not None:
        a, b = terms.coupled_wrist
        dq_m = dq[:, a] + dq[:, b]  # the shared motor turns with q_a + q_b
        for values in (ddq[:, a] + ddq[:, b], dq_m, np.sign(dq_m)):
            out[:, a, col] = values  # rows a and b alike: column b of Rq^T
            out[:, b, col] = values
            col += 1
    return out


def figaroh_coupling_columns(dq: FloatArray, ddq: FloatArray, pair: tuple[int, int]) -> FloatArray:
    """Coupled-wrist columns in the figaroh basis (for comparing with its published values).

    Row ``a`` gets ``(ddq_b, dq_b, sign(dq_a + dq_b))`` and row ``b`` gets
    ``(ddq_a, dq_a, sign(dq_a + dq_b))``, for ``Iam, fvm, fsm``.

    Returns
    -------
    :
        Shape (n_samples, nv, 3).
    """
    a, b = pair
    out = np.zeros((*dq.shape, 3))
    sign = np.sign(dq[:, a] + dq[:, b])
    out[:, a, 0], out[:, a, 1], out[:, a, 2] = ddq[:, b], dq[:, b], sign
    out[:, b, 0], out[:, b, 1], out[:, b, 2] = ddq[:, a], dq[:, a], sign
    return out
