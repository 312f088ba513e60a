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

:func:`write_identified_model` is the other write-back, for physically consistent estimates of
the standard parameters (:mod:`ident.identify.estimators`, ``lmi`` or ``log_cholesky``): every
identified link gets its identified inertial, the joints' viscous and Coulomb friction go into
``<dynamics damping friction>``, and all per-joint extras (rotor inertia, offsets, coupled-motor
terms) into a sidecar mapping. It refuses an inconsistent estimate.

Both parse the URDF with the standard library's expat parser and refuse a document type
declaration (``<!DOCTYPE``/``<!ENTITY``): the robot loader (urdfdom) does not expand
entities, so such a file would not describe the same robot to every reader.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from ident.errors import ModelError
from ident.inputs import refuse_dtd

__all__ = [
    "DEFAULT_MAX_RELATIVE_STD_PCT",
    "IdentifiedModel",
    "LinkUpdate",
    "UrdfUpdate",
    "parse_urdf",
    "update_urdf_inertials",
    "write_identified_model",
]

FloatArray = npt.NDArray[np.float64]

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
    """

    link: str
    joint: str
    written: dict[str, tuple[float, float]]
    uncertain: dict[str, float]
    rejected: dict[str, tuple[float, float]]
    not_determined: tuple[str, ...]
    problem: str = ""
    relative_std_pct: dict[str, float] = field(default_factory=dict)

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


def parse_urdf(urdf_text: str, source: str = "URDF") -> ET.Element:
    """Parse URDF text into an element tree, refusing what the robot loader would not read.

    Raises
    ------
    ModelError
        For a document type declaration (entities), malformed XML, or a root other than
        ``<robot>``; nothing has been changed then.
    """
    refuse_dtd(urdf_text, source)  # the rule of every URDF reader (ident.inputs)
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as e:
        raise ModelError(f"{source}: not well-formed XML ({e}).") from e
    if root.tag != "robot":
        raise ModelError(f"{source}: the root element is <{root.tag}>, expected <robot>.")
    return root


def _fmt(value: float) -> str:
    """Shortest text that reads back as the same float (write-back must not round)."""
    return repr(float(value))


def _inertial_element(link: ET.Element, phi: FloatArray) -> None:
    """Replace ``link``'s ``<inertial>`` by the parameters ``phi`` (about the link origin)."""
    from ident.robot.inertia import com_and_inertia

    mass, com, inertia = com_and_inertia(phi)
    old = link.find("inertial")
    if old is not None:
        link.remove(old)
    inertial = ET.SubElement(link, "inertial")
    ET.SubElement(inertial, "mass", value=_fmt(float(mass)))
    ET.SubElement(inertial, "origin", rpy="0 0 0", xyz=" ".join(_fmt(c) for c in com))
    ET.SubElement(
        inertial,
        "inertia",
        ixx=_fmt(inertia[0, 0]),
        ixy=_fmt(inertia[0, 1]),
        ixz=_fmt(inertia[0, 2]),
        iyy=_fmt(inertia[1, 1]),
        iyz=_fmt(inertia[1, 2]),
        izz=_fmt(inertia[2, 2]),
    )


