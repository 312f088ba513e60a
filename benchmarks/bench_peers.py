"""Side by side with the peers: ``ident`` against ``mujoco.sysid`` on the same simulated logs.

    PYTHONPATH=src python benchmarks/bench_peers.py [--quick] [--robots ur5 panda]
        [--parts sysid ...] [--seeds 5] [--kinds ident mujoco] [--starts cad ident]
        [--records FILE] [--write-docs docs/benchmarks.md]

1. **Data.** The MuJoCo-simulated controller log of ``configs/<robot>.yaml`` (1 kHz computed-torque
   loop, viscous + Coulomb friction, armature, 2^19-count encoders, torque noise: the run's own
   ``measurement`` section, :func:`ident.measure.mujoco_sim.simulate`) on a fixed joint-space
   Fourier excitation of the config's family (the middle of its design box plus a seeded random
   offset; no optimizer, so the benchmark takes seconds to set up). The first 70 % of the samples
   identify (``validation.identify_fraction``), the last 30 % are held out.
2. **ident**: ``read_log`` + :func:`ident.identify_measurements` with the config's
   ``identification`` sections (WLS on base parameters; link inertias, armature, viscous and
   Coulomb friction).
3. **mujoco.sysid** (MuJoCo 4.0's rollout-based Gauss-Newton) at its best set-up: the same
   model built as an ``MjSpec`` from the same URDF, one ``InertiaType.Pseudo`` (log-Cholesky)
   parameter per moving body, ``armature``, ``damping`` and ``frictionloss`` per joint; the
   identification samples cut into windows of ``--window`` seconds (0.5), each rolled out open
   loop from the logged state (encoder position, central-difference velocity) under the logged
   torque and compared with the logged positions AND velocities, each joint's divided by the
   rollout objective's scale (its standard deviation over the whole log as ident filters it,
   :func:`ident.identify.assessment.rollout.log_motion_scale`); ``x_scale='jac'``; run to its own
   convergence (its ``xtol``/``gtol`` tests or no further reduction) under a cap of
   ``--max-iters`` (200), the iterations and the reason it stopped reported. Starts
   (``--starts``, :data:`SYSID_STARTS`): ``cad``, the URDF's nominal bodies (the simulator's:
   the CAD is exact) with every joint's armature, damping and frictionloss 1.5x its truth;
   ``ident``, ident's written model; ``bad-cad``, every mass 4x and centre of mass 8 cm off.
4. **The same yardsticks for both**, computed here once: each estimate is mapped to ``ident``'s
   standard parameters (Pinocchio's order per body, friction and armature per joint) and
   projected on the base parameters; torque error = ||prediction - commanded torque|| /
   ||commanded torque|| on the held-out states (the simulator's noise-free torque; the
   prediction is the identified model's inverse dynamics, rigid body + armature + viscous +
   Coulomb), base-parameter error = ||beta - beta_true|| / ||beta_true||; the held-out rollout
   objective J of :mod:`ident.identify.assessment.rollout` (open-loop MuJoCo rollouts under the
   measured torque, 0.5 s windows of the held-out part, ident's preprocessing) of each model
   written by ident's MJCF writer, on the same windows for every model, the truth included;
   CPU time of the call (``time.process_time``, every thread: ident reading the log + estimate,
   intervals, consistent model and its bootstrap; sysid ``optimize`` on one rollout thread),
   each tool's imports outside it.
5. **Logs of the duel** (``--parts sysid``, :func:`duel_case`): ``configs/<robot>.yaml``'s
   measurement as ident simulates it (Coulomb friction exactly ident's regressor column) and
   MuJoCo-native (``friction.semantics: mujoco``: frictionloss by the constraint solver),
   ``--seeds`` seeds each (excitation offset and noise); medians and worst over seeds
   (:func:`duel_table`). ``--records FILE`` keeps each case as a JSON line, so the full duel
   (2 robots x 2 kinds x 5 seeds x 2 sysid runs, hours of CPU) can run in pieces.
6. **Excitation** (``--parts excitation``, :func:`excitation_part`): ident's config-driven design
   at FIGAROH's UR10 truth-fixture settings (figaroh-examples ``examples/ur10/data/truth/
   manifest.json``: 10 s, 1000 samples at 100 Hz, ``|q - centre| <= 1.2`` rad, 0.7 x velocity
   and 0.8 x torque limits; ``benchmarks/data/figaroh_ur10_truth_train.json``) and on the 7-joint
   Panda (10 s, 1000 samples, 1 cm clearance), its condition number on FIGAROH's convention
   (raw SI base regressor of the 10 standard parameters per link; details above
   :func:`excitation_part`).
7. **FIGAROH's UR10 truth fixture** (``--parts ur10-truth``, ``benchmarks/peer_ur10_truth.py``):
   ident's written model, fitted on FIGAROH's training series with their ``low`` noise, against
   the noise-free truth on a validation series (goal 0.05 N*m, their tolerance 0.1 N*m), and
   FIGAROH's base OLS on the same samples when the ``peers`` extra is installed.

``--quick``: the UR5's ident-simulated log, one seed, mujoco.sysid from ident's model only, 3
optimizer iterations; the excitation at 100 samples, the UR10 truth on one seed, the long log on
30 s; no TX40 example. Default: one 10 s period (``--periods``; the configs log 3).
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import json
import os
import platform
import re
import resource
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin
import yaml
from mujoco import minimize

from ident.dynamics.friction import extra_columns
from ident.dynamics.parameter_model import ParameterModel
from ident.dynamics.regressor import joint_torque_regressor
from ident.identify.assessment.rollout import held_out_windows, motion_scale, rollout_score
from ident.identify.config import RefinementConfig
from ident.identify.model_files.files import save_identified_model
from ident.identify.model_files.fused_bodies import fused_bodies, parse_urdf
from ident.identify.model_files.mjcf import identified_mjcf
from ident.identify.pipeline.core import identify_measurements
from ident.identify.refinement.rollout_refinement import refinement_entry, refinement_text
from ident.measure.logs import read_log
from ident.measure.mujoco_model import FRICTION_SOLIMP, dynamics_only_urdf
from ident.measure.mujoco_sim import SimulatedLog, simulate, write_log
from ident.run.elite_identification import elite_trajectory
from ident.run.log_measurement import identify_config, true_parameters
from ident.run.setup import load_run

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
import peer_ur10_truth as ur10_truth  # noqa: E402
from bench_identify_long import PEAK_MB_SOURCE  # noqa: E402

FloatArray = np.ndarray


@dataclass
class ServoLog:
    """A log of position servos that log no torque, as mujoco.sysid gets it
    (``benchmarks/bench_servo.py --peer sysid``): the samples ``ident identify`` read.

    ``q``, ``q_cmd``: measured and commanded positions [rad], shapes (n, nv), on one uniform
    grid per ``segments`` ``[start, stop)`` (episodes); ``ranges``: the identification part's
    ``[lo, hi)`` samples (within segments, the held-out part and the trims left out); ``kp``
    [N*m/rad], ``kv`` [N*m*s/rad]: the servos' true gains, shapes (nv,); ``forcerange`` [N*m];
    ``delay_steps``: the command's delay in samples (MuJoCo's actuator delay, whole samples);
    ``kp_groups``: joints (indices) whose servos have one setting, one ``kp`` (and ``kv``)
    parameter each (ident's ``equal_kp``; None: one per joint); ``fold_kv``: no ``kv``
    parameter, the servos' ``kv`` 0 and the velocity gain in the joint damping (ident's
    ``kd + fv``: the log sees their sum only).
    """

    q: FloatArray
    q_cmd: FloatArray
    segments: list[tuple[int, int]]
    ranges: list[tuple[int, int]]
    kp: FloatArray
    kv: FloatArray
    forcerange: float
    delay_steps: int
    kp_groups: list[list[int]] | None = None
    fold_kv: bool = False


@dataclass
class Case:
    """One robot's simulated log and everything both tools need."""

    name: str
    setup: Any
    log: SimulatedLog  # a servo case's first episode: its truth and rate are every episode's
    n_identify: int  # samples of the identification part (the first ones; torque logs)
    servo: ServoLog | None = None  # position servos: sysid's controls are the commands


@dataclass
class ToolRun:
    """One tool's estimate over ``pm.names`` with its cost."""

    tool: str
    x: FloatArray  # (n_all,) standard parameters + friction/armature, ident's names
    wall_s: float
    peak_mb: float
    note: str = ""
    cpu_s: float = float("nan")  # process CPU time of the call [s] (every thread)
    info: dict[str, Any] = dataclasses.field(default_factory=dict)


