"""An MJCF (MuJoCo) model of an identified robot: its written URDF plus the joint extras.

The URDF is converted by MuJoCo's own URDF importer after the edits of
:func:`ident.measure.mujoco_model.mujoco_urdf` (the conversion the simulator uses): no geometry,
the identification's locked joints fixed at their positions, inertials exactly as given (no
inertia from geometry, no balancing). Every link stays its own body (``fusestatic`` off), so the
MJCF body tree is the URDF's link tree; limits (``range``) and effort limits
(``actuatorfrcrange``) are kept. Each moving joint's child link carries the whole identified
body (the links welded or locked to it included, as Pinocchio fuses them); the other links are
massless. So the MJCF does not depend on how the URDF splits a body between its links, nor on
the file's inertials of links that never move (real files have inconsistent ones, which MuJoCo
refuses).

Joint extras, identified with the torque model
``tau_j = rnea_j + Ia_j ddq_j + fv_j dq_j + fs_j sign(dq_j) + off_j``, map to MuJoCo as:

- rotor inertia ``Ia_j`` -> ``armature``: exact (MuJoCo adds it to the diagonal of the mass
  matrix, as the model does);
- viscous friction ``fv_j`` -> ``damping``: exact in inverse dynamics (``mj_inverse`` adds
  ``fv_j dq_j``); in simulation MuJoCo integrates damping implicitly (Euler integrator), a
  slightly different discrete-time system than an explicit ``-fv dq`` torque;
- Coulomb friction ``fs_j`` -> ``frictionloss``: approximate. MuJoCo's friction loss is a
  constraint force bounded by ``fs_j`` (dry friction with a soft, regularized stick phase), not
  the torque ``fs_j sign(dq_j)``: they agree while the joint slides, not near zero velocity;
- a coupled motor (one motor turning with ``q_a + q_b``, the TX40 wrist) -> a fixed tendon
  ``q_a + q_b`` with ``armature`` = ``Iam``, ``damping`` = ``fvm`` (exact, rows ``a`` and ``b``)
  and ``frictionloss`` = ``fsm`` (approximate, as above);
- offsets ``off_j`` have no MJCF counterpart: they stay in the joint-extras file only.

Numbers: MuJoCo's own MJCF writer prints 6 significant digits; every numeric attribute that
changes the dynamics (body poses, inertials, joint axes and positions, damping, armature,
friction loss, gravity) is rewritten with the compiled model's values at full precision, so the
MJCF reloads to the same model (inverse dynamics equal to about 1e-15 relative).
"""

from __future__ import annotations

# xml.etree: MuJoCo's MjSpec does the conversion (from_string, joint extras, tendons, to_xml);
# xml.etree is left for (1) _with_bodies, the URDF inertials replaced in the text before MuJoCo's
# importer reads it: doing it on the spec instead (mass, ipos, fullinertia, explicitinertial=False
# for the others) gives bitwise-equal body_mass, body_inertia, dof_armature/damping/frictionloss
# and the moving bodies' ipos/iquat, but the massless bodies' ipos/iquat differ (checked on UR5:
# ee_link pos 0.0823 -> 0), 3 lines of the written MJCF; (2) _full_precision: MjSpec.to_xml prints
# 6 significant digits (checked on mujoco 4.0.0: mass 1.234567890123 written "1.23457", the
# reloaded body_mass off by 2.1e-6, armature by 2.1e-7), so the dynamics' numbers are rewritten at
# full precision.
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from ident.errors import ModelError
from ident.measure.mujoco_model import mujoco_urdf

__all__ = ["MJCF_NOTE", "identified_mjcf", "with_joint_values"]

FloatArray = npt.NDArray[np.float64]

#: The comment at the top of every written MJCF.
MJCF_NOTE = """
  Identified model written by ident from the identified URDF and the joint extras.
  Dynamics only: the URDF's visual and collision geometry is dropped (meshes need not exist);
  add geoms for contacts or display. Joints locked during the identification are fixed here.
  armature = rotor inertia (exact); damping = viscous friction (exact in inverse dynamics,
  integrated implicitly in simulation); frictionloss = Coulomb friction (approximate: a
  constraint-based dry friction bounded by it, not the torque fs*sign(dq)). A coupled motor is
  a fixed tendon q_a + q_b with its armature, damping and frictionloss. Torque offsets are not
  represented: see the joint-extras file. Position servos (a robot whose log had no torque):
  a <position> actuator per joint, kp as identified (or given), forcerange as configured, kv =
  0: the servo's kd and the viscous friction are known only as their sum, which is the joint's
  damping.
"""


