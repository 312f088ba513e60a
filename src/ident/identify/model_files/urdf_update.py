"""Write identified inertial parameters back into a copy of a URDF, where that is safe.

A base parameter determines a standard parameter when it *is* that parameter alone (an
independent column with nothing regrouped into it, e.g. ``Ixy3`` or ``mcx4``). Regrouped base
parameters (``Izz1R = Izz1 + Ia1 + Iyy2 + ...``) do not: the data fix only the sum. Per link:

1. a determined parameter is a candidate when its relative standard deviation is below
   ``max_relative_std_pct``; the others keep their nominal (URDF) values;
2. the link's new standard vector (about the joint-frame origin, Pinocchio order) is the nominal
   one with the candidates replaced;
3. if that vector is not physically consistent (positive mass, inertia about the centre of mass
   positive semi-definite, triangle inequality: :func:`ident.robot.inertia.consistency_problems`),
   the link keeps its nominal ``<inertial>`` and the reason is recorded; otherwise the new
   values are written as ``<inertial>`` (centre of mass, inertia about it, ``rpy="0 0 0"``).

Links without written values keep their ``<inertial>`` element untouched, so every link of the
copy is as consistent as the URDF's.

:func:`identified_urdf` (and its wrapper :func:`write_identified_model`) is the other
write-back, for physically consistent estimates of the standard parameters
(:mod:`ident.identify.estimators`, ``lmi`` or ``log_cholesky``): every identified link gets its
identified inertial, the joints' viscous and Coulomb friction go into ``<dynamics damping
friction>``, and all per-joint extras (rotor inertia, offsets, coupled-motor terms) into a
sidecar mapping. It refuses an inconsistent estimate.

Both read the URDF as urdfdom (Pinocchio, MuJoCo) does: only the top-level ``<robot>/<link>``
and ``<robot>/<joint>`` elements are kinematics (a ``<joint>`` in a ``<transmission>`` is not).
An identified body is Pinocchio's: the moving joint's child link plus every link fused into it
through fixed or locked joints (:func:`fused_bodies`); it is split back exactly by
:func:`compose_body` (the welded links keep their nominal inertials, or are scaled down when the
carrying link would otherwise be inconsistent), so the reloaded model with the same locks has
the written parameters. Only the edited ``<inertial>`` and ``<dynamics>`` elements change: the
rest of the file is kept byte for byte (:mod:`ident.identify.model_files.urdf_edit`).

Both refuse a document type declaration (``<!DOCTYPE``/``<!ENTITY``): the robot loader
(urdfdom) does not expand entities, so such a file would not describe the same robot to every
reader.
"""

from __future__ import annotations

import math

# xml.etree: reads the URDF's structure (links, nominal <inertial>) next to the text spans of
# urdf_edit, which write the edits so that the rest of the user's file stays byte for byte
# (yourdfpy's round trip drops its 6 <transmission>, 8 <gazebo> blocks and 24 comments on example-
# robot-data's UR5, checked, and gives no text positions); the nominal inertials are read with
# Pinocchio's rpyToMatrix, so a link that is not written back is bit-identical in the reloaded
# model; yourdfpy turns <origin rpy> into a matrix with its own code (checked: rpy 0.3 -1.2 2.1
# differs from pin.rpy.rpyToMatrix by 1.1e-16).
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ident.errors import ModelError
from ident.identify.model_files.fused_bodies import (
    FusedBody,
    compose_body,
    fused_bodies,
    link_inertial,
    model_of_urdf,
    parse_urdf,
)
from ident.identify.model_files.urdf_edit import (
    UrdfSpans,
    apply_edits,
    dynamics_edit,
    inertial_edit,
    spans,
)

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "DEFAULT_MAX_RELATIVE_STD_PCT",
    "FusedBody",
    "IdentifiedModel",
    "LinkUpdate",
    "UrdfUpdate",
    "compose_body",
    "fused_bodies",
    "identified_urdf",
    "model_of_urdf",
    "parse_urdf",
    "update_urdf_inertials",
    "write_identified_model",
]