def _peak_rss_mb() -> float:
    """Peak resident set of this process [MB] (Linux reports kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


#: The simulated logs (``--kinds``): ``ident``, the configs' own ``measurement`` (Coulomb
#: friction as ident's ``fs sign(dq)``, exactly ident's regressor column); ``mujoco``, the same
#: with ``friction.semantics: mujoco`` (MuJoCo's frictionloss, solved by its constraint solver:
#: sysid's model class, not ident's).
LOG_KINDS = ("ident", "mujoco")


def make_case(name: str, *, periods: int = 1, seed: int = 0, kind: str = "ident") -> Case:
    """Simulate ``periods`` 10 s periods of ``configs/<name>.yaml``'s log on a fixed excitation
    (module docstring), with the friction of ``kind`` (:data:`LOG_KINDS`)."""
    setup = load_run(ROOT / "configs" / f"{name}.yaml")
    config = setup.config
    m = config.measurement.model_copy(update={"n_periods": periods})
    if kind == "mujoco":
        friction = m.friction.model_copy(update={"semantics": "mujoco"})
        m = m.model_copy(update={"friction": friction})
    config = config.model_copy(update={"measurement": m})
    setup = dataclasses.replace(setup, config=config)
    bounds = setup.bounds
    rng = np.random.default_rng(seed)
    x = bounds.mean(axis=1) + 0.25 * (bounds[:, 1] - bounds[:, 0]) * rng.uniform(
        -1, 1, bounds.shape[0]
    )
    t, q, dq, ddq, _ = elite_trajectory(setup.family, x)
    log = simulate(setup.robot, t, q, dq, ddq, config.measurement, rng=seed)
    frac = config.identification.validation.identify_fraction
    return Case(name=name, setup=setup, log=log, n_identify=int(frac * log.n_samples))


# ---------------------------------------------------------------------------------------------
# ident


#: Cases run_ident identified in this process (its first call pays the first-call costs).
_IDENT_CALLS: list[str] = []


def run_ident(case: Case) -> tuple[ToolRun, Any]:
    """Read the log as ``ident identify`` does and identify it; the estimate over pm.names."""
    robot = case.setup.robot
    with tempfile.TemporaryDirectory(prefix="bench-peers-") as tmp:
        files = write_log(tmp, case.log)
        section = yaml.safe_load(files.yaml.read_text(encoding="utf-8"))
        log_section = dict(section["log"])
        for key in ("time", "position", "torque"):
            if isinstance(log_section.get(key), dict):
                log_section[key] = {
                    **log_section[key],
                    "path": str(Path(tmp) / log_section[key]["path"]),
                }
        section = {**section, "log": log_section}
        cfg = identify_config(case.setup.config, section)
        # imports outside the timed call, as sysid's: ident imports cvxpy (its LMI) lazily
        t_import = time.perf_counter()
        import cvxpy  # noqa: F401

        t_import = time.perf_counter() - t_import
        rss0 = _peak_rss_mb()
        c0, t0 = time.process_time(), time.perf_counter()
        read = read_log(cfg.log, cfg.transmission, robot.joint_names, source=str(files.yaml))
        result = identify_measurements(cfg, read, model=robot.model)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        peak = _peak_rss_mb() - rss0
    pm = result.parameters
    # the base estimate, expressed back on pm.names through the base map's independent columns
    x = np.zeros(len(pm.names))
    x[np.asarray(pm.base.independent)] = result.estimate.x
    held = result.predictions.get("identified")
    parts = ", ".join(
        f"{k} {v:.2f}" for k, v in result.timings.items() if k not in ("total", "read") and v > 0.01
    )
    _IDENT_CALLS.append(case.name)
    which = "first call" if len(_IDENT_CALLS) == 1 else f"call {len(_IDENT_CALLS)}"
    note = (
        f"{which} in the process (numba kernels loaded from their on-disk cache; compiling "
        f"them, once per installation, is not included); import of cvxpy {t_import:.2f} s, "
        f"outside the call as sysid's imports; the call's stages [s]: {parts}"
    )
    if held is not None:
        note += (
            "; ident's own held-out figure (its filtered states, rows above the velocity "
            f"threshold): {held.metrics.total_relative_residual:.4f}"
        )
    return ToolRun("ident", x, wall, peak, note, cpu_s=cpu), result


def ident_refined_model(
    result: Any, rollout: float, truth_rollout: float
) -> tuple[mujoco.MjModel, dict]:
    """ident's written model after ``refinement: rollout`` (its joints' frictionloss, damping
    and armature refined on rollouts of the identification part, accepted only when the
    held-out rollout objective and torque error do not get worse:
    :func:`ident.identify.refinement.rollout_refinement.refinement_entry`), loaded, and the
    refinement's ``result.json`` entry (``cpu_s`` its CPU). ``rollout``, ``truth_rollout``:
    the held-out objectives of ident's written model and of the truth (the entry's reference),
    scored by the caller on the same windows."""
    config = result.config.model_copy(update={"refinement": RefinementConfig(method="rollout")})
    refined = dataclasses.replace(result, config=config)
    with tempfile.TemporaryDirectory(prefix="bench-peers-refined-") as tmp:
        entry = save_identified_model(refined, tmp)
        if not entry["written"]:
            raise RuntimeError(f"ident wrote no model: {entry['note']}")
        mjcf = Path(tmp) / entry["files"]["mjcf"]
        check = {"objective": rollout, "reference": "truth", "reference_objective": truth_rollout}
        refinement = refinement_entry(refined, Path(tmp), entry, check)
        return mujoco.MjModel.from_xml_path(str(mjcf)), refinement


def ident_written_model(result: Any) -> mujoco.MjModel:
    """ident's written model (the MJCF ``ident identify`` writes: its consistent bodies,
    armature, viscous and Coulomb friction as MuJoCo's frictionloss), loaded."""
    with tempfile.TemporaryDirectory(prefix="bench-peers-model-") as tmp:
        entry = save_identified_model(result, tmp)
        if not entry["written"]:
            raise RuntimeError(f"ident wrote no model: {entry['note']}")
        return mujoco.MjModel.from_xml_path(str(Path(tmp) / entry["files"]["mjcf"]))


# ---------------------------------------------------------------------------------------------
# mujoco.sysid


def sysid_spec(case: Case) -> tuple[mujoco.MjSpec, list[str], list[str]]:
    """The robot as an MjSpec for mujoco.sysid: motors (a servo case: ``<position>`` servos,
    :func:`_add_actuator`), joint-position and velocity sensors, fused bodies.

    Same URDF text as ident's simulator (:func:`dynamics_only_urdf`), same timestep, integrator
    and gravity; contacts and joint limits off; constraints on (``frictionloss`` is one). Bodies
    rigidly fixed to a moving body are fused into it here (their inertia written on the moving
    body, the body deleted) so that a parameter of the moving body is its whole inertia.
    Returns the spec, the moving bodies (one per joint) and the joint names.
    """
    robot = case.setup.robot
    spec = mujoco.MjSpec.from_string(dynamics_only_urdf(robot))
    model = spec.compile()
    joints = list(robot.joint_names)
    bodies = [model.body(int(model.joint(j).bodyid[0])).name for j in joints]
    for b in bodies:  # the compiled (fused) inertia, written explicitly on the spec's body
        mb, sb = model.body(b), spec.body(b)
        sb.mass = float(mb.mass[0])
        sb.ipos = np.array(mb.ipos)
        sb.iquat = np.array(mb.iquat)
        sb.inertia = np.array(mb.inertia)
        sb.fullinertia = np.full(6, np.nan)  # the URDF's full tensor would override
        sb.explicitinertial = True
    for b in bodies:
        for child in list(spec.body(b).bodies):
            if not child.joints:
                spec.delete(child)
    spec.option.timestep = 1.0 / case.log.rate_hz
    # an iterate whose principal inertias miss A + B >= C by rounding (a thin link near a
    # bound) stops the compiler; its message's fix, which leaves a valid inertia as it is
    spec.compiler.balanceinertia = True
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    spec.option.gravity = np.asarray(robot.model.gravity.linear, dtype=float)
    spec.option.disableflags |= (
        mujoco.mjtDisableBit.mjDSBL_CONTACT
        | mujoco.mjtDisableBit.mjDSBL_SPRING
        | mujoco.mjtDisableBit.mjDSBL_EULERDAMP
    )
    for j in joints:
        sj = spec.joint(j)
        sj.limited = mujoco.mjtLimited.mjLIMITED_FALSE
        for attr in ("armature", "damping", "frictionloss"):
            set_joint(sj, attr, 0.0)
    for k, j in enumerate(joints):
        _add_actuator(spec, j, case.servo, k)
    # all positions, then all velocities: the sensor columns of the windows' measured data
    for kind, sensor in (
        ("pos", mujoco.mjtSensor.mjSENS_JOINTPOS),
        ("vel", mujoco.mjtSensor.mjSENS_JOINTVEL),
    ):
        for j in joints:
            spec.add_sensor(
                name=f"{j}_{kind}", type=sensor, objname=j, objtype=mujoco.mjtObj.mjOBJ_JOINT
            )
    return spec, bodies, joints


