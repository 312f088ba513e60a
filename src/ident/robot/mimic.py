"""Mimic joints of a URDF: ``<mimic joint="leader" multiplier="m" offset="o"/>``.

A follower joint moves with its leader, ``q_f = m q_l + o`` (so ``dq_f = m dq_l`` and
``ddq_f = m ddq_l``); it has no coordinate, motor or torque of its own. What ident does with one:

- leader locked (by ``lock`` or because it is off the chain): the follower is locked too, at
  ``m q_lock + o`` (:func:`resolve_mimic_locks`);
- leader and follower both on the identified chain: the follower becomes a Pinocchio mimic joint
  (:func:`coupled_model`): the model's ``q`` holds the leader only, its body moves with the
  leader, and the leader's torque is ``tau_l + m tau_f`` of the uncoupled joints;
- not supported, with a one-line :class:`~ident.errors.ModelError` naming the joint and the file:
  a leader that is itself a follower (a chain of mimics), a follower locked while its leader
  moves, a follower above its leader in the chain, a multiplier of 0 or a leader that is not a
  revolute or prismatic joint.
"""

from __future__ import annotations

import math

# xml.etree: every <mimic> value is checked with an error naming the joint and the attribute;
# yourdfpy raises a bare ValueError for multiplier="x" ("could not convert string to float: 'x'",
# checked) and takes inf silently; it reads the tree parse_xml (ident.robot.urdf_load) already
# parsed and checked.
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.errors import ModelError

__all__ = [
    "Mimic",
    "coupled_model",
    "follower_limits",
    "mimic_lock_reasons",
    "read_mimics",
    "reject_coupled_chain",
    "resolve_mimic_locks",
]

FloatArray = npt.NDArray[np.float64]

_SUPPORTED = (
    "supported: a follower whose leader is an independent revolute or prismatic joint, either "
    "both on the identified chain (the follower below its leader) or with the leader locked"
)


@dataclass(frozen=True)
class Mimic:
    """One follower joint: ``q_follower = multiplier * q_leader + offset``.

    Attributes
    ----------
    follower, leader :
        Joint names.
    multiplier :
        ``m`` [1, or m/rad and rad/m between a prismatic and a revolute joint].
    offset :
        ``o`` [rad or m].
    q_lower, q_upper :
        The follower's own position limits [rad or m]; ``-inf``/``inf`` where unknown.
    dq_max :
        The follower's own velocity limit [rad/s or m/s]; ``inf`` where unknown.
    """

    follower: str
    leader: str
    multiplier: float
    offset: float
    q_lower: float = -math.inf
    q_upper: float = math.inf
    dq_max: float = math.inf

    def position(self, q_leader: npt.ArrayLike) -> FloatArray:
        """The follower's position [rad or m] for leader positions ``q_leader`` (any shape)."""
        return self.multiplier * np.asarray(q_leader, dtype=float) + self.offset

    def leader_range(self) -> tuple[float, float]:
        """The leader positions that keep the follower within its position limits."""
        ends = sorted(((self.q_lower - self.offset) / self.multiplier,
                       (self.q_upper - self.offset) / self.multiplier))  # fmt: skip
        return (ends[0] if math.isfinite(ends[0]) else -math.inf,
                ends[1] if math.isfinite(ends[1]) else math.inf)  # fmt: skip


def _number(element: ET.Element, key: str, default: str, joint: str, where: str) -> float:
    try:
        value = float(element.get(key, default))
    except ValueError as e:
        raise ModelError(
            f"{where}: joint {joint!r}: <mimic {key}={element.get(key)!r}> is not a number; fix "
            "the file."
        ) from e
    if not math.isfinite(value):
        raise ModelError(
            f"{where}: joint {joint!r}: <mimic {key}> is {value}; give a finite value."
        )
    return value