FloatArray = npt.NDArray[np.float64]
#: A text edit of the URDF: (start, end, replacement bytes) (:func:`apply_edits`).
Edit = tuple[int, int, bytes]

DEFAULT_MAX_RELATIVE_STD_PCT = 10.0
_LABELS = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


@dataclass(frozen=True)
class LinkUpdate:
    """What happened to one link's inertial parameters.

    Attributes
    ----------
    link, joint :
        The link and its parent joint.
    written :
        ``{parameter: (nominal, identified)}`` written into the copy [SI].
    uncertain :
        ``{parameter: relative std [%]}`` determined alone but at or above the threshold: kept
        nominal.
    rejected :
        ``{parameter: (nominal, identified)}`` below the threshold but not written because the
        link would be physically inconsistent with them (see ``problem``).
    not_determined :
        Parameters no base parameter determines alone: kept nominal.
    problem :
        Why the link kept its nominal inertial although it had candidates, else ``""``.
    relative_std_pct :
        ``{parameter: relative std [%]}`` of every parameter determined alone.
    welded :
        The other links fused into this body (behind fixed or locked joints).
    welded_scale :
        The factor their inertials were scaled by (1: kept, see :func:`compose_body`).
    """

    link: str
    joint: str
    written: dict[str, tuple[float, float]]
    uncertain: dict[str, float]
    rejected: dict[str, tuple[float, float]]
    not_determined: tuple[str, ...]
    problem: str = ""
    relative_std_pct: dict[str, float] = field(default_factory=dict)
    welded: tuple[str, ...] = ()
    welded_scale: float = 1.0

    @property
    def status(self) -> str:
        """``"updated"``, ``"nominal (inconsistent)"`` or ``"nominal"``."""
        if self.written:
            return "updated"
        return "nominal (inconsistent)" if self.problem else "nominal"


@dataclass(frozen=True)
class UrdfUpdate:
    """A URDF copy with the safely identified inertial parameters written in.

    Attributes
    ----------
    text :
        The new URDF.
    links :
        One :class:`LinkUpdate` per moving link, in chain order.
    max_relative_std_pct :
        The threshold used [%].
    """

    text: str
    links: tuple[LinkUpdate, ...]
    max_relative_std_pct: float

    @property
    def written(self) -> dict[str, tuple[float, float]]:
        """``{parameter: (nominal, identified)}`` written, every link."""
        return {k: v for link in self.links for k, v in link.written.items()}

    @property
    def uncertain(self) -> dict[str, float]:
        """``{parameter: relative std [%]}`` kept nominal for their uncertainty, every link."""
        return {k: v for link in self.links for k, v in link.uncertain.items()}

    @property
    def not_determined(self) -> tuple[str, ...]:
        """Parameters no base parameter determines alone, every link."""
        return tuple(n for link in self.links for n in link.not_determined)

    @property
    def inconsistent_links(self) -> dict[str, str]:
        """``{link: problem}`` of the links kept nominal because the update was inconsistent."""
        return {link.link: link.problem for link in self.links if link.problem}


def _own_edits(urdf: UrdfSpans, link: str, own: FloatArray) -> tuple[int, int, bytes]:
    """The edit writing ``own`` (about the link origin) as the link's ``<inertial>``."""
    from ident.robot.inertia import com_and_inertia

    mass, com, inertia = com_and_inertia(own)
    if not mass > 0:
        com, inertia = np.zeros(3), np.zeros((3, 3))
    return inertial_edit(urdf, link, float(mass), com, inertia)


def _scaled_edit(
    urdf: UrdfSpans, root: ET.Element, link: str, scale: float
) -> tuple[int, int, bytes]:
    """The edit scaling ``link``'s own inertial by ``scale`` (same centre of mass)."""
    element = {e.get("name"): e for e in root.findall("link")}[link]
    return _own_edits(urdf, link, scale * link_inertial(element))