def _add_actuator(spec: mujoco.MjSpec, joint: str, servo: ServoLog | None, k: int) -> None:
    """Joint ``joint``'s actuator ``<joint>_motor``: a torque motor, or (``servo``, joint
    ``k``) the simulated servo's model class, MuJoCo's ``<position>`` (its true gains here;
    the parameters set them), force range and command delay of ``servo.delay_steps`` samples
    read with zero-order hold, and the friction loss's stiff constraint, as
    :mod:`ident.measure.mujoco_model` builds the simulator's (sysid's model class is then the
    truth's: the most it could be given)."""
    act = spec.add_actuator(name=f"{joint}_motor", target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    if servo is None:
        return
    sj = spec.joint(joint)
    sj.solref_friction = [2.0 * float(spec.option.timestep), 1.0]
    sj.solimp_friction = list(FRICTION_SOLIMP)
    act.set_to_position(kp=float(servo.kp[k]), kv=0.0 if servo.fold_kv else float(servo.kv[k]))
    act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    act.forcerange = [-servo.forcerange, servo.forcerange]
    if servo.delay_steps > 0:
        act.nsample, act.interp = servo.delay_steps, 0
        act.delay = (servo.delay_steps - 0.5) * float(spec.option.timestep)


def set_joint(joint: Any, attr: str, value: float) -> None:
    """Set a joint's armature, frictionloss or (linear) damping on an MjSpec joint."""
    if attr == "damping":  # MuJoCo 4: [linear, ...] coefficients; the first is viscous damping
        d = np.zeros(3)
        d[0] = value
        joint.damping = d
    else:
        setattr(joint, attr, value)


def _theta_modifier(body_name: str) -> Any:
    """sysid's log-Cholesky write (``apply_body_theta_inertia``) without its first step.

    ``mujoco.sysid`` recompiles the spec with ``inertiafromgeom="true"`` before writing theta
    (``_infer_inertial``): on a geometry-free dynamics model every body then weighs zero and the
    compiler refuses it. This writes the same theta -> (mass, CoM, inertia) map directly.
    """
    from mujoco.sysid._src.model_modifier import pi_from_theta, skew

    def modify(spec: mujoco.MjSpec, param: Any) -> None:
        pi = pi_from_theta(np.asarray(param.value, dtype=float))
        body = spec.body(body_name)
        body.explicitinertial = True
        body.mass = pi[0]
        body.ipos = pi[1:4] / pi[0]
        body.inertia = np.zeros(3)
        body.iquat = np.array([1.0, 0.0, 0.0, 0.0])  # (NaN, as sysid writes, fails to compile)
        S = skew(np.asarray(body.ipos))
        full = pi[4:].reshape(3, 3) + pi[0] * S @ S
        body.fullinertia = np.array(
            [full[0, 0], full[1, 1], full[2, 2], full[0, 1], full[0, 2], full[1, 2]]
        )

    return modify


#: mujoco.sysid's starting models (``--starts``). ``cad``: the URDF's nominal bodies (which are
#: the simulator's: a CAD that is exact) with every joint's armature, damping and frictionloss
#: at :data:`JOINT_TERM_START` x its truth; ``ident``: ident's written model (its MJCF: bodies,
#: armature, viscous and Coulomb friction); ``bad-cad``: every mass 4x, every centre of mass
#: 8 cm off (outside the +-5 cm box sysid's parameter is then given), joint terms as ``cad``.
#: On a servo log (:class:`ServoLog`) ``cad`` has the joint terms off (the URDF as a user has
#: it) and ``near-cad`` has them at :data:`JOINT_TERM_START` x the truth (``cad`` on a torque
#: log); the gains start at that factor x the truth in both. ``datasheet`` (servo logs): the
#: URDF's bodies, the armature and the gains at that factor x the truth (a servo's datasheet:
#: rotor inertia x gear ratio^2, its P and D settings, 50 % off), no friction.
SYSID_STARTS = ("cad", "ident", "bad-cad", "near-cad", "datasheet")
#: Rollout threads of sysid's residual (its default: every core).
SYSID_THREADS = 2
#: The CAD start's joint terms over their truth (50 % off).
JOINT_TERM_START = 1.5
#: sysid's joint terms and the log's truth keys (``case.log.truth``).
JOINT_TERMS = (("armature", "armature"), ("damping", "viscous"), ("frictionloss", "coulomb"))


def _start_spec(
    spec: mujoco.MjSpec, bodies: list[str], start: str, ident_model: mujoco.MjModel | None
) -> mujoco.MjSpec:
    """A copy of ``spec`` with the bodies of ``start`` (:data:`SYSID_STARTS`)."""
    bad = spec.copy()
    if start == "ident":
        assert ident_model is not None, "the ident start needs ident's model"
        for b in bodies:
            mb, sb = ident_model.body(b), bad.body(b)
            sb.mass = float(mb.mass[0])
            sb.ipos, sb.iquat = np.array(mb.ipos), np.array(mb.iquat)
            sb.inertia = np.array(mb.inertia)
        return bad
    mass, shift = {"bad-cad": (4.0, 0.08)}.get(start, (1.0, 0.0))
    for b in bodies:
        sb = bad.body(b)
        sb.mass = sb.mass * mass
        sb.inertia = np.array(sb.inertia) * mass
        sb.ipos = np.array(sb.ipos) + shift
    return bad


def _joint_start(
    case: Case, start: str, ident_model: mujoco.MjModel | None
) -> dict[tuple[str, str], float]:
    """``{(joint, attr): value}``: the joint terms sysid starts from (:data:`SYSID_STARTS`)."""
    joints, truth = list(case.setup.robot.joint_names), case.log.truth
    out = {}
    for k, j in enumerate(joints):
        for attr, key in JOINT_TERMS:
            if start == "ident":
                assert ident_model is not None
                d = int(ident_model.joint(j).dofadr[0])
                out[j, attr] = float(getattr(ident_model, f"dof_{attr}")[d])
            elif case.servo is not None and start == "cad":  # the URDF's: no joint terms
                out[j, attr] = 0.0
            elif start == "datasheet":  # the rotor's inertia only
                out[j, attr] = JOINT_TERM_START * float(truth[key][k]) * (attr == "armature")
            else:
                out[j, attr] = JOINT_TERM_START * float(truth[key][k])
            if case.servo is not None and case.servo.fold_kv and start != "ident":
                # the velocity gain's start (ident's model has it in its damping already)
                out[j, attr] += JOINT_TERM_START * float(case.servo.kv[k]) * (attr == "damping")
    return out


class _BudgetSpent(Exception):
    """Raised by run_sysid's iteration callback when its CPU budget is spent."""


@dataclass
class SysidProblem:
    """mujoco.sysid's problem on a case: its spec, start and true parameters, residual."""

    spec: mujoco.MjSpec
    joints: list[str]
    params: Any  # sysid.ParameterDict at the start
    truth: Any  # sysid.ParameterDict at the simulator's truth
    residual_fn: Any
    n_windows: int

    def objective(self, params: Any) -> float:
        """sysid's objective ``0.5 ||r||^2`` at ``params``."""
        r = self.residual_fn(params.as_vector(), params.copy())[0]
        return 0.5 * float(np.sum(np.concatenate(r) ** 2))


def _sysid_params(
    case: Case,
    spec: mujoco.MjSpec,
    bodies: list[str],
    start: str,
    ident_model: mujoco.MjModel | None,
) -> tuple[Any, Any]:
    """sysid's parameters at the start and at the truth: one log-Cholesky inertia per moving
    body, armature, damping and frictionloss per joint in a box of the robot's largest truth."""
    from mujoco import sysid  # optional: the `peers` extra (absl-py, colorama, tabulate)

    start_spec = _start_spec(spec, bodies, start, ident_model)
    start_model = start_spec.compile()
    truth = case.log.truth
    params = sysid.ParameterDict()
    ipos_box = 0.05 if start == "bad-cad" else 0.5
    for b in bodies:
        p = sysid.body_inertia_param(
            start_spec,
            start_model,
            b,
            sysid.InertiaType.Pseudo,
            ipos_bound_off=np.array([-ipos_box, ipos_box]),
            modifier=_theta_modifier(b),
        )
        params.add(p)
    limits = {
        "armature": (1e-4, 2.0 * float(np.max(truth["armature"])) + 0.1),
        "damping": (0.0, 2.0 * float(np.max(truth["viscous"])) + 1.0),
        "frictionloss": (0.0, 2.0 * float(np.max(truth["coulomb"])) + 1.0),
    }
    for (j, attr), value in _joint_start(case, start, ident_model).items():
        lo, hi = limits[attr]

        def modify(s: mujoco.MjSpec, p: Any, j: str = j, attr: str = attr) -> None:
            set_joint(s.joint(j), attr, float(p.value[0]))

        params.add(
            sysid.Parameter(f"{j}_{attr}", float(np.clip(value, lo, hi)), lo, hi, modifier=modify)
        )
    model = spec.compile()
    # the truth in sysid's parameters, read before the optimizer rewrites the spec's inertials
    truth_params = params.copy()
    for b in bodies:
        truth_params[f"{b}_inertia"].value = sysid.body_inertia_param(
            spec.copy(), model, b, sysid.InertiaType.Pseudo
        ).value
    for k, j in enumerate(case.setup.robot.joint_names):
        for attr, key in JOINT_TERMS:
            value = float(truth[key][k])
            if case.servo is not None and case.servo.fold_kv and attr == "damping":
                value += float(case.servo.kv[k])
            truth_params[f"{j}_{attr}"].value = np.array([value])
    if case.servo is not None:
        joints = list(case.setup.robot.joint_names)
        start_gains = _servo_start(case.servo, joints, ident_model if start == "ident" else None)
        _servo_params(case.servo, start_gains, params, truth_params)
    return params, truth_params


def _servo_start(
    servo: ServoLog, joints: list[str], ident_model: mujoco.MjModel | None
) -> dict[str, dict[str, float]]:
    """``{joint: {"kp", "kv"}}``: the servo gains sysid starts from: :data:`JOINT_TERM_START`
    x the truth (a datasheet's figure, 50 % off), or (``ident_model``, the ``ident`` start)
    ident's written ``<position>`` servos ``servo_<joint>`` (``kv = 0``: its ``kd`` is in the
    joint damping, which sysid starts from too)."""
    if ident_model is None:
        return {
            j: {
                "kp": JOINT_TERM_START * float(servo.kp[k]),
                "kv": JOINT_TERM_START * float(servo.kv[k]),
            }
            for k, j in enumerate(joints)
        }
    out = {}
    for j in joints:
        a = int(ident_model.actuator(f"servo_{j}").id)
        gain, bias = ident_model.actuator_gainprm[a, 0], ident_model.actuator_biasprm[a, 2]
        out[j] = {"kp": float(gain), "kv": float(-bias)}
    return out


def _servo_params(
    servo: ServoLog, start: dict[str, dict[str, float]], params: Any, truth: Any
) -> None:
    """Add the ``<position>`` servos' ``kp`` and ``kv`` (sysid's ``apply_pgain``,
    ``apply_dgain``; no ``kv`` with ``servo.fold_kv``) to ``params`` at ``start``
    (:func:`_servo_start`; a group of ``servo.kp_groups``, its first joint's) and to ``truth``
    at the truth; one parameter per joint or group (``<joint>_kp``, ``<j1>+<j2>_kp``), boxes
    from 0 to 3x the largest true gain."""
    from mujoco import sysid
    from mujoco.sysid._src.model_modifier import apply_dgain, apply_pgain

    joints = list(start)
    groups = servo.kp_groups or [[k] for k in range(len(joints))]
    gains = [("kp", servo.kp, apply_pgain)] + (
        [] if servo.fold_kv else [("kv", servo.kv, apply_dgain)]
    )
    for name, values, write in gains:
        hi = 3.0 * float(np.max(values))
        for group in groups:
            motors = [f"{joints[k]}_motor" for k in group]

            def modify(s: mujoco.MjSpec, p: Any, motors: list = motors, write: Any = write) -> None:
                for motor in motors:
                    write(s, motor, float(p.value[0]))

            label = "+".join(joints[k] for k in group) + f"_{name}"
            value = float(np.clip(start[joints[group[0]]][name], 0.0, hi))
            params.add(sysid.Parameter(label, value, 0.0, hi, modifier=modify))
            true = float(values[group[0]])
            truth.add(sysid.Parameter(label, true, 0.0, hi, modifier=modify))


def _sysid_samples(case: Case) -> tuple[FloatArray, FloatArray, FloatArray, list[tuple[int, int]]]:
    """What sysid gets of the log: encoder positions ``q`` [rad], their central differences
    ``dq`` [rad/s] (within each segment), the controls (the logged torque [N*m]; a servo case:
    the commanded positions [rad]), shapes (n, nv), and the identification part's ``[lo, hi)``
    sample ranges (a torque log: its first ``n_identify`` samples)."""
    dt = 1.0 / case.log.rate_hz
    if case.servo is None:
        q = np.asarray(case.log.q)
        ranges = [(0, case.n_identify)]
        return q, np.gradient(q, dt, axis=0), np.asarray(case.log.tau_measured), ranges
    servo = case.servo
    q = np.asarray(servo.q)
    dq = np.concatenate([np.gradient(q[a:b], dt, axis=0) for a, b in servo.segments])
    return q, dq, np.asarray(servo.q_cmd), list(servo.ranges)


def _initial_state(
    model: mujoco.MjModel, q: FloatArray, dq: FloatArray, control: FloatArray, i0: int
) -> FloatArray:
    """sysid's initial state of a window starting at sample ``i0`` (its time 0): the logged
    position and velocity, and each delayed actuator's history holding the ``nsample``
    commands before ``i0`` at times ``-nsample h .. -h`` (what the servo was executing)."""
    from mujoco import sysid

    state = sysid.create_initial_state(model, q[i0], dq[i0])
    if not np.any(model.actuator_history[:, 0] > 0):
        return state
    data = mujoco.MjData(model)
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
    mujoco.mj_setState(model, data, state, full)
    h = model.opt.timestep
    for i in range(model.nu):
        n = int(model.actuator_history[i, 0])
        if n > 0:
            times = (np.arange(n) - n).astype(float)[:, None] * h
            values = np.ascontiguousarray(control[i0 - n : i0, i : i + 1])
            mujoco.mj_initCtrlHistory(model, data, i, times, values)
    mujoco.mj_getState(model, data, state, full)
    return state


def sysid_scorable(q: FloatArray, dq: FloatArray, i0: int, n_win: int) -> bool:
    """Whether sysid can score the window of ``n_win`` samples from ``i0``: its residual is
    divided by each sensor's norm over the window's measured samples after the first
    (``normalize_residual``; the first is the initial condition), so a joint that sticks for
    the whole window (its encoder velocity exactly 0: MuJoCo's friction loss holds it) makes
    the objective NaN and the solve fail at its first factorization. Such windows are left out
    of sysid's windows (the Panda's MuJoCo-native log, seed 0: the first, joint 5 stuck)."""
    measured = np.hstack([q[i0 + 2 : i0 + n_win + 1], dq[i0 + 2 : i0 + n_win + 1]])
    return bool(np.all(np.linalg.norm(measured, axis=0) > 0))


def sysid_problem(
    case: Case,
    *,
    start: str,
    window_s: float,
    ident_model: mujoco.MjModel | None = None,
    max_windows: int | None = None,
    scale: FloatArray | None = None,
    velocity_weight: float = 1.0,
) -> SysidProblem:
    """mujoco.sysid's parameters, windows and residual on the identification samples.

    Windows of ``window_s`` seconds (at most ``max_windows``, the first ones) within the
    identification part's ranges (:func:`_sysid_samples`), each rolled out open loop from the
    logged state (encoder position, central-difference velocity; a delayed servo's history of
    commands, :func:`_initial_state`) under the logged torque (a servo case: the commanded
    positions); the residual is the positions and velocities at every following sample, each
    joint's divided by ``scale`` (2, nv): rows ``sd_q``, ``sd_dq`` in ``case``'s joint order,
    the rollout objective's (:func:`ident.identify.assessment.rollout.log_motion_scale` of
    ident's identification, so sysid minimises the objective it is scored on); None: the
    same formula (:func:`motion_scale`) over every sample sysid gets of the log. The
    velocities' weights are times ``velocity_weight`` (0: positions only).
    """
    from mujoco import sysid

    spec, bodies, joints = sysid_spec(case)
    params, truth_params = _sysid_params(case, spec, bodies, start, ident_model)
    model = spec.compile()
    n_win = max(2, int(round(window_s * case.log.rate_hz)))
    dt = 1.0 / case.log.rate_hz
    q, dq, control, ranges = _sysid_samples(case)
    scale = motion_scale(q, dq) if scale is None else np.asarray(scale, dtype=float)
    weights = 1.0 / scale.ravel()  # sensor order: positions, then velocities
    weights[q.shape[1] :] *= velocity_weight
    starts = [i0 for lo, hi in ranges for i0 in range(lo, hi - n_win - 1, n_win)]
    starts = [i0 for i0 in starts if sysid_scorable(q, dq, i0, n_win)]
    states, controls, sensors, names = [], [], [], []
    for k, i0 in enumerate(starts[:max_windows]):
        states.append(_initial_state(model, q, dq, control, i0))
        tc = np.arange(n_win) * dt
        controls.append(sysid.TimeSeries(tc, control[i0 : i0 + n_win]))
        measured = np.hstack([q[i0 + 1 : i0 + n_win + 1], dq[i0 + 1 : i0 + n_win + 1]])
        sensors.append(sysid.TimeSeries.from_names(tc + dt, measured, model))
        names.append(f"w{k}")
    seqs = sysid.ModelSequences(case.name, spec, names, states, controls, sensors)
    # CPU time is what is compared (every thread's), so the thread count changes the wall only
    residual_fn = sysid.build_residual_fn(
        models_sequences=[seqs], sensor_weights=weights, n_threads=SYSID_THREADS
    )
    return SysidProblem(spec, joints, params, truth_params, residual_fn, len(names))


#: sysid's stages (``run_sysid(stages=...)``): ``all`` frees every parameter; ``joints``
#: keeps the links at the start's (frozen) and frees the joint terms and the servo gains.
SYSID_STAGE_FREE = {"all": "every parameter", "joints": "the joint terms and gains, links fixed"}


def run_sysid(
    case: Case,
    pm: ParameterModel,
    *,
    start: str,
    window_s: float,
    max_iters: int,
    ident_model: mujoco.MjModel | None = None,
    max_windows: int | None = None,
    cpu_budget_s: float | None = None,
    scale: FloatArray | None = None,
    stages: tuple[str, ...] = ("all",),
    velocity_weight: float = 1.0,
) -> ToolRun:
    """Identify the log with mujoco.sysid (module docstring); the estimate over pm.names.

    MuJoCo's Gauss-Newton (sysid's ``optimizer="mujoco"`` backend) with ``x_scale="jac"``
    (each parameter scaled by its Jacobian column's norm, refreshed every iteration) and its own
    stopping tests (``xtol``, ``gtol`` 1e-8, or no further reduction) under a cap of
    ``max_iters`` per stage; ``stages`` (:data:`SYSID_STAGE_FREE`) run one after the other,
    each from the previous one's stop. ``info`` holds the iterations (finite-difference
    Jacobians, every stage's) and each stage's stop (``"maximum iterations reached."`` when the
    cap stopped it). ``cpu_budget_s``: stop after the first iteration that ends past this much
    CPU time (over the stages), with its iterate, reported as not converged (a shared
    machine's time limit; None: no budget). ``scale``, ``velocity_weight``:
    :func:`sysid_problem`'s."""
    from mujoco import sysid

    problem = sysid_problem(
        case,
        start=start,
        window_s=window_s,
        ident_model=ident_model,
        max_windows=max_windows,
        scale=scale,
        velocity_weight=velocity_weight,
    )
    opt, jacobians, statuses = problem.params.copy(), [0], []
    rss0 = _peak_rss_mb()
    c0, t0 = time.process_time(), time.perf_counter()
    for stage in stages:
        status = _sysid_stage(problem, opt, stage, max_iters, jacobians, (c0, cpu_budget_s))
        statuses.append(f"{stage}: {status}" if len(stages) > 1 else status)
        if status.startswith("NOT converged"):
            break
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    peak = _peak_rss_mb() - rss0
    _unfreeze(opt)
    iterations, status = jacobians[0], "; ".join(statuses)
    # sysid's objective 0.5 ||r||^2 at its start, its stop and the truth: how far it has to go
    y = {
        label: problem.objective(p)
        for label, p in (("start", problem.params), ("stop", opt), ("truth", problem.truth))
    }
    identified = sysid.apply_param_modifiers(opt, problem.spec)
    info = {"iterations": iterations, "status": status, "objective": y}
    if case.servo is not None:
        info |= _servo_gains(identified, problem.joints)
    x = standard_from_mujoco(identified, pm, problem.joints)
    note = (
        f"{problem.n_windows} windows of {window_s:g} s, x_scale='jac', stages "
        f"{'+'.join(stages)}, {iterations} iterations (cap {max_iters} a stage): {status}; "
        f"objective 0.5||r||^2 at start {y['start']:.4g}, at stop {y['stop']:.4g}, at the "
        f"truth {y['truth']:.4g}"
    )
    return ToolRun(f"mujoco.sysid ({start})", x, wall, peak, note, cpu_s=cpu, info=info)


def _unfreeze(params: Any) -> None:
    """Every parameter of ``params`` (a sysid ParameterDict) free again."""
    for p in params.values():
        p.frozen = False


def _sysid_stage(
    problem: SysidProblem,
    opt: Any,
    stage: str,
    max_iters: int,
    jacobians: list[int],
    budget_of: tuple[float, float | None],
) -> str:
    """One stage (:data:`SYSID_STAGE_FREE`) of :func:`run_sysid` from ``opt`` (its stop
    written back to it); counts its Jacobians in ``jacobians[0]``; its stop's reason.
    ``budget_of``: the process CPU time [s] the run started at, and its budget (or None)."""
    _unfreeze(opt)
    if stage == "joints":  # the links stay at the start's: written on the spec once, frozen
        for name, p in opt.items():
            if name.endswith("_inertia"):
                p.apply_modifier(problem.spec)
                p.frozen = True
    elif stage != "all":
        raise ValueError(f"unknown sysid stage {stage!r}: one of {sorted(SYSID_STAGE_FREE)}")
    trace = io.StringIO()
    last = [opt.as_vector()]

    def residual(x: FloatArray) -> FloatArray:  # sysid.optimize's, counting the Jacobians
        jacobians[0] += int(x.ndim == 2 and x.shape[1] > 1)
        return np.concatenate(problem.residual_fn(x, opt)[0])

    def budget(log: list[Any]) -> None:  # the iterate so far; stop when the CPU budget is spent
        last[0] = np.asarray(log[-1].candidate).ravel()
        c0, cpu_budget_s = budget_of
        if cpu_budget_s is not None and time.process_time() - c0 > cpu_budget_s:
            raise _BudgetSpent

    # sysid.optimize(optimizer="mujoco") is this call with verbosity FULLITER, which costs one
    # more finite-difference Jacobian at the end (for its log); FINAL prints the stop only
    try:
        x, _ = minimize.least_squares(
            x0=opt.as_vector(),
            bounds=opt.get_bounds(),
            residual=residual,
            verbose=minimize.Verbosity.FINAL,
            output=trace,
            max_iter=max_iters,
            x_scale="jac",
            iter_callback=budget,
        )
        stop = re.search(r"Terminated after \d+ iterations: ([^y]*)", trace.getvalue())
        status = stop.group(1).strip() if stop else "unknown (no final message)"
    except _BudgetSpent:
        x = last[0]
        status = f"NOT converged: stopped by the CPU budget of {budget_of[1]:g} s"
    opt.update_from_vector(x)
    return status


def _servo_gains(model: mujoco.MjModel, joints: list[str]) -> dict[str, list[float]]:
    """The ``<position>`` servos' ``kp`` and ``kv`` of a compiled model, per joint, with each
    ``kv`` folded into its joint's ``dof_damping`` (``model`` changed): ident's ``kd + fv``,
    so that :func:`standard_from_mujoco`'s ``fv`` is the velocity term a model driven by
    ``kp e`` alone needs (the rollout score's). ``<position>``: gain ``kp``, bias ``(0, -kp,
    -kv)`` (sysid's own reader of them refuses a compiled model's actuator here)."""
    ids = [int(model.actuator(f"{j}_motor").id) for j in joints]
    kp, kv = model.actuator_gainprm[ids, 0], -model.actuator_biasprm[ids, 2]
    for j, gain in zip(joints, kv, strict=True):
        model.dof_damping[int(model.joint(j).dofadr[0])] += gain
    return {"kp": [float(g) for g in kp], "kv": [float(g) for g in kv]}


def standard_from_mujoco(
    model: mujoco.MjModel, pm: ParameterModel, joints: list[str]
) -> FloatArray:
    """A compiled MuJoCo model's parameters over ``pm.names`` (inertia about the body origin,
    Pinocchio's order; ``fv`` = damping, ``fs`` = frictionloss, ``Ia`` = armature)."""
    std = np.zeros(10 * len(joints))
    for k, j in enumerate(joints):
        b = model.body(int(model.joint(j).bodyid[0]))
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, b.iquat)
        R = R.reshape(3, 3)
        I_com = R @ np.diag(b.inertia) @ R.T
        inertia = pin.Inertia(float(b.mass[0]), np.array(b.ipos), I_com)
        std[10 * k : 10 * k + 10] = inertia.toDynamicParameters()
    extras = {}
    for k, j in enumerate(joints):
        mj = model.joint(j)
        d = int(mj.dofadr[0])
        extras[f"fv{k + 1}"] = float(model.dof_damping[d])
        extras[f"fs{k + 1}"] = float(model.dof_frictionloss[d])
        extras[f"Ia{k + 1}"] = float(model.dof_armature[d])
    x = np.zeros(len(pm.names))
    for i, name in enumerate(pm.names):
        if pm.inertial_index[i] >= 0:
            x[i] = std[pm.inertial_index[i]]
        else:
            x[i] = extras.get(name, 0.0)
    return x


