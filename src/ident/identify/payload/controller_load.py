"""A payload in the formats robot controllers take, checked against their limits.

- **Universal Robots** (URScript, PolyScope 5.10+ and e-Series):
  ``set_target_payload(m, cog, inertia)`` with the mass [kg], the centre of gravity [m] in the
  tool flange frame (``tool0`` of the UR URDFs) and the inertia matrix [kg*m^2] about the centre
  of gravity, tool flange axes, as ``[Ixx, Iyy, Izz, Ixy, Ixz, Iyz]``. Older controllers take
  ``set_payload(m, cog)`` (no inertia), written beside it.
- **Franka** (libfranka): ``robot.setLoad(load_mass, F_x_Cload, load_inertia)`` with the mass
  [kg], the centre of mass [m] in the flange frame and the inertia [kg*m^2] about the centre of
  mass, a column-major 3x3 ``std::array<double, 9>``.

The values must be expressed in the frame the controller means (``payload.link`` / the stream
config's ``link``: ``tool0`` for a UR, the flange ``panda_link8`` for a Franka); this module does
not move frames. :func:`check_load` checks the estimate against the limits: a positive mass, the
mass's 95 % interval within the rated payload, the centre of mass within its allowed distance
from the flange, a physical inertia about the centre of mass (positive definite, triangle
inequalities). A limit the config does not give is reported as ``not run``, never as passed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["LimitCheck", "LoadLimits", "check_load", "franka_set_load", "ur_set_payload"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class LoadLimits:
    """A controller's payload limits (SI); None: not known (the check is not run)."""

    max_mass_kg: float | None = None
    max_com_distance_m: float | None = None


@dataclass(frozen=True)
class LimitCheck:
    """One check: ``name``, ``status`` (``pass``, ``fail`` or ``not run``) and what it saw."""

    name: str
    status: str
    detail: str


def ur_set_payload(mass: float, com: npt.ArrayLike, inertia_com: npt.ArrayLike) -> dict:
    """URScript lines of a payload: ``{"set_target_payload": ..., "set_payload": ...}``.

    ``mass`` [kg], ``com`` (3,) [m] and ``inertia_com`` (3, 3) [kg*m^2] in the tool flange frame.
    """
    c = np.asarray(com, dtype=float)
    In = np.asarray(inertia_com, dtype=float)
    cog = ", ".join(f"{v:.6f}" for v in c)
    six = (In[0, 0], In[1, 1], In[2, 2], In[0, 1], In[0, 2], In[1, 2])
    inertia = ", ".join(f"{v:.6g}" for v in six)
    return {
        "set_target_payload": f"set_target_payload({mass:.4f}, [{cog}], [{inertia}])",
        "set_payload": f"set_payload({mass:.4f}, [{cog}])",
    }


def franka_set_load(mass: float, com: npt.ArrayLike, inertia_com: npt.ArrayLike) -> dict:
    """libfranka ``setLoad`` arguments and the C++ call of a payload (flange frame, SI)."""
    c = [float(v) for v in np.asarray(com, dtype=float)]
    # column-major: the matrix is symmetric, so its flattening in either order is the same
    inertia = [float(v) for v in np.asarray(inertia_com, dtype=float).reshape(-1, order="F")]
    return {
        "load_mass": float(mass),
        "F_x_Cload": c,
        "load_inertia": inertia,
        "cpp": "robot.setLoad("
        + f"{mass:.4f}, {{{{{', '.join(f'{v:.6f}' for v in c)}}}}}, "
        + f"{{{{{', '.join(f'{v:.6g}' for v in inertia)}}}}});",
    }


def check_load(
    mass: float,
    com: npt.ArrayLike,
    inertia_com: npt.ArrayLike,
    mass_interval: tuple[float, float],
    limits: LoadLimits,
) -> list[LimitCheck]:
    """The checks of the module docstring for a payload ``mass`` [kg] (its interval
    ``mass_interval``), ``com`` (3,) [m] and ``inertia_com`` (3, 3) [kg*m^2]."""
    lo, hi = mass_interval
    checks = [_check("mass positive", lo > 0, f"95 % interval [{lo:.4g}, {hi:.4g}] kg")]
    if limits.max_mass_kg is None:
        checks.append(LimitCheck("rated payload", "not run", "no max_mass_kg given"))
    else:
        detail = f"upper end {hi:.4g} kg vs {limits.max_mass_kg:.4g} kg"
        checks.append(_check("rated payload", hi <= limits.max_mass_kg, detail))
    dist = float(np.linalg.norm(np.asarray(com, dtype=float)))
    name = "centre of mass distance"
    if limits.max_com_distance_m is None:
        checks.append(LimitCheck(name, "not run", "no max_com_distance_m given"))
    else:
        detail = f"{1e3 * dist:.1f} mm vs {1e3 * limits.max_com_distance_m:.1f} mm"
        checks.append(_check(name, dist <= limits.max_com_distance_m, detail))
    ev = np.linalg.eigvalsh(np.asarray(inertia_com, dtype=float))
    physical = bool(ev[0] > 0 and ev[0] + ev[1] >= ev[2] - 1e-12 * max(ev[2], 1e-300))
    moments = ", ".join(f"{v:.3g}" for v in ev)
    checks.append(_check("physical inertia", physical, f"principal moments {moments} kg*m^2"))
    return checks


def _check(name: str, ok: bool, detail: str) -> LimitCheck:
    return LimitCheck(name, "pass" if ok else "fail", detail)
