"""A dynamics-only MuJoCo model of a :class:`~ident.model.Robot`, joint for joint.

MuJoCo (``mujoco`` 4.0) compiles the robot's URDF text after these edits, so that its rigid-body
dynamics are exactly the Pinocchio model's (MuJoCo's inverse dynamics equals Pinocchio's RNEA to
about 1e-15 relative):

- ``<visual>`` and ``<collision>`` elements are dropped: no ``package://`` mesh has to resolve,
  and no inertia is computed from geometry (``inertiafromgeom="false"``), as in Pinocchio;
- the robot's locked joints become ``fixed`` joints whose origin includes the locked position
  (rotation ``q`` about the axis for a revolute joint, translation ``q`` along it for a prismatic
  one), as Pinocchio's reduced model does;
- ``<dynamics>`` is dropped; damping, armature and friction are set from the measurement
  config, never from the file;
- the ``<inertial>`` of a link fixed to the world (through fixed or locked joints) whose
  inertia MuJoCo refuses is dropped: no torque depends on it, and MuJoCo would refuse the whole
  file (TIAGo's base antennas; :func:`world_fixed_inertia_note` names them for the run's
  output); a refused inertia of a link that moves stays an error (:func:`inertia_problem`);
- a mimic joint of the robot's chain keeps its ``<mimic>``: MuJoCo's URDF import makes it a joint
  equality ``q_f = o + m q_l`` (``polycoef="o m 0 0 0"``), the only constraint left on (stiff:
  ``solref`` twice the timestep), so the follower moves with its leader and the leader's force is
  ``tau_l + m tau_f``; a locked follower is fixed like any locked joint;
- a payload of the measurement config (``measurement.payload``) is a body ``ident_payload``
  without joint (welded) added to its link's body in MuJoCo's spec (``MjSpec``), with the
  payload's mass, centre of mass and inertia;
- the actuators of the measurement config (``measurement.actuator``), when asked for, are added
  to the spec, one per robot joint, named ``ident_<joint>`` (:func:`_add_actuators`).

Compiled model settings: gravity from the Pinocchio model (``model.gravity``), contacts, joint
limits, equality constraints (but the mimic joints') and MuJoCo's friction loss off
(``mjDSBL_CONSTRAINT``, or ``mjDSBL_CONTACT`` and no limits with mimic joints), springs off
(``mjDSBL_SPRING``), semi-implicit Euler integration with explicit damping
(``mjDSBL_EULERDAMP``: the stored ``qacc`` is the acceleration that is integrated). Joints are
matched to the robot's by name; links fixed to the world are fused by MuJoCo (they do not move).
With ``native_friction`` the constraint solver stays on for the joints' friction loss
(``dof_frictionloss``, :func:`set_joint_parameters`); contacts and limits stay off.
"""

from __future__ import annotations

# xml.etree kept for mujoco_urdf, the URDF text edits made BEFORE MuJoCo's importer reads it:
# the <mujoco><compiler inertiafromgeom/balanceinertia/discardvisual> extension must be in the
# text the importer parses; a locked joint is folded into its URDF <origin> so MuJoCo computes
# the body frame from that rpy, as it does for the identified MJCF whose text must not change
# (identify/model_files/mjcf.py prints the compiled frames at full precision); and
# yourdfpy's write drops unknown elements (checked on example-robot-data's UR5: its 6
# <transmission>, 8 <gazebo> blocks and 24 comments are gone, rpy "0 0 0" becomes
# "0.0 -0.0 0.0"). The payload is added with MjSpec (_add_payload).
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field

import mujoco
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.errors import ModelError
from ident.measure.mujoco_config import ActuatorConfig, PayloadConfig, per_joint
from ident.measure.mujoco_log import route_mujoco_warnings
from ident.model import Robot
from ident.robot.inertia import com_and_inertia, urdf_inertia_tensor

route_mujoco_warnings()  # MuJoCo warnings as Python warnings, no MUJOCO_LOG.TXT

