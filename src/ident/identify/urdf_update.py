"""Write identified inertial parameters back into a copy of a URDF, where they determine one.

A base parameter determines a standard parameter when it *is* that parameter alone (an
independent column with nothing regrouped into it, e.g. ``Ixy3`` or ``mcx4``). Regrouped base
parameters (``Izz1R = Izz1 + Ia1 + Iyy2 + ...``) do not: the data fix only the sum. For every
link, the new standard vector (about the joint-frame origin, Pinocchio order) keeps the URDF's
values except the determined ones, and is written as ``<inertial>`` (centre of mass, inertia
about it, ``rpy="0 0 0"``). Whether the result is physically consistent (positive mass,
positive definite inertia satisfying the triangle inequalities) is checked and reported.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["UrdfUpdate", "update_urdf_inertials"]

FloatArray = npt.NDArray[np.float64]

_LABELS = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


@dataclass(frozen=True)
class UrdfUpdate:
    """A URDF copy with identified parameters written in.

    Attributes
    ----------
    text :
        The new URDF.
    written :
        ``{parameter name: (old value, new value)}``.
    not_determined :
        Standard inertial parameters the identification does not determine alone.
    inconsistent_links :
        Links whose written inertia is not physically consistent, with the reason.
    """

    text: str
    written: dict[str, tuple[float, float]]
    not_determined: tuple[str, ...]
    inconsistent_links: dict[str, str]


def _consistency(phi: FloatArray) -> str | None:
    import pinocchio as pin

    if phi[0] <= 0:
        return f"mass {phi[0]:.4g} kg <= 0"
    inertia = pin.Inertia.FromDynamicParameters(phi)
    eig = np.linalg.eigvalsh(inertia.inertia)
    if eig.min() < 0:
        return f"inertia about the centre of mass not positive semi-definite (eig {eig.min():.3g})"
    if eig[2] > eig[0] + eig[1] + 1e-12:
        return "principal moments violate the triangle inequality"
    return None


def update_urdf_inertials(
    urdf_text: str,
    joint_names: tuple[str, ...],
    nominal: FloatArray,
    identified: dict[str, float],
) -> UrdfUpdate:
    """Return a URDF copy with the determined standard parameters replaced.

    Parameters
    ----------
    urdf_text :
        Original URDF.
    joint_names :
        Joints in chain order; body ``i`` is the child link of joint ``i``.
    nominal :
        Nominal standard parameters, Pinocchio order, shape (10 * n,).
    identified :
        ``{standard parameter name (e.g. "Ixy3"): value}`` for the parameters the
        identification determines alone [SI].
    """
    import pinocchio as pin

    root = ET.fromstring(urdf_text)
    child_of = {
        j.get("name"): j.find("child").get("link")  # type: ignore[union-attr]
        for j in root.iter("joint")
        if j.find("child") is not None
    }
    links = {link.get("name"): link for link in root.iter("link")}
    written: dict[str, tuple[float, float]] = {}
    not_determined: list[str] = []
    inconsistent: dict[str, str] = {}
    for i, joint in enumerate(joint_names):
        phi = np.array(nominal[10 * i : 10 * i + 10], dtype=float)
        changed = False
        for k, label in enumerate(_LABELS):
            name = f"{label}{i + 1}"
            if name in identified:
                written[name] = (float(phi[k]), float(identified[name]))
                phi[k] = identified[name]
                changed = True
            else:
                not_determined.append(name)
        if not changed:
            continue
        link = links[child_of[joint]]
        inertia = pin.Inertia.FromDynamicParameters(phi)
        problem = _consistency(phi)
        if problem:
            inconsistent[link.get("name") or joint] = problem
        old = link.find("inertial")
        if old is not None:
            link.remove(old)
        inertial = ET.SubElement(link, "inertial")
        com = inertia.lever
        I = inertia.inertia
        ET.SubElement(inertial, "mass", value=f"{inertia.mass:.9g}")
        ET.SubElement(inertial, "origin", rpy="0 0 0", xyz=" ".join(f"{c:.9g}" for c in com))
        ET.SubElement(
            inertial,
            "inertia",
            ixx=f"{I[0, 0]:.9g}",
            ixy=f"{I[0, 1]:.9g}",
            ixz=f"{I[0, 2]:.9g}",
            iyy=f"{I[1, 1]:.9g}",
            iyz=f"{I[1, 2]:.9g}",
            izz=f"{I[2, 2]:.9g}",
        )
    ET.indent(root, space="  ")
    text = '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode")
    return UrdfUpdate(
        text=text + "\n",
        written=written,
        not_determined=tuple(not_determined),
        inconsistent_links=inconsistent,
    )