# ---------------------------------------------------------------------------------------------
# the yardsticks


def evaluate(case: Case, pm: ParameterModel, run: ToolRun) -> dict[str, Any]:
    """Held-out torque error and parameter error of one estimate (module docstring, 4)."""
    robot = case.setup.robot
    sl = slice(case.n_identify, None)
    q, dq, ddq = (np.asarray(a)[sl] for a in (case.log.q_true, case.log.dq_true, case.log.ddq_true))
    tau = np.asarray(case.log.tau_measured)[sl]
    tau_free = np.asarray(case.log.tau_cmd)[sl]
    idx = np.asarray(pm.base.independent)
    Wb = pm.columns(
        joint_torque_regressor(robot.chain, q, dq, ddq), extra_columns(pm.terms, dq, ddq), idx
    )
    beta = pm.base.project(run.x)
    beta_true = pm.base.project(true_parameters(pm, case.setup.config))
    pred = np.einsum("njp,p->nj", Wb, beta)
    rel_joint = np.sqrt(np.mean((pred - tau) ** 2, axis=0)) / np.sqrt(np.mean(tau**2, axis=0))
    rel_all = float(np.linalg.norm(pred - tau) / np.linalg.norm(tau))
    free = float(np.linalg.norm(pred - tau_free) / np.linalg.norm(tau_free))
    Wf = Wb.reshape(-1, len(idx))
    return {
        "tool": run.tool,
        "held_out": rel_all,
        "held_out_joint": rel_joint,
        "noise_free": free,
        "param": float(np.linalg.norm(beta - beta_true) / np.linalg.norm(beta_true)),
        "param_torque": float(
            np.linalg.norm(Wf @ (beta - beta_true)) / np.linalg.norm(Wf @ beta_true)
        ),
        "wall_s": run.wall_s,
        "peak_mb": run.peak_mb,
        "note": run.note,
    }