def _fmt(values: npt.ArrayLike) -> str:
    return " ".join(repr(float(v) + 0.0) for v in np.atleast_1d(np.asarray(values, float)))


def _vector_or_scalar(current: Any, value: float) -> Any:
    """``value`` in the shape of a spec attribute (MuJoCo 4 damping is a 3-vector)."""
    if np.ndim(current) == 0:
        return value
    out = np.zeros(np.shape(current))
    out[0] = value
    return out


def _compile(spec: mujoco.MjSpec, where: str) -> mujoco.MjModel:
    try:
        return spec.compile()
    except ValueError as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ModelError(f"{where}: MuJoCo cannot compile the identified model ({first}).") from e


def identified_mjcf(
    urdf_text: str,
    joint_names: tuple[str, ...],
    bodies: Mapping[str, npt.ArrayLike],
    extras: Mapping[str, Mapping[str, float]],
    *,
    coupled_motors: Sequence[Mapping[str, Any]] = (),
    locked_joints: Mapping[str, float] | None = None,
    gravity: npt.ArrayLike = (0.0, 0.0, -9.81),
    source: str = "identified URDF",
    position_servos: Mapping[str, Mapping[str, float | None]] | None = None,
) -> str:
    """The MJCF text of an identified robot.

    Parameters
    ----------
    urdf_text :
        The robot's URDF (its kinematics, names and limits are used; meshes are not needed).
    joint_names :
        The moving joints, base to tip (``Robot.joint_names``).
    bodies :
        ``{link: parameters (10,)}``: each moving joint's child link and its identified body
        about the link frame origin (Pinocchio order) [SI], the links welded or locked to it
        included. Every other link gets no inertia: it is fused into one of these bodies, or
        does not move (fixed to the world), as in Pinocchio's model; so the MJCF does not
        depend on the file's inertials of those links (which MuJoCo may refuse).
    extras :
        ``{joint: {"rotor_inertia", "viscous", "coulomb"}}`` [kg*m^2, N*m*s/rad, N*m] (the
        sidecar's ``"joints"``); a missing joint or key counts as 0.
    coupled_motors :
        The sidecar's ``"coupled_motors"``: each ``{"joints": [a, b], "rotor_inertia",
        "viscous", "coulomb"}`` becomes a fixed tendon ``q_a + q_b`` with that ``armature``,
        ``damping`` and ``frictionloss``: exactly the coupled motor's ``Iam (ddq_a + ddq_b)``
        and ``fvm (dq_a + dq_b)`` in rows ``a`` and ``b`` (``fsm`` as a friction loss).
    locked_joints, gravity, source :
        Joints held fixed (name -> position [rad or m]), as the identified robot; gravity
        [m/s^2], shape (3,); the URDF's name for messages.
    position_servos :
        ``{joint: {"kp", "forcerange"}}`` [N*m/rad, N*m or None]: a ``<position>`` actuator
        ``servo_<joint>``, ``kp (ctrl - q)`` clipped (``kv = 0``: ``kd`` is in the damping,
        ``kd + fv``, not separable); not in ``mj_inverse``'s ``qfrc_inverse``.

    Returns
    -------
    :
        MJCF text; MuJoCo compiles it without any mesh file, its moving joints are
        ``joint_names`` and its inverse dynamics is the URDF's (Pinocchio RNEA) plus
        ``armature ddq + damping dq`` (friction loss is a constraint: off in ``mj_inverse``
        with ``mjDSBL_CONSTRAINT``). Raises :class:`ModelError` (MuJoCo, joints differ).
    """
    text = mujoco_urdf(_with_bodies(urdf_text, bodies, source), dict(locked_joints or {}), source)
    spec = _spec(text, joint_names, source)
    _set_joint_extras(spec, joint_names, extras)
    _add_coupled_motors(spec, coupled_motors, joint_names, source)
    _add_position_servos(spec, position_servos or {}, joint_names, source)
    spec.option.gravity = np.asarray(gravity, dtype=float)
    root = ET.fromstring(spec.to_xml())
    _full_precision(root, _compile(spec, source))
    ET.indent(root, space="  ")
    return f"<!--{MJCF_NOTE}-->\n{ET.tostring(root, encoding='unicode')}\n"