__all__ = [
    "FRICTION_SOLIMP",
    "JOINT_PARAMETER_FIELDS",
    "PAYLOAD_LINK",
    "MujocoRobot",
    "dynamics_only_urdf",
    "inertia_problem",
    "load_mujoco",
    "mujoco_urdf",
    "refused_inertias",
    "set_joint_parameters",
    "world_fixed_inertia_note",
    "world_fixed_links",
]

#: Name of the link that carries a simulated payload.
PAYLOAD_LINK = "ident_payload"

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

_ONE_DOF = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))

#: ident's per-joint parameters (``ident.dynamics.friction``'s names) and the MuJoCo ``MjModel``
#: field each one is, value for value: both SI and joint-side, the same quantity (revolute:
#: N*m*s/rad, N*m, kg*m^2; prismatic: N*s/m, N, kg). :func:`set_joint_parameters` writes them.
JOINT_PARAMETER_FIELDS = {"fv": "dof_damping", "fs": "dof_frictionloss", "Ia": "dof_armature"}

#: Impedance of the joints' friction-loss constraints (MuJoCo's ``dof_solimp``: dmin, dmax,
#: width, midpoint, power), with ``dof_solref = (2 h, 1)`` (time constant two timesteps, MuJoCo's
#: smallest stable one). A friction constraint sits at zero violation, so its impedance is
#: ``dmin``: 0.9999, MuJoCo's largest, lets a stuck joint creep by ``(1 - dmin) h a_free``
#: [rad/s] (a_free: its acceleration without friction), 1e-4 of MuJoCo's default's (0.9, time
#: constant 0.02 s: 0.02 rad/s on a 1-DoF test pendulum 2 N*m inside its friction band, and a
#: smooth transition 0.2 rad/s wide instead of a stick-slip switch within one step).
FRICTION_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)


@dataclass(frozen=True, eq=False)
class MujocoRobot:
    """A compiled MuJoCo model and the map from the robot's joints to its arrays.

    Attributes
    ----------
    model :
        The ``mujoco.MjModel`` (mutable: ``dof_damping``, ``dof_armature``, ``opt`` may be set).
    joint_names :
        The robot's joint names (``Robot.joint_names``), base to tip.
    qpos_index :
        ``qpos`` address of each robot joint, shape (nq,): ``data.qpos[qpos_index]`` is the
        robot's ``q``.
    dof_index :
        ``qvel``/``qacc``/force address of each robot joint, shape (nv,).
    mimic :
        Per mimic joint of the robot: its ``qpos`` address, ``qvel`` address, its leader's
        index in ``q``, multiplier and offset (:meth:`set_state` places it).
    actuator_index :
        Id of each robot joint's actuator, shape (nv,) (``data.ctrl[actuator_index]``,
        ``data.actuator_force[actuator_index]``); empty when none was added.
    """

    model: mujoco.MjModel
    joint_names: tuple[str, ...]
    qpos_index: IntArray
    dof_index: IntArray
    mimic: tuple[tuple[int, int, int, float, float], ...] = ()
    actuator_index: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def set_state(self, data: mujoco.MjData, q: FloatArray, dq: FloatArray) -> None:
        """Set the robot's joints to ``q, dq`` (nq,) and each mimic joint to ``m q_l + o``,
        ``m dq_l`` (on its equality constraint, so the simulation starts without a jolt)."""
        data.qpos[self.qpos_index] = q
        data.qvel[self.dof_index] = dq
        for qpos, dof, leader, multiplier, offset in self.mimic:
            data.qpos[qpos] = multiplier * q[leader] + offset
            data.qvel[dof] = multiplier * dq[leader]

    def start_control(self, data: mujoco.MjData, ctrl: FloatArray) -> None:
        """Set the actuators' control to ``ctrl`` (nv,) [N*m or rad], and, for delayed
        actuators, every sample of their history to it: the first steps then apply it, as if it
        had been held forever (MuJoCo's reset history holds zeros)."""
        data.ctrl[self.actuator_index] = ctrl
        for i, value in zip(self.actuator_index, np.asarray(ctrl, dtype=float), strict=True):
            n = int(self.model.actuator_history[i, 0])
            if n > 0:
                mujoco.mj_initCtrlHistory(self.model, data, int(i), None, np.full((n, 1), value))