def check_mapping(case: Case, pm: ParameterModel) -> float:
    """The sysid spec at the truth, mapped to pm.names, against ident's truth (max abs diff)."""
    spec, _, joints = sysid_spec(case)
    truth = case.log.truth
    for k, j in enumerate(joints):
        sj = spec.joint(j)
        set_joint(sj, "armature", float(truth["armature"][k]))
        set_joint(sj, "damping", float(truth["viscous"][k]))
        set_joint(sj, "frictionloss", float(truth["coulomb"][k]))
    x = standard_from_mujoco(spec.compile(), pm, joints)
    return float(np.max(np.abs(x - true_parameters(pm, case.setup.config))))


# ---------------------------------------------------------------------------------------------
# the duel: both tools at their best set-up, several seeds, two log kinds (module docstring, 5)


def model_mjcf(case: Case, pm: ParameterModel, x: FloatArray) -> mujoco.MjModel:
    """A full estimate ``x`` over ``pm.names`` (standard parameters of every link, ``Ia``,
    ``fv``, ``fs`` per joint) as a MuJoCo model, written by ident's MJCF writer (the one of
    ident's own model and of the rollout check's truth)."""
    robot = case.setup.robot
    source = str(robot.urdf_path or robot.name)
    carriers = [
        b.carrier for b in fused_bodies(parse_urdf(robot.urdf_text, source), robot.model, source)
    ]
    std = np.zeros(10 * len(carriers))
    index = np.asarray(pm.inertial_index)
    std[index[index >= 0]] = np.asarray(x)[index >= 0]
    value = dict(zip(pm.names, np.asarray(x, dtype=float), strict=True))
    extras = {
        j: {
            "rotor_inertia": value.get(f"Ia{k + 1}", 0.0),
            "viscous": value.get(f"fv{k + 1}", 0.0),
            "coulomb": value.get(f"fs{k + 1}", 0.0),
        }
        for k, j in enumerate(robot.joint_names)
    }
    text = identified_mjcf(
        robot.urdf_text,
        tuple(robot.joint_names),
        {c: std[10 * k : 10 * k + 10] for k, c in enumerate(carriers)},
        extras,
        locked_joints=robot.locked_joints,
        gravity=np.asarray(robot.model.gravity.linear, dtype=float),
        source=source,
    )
    return mujoco.MjModel.from_xml_string(text)


def cad_start(case: Case, pm: ParameterModel) -> FloatArray:
    """sysid's CAD start over ``pm.names``: the truth's bodies, joint terms x1.5."""
    x = true_parameters(pm, case.setup.config).copy()
    extra = np.asarray(pm.inertial_index) < 0
    x[extra] *= JOINT_TERM_START
    return x


#: The rows of a duel table, in order: the truth, the models the tools start from, the tools.
DUEL_TOOLS = ("truth", "CAD start", "ident", "mujoco.sysid (cad)", "mujoco.sysid (ident)")


def _row(
    case: Case, pm: ParameterModel, run: ToolRun, rollout: tuple[Any, Any, mujoco.MjModel]
) -> dict[str, Any]:
    """One tool's JSON-ready figures on a case: torque and base errors (:func:`evaluate`),
    the held-out rollout objective of its MuJoCo model, its CPU and wall time."""
    measurements, windows, model = rollout
    r = evaluate(case, pm, run)
    return {
        "torque": r["noise_free"],
        "held_out": r["held_out"],
        "base": r["param"],
        "rollout": rollout_score(model, measurements, windows).objective,
        "refined_rollout": None,  # ident's row: its model after `refinement: rollout`
        "cpu_s": None if np.isnan(run.cpu_s) else run.cpu_s,
        "wall_s": run.wall_s,
        **run.info,
    }


def duel_case(
    name: str,
    kind: str,
    seed: int,
    *,
    periods: int = 1,
    window_s: float = 0.5,
    max_iters: int = 200,
    starts: tuple[str, ...] = ("cad", "ident"),
    max_windows: int | None = None,
    cpu_budget_s: float | None = None,
) -> dict[str, Any]:
    """One (robot, log kind, seed) of the duel: ident, then mujoco.sysid from each start, every
    model scored on the same held-out rollout windows (ident's held-out part, its
    preprocessing; :func:`ident.identify.assessment.rollout.held_out_windows`), the truth and
    the CAD start included. JSON-ready: the case, the load average at start and per tool
    :func:`_row`'s figures."""
    load = os.getloadavg()[0]
    case = make_case(name, periods=periods, seed=seed, kind=kind)
    run, result = run_ident(case)
    pm = result.parameters
    ident_model = ident_written_model(result)
    measurements, windows = held_out_windows(result)
    if tuple(measurements.joint_names) != tuple(case.setup.robot.joint_names):
        raise RuntimeError("ident's joints are not the robot's, in order: no shared scale")
    x_true = true_parameters(pm, case.setup.config)
    fixed = {
        "truth": (ToolRun("truth", x_true, 0.0, 0.0), model_mjcf(case, pm, x_true)),
        "CAD start": (ToolRun("CAD start", cad_start(case, pm), 0.0, 0.0), None),
        "ident": (run, ident_model),
    }
    rows = {}
    for tool, (r, model) in fixed.items():
        model = model_mjcf(case, pm, r.x) if model is None else model
        r.cpu_s = r.cpu_s if tool == "ident" else float("nan")
        rows[tool] = _row(case, pm, r, (measurements, windows, model))
    refined_model, refinement = ident_refined_model(
        result, rows["ident"]["rollout"], rows["truth"]["rollout"]
    )
    rows["ident"]["refined_rollout"] = rollout_score(refined_model, measurements, windows).objective
    rows["ident"]["refinement"] = {
        k: refinement.get(k) for k in ("accepted", "note", "iterations", "stop", "cpu_s")
    }
    print(f"{name} {kind} seed {seed}: ident refined: {refinement_text(refinement)}", flush=True)
    for start in starts:
        s = run_sysid(
            case,
            pm,
            start=start,
            window_s=window_s,
            max_iters=max_iters,
            ident_model=ident_model,
            max_windows=max_windows,
            cpu_budget_s=cpu_budget_s,
            scale=measurements.scale,  # the objective it is scored on (same joint order)
        )
        rows[s.tool] = _row(case, pm, s, (measurements, windows, model_mjcf(case, pm, s.x)))
        print(f"{name} {kind} seed {seed}: {s.tool}: {s.note}", flush=True)
    return {
        "robot": name,
        "kind": kind,
        "seed": seed,
        "periods": periods,
        "window_s": window_s,
        "max_iters": max_iters,
        "load_start": load,
        "n_samples": case.log.n_samples,
        "n_identify": case.n_identify,
        "rollout_windows": int(windows.shape[0]),
        "rows": rows,
    }


def _stat(values: list[float], fmt: str) -> str:
    """``median (worst)`` of per-seed figures (worst: the largest)."""
    if not values:
        return "-"
    return f"{fmt.format(float(np.median(values)))} ({fmt.format(max(values))})"


def _refined(rows: list[dict[str, Any]]) -> list[float]:
    """The refined rollout objectives of a tool's rows (ident's only)."""
    return [x["refined_rollout"] for x in rows if x.get("refined_rollout") is not None]


def duel_verdict(records: list[dict[str, Any]]) -> dict[str, Any]:
    """The targets on one (robot, kind): ident's median torque and base errors at most 1/3 of
    sysid's best start's (the start with the lower median), its median CPU at least 10x less."""
    med = {
        t: {k: float(np.median([r["rows"][t][k] for r in records])) for k in ("torque", "base")}
        for t in records[0]["rows"]
        if t.startswith("mujoco.sysid")
    }
    if not med:
        return {}
    best = min(med, key=lambda t: med[t]["torque"])
    ours = {
        k: float(np.median([r["rows"]["ident"][k] for r in records])) for k in ("torque", "base")
    }
    cpu = {t: float(np.median([r["rows"][t]["cpu_s"] for r in records])) for t in ("ident", best)}
    return {
        "best": best,
        "torque_ratio": ours["torque"] / med[best]["torque"],
        "base_ratio": ours["base"] / med[best]["base"],
        "cpu_ratio": cpu[best] / cpu["ident"],
    }


def duel_table(records: list[dict[str, Any]]) -> str:
    """The markdown tables of the duel, one per (robot, log kind): per tool the median and
    worst over seeds of each figure, and the targets' verdict."""
    out = []
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in records:
        groups.setdefault((r["robot"], r["kind"]), []).append(r)
    for (robot, kind), recs in sorted(groups.items()):
        r0 = recs[0]
        loads = [r["load_start"] for r in recs]
        out += [
            f"**{robot}, {kind}-simulated log** ({len(recs)} seeds: "
            f"{', '.join(str(r['seed']) for r in recs)}; {r0['n_samples']} samples at 1 kHz, "
            f"identification {r0['n_identify']}; {r0['rollout_windows']} held-out rollout "
            f"windows of 0.5 s; load average at start {min(loads):.1f}-{max(loads):.1f})",
            "",
            "| model | torque err. | base-param err. | held-out rollout J | refined rollout J "
            "| CPU [s] | sysid iterations, stop |",
            "|---|---|---|---|---|---|---|",
        ]
        tools = [t for t in DUEL_TOOLS if t in r0["rows"]]
        tools += [t for t in r0["rows"] if t not in tools]
        for tool in tools:
            rows = [r["rows"][tool] for r in recs if tool in r["rows"]]
            cpu = [x["cpu_s"] for x in rows if x["cpu_s"] is not None]
            stops = sorted({f"{x['iterations']}: {x['status']}" for x in rows if "status" in x})
            out.append(
                f"| {tool} | {_stat([x['torque'] for x in rows], '{:.4f}')} "
                f"| {_stat([x['base'] for x in rows], '{:.4f}')} "
                f"| {_stat([x['rollout'] for x in rows], '{:.3g}')} "
                f"| {_stat(refined, '{:.3g}') if (refined := _refined(rows)) else '-'} | "
                f"{_stat(cpu, '{:.1f}')} | {'; '.join(stops) or '-'} |"
            )
        v = duel_verdict(recs)
        stopped = [
            x for r in recs for x in r["rows"].values() if x.get("status", "").startswith("NOT")
        ]
        if stopped:  # a sysid stopped by the CPU budget: its figures are no verdict
            out += [
                "",
                f"Targets not judged: {len(stopped)} sysid run(s) here stopped by the CPU budget "
                "before converging.",
            ]
        elif v:
            holds = {
                k: "holds" if ok else "fails"
                for k, ok in (
                    ("torque", v["torque_ratio"] <= 1 / 3),
                    ("base", v["base_ratio"] <= 1 / 3),
                    ("cpu", v["cpu_ratio"] >= 10),
                )
            }
            out += [
                "",
                f"Targets against sysid's best start here ({v['best']}, medians): ident's torque "
                f"error {v['torque_ratio']:.2f}x its ({holds['torque']}: <= 1/3), base error "
                f"{v['base_ratio']:.2f}x ({holds['base']}), CPU {v['cpu_ratio']:.0f}x less "
                f"({holds['cpu']}: >= 10x).",
            ]
        out.append("")
    return "\n".join(out).rstrip()


