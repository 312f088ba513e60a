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