def _set_joint_extras(
    spec: mujoco.MjSpec, joint_names: tuple[str, ...], extras: Mapping[str, Mapping[str, float]]
) -> None:
    """Each moving joint's ``armature``, ``damping`` and ``frictionloss`` from the sidecar's
    rotor inertia, viscous and Coulomb friction (0 where missing)."""
    for name in joint_names:
        joint = spec.joint(name)
        values = extras.get(name, {})
        joint.armature = float(values.get("rotor_inertia", 0.0))
        joint.damping = _vector_or_scalar(joint.damping, float(values.get("viscous", 0.0)))
        joint.frictionloss = float(values.get("coulomb", 0.0))


def _spec(text: str, joint_names: tuple[str, ...], source: str) -> mujoco.MjSpec:
    """MuJoCo's spec of the converted URDF ``text``, one body per link, its moving joints
    checked against ``joint_names`` (:func:`identified_mjcf`)."""
    try:
        spec = mujoco.MjSpec.from_string(text)
    except ValueError as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ModelError(f"{source}: MuJoCo cannot read the URDF ({first}).") from e
    spec.compiler.fusestatic = False
    names = [j.name for j in spec.joints]
    if sorted(names) != sorted(joint_names):
        raise ModelError(
            f"{source}: MuJoCo's moving joints ({', '.join(names)}) are not the identified "
            f"robot's ({', '.join(joint_names)}); lock the same joints."
        )
    return spec


def _add_coupled_motors(
    spec: mujoco.MjSpec,
    coupled_motors: Sequence[Mapping[str, Any]],
    joint_names: tuple[str, ...],
    source: str,
) -> None:
    """One fixed tendon ``q_a + q_b`` per coupled motor, with its armature, damping and
    friction loss (:func:`identified_mjcf`)."""
    for k, motor in enumerate(coupled_motors):
        pair = motor.get("joints")
        if not pair or any(name not in joint_names for name in pair):
            raise ModelError(
                f"{source}: coupled motor {motor.get('motor_joint')!r} has no joint pair; "
                "give the identification's coupled joints (coupled_pair)."
            )
        tendon = spec.add_tendon()
        tendon.name = f"coupled_motor_{k + 1}"
        for name in pair:
            tendon.wrap_joint(name, 1.0)
        tendon.armature = float(motor.get("rotor_inertia", 0.0))
        tendon.damping = _vector_or_scalar(tendon.damping, float(motor.get("viscous", 0.0)))
        tendon.frictionloss = float(motor.get("coulomb", 0.0))


def _add_position_servos(
    spec: mujoco.MjSpec,
    servos: Mapping[str, Mapping[str, float | None]],
    joint_names: tuple[str, ...],
    source: str,
) -> None:
    """One ``<position>`` actuator ``servo_<joint>`` per entry (:func:`identified_mjcf`)."""
    for name, values in servos.items():
        if name not in joint_names:
            raise ModelError(f"{source}: position servo of {name!r}: no such moving joint.")
        act = spec.add_actuator(
            name=f"servo_{name}", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT
        )
        act.set_to_position(kp=float(values["kp"] or 0.0), kv=0.0)
        limit = values.get("forcerange")
        if limit is not None:
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.forcerange = [-float(limit), float(limit)]


def _with_bodies(urdf_text: str, bodies: Mapping[str, npt.ArrayLike], source: str) -> str:
    """The URDF with the ``bodies`` as the only inertials (all other links massless)."""
    from ident.robot.inertia import URDF_INERTIA_ENTRIES, com_and_inertia

    root = ET.fromstring(urdf_text)
    links = {link.get("name"): link for link in root.findall("link")}
    missing = sorted(set(bodies) - set(links))
    if missing:
        raise ModelError(f"{source}: no link {', '.join(missing)} in the URDF.")
    for link in links.values():
        for element in link.findall("inertial"):
            link.remove(element)
    for name, params in bodies.items():
        mass, com, inertia = com_and_inertia(np.asarray(params, dtype=float))
        inertial = ET.SubElement(links[name], "inertial")
        ET.SubElement(inertial, "origin", xyz=_fmt(com), rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=_fmt(mass))
        ET.SubElement(
            inertial,
            "inertia",
            {key: _fmt(inertia[i, j]) for key, (i, j) in URDF_INERTIA_ENTRIES.items()},
        )
    return ET.tostring(root, encoding="unicode")