def _limits(model: pin.Model, name: str) -> tuple[float, float, float]:
    """Position and velocity limits of a 1-DoF joint of ``model``; infinite where unknown."""
    joint = model.joints[model.getJointId(name)]
    low = float(model.lowerPositionLimit[joint.idx_q])
    high = float(model.upperPositionLimit[joint.idx_q])
    speed = float(model.velocityLimit[joint.idx_v])
    if not high > low:  # URDFs without limits give an empty range: unknown
        low, high = -math.inf, math.inf
    low = low if abs(low) < 1e300 else -math.inf
    high = high if abs(high) < 1e300 else math.inf
    return low, high, speed if 0.0 < speed < 1e300 else math.inf


def read_mimics(root: ET.Element, model: pin.Model, where: str) -> dict[str, Mimic]:
    """The ``<mimic>`` tags of a URDF, follower name -> :class:`Mimic` (file order).

    ``model`` is the uncoupled Pinocchio model of the same text (every joint independent): it
    gives the follower's limits and checks that both joints exist and have one coordinate.

    Raises
    ------
    ModelError
        Naming the joint and ``where``, for an unknown leader, a value that is not a finite
        number, a multiplier of 0, or a leader that is itself a follower.
    """
    out: dict[str, Mimic] = {}
    for joint in root.findall("joint"):
        tag = joint.find("mimic")
        if tag is None:
            continue
        name, leader = joint.get("name", "?"), tag.get("joint", "")
        for joint_name in (name, leader):
            if (
                not model.existJointName(joint_name)
                or model.joints[model.getJointId(joint_name)].nq != 1
            ):
                raise ModelError(
                    f"{where}: joint {name!r} mimics {leader!r}, which is not a revolute or "
                    f"prismatic joint of the file; {_SUPPORTED}."
                )
        multiplier = _number(tag, "multiplier", "1", name, where)
        if multiplier == 0.0:
            raise ModelError(
                f"{where}: joint {name!r} mimics {leader!r} with multiplier 0, so it never moves; "
                "make it a fixed joint."
            )
        low, high, speed = _limits(model, name)
        out[name] = Mimic(name, leader, multiplier, _number(tag, "offset", "0", name, where),
                          low, high, speed)  # fmt: skip
    for mimic in out.values():
        if mimic.leader in out:
            raise ModelError(
                f"{where}: joint {mimic.follower!r} mimics {mimic.leader!r}, which mimics "
                f"{out[mimic.leader].leader!r} (a chain of mimic joints); {_SUPPORTED}: let "
                f"{mimic.follower!r} mimic {out[mimic.leader].leader!r} with the product of the "
                "multipliers."
            )
    return out


def resolve_mimic_locks(
    mimics: Mapping[str, Mimic], locked: Mapping[str, float], given: Sequence[str], where: str
) -> tuple[dict[str, float], tuple[Mimic, ...]]:
    """Lock the followers of locked leaders at their mimic value; the mimics left moving.

    Parameters
    ----------
    mimics :
        :func:`read_mimics`.
    locked :
        Joint name -> locked position [rad or m], the user's locks and the chain selection's.
    given :
        The joints the user locked (the others were locked by the chain selection).
    where :
        The file, for the messages.

    Returns
    -------
    locked, coupled :
        ``locked`` with every follower of a locked leader at ``m q_lock + o`` (unless the user
        locked the follower too: a lock given for a joint is where it is held), and the mimics
        whose leader and follower both move (the model couples them, :func:`coupled_model`).

    Raises
    ------
    ModelError
        For a mimic value outside the follower's limits, or a follower locked while its leader
        moves.
    """
    out = dict(locked)
    coupled = []
    for mimic in mimics.values():
        name, leader = mimic.follower, mimic.leader
        if leader in out:
            if name in given:  # the user's own lock of the follower stands
                continue
            value = float(mimic.position(out[leader]))
            if not mimic.q_lower - 1e-12 <= value <= mimic.q_upper + 1e-12:
                raise ModelError(
                    f"{where}: joint {name!r} mimics {leader!r}: with {leader!r} locked at "
                    f"{out[leader]:g} it would sit at {value:g}, outside its limits "
                    f"[{mimic.q_lower:g}, {mimic.q_upper:g}]; lock {leader!r} elsewhere."
                )
            out[name] = value
        elif name in out:
            how = "is locked" if name in given else "is off the chain (locked by base/tip link)"
            raise ModelError(
                f"{where}: joint {name!r} mimics {leader!r}, which moves, but {name!r} {how}; "
                f"lock {leader!r} too, or keep both on the chain ({_SUPPORTED})."
            )
        else:
            coupled.append(mimic)
    return out, tuple(coupled)


