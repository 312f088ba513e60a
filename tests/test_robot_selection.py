"""One robot selection for every command: chains of URDFs, inertial checks, same verdicts.

The reference for "same robot" is the command's own rank of the base parameters: ``verify``
(random states, both methods), ``run`` (the stage's structural base parameters) and
``identify`` (the identification model's base parameters) must agree on it, and must accept
and refuse the same files, over every URDF of example-robot-data.
"""

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from robots import ERD_ROBOTS, ERD_SHARE, PANDA_URDF, UR5_URDF

from ident.cli.verify import run_verification
from ident.dynamics.friction import ExtraTerms
from ident.dynamics.parameter_model import build_parameter_model
from ident.errors import ConfigError, IdentError, ModelError
from ident.model.selection import RobotSelection, load_robot, selection_from_flags
from ident.robot.urdf_load import suggested_locks
from ident.run.config import RunConfig
from ident.run.pipeline import build_stage_info
from ident.run.setup import prepare_run

FINGERS = {"panda_finger_joint1": 0.01, "panda_finger_joint2": 0.01}


def test_base_and_tip_link_select_the_arm_of_panda() -> None:
    robot = load_robot(RobotSelection(urdf=PANDA_URDF, tip_link="panda_link7"))
    assert robot.joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))
    assert set(robot.locked_joints) == {"panda_finger_joint1", "panda_finger_joint2"}
    # the locked fingers' mass rides on the last body: same torques as locking them by name
    by_name = load_robot(RobotSelection(urdf=PANDA_URDF, lock={k: 0.0 for k in FINGERS}))
    np.testing.assert_allclose(robot.parameters(), by_name.parameters(), rtol=1e-12)
    # a shorter chain: joints 5..7 move, the rest is held
    part = load_robot(
        RobotSelection(urdf=PANDA_URDF, base_link="panda_link4", tip_link="panda_link7")
    )
    assert part.joint_names == ("panda_joint5", "panda_joint6", "panda_joint7")
    # joint 4's range [-3.0718, -0.0698] excludes 0: held at the closest limit, not at an
    # impossible posture
    assert part.locked_joints["panda_joint4"] == pytest.approx(-0.0698)
    assert part.locked_joints["panda_joint1"] == 0.0


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"tip_link": "panda_lnk7"}, "did you mean 'panda_link7'"),
        ({"base_link": "panda_link5", "tip_link": "panda_link2"}, "not below robot.base_link"),
        ({"base_link": "panda_link7", "tip_link": "panda_link7"}, "no joint moves"),
    ],
)
def test_bad_chain_selection_names_the_key(fields, message) -> None:
    with pytest.raises(ModelError, match=message):
        load_robot(RobotSelection(urdf=PANDA_URDF, **fields))


def _with_broken_inertial(tmp_path: Path, link: str) -> Path:
    text = UR5_URDF.read_text()
    start = text.index(f'<link name="{link}">')
    mass = text.index('<mass value="', start)
    end = text.index('"', mass + len('<mass value="'))
    broken = text[: mass + len('<mass value="')] + "-1.0" + text[end:]
    path = tmp_path / f"ur5_broken_{link}.urdf"
    path.write_text(broken)
    return path


def test_inertials_are_checked_on_moving_links_only_with_an_override(tmp_path) -> None:
    # base_link is fixed to the world: its inertial cannot change any torque
    fixed = load_robot(RobotSelection(urdf=_with_broken_inertial(tmp_path, "base_link")))
    reference = load_robot(RobotSelection(urdf=UR5_URDF))
    np.testing.assert_array_equal(fixed.parameters(), reference.parameters())
    moving = _with_broken_inertial(tmp_path, "forearm_link")
    with pytest.raises(ModelError, match="forearm_link.*inertia_check: false"):
        load_robot(RobotSelection(urdf=moving))
    loaded = load_robot(RobotSelection(urdf=moving, inertia_check=False))
    assert loaded.parameters()[20] == -1.0  # body 3's mass, as the file says


def test_shorthand_and_flags_build_the_same_selection() -> None:
    assert RobotSelection.model_validate("configs/paper6r.yaml").description == Path(
        "configs/paper6r.yaml"
    )
    assert RobotSelection.model_validate("x/robot.URDF").urdf == Path("x/robot.URDF")
    flags = selection_from_flags(urdf=PANDA_URDF, lock=FINGERS)
    assert flags == RobotSelection(urdf=PANDA_URDF, lock=FINGERS)
    with pytest.raises(ConfigError, match="--urdf only"):
        selection_from_flags(robot=Path("configs/paper6r.yaml"), tip_link="flange")
    with pytest.raises(ValueError, match="exactly one"):
        RobotSelection()