def _origin(joint: ET.Element) -> tuple[FloatArray, FloatArray]:
    origin = joint.find("origin")
    xyz = np.zeros(3)
    rpy = np.zeros(3)
    if origin is not None:
        xyz = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
        rpy = np.array([float(v) for v in origin.get("rpy", "0 0 0").split()])
    return xyz, rpy


def _lock(joint: ET.Element, value: float) -> None:
    """Make ``joint`` fixed at ``value`` by folding the motion into its origin."""
    axis_element = joint.find("axis")  # URDF's default axis is x
    axis_text = axis_element.get("xyz", "1 0 0") if axis_element is not None else "1 0 0"
    axis = np.array([float(v) for v in axis_text.split()])
    axis = axis / np.linalg.norm(axis)
    xyz, rpy = _origin(joint)
    rotation = pin.rpy.rpyToMatrix(*rpy)
    if joint.get("type") == "prismatic":
        xyz = xyz + rotation @ (axis * value)
    else:  # revolute or continuous
        rotation = rotation @ pin.AngleAxis(value, axis).matrix()
        rpy = pin.rpy.matrixToRpy(rotation)
    origin = joint.find("origin")
    if origin is None:
        origin = ET.SubElement(joint, "origin")
    origin.set("xyz", " ".join(repr(float(v)) for v in xyz))
    origin.set("rpy", " ".join(repr(float(v)) for v in rpy))
    joint.set("type", "fixed")
    for tag in ("axis", "limit", "dynamics", "mimic", "safety_controller", "calibration"):
        for element in joint.findall(tag):
            joint.remove(element)


def dynamics_only_urdf(robot: Robot) -> str:
    """The robot's URDF text prepared for MuJoCo (see the module docstring).

    Raises
    ------
    ModelError
        If a locked joint is not in the URDF.
    """
    return mujoco_urdf(robot.urdf_text, robot.locked_joints, str(robot.urdf_path or robot.name))


def _principal_moments(inertia: ET.Element) -> tuple[FloatArray, bool]:
    """The eigenvalues [kg*m^2] of a URDF ``<inertia>`` (ascending, shape (3,)), and whether
    it has a nonzero product of inertia (MuJoCo's ``fullinertia`` then)."""
    matrix = urdf_inertia_tensor(inertia.attrib)
    products = bool(np.any(matrix[np.triu_indices(3, 1)] != 0.0))
    return np.linalg.eigvalsh(matrix).astype(np.float64), products