def mimic_lock_reasons(mimics: Mapping[str, Mimic], locked: Mapping[str, float]) -> dict[str, str]:
    """Follower name -> ``"follows <leader> (mimic)"`` for every follower of a locked leader."""
    return {
        name: f"follows {mimic.leader} (mimic)"
        for name, mimic in mimics.items()
        if mimic.leader in locked
    }


def coupled_model(model: pin.Model, coupled: Sequence[Mimic], where: str) -> pin.Model:
    """``model`` with each follower of ``coupled`` made a Pinocchio mimic joint of its leader.

    The follower keeps its body and joint frame; it loses its coordinate (``nq`` and ``nv`` drop
    by one per follower), so Pinocchio's algorithms take the leaders' ``q`` and return the
    leaders' torques ``tau_l + m tau_f``. ``model`` itself when ``coupled`` is empty.

    Raises
    ------
    ModelError
        For a follower above its leader in the chain (Pinocchio couples a joint to an earlier
        one only).
    """
    for mimic in coupled:
        leader, follower = model.getJointId(mimic.leader), model.getJointId(mimic.follower)
        if follower < leader:
            raise ModelError(
                f"{where}: joint {mimic.follower!r} mimics {mimic.leader!r}, which comes after "
                f"it in the chain; {_SUPPORTED}."
            )
        model = pin.transformJointIntoMimic(model, leader, follower, mimic.multiplier,
                                            mimic.offset)  # fmt: skip
    return model


def follower_limits(
    joint_names: Sequence[str],
    q_lower: FloatArray,
    q_upper: FloatArray,
    dq_max: FloatArray,
    coupled: Sequence[Mimic],
    where: str,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The leaders' limits narrowed so that every follower keeps its own.

    A follower's position range, mapped through ``q_l = (q_f - o) / m``, and its velocity limit
    ``dq_max_f / |m|`` bound its leader; the excitation, which keeps the chain's joints within
    their limits, then keeps the followers within theirs.

    Returns
    -------
    :
        ``q_lower, q_upper, dq_max`` of the chain's joints (``joint_names``), shape (nq,) each.

    Raises
    ------
    ModelError
        When no leader position keeps a follower within its range.
    """
    lower, upper, speed = (np.array(a, dtype=float) for a in (q_lower, q_upper, dq_max))
    for mimic in coupled:
        j = list(joint_names).index(mimic.leader)
        low, high = mimic.leader_range()
        lower[j], upper[j] = max(lower[j], low), min(upper[j], high)
        speed[j] = min(speed[j], mimic.dq_max / abs(mimic.multiplier))
        if not lower[j] < upper[j]:
            raise ModelError(
                f"{where}: joint {mimic.follower!r} mimics {mimic.leader!r}, but no position of "
                f"{mimic.leader!r} within its limits keeps {mimic.follower!r} within "
                f"[{mimic.q_lower:g}, {mimic.q_upper:g}]; fix the limits or the mimic."
            )
    return lower, upper, speed


def reject_coupled_chain(model: pin.Model, what: str, where: str) -> None:
    """Raise a ModelError naming the first mimic joint of ``model`` (one with no coordinate of
    its own), for a step (``what``) that does not take a chain with mimic joints yet."""
    for i in range(1, model.njoints):
        if model.nvs[i] == 0:
            raise ModelError(
                f"{where}: joint {model.names[i]!r} is a mimic joint on the identified chain; "
                f"{what} of such a chain is not supported yet (ident verify, the regressor, the "
                "excitation's safety check and the MuJoCo model are); lock its leader (the "
                "follower is locked with it) or choose a chain without it."
            )