# ---------------------------------------------------------------------------------------------
# Pinocchio: regressor + normal equations per sample against pin.rnea per sample


def pinocchio_part(n: int = 2000, repeat: int = 5) -> str:
    """CPU seconds per sample (``time.process_time``: a measurement is not charged for the time
    the process waits for a core on a shared machine) on a 7-joint arm (the Panda without
    fingers), best of ``repeat`` (the three measured in turn in every repetition, so a load
    change hits all of them): ident's chunked path (regressor kernel + friction columns + base
    columns + per-joint reduction, :func:`bench_identify_long.per_sample`), a Python loop over
    ``pin.computeJointTorqueRegressor`` + ``Y^T Y``, and a Python loop over ``pin.rnea``."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_identify_long import panda7, per_sample
    from threadpoolctl import threadpool_limits

    # BLAS on one thread, as ident.identify_measurements runs it: on a loaded 2-core machine a
    # second OpenBLAS thread made the reduction 25x slower (900 us per sample instead of 37)
    with (
        threadpool_limits(limits=1, user_api="blas"),
        tempfile.TemporaryDirectory(prefix="bench-peers-") as tmp,
    ):
        urdf = panda7(Path(tmp))
        model = pin.buildModelFromUrdf(str(urdf))
        data = model.createData()
        rng = np.random.default_rng(1)
        q, dq, ddq = rng.normal(size=(3, n, model.nv))
        ours, loop, rnea, traj = [], [], [], []
        for _ in range(repeat):
            a, b = per_sample(urdf, n)
            ours.append(a)
            loop.append(b)
            traj.append(per_sample(urdf, n, trajectory=True)[0])
            t0 = time.process_time()
            for k in range(n):
                pin.rnea(model, data, q[k], dq[k], ddq[k])
            rnea.append((time.process_time() - t0) / n)
    o, lp, r, tr = min(ours), min(loop), min(rnea), min(traj)
    return "\n".join(
        [
            f"**Pinocchio** (7-joint Panda, {n} random states, CPU time, best of {repeat})",
            "",
            "| per sample | CPU us | / pin.rnea |",
            "|---|---|---|",
            f"| pin.rnea (Python loop over the C++ call) | {r * 1e6:.2f} | 1.0x |",
            f"| ident: regressor + friction + base columns + normal equations | {o * 1e6:.2f} "
            f"| {o / r:.1f}x |",
            f"| Python loop: pin.computeJointTorqueRegressor + Y^T Y | {lp * 1e6:.2f} "
            f"| {lp / r:.1f}x |",
            f"| ident, same, on a Fourier excitation's states (rows worse conditioned: most "
            f"joints' reduction by QR, not the Gram) | {tr * 1e6:.2f} | {tr / r:.1f}x |",
        ]
    )


# ---------------------------------------------------------------------------------------------
# FIGAROH on the TX40 log, its own example (fetched by benchmarks/fetch_figaroh_examples.sh)

_FIGAROH_CHILD = (
    PEAK_MB_SOURCE
    + """
import json, os, resource, sys, time
root = sys.argv[1]
os.chdir(os.path.join(root, "examples", "staubli_TX40"))
sys.path.insert(0, root)
import numpy as np
from examples.staubli_tx40.utils.staubli_tx40_tools import TX40Identification
from figaroh.tools.robot import load_robot
t0 = time.perf_counter()
robot = load_robot("urdf/tx40_mdh_modified.urdf", package_dirs="models")
iden = TX40Identification(robot, "config/staubli_tx40_unified_config.yaml")
iden.initialize()
iden.solve(decimate=True, plotting=False, save_results=False, wls=False)
wall = time.perf_counter() - t0
res = np.asarray(iden.tau_noised) - np.asarray(iden.tau_identif)
print("RESULT " + json.dumps({
    "n_base": len(iden.params_base), "cond": float(iden.result["condition number"]),
    "rmse": float(iden.rms_error),
    "relative": float(np.linalg.norm(res) / np.linalg.norm(iden.tau_noised)),
    "rows": int(np.asarray(iden.tau_noised).size), "wall": wall,
    "rss_mb": peak_mb()}))
"""
)

_IDENT_CHILD = (
    PEAK_MB_SOURCE
    + """
import json, resource, sys, time
import numpy as np
from ident.identify.config import load_identify_config
from ident.identify.pipeline.real import identify
t0 = time.perf_counter()
r = identify(load_identify_config(sys.argv[1]))
wall = time.perf_counter() - t0
e = r.estimate
held = r.predictions["identified"].metrics.total_relative_residual
print("RESULT " + json.dumps({
    "n_base": int(len(e.x)), "cond": float(e.condition_number),
    "rmse": float(np.sqrt(np.mean(np.asarray(e.residual_rms) ** 2))),
    "relative": float(e.relative_residual), "held_out": float(held),
    "rows": int(r.n_identify_rows), "wall": wall,
    "rss_mb": peak_mb()}))
"""
)


def _child(code: str, *args: str) -> dict[str, Any]:
    """Run ``code`` in a fresh interpreter; its ``RESULT {json}`` line (peak RSS of its own)."""
    import json
    import os
    import subprocess

    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT / "src")}
    out = subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, env=env, check=False
    )
    for line in out.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT ") :])
    tail = (out.stderr.strip().splitlines() or ["no output"])[-1]
    raise RuntimeError(f"child failed: {tail}")


def figaroh_part(examples: Path | None) -> str:
    """FIGAROH's TX40 example against ``ident identify configs/tx40.yaml``, each in a child."""
    head = "**FIGAROH** (Staubli TX40 log, 45,000 samples at 5 kHz)"
    try:
        import figaroh  # noqa: F401
    except ImportError:
        return f"{head}: figaroh not installed (pip install -e '.[peers]'): skipped"
    if examples is None or not (examples / "examples" / "staubli_tx40").exists():
        return (
            f"{head}: FIGAROH's examples not found; run "
            "benchmarks/fetch_figaroh_examples.sh DIR and pass --figaroh-examples DIR: skipped"
        )
    fig = _child(_FIGAROH_CHILD, str(examples))
    ours = _child(_IDENT_CHILD, str(ROOT / "configs" / "tx40.yaml"))
    rows = [
        f"{head}",
        "",
        "| tool | base params | cond. | in-sample torque RMSE [N m] | in-sample rel. residual "
        "| held-out rel. residual | rows | wall [s] | peak RSS [MB] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in (
        ("ident (configs/tx40.yaml, WLS)", ours),
        ("FIGAROH 1.0.2 (its example, OLS)", fig),
    ):
        held = f"{r['held_out']:.4f}" if "held_out" in r else "none (fits the whole log)"
        rows.append(
            f"| {name} | {r['n_base']} | {r['cond']:.4g} | {r['rmse']:.3f} | {r['relative']:.4f} "
            f"| {held} | {r['rows']} | {r['wall']:.1f} | {r['rss_mb']:.0f} |"
        )
    return "\n".join(rows)


# ---------------------------------------------------------------------------------------------
# excitation quality at the peers' settings
#
# FIGAROH's UR10 dynamic truth fixture v1 (thanhndv212/figaroh-examples, examples/ur10/
# identification_truth.py, data/truth/manifest.json and protocol.yaml; the numbers used here are
# in benchmarks/data/figaroh_ur10_truth_train.json with their source and licence): its URDF
# examples/ur10/urdf/ur10_robot.urdf (UR10e link lengths: 0.1807, 0.6127, 0.57155, 0.17415,
# 0.11985, 0.11655 m; sha256 1da0c0de..., the file at the pinned commit c0b5c7f that
# fetch_figaroh_examples.sh fetches); 10 s at 100 Hz = 1000 samples; a 5-harmonic Fourier series
# at 0.1 Hz about the posture (0, -pi/2, pi/2, -pi/2, -pi/2, 0) rad with |q - centre| <= 1.2 rad,
# |dq| <= 0.7 x (2.094, 2.094, 3.142, 3.142, 3.142, 3.142) rad/s, |tau| <= 0.8 x (330, 330, 150,
# 54, 54, 54) N m, no acceleration limit, no collision check; the training trajectory is the
# best-conditioned of 20 random seeds (seed 18). Its condition number, 77.018, is that "of the
# unscaled training base regressor": Pinocchio's joint-torque regressor (10 standard parameters
# per link, no friction, actuator inertia or offset), the columns whose sum of squares is below
# 1e-6 dropped (11 of 60), then the 36 columns protocol.yaml lists as base_indices (chosen by
# FIGAROH's own column-pivoted QR, ties broken by parameter name). This piece rebuilds that
# trajectory from the manifest's coefficients and gets 77.0185 on FIGAROH's URDF (verified when
# --figaroh-examples holds it; the same matrix, 1e-12 relative).
#
# The 7-joint case: the issue quotes a Drake-based design at 116.7 for 10 s, 1000 samples and
# 1 cm clearance. The nearest published Drake-based excitation design found is
# nepfaff/robot_payload_id (Pfaff et al., a KUKA iiwa, Drake's MathematicalProgram, a
# condition-number cost); neither the figure 116.7 nor its base-parameter convention was found in
# the stored sources. Assumed: the same convention as FIGAROH's (raw SI base regressor of the 10
# standard parameters per link, no friction columns), on the Franka Panda of configs/panda.yaml
# (7 joints, fingers locked: the same kinematics as bench_identify_long's finger-less panda7),
# not on the iiwa.

# the fixture's numbers, its training series and FIGAROH's base regressor: one place,
# benchmarks/peer_ur10_truth.py
load_ur10_fixture = ur10_truth.load_fixture
fixture_trajectory = ur10_truth.fixture_trajectory
peer_columns = ur10_truth.peer_columns
fixture_base_columns = ur10_truth.fixture_base_columns


def peer_base_regressor(
    model: pin.Model, q: FloatArray, dq: FloatArray, ddq: FloatArray, base: Any = None
) -> FloatArray:
    """The matrix of :func:`peer_columns`."""
    return peer_columns(model, q, dq, ddq, base)[0]


