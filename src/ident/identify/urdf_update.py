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
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from ident.errors import ModelError

__all__ = ["DEFAULT_MAX_RELATIVE_STD_PCT", "LinkUpdate", "UrdfUpdate", "update_urdf_inertials"]

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


def _inertial_element(link: ET.Element, phi: FloatArray) -> None:
    """Replace ``link``'s ``<inertial>`` by the parameters ``phi`` (about the link origin)."""
    from ident.robot.inertia import com_and_inertia

    mass, com, inertia = com_and_inertia(phi)
    old = link.find("inertial")
    if old is not None:
        link.remove(old)
    inertial = ET.SubElement(link, "inertial")
    ET.SubElement(inertial, "mass", value=f"{float(mass):.9g}")
    ET.SubElement(inertial, "origin", rpy="0 0 0", xyz=" ".join(f"{c:.9g}" for c in com))
    ET.SubElement(
        inertial,
        "inertia",
        ixx=f"{inertia[0, 0]:.9g}",
        ixy=f"{inertia[0, 1]:.9g}",
        ixz=f"{inertia[0, 2]:.9g}",
        iyy=f"{inertia[1, 1]:.9g}",
        iyz=f"{inertia[1, 2]:.9g}",
        izz=f"{inertia[2, 2]:.9g}",
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
    root = ET.fromstring(urdf_text)
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