def _model_and_bodies(
    urdf_text: str,
    joint_names: tuple[str, ...],
    model: pin.Model | None,
    locked: Mapping[str, float] | None,
    source: str,
) -> tuple[ET.Element, list[FusedBody]]:
    root = parse_urdf(urdf_text, source)
    if model is None:
        model = model_of_urdf(urdf_text, locked, source)
    if tuple(model.names[1:]) != tuple(joint_names):
        raise ModelError(
            f"{source}: the model's moving joints ({', '.join(model.names[1:])}) are not the "
            f"identified ones ({', '.join(joint_names)}); lock the same joints as the "
            "identification did."
        )
    return root, fused_bodies(root, model, source)


def update_urdf_inertials(
    urdf_text: str,
    joint_names: tuple[str, ...],
    nominal: FloatArray,
    identified: dict[str, tuple[float, float]],
    *,
    max_relative_std_pct: float = DEFAULT_MAX_RELATIVE_STD_PCT,
    locked: Mapping[str, float] | None = None,
    model: pin.Model | None = None,
) -> UrdfUpdate:
    """Return a URDF copy with the well-identified, consistent standard parameters replaced.

    Parameters
    ----------
    urdf_text :
        Original URDF.
    joint_names :
        Joints in chain order; body ``i`` is carried by joint ``i`` (its child link, plus the
        links fused into it: see :func:`fused_bodies`).
    nominal :
        Nominal standard parameters (about each joint frame's origin), Pinocchio order,
        shape (10 * n,).
    identified :
        ``{standard parameter name (e.g. "Ixy3"): (value [SI], relative std [%])}`` for the
        parameters the identification determines alone. A non-finite relative std counts as
        above the threshold.
    max_relative_std_pct :
        Only values with a relative standard deviation below this are written [%].
    locked :
        Joints the identification held fixed (name -> position), as in
        :meth:`ident.model.Robot.from_urdf`; ignored when ``model`` is given.
    model :
        The identified robot's Pinocchio model (``Robot.model``); built from the text and
        ``locked`` when omitted.

    Raises :class:`ModelError` if a joint or its child link is not in the URDF, or the model's
    joints differ from ``joint_names``.
    """
    if not max_relative_std_pct > 0:
        raise ValueError(f"max_relative_std_pct = {max_relative_std_pct} must be > 0")
    root, bodies = _model_and_bodies(urdf_text, joint_names, model, locked, "URDF")
    urdf = spans(urdf_text)
    edits: list[Edit] = []
    updates: list[LinkUpdate] = []
    for i, fused in enumerate(bodies):
        phi = np.array(nominal[10 * i : 10 * i + 10], dtype=float)
        update, link_edits = _cautious_link(
            i, fused, phi, identified, max_relative_std_pct, urdf, root
        )
        updates.append(update)
        edits.extend(link_edits)
    return UrdfUpdate(
        text=apply_edits(urdf.data, edits),
        links=tuple(updates),
        max_relative_std_pct=float(max_relative_std_pct),
    )


def _cautious_link(
    i: int,
    fused: FusedBody,
    phi: FloatArray,
    identified: dict[str, tuple[float, float]],
    max_relative_std_pct: float,
    urdf: UrdfSpans,
    root: ET.Element,
) -> tuple[LinkUpdate, list[Edit]]:
    """Body ``i`` of :func:`update_urdf_inertials`: its :class:`LinkUpdate` and text edits.

    ``phi`` is the body's nominal parameters, shape (10,), replaced in place by the
    well-identified values.
    """
    from ident.robot.inertia import consistency_problems

    candidates, uncertain, not_determined, relative_std = _well_identified(
        i, phi, identified, max_relative_std_pct
    )
    problem = ""
    written: dict[str, tuple[float, float]] = {}
    rejected: dict[str, tuple[float, float]] = {}
    scale = 1.0
    edits: list[Edit] = []
    if candidates:
        problems = consistency_problems(phi)
        if problems:
            problem = "; ".join(problems)
            rejected = candidates
        else:
            written = candidates
            own, scale = compose_body(phi, fused.welded_sum)
            edits.append(_own_edits(urdf, fused.carrier, own))
            if scale != 1.0:
                edits.extend(_scaled_edit(urdf, root, n, scale) for n, _ in fused.welded)
    update = LinkUpdate(
        link=fused.carrier,
        joint=fused.joint,
        written=written,
        uncertain=uncertain,
        rejected=rejected,
        not_determined=tuple(not_determined),
        problem=problem,
        relative_std_pct=relative_std,
        welded=tuple(n for n, _ in fused.welded),
        welded_scale=scale,
    )
    return update, edits