# --------------------------------------------------------------------------------------
# every example-robot-data URDF: same verdict and same rank in verify, run and identify


def _erd_selection(path: Path) -> RobotSelection:
    """The file with the joints suggested for locking held at 0 (clipped into their range)."""
    model = pin.buildModelFromUrdf(str(path))
    lock = {}
    for name in suggested_locks(model):
        idx = model.joints[model.getJointId(name)].idx_q
        low, high = model.lowerPositionLimit[idx], model.upperPositionLimit[idx]
        lock[name] = float(np.clip(0.0, low, high)) if high > low else 0.0
    return RobotSelection(urdf=path, lock=lock, package_dirs=[ERD_SHARE])  # run's collision meshes


def _verdicts(selection: RobotSelection) -> dict[str, object]:
    out: dict[str, object] = {}
    try:
        out["verify"] = run_verification(selection, samples=120, seed=0)["rank"]
    except IdentError as e:
        out["verify"] = f"refused: {type(e).__name__}"
    try:
        # the rank is the question here, not a safety margin: robots whose links sit within
        # the default 3 cm in every posture, or legged robots whose feet start below z = 0,
        # are refused by the safety section (tests/test_safety_environment.py); the safety
        # model is still built on every robot's collision meshes; robots without any geometry
        # are refused unless self-collision is declined (tests/test_mesh_paths.py)
        safety = {
            "clearance_m": 0.0,
            "floor": {"enabled": False},
            "self_collision": _has_geometry(selection.urdf),
        }
        setup = prepare_run(
            RunConfig(
                robot=selection,
                excitation={"family": "joint_fourier", "n_samples": 40},
                safety=safety,
            )
        )
        info = build_stage_info(
            setup.robot, setup.stage, setup.family, "qr", np.random.default_rng(0)
        )
        out["run"] = info.base.rank
    except IdentError as e:
        out["run"] = f"refused: {type(e).__name__}"
    try:
        model = load_robot(selection).model
        rigid = ExtraTerms.from_options(  # the rigid bodies, as verify and run count them
            model.nv, rotor_inertia=False, viscous=False, coulomb=False, offset=False
        )
        out["identify"] = build_parameter_model(model, rigid).base.rank
    except IdentError as e:
        out["identify"] = f"refused: {type(e).__name__}"
    return out


def _has_geometry(path: Path) -> bool:
    text = path.read_text()
    return "<collision" in text or "<visual" in text


def _loadable_by_pinocchio(path: Path) -> bool:
    try:
        pin.buildModelFromUrdf(str(path))
    except (RuntimeError, ValueError):
        return False
    return True


# Heavy files (9-28 s each here: hundreds of meshes or dozens of joints) whose structure a
# lighter file of the same family covers: tiago_no_hand, b1-z1, go1/go2/laikago, so100, the
# talos and romeo humanoids, the double pendulum. They add no verdict path, only CI time.
COVERED_BY_A_LIGHTER_FILE = {
    "tiago_description/robots/tiago.urdf",
    "tiago_description/robots/tiago_dual.urdf",
    "tiago_pro_description/robots/tiago_pro.urdf",
    "alexander_description/urdf/alexander_v1.lowerBodyOnly.urdf",
    "a1_description/urdf/a1.urdf",
    "g1_description/urdf/g1_29dof_rev_1_0.urdf",
    "g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf",
    "so_arm_description/urdf/so101.urdf",
    "human_description/robots/human.urdf",
    "asr_twodof_description/urdf/TwoDofs.urdf",
    "z1_description/urdf/z1.urdf",
}
ERD_URDFS = sorted(
    p
    for p in ERD_ROBOTS.rglob("*.urdf")
    if str(p.relative_to(ERD_ROBOTS)) not in COVERED_BY_A_LIGHTER_FILE and _loadable_by_pinocchio(p)
)


@pytest.mark.slow
@pytest.mark.parametrize("path", ERD_URDFS, ids=lambda p: str(p.relative_to(ERD_ROBOTS)))
def test_verify_run_identify_agree_on_every_example_robot(path: Path) -> None:
    verdicts = _verdicts(_erd_selection(path))
    assert len(set(verdicts.values())) == 1, verdicts