def world_fixed_links(urdf_text: str, locked_joints: Mapping[str, float] | None = None) -> set[str]:
    """The URDF's links that never move: the root link and every link joined to it through
    ``fixed`` joints or joints of ``locked_joints`` (names) only. No torque of the robot
    depends on their inertials (Pinocchio leaves them out of every body; MuJoCo fuses them into
    its world body)."""
    root = ET.fromstring(urdf_text)
    locked = set(locked_joints or {})
    children: dict[str, list[tuple[str, bool]]] = {}
    child_links = set()
    for joint in root.findall("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if parent is None or child is None:
            continue
        still = joint.get("type") == "fixed" or joint.get("name") in locked
        children.setdefault(str(parent.get("link")), []).append((str(child.get("link")), still))
        child_links.add(str(child.get("link")))
    todo = [str(link.get("name")) for link in root.findall("link")]
    todo = [name for name in todo if name not in child_links]  # the root link(s)
    fixed: set[str] = set()
    while todo:
        name = todo.pop()
        fixed.add(name)
        todo += [child for child, still in children.get(name, []) if still]
    return fixed


def refused_inertias(urdf_text: str) -> dict[str, FloatArray]:
    """The links whose ``<inertia>`` MuJoCo refuses, with their principal moments [kg*m^2]
    (ascending, shape (3,)): MuJoCo compiles every link of the file, also those that never
    move, and refuses an inertia with products of inertia whose principal moments are not all
    positive ("inertia must have positive eigenvalues", e.g. TIAGo's 1 mg antennas), or a
    negative principal moment. Pinocchio (the identification) accepts them."""
    bad: dict[str, FloatArray] = {}
    for link in ET.fromstring(urdf_text).findall("link"):
        inertia = link.find("inertial/inertia")
        if inertia is None:
            continue
        moments, products = _principal_moments(inertia)
        if moments[0] < 0.0 or (products and moments[0] <= 0.0):
            bad[str(link.get("name"))] = moments
    return bad


def _named(bad: Mapping[str, FloatArray]) -> str:
    """``'a' (m1, m2, m3), 'b' (...)``: links and their principal moments."""
    return ", ".join(f"'{k}' ({', '.join(f'{m:.3g}' for m in v)})" for k, v in bad.items())


def inertia_problem(
    urdf_text: str, where: str, locked_joints: Mapping[str, float] | None = None
) -> str:
    """Why MuJoCo would refuse the URDF's inertias of links that move ('' when it would not),
    one line naming the links and the fix (:func:`refused_inertias`). Links that never move
    (:func:`world_fixed_links`, ``locked_joints`` held) are not a problem: the simulation
    leaves their inertials out (:func:`world_fixed_inertia_note`)."""
    fixed = world_fixed_links(urdf_text, locked_joints)
    bad = {k: v for k, v in refused_inertias(urdf_text).items() if k not in fixed}
    if not bad:
        return ""
    return (
        f"{where}: MuJoCo refuses the inertia of {'links' if len(bad) > 1 else 'link'} "
        f"{_named(bad)} (principal moments [kg*m^2] not all positive); give "
        f"{'each' if len(bad) > 1 else 'it'} a positive definite <inertia> in the URDF "
        "(e.g. its ixy, ixz, iyz set to 0), or identify from a log (measurement.source: log)."
    )


def _left_out(urdf_text: str, locked_joints: Mapping[str, float] | None) -> dict[str, FloatArray]:
    """The links that never move whose inertia MuJoCo refuses: the simulation leaves their
    ``<inertial>`` out."""
    fixed = world_fixed_links(urdf_text, locked_joints)
    return {k: v for k, v in refused_inertias(urdf_text).items() if k in fixed}


def world_fixed_inertia_note(
    urdf_text: str, locked_joints: Mapping[str, float] | None = None
) -> str:
    """One line naming the links that never move whose inertia MuJoCo refuses, left out of the
    MuJoCo simulation (no torque depends on them), or '' when there are none (TIAGo: its
    base's two 1 mg antennas)."""
    bad = _left_out(urdf_text, locked_joints)
    if not bad:
        return ""
    return (
        f"the inertia{'s' if len(bad) > 1 else ''} of {_named(bad)} (principal moments "
        "[kg*m^2] not all positive, which MuJoCo refuses) left out of the MuJoCo simulation: "
        f"{'these links are' if len(bad) > 1 else 'the link is'} fixed to the world, so no "
        "torque depends on them; the identification reads the URDF as it is"
    )


def _add_payload(spec: mujoco.MjSpec, robot: Robot, payload: PayloadConfig, where: str) -> None:
    """Add the payload to ``spec`` as a body ``ident_payload`` without joint in the body of its
    link (default: the child of the robot's last moving joint), in that link's frame.

    A body without joint is welded to its parent: MuJoCo's ``fusestatic`` merges it as it merges
    a URDF fixed joint's child (the compiled inertias were checked bitwise equal to those of a
    ``<link>`` welded by a ``fixed`` ``<joint>`` in the URDF text, the former implementation).

    Raises
    ------
    ModelError
        If the payload's link is not a link of the URDF.
    """
    last = spec.joint(robot.joint_names[-1])
    parent = payload.link if payload.link is not None else (last.parent.name if last else None)
    # the URDF's links are the Pinocchio model's BODY frames (MuJoCo's spec also answers
    # "world" for its world body, which a URDF need not have)
    if parent is None or not robot.model.existBodyName(parent) or spec.body(parent) is None:
        raise ModelError(
            f"{where}: measurement.payload.link = {parent!r} is not a link of the URDF; "
            "name one of its links, or null for the last moving link."
        )
    mass, com, inertia = com_and_inertia(payload.parameters())
    spec.body(parent).add_body(
        name=PAYLOAD_LINK,
        mass=float(mass),
        ipos=np.asarray(com, dtype=float),
        fullinertia=[
            inertia[0, 0],
            inertia[1, 1],
            inertia[2, 2],
            inertia[0, 1],
            inertia[0, 2],
            inertia[1, 2],
        ],  # fmt: skip
    )


def _add_actuators(
    spec: mujoco.MjSpec, robot: Robot, actuator: ActuatorConfig, timestep_s: float
) -> None:
    """Add one actuator ``ident_<joint>`` per robot joint, in joint order (ids 0..nv-1 when the
    URDF has none), acting on the joint with gear 1:

    - ``motor``: force = control [N*m or N];
    - ``position``: force = ``kp (control - q) - kv dq`` (MuJoCo's ``<position>``: gain ``kp``,
      bias ``(0, -kp, -kv)``), the control a joint position [rad or m];
    - ``forcerange``: the force clipped to ``[-f, f]`` (``forcelimited``);
    - ``delay_steps = k > 0``: MuJoCo's actuator delay, a history of ``nsample = k`` controls
      read with zero-order hold at ``time - (k - 1/2) h``: the sample exactly ``k`` steps old,
      whatever the rounding of the accumulated ``time`` (a delay of exactly ``k h`` reads the
      sample before it once ``time`` rounds low, measured after 40 000 steps of 0.1 ms).
    """
    n = robot.nv
    kp = per_joint(actuator.kp if actuator.kp is not None else 0.0, n)
    kv = per_joint(actuator.kv if actuator.kv is not None else 0.0, n)
    limit = per_joint(actuator.forcerange, n) if actuator.forcerange is not None else None
    for j, name in enumerate(robot.joint_names):
        act = spec.add_actuator(
            name=f"ident_{name}", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT
        )
        if actuator.kind == "position":
            act.set_to_position(kp=float(kp[j]), kv=float(kv[j]))
        else:
            act.set_to_motor()
        if limit is not None:
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.forcerange = [-float(limit[j]), float(limit[j])]
        if actuator.delay_steps > 0:
            act.nsample = actuator.delay_steps
            act.interp = 0
            act.delay = (actuator.delay_steps - 0.5) * timestep_s


def _compile(
    robot: Robot,
    payload: PayloadConfig | None,
    actuator: ActuatorConfig | None = None,
    timestep_s: float = 0.001,
) -> mujoco.MjModel:
    """MuJoCo's model of :func:`dynamics_only_urdf`, with the payload and the actuators
    (:func:`load_mujoco`)."""
    where = str(robot.urdf_path or robot.name)
    try:
        spec = mujoco.MjSpec.from_string(dynamics_only_urdf(robot))
        if payload is not None:
            _add_payload(spec, robot, payload, where)
        if actuator is not None:
            _add_actuators(spec, robot, actuator, timestep_s)
        return spec.compile()
    except ValueError as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ModelError(f"{where}: MuJoCo cannot compile the URDF ({first}).") from e


def mujoco_urdf(urdf_text: str, locked_joints: Mapping[str, float], where: str) -> str:
    """URDF text prepared for MuJoCo: no geometry, locked joints fixed, no ``<dynamics>``, no
    inertial MuJoCo refuses on a link fixed to the world.

    The conversion of :func:`dynamics_only_urdf` for any URDF text (e.g. a written identified
    model): see the module docstring.

    Raises
    ------
    ModelError
        If a locked joint is not in the URDF.
    """
    left_out = _left_out(urdf_text, locked_joints)  # fixed to the world: no torque sees them
    root = ET.fromstring(urdf_text)
    for link in root.findall("link"):
        dropped = ("visual", "collision", "inertial") if link.get("name") in left_out else ()
        for tag in dropped or ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
    for element in root.findall("mujoco"):
        root.remove(element)
    joints = {joint.get("name"): joint for joint in root.findall("joint")}
    for name, value in locked_joints.items():
        if name not in joints:
            raise ModelError(f"{where}: locked joint {name!r} is not in the URDF.")
        _lock(joints[name], float(value))
    for joint in joints.values():  # a locked joint lost its <mimic>; a moving follower keeps it
        for element in joint.findall("dynamics"):
            joint.remove(element)
    compiler = ET.SubElement(ET.SubElement(root, "mujoco"), "compiler")
    compiler.set("inertiafromgeom", "false")
    compiler.set("balanceinertia", "false")
    compiler.set("discardvisual", "true")
    return ET.tostring(root, encoding="unicode")


def load_mujoco(
    robot: Robot,
    *,
    timestep_s: float = 0.001,
    payload: PayloadConfig | None = None,
    actuator: ActuatorConfig | None = None,
    native_friction: bool = False,
) -> MujocoRobot:
    """Compile the robot's dynamics-only MuJoCo model.

    Damping, armature and friction loss are zero; set them with :func:`set_joint_parameters`
    for a simulation.

    Parameters
    ----------
    robot :
        The robot (its URDF text, locked joints and gravity are used).
    timestep_s :
        MuJoCo timestep [s].
    payload :
        A payload welded to a link (see the module docstring), or None.
    actuator :
        Actuators to add, one per robot joint (:func:`_add_actuators`), or None (no actuator:
        forces go through ``qfrc_applied``).
    native_friction :
        Keep MuJoCo's constraint solver on for the joints' friction loss (contacts and joint
        limits stay off; the friction constraints get ``dof_solref = (2 h, 1)`` and
        :data:`FRICTION_SOLIMP`). False: no friction loss acts even when set.

    Returns
    -------
    :
        The model and the index maps of the robot's joints.

    Raises
    ------
    ModelError
        If MuJoCo cannot compile the URDF, or its moving joints differ from the robot's.
    """
    where = str(robot.urdf_path or robot.name)
    model = _compile(robot, payload, actuator, timestep_s)
    ids = _robot_joint_ids(model, robot, where)
    _set_dynamics_only(model, robot, timestep_s, native_friction)
    actuators = [] if actuator is None else [f"ident_{name}" for name in robot.joint_names]
    return MujocoRobot(
        model=model,
        joint_names=tuple(robot.joint_names),
        qpos_index=np.array([model.jnt_qposadr[i] for i in ids], dtype=np.int64),
        dof_index=np.array([model.jnt_dofadr[i] for i in ids], dtype=np.int64),
        mimic=_mimic_addresses(model, robot),
        actuator_index=np.array(
            [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in actuators],
            dtype=np.int64,
        ),
    )


def set_joint_parameters(mj: MujocoRobot, values: Mapping[str, FloatArray]) -> None:
    """Write ident's per-joint parameters into the MuJoCo model: the one map between them.

    ``values[kind]`` (nv,) for ``kind`` in :data:`JOINT_PARAMETER_FIELDS` (``fv`` viscous
    [N*m*s/rad], ``fs`` Coulomb [N*m], ``Ia`` rotor inertia [kg*m^2]; SI, joint side) goes
    unchanged to that field (``dof_damping``, ``dof_frictionloss``, ``dof_armature``) at the
    robot joints' dofs; a kind left out is not touched (zero after :func:`load_mujoco`). The
    MuJoCo model then simulates ``tau = RNEA + Ia ddq + fv dq + fs sign(dq)`` while a joint
    slides (``fs`` only with ``native_friction``); mimic followers keep zero.

    Raises
    ------
    KeyError
        For a kind that is not one of ident's joint parameters.
    """
    for kind, value in values.items():
        field_array = getattr(mj.model, JOINT_PARAMETER_FIELDS[kind])
        field_array[mj.dof_index] = np.asarray(value, dtype=float)


def _robot_joint_ids(model: mujoco.MjModel, robot: Robot, where: str) -> list[int]:
    """MuJoCo ids of the robot's joints, in its order; raises :class:`ModelError` when the
    moving joints differ (mimic followers aside) or one is not 1-DoF in MuJoCo."""
    mj_names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(model.njnt)]
    followers = {m.follower for m in robot.mimic_joints}
    extra = sorted(set(mj_names) - set(robot.joint_names) - followers)
    missing = sorted(set(robot.joint_names) - set(mj_names))
    if extra or missing:
        raise ModelError(
            f"{where}: MuJoCo's joints differ from the robot's: "
            + (f"not in the robot: {', '.join(extra)} (lock them); " if extra else "")
            + (f"not in MuJoCo: {', '.join(missing)}; " if missing else "")
            + "the simulator needs the same moving joints."
        )
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in robot.joint_names]
    for name, i in zip(robot.joint_names, ids, strict=True):
        if int(model.jnt_type[i]) not in _ONE_DOF:
            raise ModelError(f"{where}: joint {name!r} is not a 1-DoF joint in MuJoCo.")
    return ids