def _well_identified(
    i: int, phi: FloatArray, identified: dict[str, tuple[float, float]], max_relative_std_pct: float
) -> tuple[dict[str, tuple[float, float]], dict[str, float], list[str], dict[str, float]]:
    """Body ``i``'s parameters sorted: candidates ``{name: (nominal, identified)}`` (relative
    std below ``max_relative_std_pct`` [%]; written into ``phi`` (10,) in place), uncertain
    ``{name: relative std}``, not determined names, and every relative std [%]."""
    candidates: dict[str, tuple[float, float]] = {}
    uncertain: dict[str, float] = {}
    not_determined: list[str] = []
    relative_std: dict[str, float] = {}
    for k, label in enumerate(_LABELS):
        name = f"{label}{i + 1}"
        if name not in identified:
            not_determined.append(name)
            continue
        value, rel_std = identified[name]
        relative_std[name] = float(rel_std)
        if math.isfinite(rel_std) and rel_std < max_relative_std_pct:
            candidates[name] = (float(phi[k]), float(value))
            phi[k] = value
        else:
            uncertain[name] = float(rel_std)
    return candidates, uncertain, not_determined, relative_std


@dataclass(frozen=True)
class IdentifiedModel:
    """A URDF carrying a whole consistent estimate, and the per-joint extras beside it.

    Attributes
    ----------
    text :
        The identified URDF.
    sidecar :
        JSON-ready mapping of every per-joint extra (see :func:`write_identified_model`).
    links :
        Identified (carrying) link names, in joint order.
    welded_scale :
        ``{carrying link: s}`` for the bodies whose welded links were scaled by ``s < 1``
        (see :func:`compose_body`); empty when every welded link kept its nominal inertial.
    """

    text: str
    sidecar: dict
    links: tuple[str, ...]
    welded_scale: dict[str, float] = field(default_factory=dict)