@dataclass
class Design:
    """One excitation designed by ident at a peer's settings."""

    robot: str
    criterion: str  # "ident" (its config's) or "peer" (raw-column condition number)
    q: FloatArray  # (n_samples, nv) one period
    dq: FloatArray
    ddq: FloatArray
    model: pin.Model
    own_cond: float  # cond of ident's own objective matrix (scaled rigid-body base columns)
    own_columns: int
    safe: str  # the dense check's verdict at 1 kHz
    wall_s: float  # this optimizer run (the shared elite search is in the first design's)
    evaluations: int


def _fixture_urdf(
    source: Path, fixture: dict[str, Any], folder: Path
) -> tuple[Path, tuple[str, ...]]:
    """``source`` with FIGAROH's fixture limits written into its joints' ``<limit>``:
    centre +- amplitude, the velocity and torque fractions (no acceleration limit); its meshes
    removed (the fixture checks no collision). With the names of the joints, in the order of
    the fixture's per-joint lists."""
    import xml.etree.ElementTree as ET

    tree = ET.parse(source)
    for link in tree.getroot().findall("link"):
        for tag in ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
    joints = [j for j in tree.getroot().findall("joint") if j.get("type") == "revolute"]
    for k, joint in enumerate(joints):
        limit = joint.find("limit")
        assert limit is not None  # a revolute joint of a URDF has one
        c, amp = fixture["center_rad"][k], fixture["amplitude_rad"]
        limit.set("lower", repr(c - amp))
        limit.set("upper", repr(c + amp))
        limit.set("velocity", repr(fixture["velocity_fraction"] * fixture["velocity_limit"][k]))
        limit.set("effort", repr(fixture["torque_fraction"] * fixture["torque_limit_nm"][k]))
    path = folder / "ur10_fixture_limits.urdf"
    tree.write(path)
    return path, tuple(str(j.get("name")) for j in joints)


def excitation_configs(
    folder: Path, ur10_urdf: Path, *, quick: bool, fill_limits: bool = True
) -> dict[str, tuple[dict[str, Any], str]]:
    """The run configs of both cases (ident's config-driven design) and a settings line each.

    Both: joint-space Fourier series, 5 harmonics, 10 s period, 1000 samples (``quick``: 100),
    each joint's series gained onto its limits (``excitation.options.fill_limits``, as FIGAROH
    gains its series; ``fill_limits=False``: the coefficient box as it is), pso (ident's
    default) after a feasible-elite search. UR10: the fixture's limits in the URDF
    (:func:`_fixture_urdf`), mean posture within 0.3 rad of the fixture's centre, torque limits
    checked, no collision or floor (as the fixture), 100 pso iterations (cheap without
    collision geometry). Panda: ``configs/panda.yaml``'s robot and safety sections (floor,
    self-collision on its meshes, datasheet accelerations, URDF torque limits) with a 1 cm
    clearance, 40 pso iterations.
    """
    fixture = load_ur10_fixture()
    if quick:
        elites = {"n_particles": 4, "n_elites": 1, "maxiter": 5}
        swarm = {"n_particles": 4, "maxiter": 1}
    else:
        elites = {"n_particles": 10, "n_elites": 3, "maxiter": 60}
        swarm = {"n_particles": 16, "maxiter": 40}
    n = 100 if quick else 1000
    excitation = {
        "family": "joint_fourier",
        "criterion": "paper",
        "n_samples": n,
        # quick: a box every design of which keeps the limits (the elite search is immediate)
        "options": {
            "n_harmonics": 5,
            "base_frequency": 2 * np.pi / 10.0,
            "amplitude_bound": 0.05 if quick else 0.3,
        },
    }
    if fill_limits:
        excitation["options"]["fill_limits"] = True
    centre = fixture["center_rad"]
    ur10_swarm = swarm if quick else {**swarm, "maxiter": 100}
    fixture_urdf, joints = _fixture_urdf(ur10_urdf, fixture, folder)
    ur10 = {
        "robot": {"urdf": str(fixture_urdf)},
        "stage": "whole",
        "seed": 0,
        "excitation": {
            **excitation,
            "bounds": {
                f"q0[{j}]": [centre[k] - 0.3, centre[k] + 0.3] for k, j in enumerate(joints)
            },
        },
        "optimizer": "pso",
        "safety": {
            "floor": {"enabled": False},
            "self_collision": False,
            "torque_limits": True,
            "check_samples": 50,
        },
        "elites": elites,
        "emupso": ur10_swarm,
    }
    panda = yaml.safe_load((ROOT / "configs" / "panda.yaml").read_text(encoding="utf-8"))
    for key in ("measurement", "identification", "quick", "controller"):
        panda.pop(key, None)
    panda["robot"]["urdf"] = str(ROOT / "robot" / "urdf" / "panda.urdf")
    panda["robot"]["package_dirs"] = [str(ROOT / "robot" / "meshes")]
    panda["excitation"] = excitation
    panda["safety"] = {**panda["safety"], "clearance_m": 0.01}
    panda["elites"], panda["emupso"] = elites, swarm
    return {
        "ur10": (
            ur10,
            f"FIGAROH's fixture: 10 s, {n} samples, abs(q - centre) <= 1.2 rad, 0.7 x velocity, "
            "0.8 x torque limits, no collision check",
        ),
        "panda": (
            panda,
            f"10 s, {n} samples, 1 cm self-collision clearance, floor, datasheet velocity, "
            "acceleration, torque limits",
        ),
    }


def design_excitation(
    name: str, config: dict[str, Any], folder: Path, *, base: Any = None
) -> list[Design]:
    """ident's designs of ``config``, both from the same feasible elites (as ``ident run``
    finds them), each checked densely at 1 kHz (no measurement):

    1. the config's own criterion (eq. 15 on the scaled rigid-body base columns);
    2. the same optimizer on the peer's quantity: eq. 15 on FIGAROH's raw base columns of
       design 1 (``base``: standard-parameter indices, see :func:`peer_columns`), every column
       scaled by one number (``1 / sqrt(sigma_min sigma_max)`` of design 1's row-normalised
       matrix), so that its condition number is the raw one and the sigma terms stay small.
    """
    from ident.excitation.objective import ExcitationObjective
    from ident.optim import minimize
    from ident.optim.elites import spawn_from_elites
    from ident.run.pipeline import feasible_start
    from ident.run.safety_check import check_elites

    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(config), encoding="utf-8")
    t0 = time.perf_counter()
    start = feasible_start(load_run(path))
    setup, problem = start.setup, start.problem
    o, e = setup.config.emupso, setup.config.elites
    elite_evaluations = e.n_particles * (e.maxiter + 1)
    designs: list[Design] = []
    objective = problem.objective
    for criterion in ("ident", "peer"):
        if criterion == "peer":
            first = designs[0]
            w, columns = peer_columns(first.model, first.q, first.dq, first.ddq, base)
            sv = np.linalg.svd(w / np.sqrt(w.shape[0]), compute_uv=False)
            objective = ExcitationObjective(
                setup.robot,
                setup.stage,
                setup.family,
                base_columns=[int(c) for c in columns],
                column_scale=1.0 / np.sqrt(sv[0] * sv[-1]),
                safety=setup.safety if setup.config.safety is not None else None,
            )
            t0 = time.perf_counter()
        gen = np.random.default_rng(setup.config.seed)
        x0 = spawn_from_elites(start.elites, o.n_particles, problem.bounds, o.sigma_fraction, gen)
        res = minimize(
            objective,
            problem.bounds,
            method=setup.config.optimizer,
            rng=gen,
            maxiter=o.maxiter,
            popsize=o.n_particles,
            vectorized=True,
            x0=x0,
        )
        wall = time.perf_counter() - t0
        x = np.asarray(res.x, dtype=float)[None, :]
        report = check_elites(setup.config, setup.robot, setup.family, setup.safety, x)[0]
        batch = setup.family.trajectories(x)
        designs.append(
            Design(
                robot=name,
                criterion=criterion,
                q=batch.q[0],
                dq=batch.dq[0],
                ddq=batch.ddq[0],
                model=setup.robot.model,
                own_cond=float(problem.objective.details(x)[0].cond),
                own_columns=len(problem.objective.columns),
                safe="safe" if report.usable else "NOT safe: " + report.failures()[0].name,
                wall_s=wall,
                evaluations=int(res.nfev) + (elite_evaluations if criterion == "ident" else 0),
            )
        )
    return designs