def _full_precision(root: ET.Element, model: mujoco.MjModel) -> None:
    """Rewrite the dynamics' numbers of MuJoCo's MJCF with the compiled model's (in place)."""
    option = root.find("option")
    if option is None:
        option = ET.Element("option")
        root.insert(1, option)
    option.set("gravity", _fmt(model.opt.gravity))
    for element in root.iter("body"):
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, element.get("name", ""))
        if i < 0:
            raise ModelError(f"MJCF: body {element.get('name')!r} not in the compiled model.")
        element.set("pos", _fmt(model.body_pos[i]))
        element.set("quat", _fmt(model.body_quat[i]))
        inertial = element.find("inertial")
        if inertial is None:
            inertial = ET.Element("inertial")
            element.insert(0, inertial)
        inertial.attrib.clear()
        inertial.set("pos", _fmt(model.body_ipos[i]))
        inertial.set("quat", _fmt(model.body_iquat[i]))
        inertial.set("mass", _fmt(model.body_mass[i]))
        inertial.set("diaginertia", _fmt(model.body_inertia[i]))
    for element in root.iter("fixed"):  # tendons
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, element.get("name", ""))
        if i < 0:
            raise ModelError(f"MJCF: tendon {element.get('name')!r} not in the compiled model.")
        element.set("armature", _fmt(model.tendon_armature[i]))
        element.set("damping", _fmt(model.tendon_damping[i]))
        element.set("frictionloss", _fmt(model.tendon_frictionloss[i]))
    for element in root.iter("position"):  # the servos: their gain at full precision
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, element.get("name", ""))
        if i < 0:
            raise ModelError(f"MJCF: actuator {element.get('name')!r} not in the compiled model.")
        element.set("kp", _fmt(model.actuator_gainprm[i, 0]))
        if model.actuator_forcelimited[i]:
            element.set("forcerange", _fmt(model.actuator_forcerange[i]))
    for element in root.iterfind("worldbody//joint"):  # not a tendon's <joint joint=...>
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, element.get("name", ""))
        if i < 0:
            raise ModelError(f"MJCF: joint {element.get('name')!r} not in the compiled model.")
        dof = model.jnt_dofadr[i]
        element.set("pos", _fmt(model.jnt_pos[i]))
        element.set("axis", _fmt(model.jnt_axis[i]))
        if model.jnt_limited[i]:
            element.set("range", _fmt(model.jnt_range[i]))
        element.set("damping", _fmt(model.dof_damping[dof]))
        element.set("armature", _fmt(model.dof_armature[dof]))
        element.set("frictionloss", _fmt(model.dof_frictionloss[dof]))


def with_joint_values(
    mjcf: str, values: Mapping[str, Mapping[str, float]], note: str | None = None
) -> str:
    """The MJCF text of :func:`identified_mjcf` with other joint values, its comments kept.

    ``values``: ``{joint: {attribute: value}}`` with attributes among ``frictionloss``,
    ``damping`` [N*m or N, N*m*s/rad or N*s/m] and ``armature`` [kg*m^2 or kg], written at full
    precision on the ``<joint>`` of that name (a ModelError for a joint the MJCF does not have);
    ``note``: a comment added after the file's first one (what changed and why).
    """
    head, sep, body = mjcf.partition("<mujoco")
    root = ET.fromstring(sep + body)
    joints = {j.get("name"): j for j in root.iterfind("worldbody//joint")}
    for name, attributes in values.items():
        if name not in joints:
            raise ModelError(f"MJCF: no joint {name!r} to set {', '.join(attributes)} on.")
        for key, value in attributes.items():
            if key not in ("frictionloss", "damping", "armature"):
                raise ModelError(f"MJCF: joint attribute {key!r} is not a joint extra.")
            joints[name].set(key, _fmt(value))
    ET.indent(root, space="  ")
    comment = "" if note is None else f"<!-- {note} -->\n"
    return f"{head}{comment}{ET.tostring(root, encoding='unicode')}\n"