def identified_urdf(
    urdf_text: str,
    model: pin.Model,
    theta: FloatArray,
    names: tuple[str, ...],
    *,
    nominal: FloatArray | None = None,
    coupled_pair: tuple[int, int] | None = None,
    source: str = "URDF",
) -> IdentifiedModel:
    """Write a physically consistent estimate of the standard parameters into a URDF copy.

    Parameters
    ----------
    urdf_text :
        The robot's URDF (the file as written: transmissions, gazebo blocks, continuous
        joints and meshes are kept as they are).
    model :
        The identified robot's Pinocchio model (``Robot.model``: continuous joints as revolute,
        locked joints removed); body ``j`` (``m{j}``, ``mcx{j}``, ...) is carried by joint ``j``.
    theta, names :
        Standard parameters (n_std,) and their names: per body ``m, mcx, mcy, mcz, Ixx, Ixy,
        Iyy, Ixz, Iyz, Izz`` about the joint frame origin (Pinocchio), plus the extras ``Ia{j}``,
        ``fv{j}``, ``fs{j}``, ``off{j}`` and coupled-motor ``Iam{b}``, ``fvm{b}``, ``fsm{b}``.
    nominal :
        Optional check: the nominal parameters in the same order; each body must equal the sum
        of its links' inertials in the file (else the model is not this file's, e.g. other
        locks), to 1e-9 relative.
    coupled_pair, source :
        The two joints ``(a, b)`` (0-based, ``ExtraTerms.coupled_wrist``) that share the
        coupled motor ``Iam{b+1}``, recorded as the motor's ``"joints"`` in the sidecar; the
        URDF's name for messages.

    Returns the URDF text and the sidecar ``{"joints": {name: {"rotor_inertia", "viscous",
    "coulomb", "offset"}}, "coupled_motors": [...], "torque_model": ...}`` [SI]. Only the
    ``<inertial>`` of the links of identified bodies and the ``<dynamics>`` of the moving
    joints change (the viscous and Coulomb friction go into ``damping`` and ``friction``);
    every other byte of the file is kept. Each body (links fused through fixed and locked
    joints) is split back by :func:`compose_body`, so the reloaded model (same locks) has the
    estimate's torques and no link has a negative mass (module docstring).

    Raises :class:`ModelError`, writing nothing, if a body of ``theta`` is physically
    inconsistent (use a constrained estimator, or the cautious :func:`update_urdf_inertials`),
    the URDF has a DTD or is malformed, a joint or its child link is missing, or ``nominal``
    does not match the file."""
    joint_names = tuple(model.names[1:])
    root, bodies = _model_and_bodies(urdf_text, joint_names, model, None, source)
    urdf = spans(urdf_text, source)
    theta = np.asarray(theta, dtype=float)
    index = {name: i for i, name in enumerate(names)}
    plan = _checked_bodies(root, bodies, theta, index, nominal, source)
    edits, scales, joints = _body_edits(urdf, root, plan, theta, index)
    sidecar: dict[str, Any] = {"units": UNITS, "torque_model": TORQUE_MODEL, "joints": joints}
    sidecar["coupled_motors"] = _coupled_motors(theta, index, joint_names, coupled_pair, source)
    return IdentifiedModel(
        text=apply_edits(urdf.data, edits),
        sidecar=sidecar,
        links=tuple(fused.carrier for fused, _ in plan),
        welded_scale=scales,
    )


#: Units of the joint-extras file (``IdentifiedModel.sidecar["units"]``).
UNITS = "SI (kg*m^2, N*m*s/rad, N*m), joint side"

#: The torque model of the joint-extras file (``IdentifiedModel.sidecar["torque_model"]``).
TORQUE_MODEL = (
    "tau_j = rnea_j(q, dq, ddq) + rotor_inertia_j ddq_j + viscous_j dq_j + "
    "coulomb_j sign(dq_j) + offset_j; a coupled motor b shared by joints a, b adds "
    "rotor_inertia (ddq_a + ddq_b) + viscous (dq_a + dq_b) + coulomb sign(dq_a + dq_b) "
    "to rows a and b"
)


def _extra(theta: FloatArray, index: dict[str, int], name: str) -> float | None:
    """The extra parameter ``name`` of ``theta``, or None when the model has none."""
    return float(theta[index[name]]) if name in index else None


def _checked_bodies(
    root: ET.Element,
    bodies: list[FusedBody],
    theta: FloatArray,
    index: dict[str, int],
    nominal: FloatArray | None,
    source: str,
) -> list[tuple[FusedBody, FloatArray]]:
    """Each fused body with its estimated parameters (shape (10,)), all checked: present,
    consistent, and (``nominal`` given) the file's nominal body (:func:`identified_urdf`)."""
    from ident.robot.inertia import consistency_problems

    problems = []
    plan = []
    for j, fused in enumerate(bodies, start=1):
        try:
            body = np.array([theta[index[f"{label}{j}"]] for label in _LABELS])
        except KeyError as e:
            raise ModelError(f"{source}: the estimate has no parameter {e} of body {j}.") from e
        if nominal is not None:
            expected = np.array([nominal[index[f"{label}{j}"]] for label in _LABELS])
            links = {e.get("name"): e for e in root.findall("link")}
            found = link_inertial(links[fused.carrier]) + fused.welded_sum
            if not np.allclose(found, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max()):
                raise ModelError(
                    f"{source}: the nominal body of joint {fused.joint!r} is not the sum of its "
                    "links' inertials in this file; give the model with the same locked joints "
                    "as the identification."
                )
        issue = consistency_problems(body)
        if issue:
            problems.append(f"{fused.carrier}: {'; '.join(issue)}")
        plan.append((fused, body))
    if problems:
        raise ModelError(
            f"{source}: the estimate is not physically consistent ({' | '.join(problems)}); "
            "the whole-model write-back takes a consistent estimate (estimation.method: lmi "
            "or log_cholesky). The cautious write-back keeps nominal values instead."
        )
    return plan