def excitation_part(
    examples: Path | None, *, quick: bool = False
) -> tuple[str, list[dict[str, Any]]]:
    """The excitation table and its rows: per robot and criterion, ident's design at the peer's
    settings and its condition number on FIGAROH's convention (:func:`peer_columns`; for the
    UR10 on FIGAROH's own URDF, its protocol's frozen columns). ``quick``: 100 samples and a
    tiny budget (seconds)."""
    fixture = load_ur10_fixture()
    theirs = (
        None if examples is None else examples / "examples" / "ur10" / "urdf" / "ur10_robot.urdf"
    )
    if theirs is not None and theirs.exists():
        ur10_urdf, which = theirs, "FIGAROH's ur10_robot.urdf"
    else:  # the fixture's truth URDF: FIGAROH's kinematics (the regressor sees nothing else)
        ur10_urdf = ROOT / "data" / "figaroh-ur10-truth" / "ur10_truth.urdf"
        which = "FIGAROH's ur10_truth.urdf (data/figaroh-ur10-truth: its kinematics)"
    fq, fdq, fddq = fixture_trajectory(fixture)
    model = pin.buildModelFromUrdf(str(ur10_urdf))
    frozen_columns = fixture_base_columns(fixture)
    frozen = np.linalg.cond(peer_base_regressor(model, fq, fdq, fddq, frozen_columns))
    # FIGAROH's frozen columns are a base of its own UR10 only (not of the CB3 lengths')
    ur10_base = frozen_columns if frozen < 1e8 else None
    theirs_cond = (
        frozen
        if ur10_base is not None
        else np.linalg.cond(peer_base_regressor(model, fq, fdq, fddq))
    )
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="bench-peers-exc-") as tmp:
        configs = excitation_configs(Path(tmp), ur10_urdf, quick=quick)
        for name, (config, settings) in configs.items():
            base = ur10_base if name == "ur10" else None
            for d in design_excitation(name, config, Path(tmp), base=base):
                w, columns = peer_columns(d.model, d.q, d.dq, d.ddq, base)
                rows.append(
                    {
                        "robot": name,
                        "settings": settings,
                        "design": d,
                        "columns": columns,
                        "cond": float(np.linalg.cond(w)),
                        "n_base": w.shape[1],
                    }
                )
    convention = (
        "FIGAROH's protocol.yaml's 36 frozen columns"
        if ur10_base is not None
        else "pivoted-QR columns"
    )
    lines = [
        "**Excitation quality at the peers' settings.** Condition number of the raw SI base "
        "regressor of one period (FIGAROH's convention): Pinocchio's joint-torque regressor, 10 "
        "standard parameters per link, no friction or armature columns, columns with sum of "
        "squares < 1e-6 dropped, then the base columns (UR10: "
        f"{convention}; Panda: the independent columns of a column-pivoted QR), not "
        "column-normalised. ident designs with each joint's series gained onto its limits "
        "(`excitation.options.fill_limits: true`, as FIGAROH gains its series). ident's own "
        "criterion (eq. 15 on its scaled rigid-body base "
        "columns) is shown beside it: its condition number is that of the column-normalised "
        f"matrix. UR10 model: {which}.",
        "",
        "| robot | settings | peer's figure | ident's criterion | ident: cond, peer convention "
        "| ident: cond of its scaled matrix | budget, dense check | wall [s] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        d = row["design"]
        if row["robot"] == "ur10":
            label = "UR10"
            peer = f"77.0 (FIGAROH's trajectory; recomputed here: {theirs_cond:.4g})"
        else:
            label = "Panda (7 joints)"
            peer = "116.7 (Drake-based; convention not found, assumed this one)"
        crit = (
            "its config's: eq. 15, scaled columns"
            if d.criterion == "ident"
            else "eq. 15 on the peer's raw base columns"
        )
        lines.append(
            f"| {label} | {row['settings']} | {peer} | {crit} | {row['cond']:.4g} "
            f"({row['n_base']} columns) | {d.own_cond:.4g} ({d.own_columns} columns) "
            f"| pso, {d.evaluations} evaluations; {d.safe} | {d.wall_s:.0f} |"
        )
    return "\n".join(lines), rows


def machine() -> str:
    import os

    load = os.getloadavg()
    return (
        f"{platform.machine()}, {os.cpu_count()} cores, {platform.python_implementation()} "
        f"{platform.python_version()}, mujoco {mujoco.__version__}, pinocchio {pin.__version__}; "
        f"load average {load[0]:.1f} at start (a shared box: figures are slower than on an idle "
        "machine)"
    )


def duel_part(args: argparse.Namespace, robots: list[str], max_iters: int) -> str:
    """Run the duel's (robot, kind, seed) cases not yet in ``args.records`` and return the
    table of every record (this run's and the file's)."""
    kinds = args.kinds or (["ident"] if args.quick else list(LOG_KINDS))
    starts = tuple(args.starts or (["ident"] if args.quick else ["cad", "ident"]))
    seeds = range(1 if args.quick else args.seeds)
    records: list[dict[str, Any]] = []
    if args.records is not None and args.records.exists():
        lines = args.records.read_text(encoding="utf-8").splitlines()
        records = [json.loads(line) for line in lines if line.strip()]
    done = {(r["robot"], r["kind"], r["seed"]) for r in records}
    for name in robots:
        for kind in kinds:
            for seed in seeds:
                if (name, kind, seed) in done or args.no_run:
                    continue
                record = duel_case(
                    name,
                    kind,
                    seed,
                    periods=args.periods,
                    window_s=args.window,
                    max_iters=max_iters,
                    starts=starts,
                    cpu_budget_s=args.sysid_cpu_budget,
                )
                records.append(record)
                if args.records is not None:
                    with args.records.open("a", encoding="utf-8") as f:
                        f.write(json.dumps(record) + "\n")
                print(duel_table([record]), flush=True)
    return duel_table(records)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--robots", nargs="+", default=None)
    ap.add_argument(
        "--max-iters", type=int, default=None, help="sysid's iteration cap (200; --quick 3)"
    )
    ap.add_argument("--window", type=float, default=0.5, help="sysid's rollout window [s]")
    ap.add_argument(
        "--starts",
        nargs="+",
        default=None,
        choices=list(SYSID_STARTS),
        help="mujoco.sysid's starting models (default: cad ident; --quick: ident)",
    )
    ap.add_argument("--seeds", type=int, default=5, help="duel: seeds 0..N-1 (--quick: 1)")
    ap.add_argument("--kinds", nargs="+", default=None, choices=list(LOG_KINDS))
    ap.add_argument(
        "--sysid-cpu-budget",
        type=float,
        default=None,
        help="duel: stop sysid after this many CPU seconds, reported as not converged",
    )
    ap.add_argument(
        "--no-run",
        action="store_true",
        help="duel: run no case, only print (and write) the table of --records",
    )
    ap.add_argument(
        "--records",
        type=Path,
        default=None,
        help="duel: append each (robot, kind, seed) as a JSON line here and skip those it "
        "already holds (a long duel run in pieces); its table is of every record it holds",
    )
    ap.add_argument("--periods", type=int, default=1, help="logged 10 s periods (config: 3)")
    ap.add_argument(
        "--parts",
        nargs="+",
        default=None,
        choices=["sysid", "pinocchio", "figaroh", "ur10-truth", "excitation", "long-log"],
        help="comparisons to run (default: all; --quick: all but figaroh)",
    )
    ap.add_argument(
        "--long-minutes", type=float, default=60.0, help="long-log part: minutes at 1 kHz"
    )
    ap.add_argument(
        "--figaroh-examples",
        type=Path,
        default=None,
        help="FIGAROH's examples, from benchmarks/fetch_figaroh_examples.sh",
    )
    ap.add_argument(
        "--write-docs",
        type=Path,
        default=None,
        help="replace the tables this run printed in this markdown file (docs/benchmarks.md)",
    )
    args = ap.parse_args(argv)
    robots = args.robots or (["ur5"] if args.quick else ["ur5", "panda"])
    max_iters = args.max_iters or (3 if args.quick else 200)
    try:
        import mujoco.sysid  # noqa: F401

        have_sysid = hasattr(mujoco.sysid, "optimize")
    except ImportError:
        have_sysid = False
    where = machine()
    print(f"machine: {where}")
    words = list(argv if argv is not None else sys.argv[1:])
    if "--write-docs" in words:  # the command as a reader would run it
        k = words.index("--write-docs")
        words = words[:k] + words[k + 2 :]
    cmd = "PYTHONPATH=src python benchmarks/bench_peers.py " + " ".join(words)
    print(f"command: {cmd}")
    sections: dict[str, str] = {}
    parts = args.parts or (
        ["sysid", "pinocchio", "ur10-truth", "excitation", "long-log"]
        if args.quick
        else ["sysid", "pinocchio", "figaroh", "ur10-truth", "excitation", "long-log"]
    )
    if "pinocchio" in parts:
        sections["pinocchio"] = pinocchio_part(
            n=300 if args.quick else 2000, repeat=1 if args.quick else 5
        )
        print("\n" + sections["pinocchio"] + "\n", flush=True)
    if "figaroh" in parts:
        sections["figaroh"] = figaroh_part(args.figaroh_examples)
        print("\n" + sections["figaroh"] + "\n", flush=True)
    if "long-log" in parts:
        sections["long-log"] = long_log_part(0.5 if args.quick else args.long_minutes)
        print("\n" + sections["long-log"] + "\n", flush=True)
    if "ur10-truth" in parts:  # FIGAROH's UR10 truth fixture (benchmarks/peer_ur10_truth.py)
        sections["ur10-truth"] = ur10_truth.table(n_seeds=1 if args.quick else 5)
        print("\n" + sections["ur10-truth"] + "\n", flush=True)
    if "excitation" in parts:
        sections["excitation"] = excitation_part(args.figaroh_examples, quick=args.quick)[0]
        print("\n" + sections["excitation"] + "\n", flush=True)
    if "sysid" in parts:
        if have_sysid:
            sections["sysid-duel"] = duel_part(args, robots, max_iters)
            print("\n" + sections["sysid-duel"] + "\n", flush=True)
        else:
            print("mujoco.sysid not importable (pip install -e '.[peers]'): skipped")
    if args.write_docs is not None:  # a skipped peer keeps the figures the page has
        measured = {k: v for k, v in sections.items() if not v.endswith("skipped")}
        write_docs(args.write_docs, measured, cmd, where)
    return 0


# ---------------------------------------------------------------------------------------------
# Long logs: ident identify on an hour at 1 kHz of a 7-joint arm, in its own process


def long_log_part(minutes: float) -> str:
    """``ident identify`` on ``minutes`` of a 7-joint 1 kHz log (the Panda without fingers,
    ``bench_identify_long.py``'s generator), as a numpy archive and as an MCAP of JointState
    messages, each in its own process: wall, CPU and peak resident memory, and the consistent
    model written (goal for one hour from MCAP: < 60 s and < 1 GB on 2 cores). No peer is run
    on it."""
    import bench_identify_long as long_log

    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-peers-long-") as tmp:
        folder = Path(tmp)
        urdf = long_log.panda7(folder)
        log = folder / "long.npz"
        long_log.generate(urdf, minutes, 1000.0, log)
        model = pin.buildModelFromUrdf(str(urdf))
        joints = [model.names[i] for i in range(1, model.njoints)]
        mcap = folder / "long.mcap"
        long_log.write_mcap(mcap, log, joints)
        cases = {
            f"numpy archive ({log.stat().st_size / 2**20:.0f} MB)": long_log.config(
                urdf, log, folder / "long.yaml", max_regressor_mb=256.0
            ),
            f"MCAP of JointState ({mcap.stat().st_size / 2**20:.0f} MB, zstd)": (
                long_log.mcap_config(urdf, mcap, folder / "mcap.yaml", joints)
            ),
        }
        for k, (what, cfg) in enumerate(cases.items()):
            load = os.getloadavg()[0]
            run = long_log.run_cli(cfg, folder / f"runs-{k}")
            (rundir,) = (folder / f"runs-{k}").iterdir()
            written = json.loads((rundir / "result.json").read_text())["model"]
            parity = max(written["reload_parity"]["urdf"], written["reload_parity"]["mjcf"])
            rows.append(
                f"| {what} | {run['wall_s']:.1f} | {run['cpu_s']:.1f} | {run['peak_mb']:.0f} | "
                f"{written['method']} URDF + MJCF, reloaded to {parity:.0e} | {load:.1f} |"
            )
    n = int(minutes * 60 * 1000)
    return "\n".join(
        [
            f"**Long log** ({minutes:g} min at 1 kHz, 7 joints: {n} samples; `ident identify` "
            "in its own process, chunked)",
            "",
            "| log | wall [s] | CPU [s] | peak RSS [MB] | written model | load at start |",
            "|---|---|---|---|---|---|",
            *rows,
            "",
            "Goal for one hour from MCAP: < 60 s and < 1 GB (1024 MB) on 2 cores.",
        ]
    )


def write_docs(path: Path, sections: dict[str, str], cmd: str, where: str) -> None:
    """Replace each section's block ``<!-- bench_peers:NAME -->`` ... ``<!-- /bench_peers:NAME
    -->`` of ``path`` with this run's command, machine and table; other blocks are kept."""
    text = path.read_text(encoding="utf-8")
    for name, body in sections.items():
        begin, end = f"<!-- bench_peers:{name} -->", f"<!-- /bench_peers:{name} -->"
        if begin not in text or end not in text:
            print(f"{path}: no block {begin}: not written")
            continue
        head, rest = text.split(begin, 1)
        _, tail = rest.split(end, 1)
        block = f"`{cmd}`\n\nmachine: {where}\n\n{body}\n"
        text = f"{head}{begin}\n{block}{end}{tail}"
    path.write_text(text, encoding="utf-8")
    print(f"{path}: {', '.join(sections)} updated")


if __name__ == "__main__":
    raise SystemExit(main())
