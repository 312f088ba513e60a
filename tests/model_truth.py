"""Torques of a run folder's identified model against the simulator's truth, on a trajectory
the run never saw (helpers of tests/test_model_default.py)."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import yaml

from ident.identify.model_files.urdf_update import model_of_urdf
from ident.model.selection import RobotSelection, load_robot


def unseen_trajectory(robot, *, seconds: float = 20.0, n: int = 2000, seed: int = 7):
    """A multi-sine (one frequency per joint, 0.05-0.25 Hz, random phase) inside the robot's
    position, velocity and acceleration limits: ``q, dq, ddq``, shapes (n, nv)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, seconds, n)[:, None]
    lo = np.clip(robot.q_lower, -np.pi, np.pi)
    hi = np.clip(robot.q_upper, -np.pi, np.pi)
    w = 2 * np.pi * rng.uniform(0.05, 0.25, robot.nv)
    amp = np.minimum.reduce(
        [0.4 * (hi - lo) / 2, 0.8 * robot.dq_max / w, 0.8 * robot.ddq_max / w**2]
    )
    phase = rng.uniform(0.0, 2 * np.pi, robot.nv)
    s, c = np.sin(w * t + phase), np.cos(w * t + phase)
    return (lo + hi) / 2 + amp * s, amp * w * c, -amp * w**2 * s


def rnea(model: pin.Model, q, dq, ddq) -> np.ndarray:
    data = model.createData()
    return np.array([pin.rnea(model, data, *s).copy() for s in zip(q, dq, ddq, strict=True)])


def truth_comparison(folder: Path) -> dict[str, float]:
    """Relative RMS (over samples and joints) of the written URDF's and MJCF's torques (plus
    the joint extras) against the truth's (the run's URDF inertials, the configured friction
    and armature) on :func:`unseen_trajectory`."""
    config = yaml.safe_load((folder / "config.yaml").read_text())
    result = json.loads((folder / "result.json").read_text())
    files = result["model"]["files"]
    robot = load_robot(RobotSelection(**config["robot"]))
    locked = robot.locked_joints
    q, dq, ddq = unseen_trajectory(robot)
    m = config["measurement"]
    n = robot.nv

    def per_joint(v):
        return np.broadcast_to(np.asarray(v, dtype=float), (n,))

    truth = rnea(model_of_urdf((folder / "robot.urdf").read_text(), locked), q, dq, ddq)
    truth += per_joint(m["armature"]) * ddq + per_joint(m["friction"]["viscous"]) * dq
    truth += per_joint(m["friction"]["coulomb"]) * np.sign(dq)

    extras = json.loads((folder / files["joint_extras"]).read_text())["joints"]
    names = robot.joint_names
    Ia, fv, fs, off = (
        np.array([extras[j][k] for j in names])
        for k in ("rotor_inertia", "viscous", "coulomb", "offset")
    )
    urdf = rnea(model_of_urdf((folder / files["urdf"]).read_text(), locked), q, dq, ddq)
    urdf += Ia * ddq + fv * dq + fs * np.sign(dq) + off

    mj = mujoco.MjModel.from_xml_path(str(folder / files["mjcf"]))
    mj.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT  # friction loss: added below
    ids = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, j) for j in names]
    qadr, dadr = [mj.jnt_qposadr[i] for i in ids], [mj.jnt_dofadr[i] for i in ids]
    data = mujoco.MjData(mj)
    mjcf = np.empty_like(truth)
    for k in range(len(q)):
        data.qpos[qadr], data.qvel[dadr], data.qacc[dadr] = q[k], dq[k], ddq[k]
        mujoco.mj_inverse(mj, data)
        mjcf[k] = data.qfrc_inverse[dadr]
    mjcf += fs * np.sign(dq) + off

    def rel(tau):
        return float(np.linalg.norm(tau - truth) / np.linalg.norm(truth))

    return {"urdf": rel(urdf), "mjcf": rel(mjcf)}