def _body_edits(
    urdf: UrdfSpans,
    root: ET.Element,
    plan: list[tuple[FusedBody, FloatArray]],
    theta: FloatArray,
    index: dict[str, int],
) -> tuple[list[Edit], dict[str, float], dict[str, dict[str, float]]]:
    """The text edits of every body and joint, the welded links' scales by carrying link, and
    the sidecar's per-joint extras (:func:`identified_urdf`)."""
    edits: list[Edit] = []
    scales = {}
    joints = {}
    for j, (fused, body) in enumerate(plan, start=1):
        own, scale = compose_body(body, fused.welded_sum)
        edits.append(_own_edits(urdf, fused.carrier, own))
        if scale != 1.0:
            scales[fused.carrier] = scale
            edits.extend(_scaled_edit(urdf, root, n, scale) for n, _ in fused.welded)
        fv, fs = _extra(theta, index, f"fv{j}"), _extra(theta, index, f"fs{j}")
        if fv is not None or fs is not None:
            edits.append(dynamics_edit(urdf, fused.joint, fv or 0.0, fs or 0.0))
        joints[fused.joint] = {
            "rotor_inertia": _extra(theta, index, f"Ia{j}") or 0.0,
            "viscous": fv or 0.0,
            "coulomb": fs or 0.0,
            "offset": _extra(theta, index, f"off{j}") or 0.0,
        }
    return edits, scales, joints


def _coupled_motors(
    theta: FloatArray,
    index: dict[str, int],
    joint_names: tuple[str, ...],
    coupled_pair: tuple[int, int] | None,
    source: str,
) -> list[dict[str, Any]]:
    """The sidecar's coupled motors (``Iam{b}``, ``fvm{b}``, ``fsm{b}`` of ``theta``)."""
    coupled = []
    for name in index:
        if name.startswith("Iam"):
            b = int(name[3:])
            pair = None
            if coupled_pair is not None:
                if int(coupled_pair[1]) != b - 1:
                    raise ModelError(
                        f"{source}: coupled_pair {tuple(coupled_pair)} does not end at the "
                        f"coupled motor's joint {b} ({name})."
                    )
                pair = [joint_names[int(k)] for k in coupled_pair]
            coupled.append(
                {
                    "motor_joint": joint_names[b - 1],
                    "joints": pair,
                    "rotor_inertia": _extra(theta, index, f"Iam{b}") or 0.0,
                    "viscous": _extra(theta, index, f"fvm{b}") or 0.0,
                    "coulomb": _extra(theta, index, f"fsm{b}") or 0.0,
                }
            )
    return coupled


def write_identified_model(
    urdf_text: str,
    joint_names: tuple[str, ...],
    theta: FloatArray,
    names: tuple[str, ...],
    nominal: FloatArray,
    *,
    source: str = "URDF",
    locked: Mapping[str, float] | None = None,
    coupled_pair: tuple[int, int] | None = None,
) -> IdentifiedModel:
    """:func:`identified_urdf` for callers without the robot's model.

    The model is built from ``urdf_text`` with the joints ``locked`` held
    (:func:`model_of_urdf`); its moving joints must be ``joint_names``, and ``nominal`` must
    be its bodies (checked).
    """
    model = model_of_urdf(urdf_text, locked, source)
    if tuple(model.names[1:]) != tuple(joint_names):
        raise ModelError(
            f"{source}: the model's moving joints ({', '.join(model.names[1:])}) are not the "
            f"identified ones ({', '.join(joint_names)}); lock the same joints as the "
            "identification did."
        )
    return identified_urdf(
        urdf_text, model, theta, names, nominal=nominal, coupled_pair=coupled_pair, source=source
    )