def update_urdf_inertials(
    urdf_text: str,
    joint_names: tuple[str, ...],
    nominal: FloatArray,
    identified: dict[str, tuple[float, float]],
    *,
    max_relative_std_pct: float = DEFAULT_MAX_RELATIVE_STD_PCT,
) -> UrdfUpdate:
    """Return a URDF copy with the well-identified, consistent standard parameters replaced.

    Parameters
    ----------
    urdf_text :
        Original URDF.
    joint_names :
        Joints in chain order; body ``i`` is the child link of joint ``i``.
    nominal :
        Nominal standard parameters (about each joint frame's origin), Pinocchio order,
        shape (10 * n,).
    identified :
        ``{standard parameter name (e.g. "Ixy3"): (value [SI], relative std [%])}`` for the
        parameters the identification determines alone. A non-finite relative std counts as
        above the threshold.
    max_relative_std_pct :
        Only values with a relative standard deviation below this are written [%].

    Raises
    ------
    ModelError
        If a joint or its child link is not in the URDF.
    """
    from ident.robot.inertia import consistency_problems

    if not max_relative_std_pct > 0:
        raise ValueError(f"max_relative_std_pct = {max_relative_std_pct} must be > 0")
    root = parse_urdf(urdf_text)
    child_of = {
        j.get("name"): j.find("child").get("link")  # type: ignore[union-attr]
        for j in root.iter("joint")
        if j.find("child") is not None
    }
    links = {link.get("name"): link for link in root.iter("link")}
    updates: list[LinkUpdate] = []
    for i, joint in enumerate(joint_names):
        link_name = child_of.get(joint)
        if link_name is None or link_name not in links:
            raise ModelError(f"URDF: joint {joint!r} or its child link not found.")
        phi = np.array(nominal[10 * i : 10 * i + 10], dtype=float)
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
        problem = ""
        written: dict[str, tuple[float, float]] = {}
        rejected: dict[str, tuple[float, float]] = {}
        if candidates:
            problems = consistency_problems(phi)
            if problems:
                problem = "; ".join(problems)
                rejected = candidates
            else:
                written = candidates
                _inertial_element(links[link_name], phi)
        updates.append(
            LinkUpdate(
                link=link_name,
                joint=joint,
                written=written,
                uncertain=uncertain,
                rejected=rejected,
                not_determined=tuple(not_determined),
                problem=problem,
                relative_std_pct=relative_std,
            )
        )
    ET.indent(root, space="  ")
    text = '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode")
    return UrdfUpdate(
        text=text + "\n",
        links=tuple(updates),
        max_relative_std_pct=float(max_relative_std_pct),
    )


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
        Identified link names, in joint order.
    """

    text: str
    sidecar: dict
    links: tuple[str, ...]


def _own_inertial(link: ET.Element) -> FloatArray:
    """The link's own ``<inertial>`` as parameters about its frame origin (10,) [SI]."""
    import pinocchio as pin

    from ident.robot.inertia import parameters_from_com

    inertial = link.find("inertial")
    if inertial is None:
        return np.zeros(10)
    mass_el = inertial.find("mass")
    mass = float(mass_el.get("value", 0.0)) if mass_el is not None else 0.0
    origin = inertial.find("origin")
    xyz = np.zeros(3)
    rotation = np.eye(3)
    if origin is not None:
        xyz = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
        rpy = np.array([float(v) for v in origin.get("rpy", "0 0 0").split()])
        rotation = pin.rpy.rpyToMatrix(rpy)
    el = inertial.find("inertia")
    values = {
        k: float(el.get(k, 0.0)) if el is not None else 0.0
        for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    }
    inertia = np.array(
        [
            [values["ixx"], values["ixy"], values["ixz"]],
            [values["ixy"], values["iyy"], values["iyz"]],
            [values["ixz"], values["iyz"], values["izz"]],
        ]
    )
    return parameters_from_com(mass, xyz, rotation @ inertia @ rotation.T)


