"""Robots the tests share: example-robot-data URDFs and small random Pinocchio chains.

Imported by the test modules as ``robots`` (pytest puts ``tests/`` on ``sys.path``).
"""

from __future__ import annotations

import importlib.metadata
from collections.abc import Callable, Sequence
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import yaml

from ident.measure.ideal import NoiseModel, simulate_measurements

# example-robot-data ships data only (no Python module): its files are under the cmeel prefix.
ERD_SHARE = Path(
    str(importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share"))
)
ERD_ROBOTS = ERD_SHARE / "example-robot-data/robots"
UR5_URDF = ERD_ROBOTS / "ur_description/urdf/ur5_robot.urdf"
PANDA_URDF = ERD_ROBOTS / "panda_description/urdf/panda.urdf"


def ur5_with_limits() -> SimpleNamespace:
    """UR5 as a plain namespace with the attributes the excitation families read (no Robot):
    its URDF limits, and 10 rad/s^2 accelerations (the URDF has none)."""
    model = pin.buildModelFromUrdf(str(UR5_URDF))
    return SimpleNamespace(
        model=model,
        joint_names=tuple(model.names[1:]),
        q_lower=model.lowerPositionLimit.copy(),
        q_upper=model.upperPositionLimit.copy(),
        dq_max=model.velocityLimit.copy(),
        ddq_max=np.full(model.nv, 10.0),
    )


def random_chain(
    joint_types: Sequence[Callable[[np.ndarray], pin.JointModel]], seed: int
) -> pin.Model:
    """Serial chain of random placements and inertias, one joint per entry of ``joint_types``.

    Each entry builds its joint from a random unit axis (drawn for every joint, used or not);
    ``seed`` seeds both numpy (axes) and Pinocchio (placements, inertias).
    """
    rng = np.random.default_rng(seed)
    pin.seed(seed)
    model, parent = pin.Model(), 0
    for k, joint_type in enumerate(joint_types):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        parent = model.addJoint(parent, joint_type(axis), pin.SE3.Random(), f"joint{k + 1}")
        model.appendBodyToJoint(parent, pin.Inertia.Random(), pin.SE3.Identity())
    return model


RP2_URDF = Path(__file__).resolve().parent / "data" / "urdf" / "rp2.urdf"
RP2_RATE_HZ = 100.0


def rp2_identify_config(tmp_path: Path, seed: int = 3) -> Path:
    """A 12 s log of the revolute-prismatic rp2 arm (wide CSV) and its identify config;
    ``seed``: of the measurement noise. The truth: the URDF's inertials, viscous friction
    (0.4, 2.0) and Coulomb friction (0.3, 1.5)."""
    model = pin.buildModelFromUrdf(str(RP2_URDF))
    t = np.arange(int(12 * RP2_RATE_HZ)) / RP2_RATE_HZ
    w = 2.0 * np.pi * 0.25 * np.array([1.0, 2.0, 3.0])
    # shoulder: +-1 rad; slider: +-0.15 m, inside its limits
    amp = np.array([[0.6, 0.08], [0.3, 0.05], [0.15, 0.02]])
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q, dq, ddq = s @ amp, (c * w) @ amp, -(s * w**2) @ amp
    m = simulate_measurements(model, t, q, dq, ddq, NoiseModel(torque_std=(0.02, 0.05)), rng=seed)
    tau = m.tau + np.array([0.4, 2.0]) * dq + np.array([0.3, 1.5]) * np.sign(dq)
    header = "t,q_shoulder,q_slider,tau_shoulder,tau_slider"
    rows = np.column_stack([t, m.q, tau])
    log = tmp_path / "rp2.csv"
    log.write_text(header + "\n" + "\n".join(",".join(f"{v:.9g}" for v in r) for r in rows))
    cfg = {
        "name": "rp2",
        "robot": {"urdf": str(RP2_URDF)},
        "log": {
            "time": {"path": str(log), "column": "t"},
            "position": {"path": str(log), "columns": ["q_shoulder", "q_slider"]},
            "torque": {"path": str(log), "columns": ["tau_shoulder", "tau_slider"]},
        },
        "transmission": {},
        "preprocess": {"lowpass": {"cutoff_hz": 10.0, "order": 4}, "trim_samples": 10},
        "model": {"viscous": True, "coulomb": True, "offset": False, "rotor_inertia": False},
        "estimation": {"method": "wls", "essential": {"enabled": False}},
        "validation": {"identify_fraction": 0.7},
    }
    path = tmp_path / "rp2.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path