def _set_dynamics_only(
    model: mujoco.MjModel, robot: Robot, timestep_s: float, native_friction: bool = False
) -> None:
    """Options of a dynamics-only model: Euler at ``timestep_s`` [s], the robot's gravity, no
    springs, limits (position or actuator force), stiffness, damping, armature, friction loss or
    gravity compensation, constraints as :func:`_constraint_flags` sets them."""
    model.opt.timestep = timestep_s
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    model.opt.gravity[:] = np.asarray(robot.model.gravity.linear, dtype=float)
    model.opt.disableflags |= (
        mujoco.mjtDisableBit.mjDSBL_SPRING | mujoco.mjtDisableBit.mjDSBL_EULERDAMP
    )
    model.opt.disableflags |= _constraint_flags(model, timestep_s, native_friction)
    model.jnt_limited[:] = 0
    # MuJoCo's URDF import turns <limit effort> into the joint's actuator force range; only
    # measurement.actuator.forcerange saturates here
    model.jnt_actfrclimited[:] = 0
    model.jnt_stiffness[:] = 0.0
    model.dof_damping[:] = 0.0
    model.dof_armature[:] = 0.0
    model.dof_frictionloss[:] = 0.0
    model.body_gravcomp[:] = 0.0


def _constraint_flags(model: mujoco.MjModel, timestep_s: float, native_friction: bool) -> int:
    """Disable bits of the constraints: all of them, or, when mimic joints' equalities are in
    the model or the friction loss is native, contacts only (limits are off through
    ``jnt_limited``), with the equalities made stiff (``solref`` time constant twice the
    timestep, MuJoCo's smallest stable one) and the friction loss as :data:`FRICTION_SOLIMP`."""
    if model.neq == 0 and not native_friction:
        return int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    model.eq_solref[:] = [2.0 * timestep_s, 1.0]
    model.eq_solimp[:, :3] = [0.99, 0.999, 0.001]
    if native_friction:
        model.dof_solref[:] = [2.0 * timestep_s, 1.0]
        model.dof_solimp[:] = FRICTION_SOLIMP
    return int(mujoco.mjtDisableBit.mjDSBL_CONTACT)


def _mimic_addresses(
    model: mujoco.MjModel, robot: Robot
) -> tuple[tuple[int, int, int, float, float], ...]:
    """``(qpos, qvel address, leader index in q, multiplier, offset)`` per mimic joint."""
    out = []
    for mimic in robot.mimic_joints:
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, mimic.follower)
        leader = list(robot.joint_names).index(mimic.leader)
        out.append((int(model.jnt_qposadr[i]), int(model.jnt_dofadr[i]), leader,
                    mimic.multiplier, mimic.offset))  # fmt: skip
    return tuple(out)