def write_identified_model(
    urdf_text: str,
    joint_names: tuple[str, ...],
    theta: FloatArray,
    names: tuple[str, ...],
    nominal: FloatArray,
    *,
    source: str = "URDF",
) -> IdentifiedModel:
    """Write a physically consistent estimate of the standard parameters into a URDF copy.

    Parameters
    ----------
    urdf_text :
        Original URDF (the one the estimate's nominal parameters come from).
    joint_names :
        Moving joints in chain order; body ``j`` (names ``m{j}``, ``mcx{j}``, ...) is carried
        by joint ``j``, its link is the joint's child.
    theta :
        Standard parameters, shape (n_std,): per body ``m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz,
        Iyz, Izz`` about the joint frame origin (Pinocchio), plus the extras ``Ia{j}``,
        ``fv{j}``, ``fs{j}``, ``off{j}`` and coupled-motor ``Iam{b}``, ``fvm{b}``, ``fsm{b}``.
    names :
        Names of ``theta``.
    nominal :
        The URDF's body parameters in the same order (Pinocchio's, fixed children merged),
        shape (n_std,).
    source :
        Name of the URDF for messages.

    Returns
    -------
    :
        The URDF text (every identified link's ``<inertial>`` replaced: mass, centre of
        mass, inertia about it in the link axes; each joint's ``<dynamics damping=fv_j
        friction=fs_j>`` where identified) and the sidecar
        ``{"joints": {name: {"rotor_inertia", "viscous", "coulomb", "offset"}},
        "coupled_motors": [...], "torque_model": ...}`` [SI].

    Notes
    -----
    Pinocchio merges links fixed to a link into its body. The part of the nominal body that
    comes from such fixed links is kept where the URDF puts it, and the link's own inertial is
    the identified body minus that part; it must be consistent too.

    Raises
    ------
    ModelError
        If a body of ``theta`` is physically inconsistent (use a constrained estimator, or
        the cautious :func:`update_urdf_inertials`), if the URDF has a DTD or is malformed, or
        if a joint or its child link is missing. Nothing is written then.
    """
    from ident.robot.inertia import consistency_problems

    root = parse_urdf(urdf_text, source)
    theta = np.asarray(theta, dtype=float)
    nominal = np.asarray(nominal, dtype=float)
    index = {name: i for i, name in enumerate(names)}
    joints = {j.get("name"): j for j in root.iter("joint")}
    links = {link.get("name"): link for link in root.iter("link")}
    problems = []
    plan = []
    for j, joint in enumerate(joint_names, start=1):
        element = joints.get(joint)
        child = element.find("child") if element is not None else None
        link_name = child.get("link") if child is not None else None
        if element is None or link_name is None or link_name not in links:
            raise ModelError(f"{source}: joint {joint!r} or its child link not found.")
        body = np.array([theta[index[f"{label}{j}"]] for label in _LABELS])
        body_nominal = np.array([nominal[index[f"{label}{j}"]] for label in _LABELS])
        fused = body_nominal - _own_inertial(links[link_name])
        own = body - fused
        issue = consistency_problems(body) or consistency_problems(own)
        if issue:
            problems.append(f"{link_name}: {'; '.join(issue)}")
        plan.append((element, links[link_name], own))
    if problems:
        raise ModelError(
            f"{source}: the estimate is not physically consistent ({' | '.join(problems)}); "
            "the whole-model write-back takes a consistent estimate (estimation.method: lmi "
            "or log_cholesky). The cautious write-back keeps nominal values instead."
        )

    def extra(name: str) -> float | None:
        return float(theta[index[name]]) if name in index else None

    sidecar_joints = {}
    for j, (element, link, own) in enumerate(plan, start=1):
        _inertial_element(link, own)
        fv, fs = extra(f"fv{j}"), extra(f"fs{j}")
        if fv is not None or fs is not None:
            dynamics = element.find("dynamics")
            if dynamics is None:
                dynamics = ET.SubElement(element, "dynamics")
            dynamics.set("damping", _fmt(fv or 0.0))
            dynamics.set("friction", _fmt(fs or 0.0))
        sidecar_joints[joint_names[j - 1]] = {
            "rotor_inertia": extra(f"Ia{j}") or 0.0,
            "viscous": fv or 0.0,
            "coulomb": fs or 0.0,
            "offset": extra(f"off{j}") or 0.0,
        }
    coupled = []
    for name in names:
        if name.startswith("Iam"):
            b = int(name[3:])
            coupled.append(
                {
                    "motor_joint": joint_names[b - 1],
                    "rotor_inertia": extra(f"Iam{b}") or 0.0,
                    "viscous": extra(f"fvm{b}") or 0.0,
                    "coulomb": extra(f"fsm{b}") or 0.0,
                }
            )
    sidecar = {
        "units": "SI (kg*m^2, N*m*s/rad, N*m), joint side",
        "torque_model": (
            "tau_j = rnea_j(q, dq, ddq) + rotor_inertia_j ddq_j + viscous_j dq_j + "
            "coulomb_j sign(dq_j) + offset_j; a coupled motor b shared by joints a, b adds "
            "rotor_inertia (ddq_a + ddq_b) + viscous (dq_a + dq_b) + coulomb sign(dq_a + dq_b) "
            "to rows a and b"
        ),
        "joints": sidecar_joints,
        "coupled_motors": coupled,
    }
    ET.indent(root, space="  ")
    text = '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode")
    return IdentifiedModel(
        text=text + "\n",
        sidecar=sidecar,
        links=tuple(str(link.get("name")) for _, link, _ in plan),
    )
