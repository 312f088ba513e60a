"""Writing identified inertial parameters back into a URDF copy: threshold, consistency, values."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from ident.dynamics.parameters import parameter_names, parameters_from_model
from ident.identify.model_files.urdf_update import update_urdf_inertials
from ident.identify.pipeline.real import load_robot_model
from ident.robot.inertia import PINOCCHIO_ORDER, consistency_problems

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "staubli-tx40"
URDF = DATA / "urdf" / "tx40_mdh_modified.urdf"
JOINTS = tuple(f"joint_{j}" for j in range(1, 7))
NAMES = parameter_names(6)


def _nominal():
    return parameters_from_model(load_robot_model(URDF))


def _load(text, tmp_path):
    """Standard parameters of a URDF text, loaded by Pinocchio."""
    path = tmp_path / "updated.urdf"
    path.write_text(text)
    return parameters_from_model(load_robot_model(path))


def _check(update, nominal, identified, threshold, tmp_path):
    """The copy loads; written = identified, else nominal; consistent links; threshold held."""
    values = _load(update.text, tmp_path)
    written = update.written
    for k, name in enumerate(NAMES):
        expected = identified[name][0] if name in written else nominal[k]
        assert values[k] == pytest.approx(expected, rel=1e-7, abs=1e-12), name
    for i in range(6):
        assert consistency_problems(values[10 * i : 10 * i + 10]) == [], f"link_{i + 1}"
    for name in written:
        assert identified[name][1] < threshold, name
    for name, rel in update.uncertain.items():
        assert not rel < threshold, name
    # every determined parameter is accounted for exactly once
    rejected = {k for link in update.links for k in link.rejected}
    assert set(written) | set(update.uncertain) | rejected == set(identified)
    assert set(update.not_determined) == set(NAMES) - set(identified)
    return values


@pytest.mark.parametrize("threshold", [5.0, 15.0, 40.0, 1e9])
def test_only_values_below_the_threshold_are_written(tmp_path, threshold):
    nominal = _nominal()
    # small consistent changes of the links' first moments and products of inertia
    # (link 6 is a point mass in the URDF: any change of its inertia alone is inconsistent)
    rel_std = {"mcx3": 2.0, "Ixy3": 12.0, "mcx4": 4.9, "Ixy4": 30.0, "Iyz5": 5.0, "mcx5": 60.0}
    change = {"mcx3": 0.004, "Ixy3": 2e-4, "mcx4": -0.003, "Ixy4": 1e-4, "Iyz5": 1e-4, "mcx5": 1e-3}
    identified = {
        name: (nominal[NAMES.index(name)] + change[name], rel) for name, rel in rel_std.items()
    }
    update = update_urdf_inertials(
        URDF.read_text(), JOINTS, nominal, identified, max_relative_std_pct=threshold
    )
    _check(update, nominal, identified, threshold, tmp_path)
    assert set(update.written) == {n for n, r in rel_std.items() if r < threshold}
    assert update.inconsistent_links == {}
    # the boundary: a relative std equal to the threshold is not written
    assert ("Iyz5" in update.written) == (threshold > 5.0)
    by_link = {link.link: link for link in update.links}
    assert by_link["link_1"].status == "nominal"
    assert by_link["link_3"].status == ("updated" if threshold > 2.0 else "nominal")


def test_inconsistent_link_keeps_its_nominal_inertial(tmp_path):
    nominal = _nominal()
    k_ixz6, k_mcx4 = NAMES.index("Ixz6"), NAMES.index("mcx4")
    identified = {
        # link 6: a product of inertia far larger than its moments -> indefinite inertia
        "Ixz6": (0.05, 1.0),
        "Izz6": (nominal[NAMES.index("Izz6")] + 1e-5, 2.0),
        # link 4: a consistent change
        "mcx4": (nominal[k_mcx4] - 0.002, 3.0),
        # link 5: uncertain, not written whatever its value
        "Ixy5": (1.0, 150.0),
        "mcx5": (np.nan, float("inf")),
    }
    update = update_urdf_inertials(
        URDF.read_text(), JOINTS, nominal, identified, max_relative_std_pct=10.0
    )
    values = _check(update, nominal, identified, 10.0, tmp_path)
    assert set(update.written) == {"mcx4"}
    assert values[k_ixz6] == pytest.approx(nominal[k_ixz6], abs=1e-12)
    (link6,) = [link for link in update.links if link.link == "link_6"]
    assert link6.status == "nominal (inconsistent)"
    assert set(link6.rejected) == {"Ixz6", "Izz6"}
    assert "positive semi-definite" in update.inconsistent_links["link_6"]
    # the rejected candidate really is inconsistent
    phi = nominal[50:60].copy()
    phi[NAMES.index("Ixz6") - 50] = 0.05
    assert consistency_problems(phi)
    assert set(update.uncertain) == {"Ixy5", "mcx5"}


def test_invalid_threshold():
    with pytest.raises(ValueError, match="max_relative_std_pct"):
        update_urdf_inertials(URDF.read_text(), JOINTS, _nominal(), {}, max_relative_std_pct=0.0)


@pytest.fixture(scope="module")
def tx40_result(tmp_path_factory):
    """WLS identification of the first 4 s of the measured TX40 log (decimated to 50 Hz)."""
    from ident.identify.config import load_identify_config
    from ident.identify.pipeline.real import identify

    cfg = yaml.safe_load((ROOT / "configs" / "tx40.yaml").read_text())
    cfg["robot"]["urdf"] = str(URDF)
    cfg["log"]["position"]["path"] = str(DATA / "data" / "pos_read_data.csv.gz")
    cfg["log"]["torque"]["path"] = str(DATA / "data" / "curr_data.csv.gz")
    cfg["log"]["max_samples"] = 20000
    cfg["estimation"]["essential"]["enabled"] = False
    for key in ("base_parameters", "essential_parameters"):
        cfg["reference"][key] = None
    path = tmp_path_factory.mktemp("cfg") / "tx40.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return identify(load_identify_config(path))


@pytest.mark.parametrize("threshold", [10.0, 50.0, 1e9])
def test_tx40_identification_written_back_safely(tx40_result, tmp_path, threshold):
    from ident.report.identify_report import identified_urdf

    cfg = tx40_result.config
    cfg = cfg.model_copy(
        update={
            "urdf_update": cfg.urdf_update.model_copy(update={"max_relative_std_pct": threshold})
        }
    )
    result = dataclasses.replace(tx40_result, config=cfg)
    update = identified_urdf(result)
    pm, est = result.parameters, result.estimate
    identified = {}
    for k, i in enumerate(pm.base.independent):
        if not pm.base_names[k].endswith("R") and pm.inertial_index[i] >= 0:
            identified[pm.names[i]] = (est.x[k], est.relative_std[k])
    assert len(identified) == 21  # as on the full log
    _check(update, _nominal(), identified, threshold, tmp_path)
    assert update.max_relative_std_pct == threshold
    if threshold == 10.0:
        # the default: none of the 21 is that well determined by 4 s of data (19 % at best)
        assert update.written == {}
        assert set(update.uncertain) == set(identified)
    if threshold == 1e9:
        # every determined parameter is a candidate; the links they make inconsistent keep
        # their nominal inertial (on this log: all of links 2-6)
        assert set(update.inconsistent_links) == {f"link_{j}" for j in range(2, 7)}
        for link in update.links:
            if link.problem:
                assert not link.written
                assert link.rejected


# ---- whole-model write-back of a consistent estimate ----------------------------------------
def _tx40_parameter_model():
    from ident.dynamics.friction import ExtraTerms
    from ident.dynamics.parameter_model import build_parameter_model

    model = load_robot_model(URDF)
    terms = ExtraTerms.from_options(
        6, rotor_inertia=[1, 2, 3, 4, 5], coupled_wrist=[5, 6]
    )  # as configs/tx40.yaml
    return model, build_parameter_model(model, terms)


def _consistent_theta(pm, seed=0):
    """Nominal bodies plus a small box each (consistent), positive friction, any offsets."""
    import pinocchio as pin

    rng = np.random.default_rng(seed)
    theta = pm.nominal.copy()
    index = {n: i for i, n in enumerate(pm.names)}
    for j in range(1, 7):
        box = pin.Inertia.FromBox(rng.uniform(0.1, 1.0), *rng.uniform(0.02, 0.2, size=3))
        extra = np.asarray(pin.SE3.Random().act(box).toDynamicParameters())
        extra[1:4] *= 0.1  # keep it near the link
        extra = np.asarray(pin.Inertia.FromDynamicParameters(extra).toDynamicParameters())
        for k, label in enumerate(PINOCCHIO_ORDER):
            theta[index[f"{label}{j}"]] += extra[k]
    for i, name in enumerate(pm.names):
        if pm.inertial_index[i] < 0:
            theta[i] = rng.uniform(0.05, 2.0) if not name.startswith("off") else rng.normal()
    return theta


def test_whole_model_write_back_reproduces_the_estimate_torques(tmp_path):
    import pinocchio as pin

    from ident.dynamics.chain import chain_from_model, random_states
    from ident.identify.estimators.identification import standard_regressor
    from ident.identify.model_files.urdf_update import write_identified_model

    model, pm = _tx40_parameter_model()
    theta = _consistent_theta(pm)
    written = write_identified_model(URDF.read_text(), JOINTS, theta, pm.names, pm.nominal)
    assert written.links == tuple(f"link_{j}" for j in range(1, 7))
    new = pin.buildModelFromXML(written.text)
    q, dq, ddq = random_states(chain_from_model(model), 50, rng=3)
    expected = standard_regressor(model, pm, q, dq, ddq) @ theta
    data = new.createData()
    rnea = np.array([pin.rnea(new, data, q[k], dq[k], ddq[k]) for k in range(50)])
    side = written.sidecar
    extras = np.zeros_like(rnea)
    for j, joint in enumerate(JOINTS):
        e = side["joints"][joint]
        extras[:, j] = (
            e["rotor_inertia"] * ddq[:, j]
            + e["viscous"] * dq[:, j]
            + e["coulomb"] * np.sign(dq[:, j])
            + e["offset"]
        )
    (motor,) = side["coupled_motors"]
    assert motor["motor_joint"] == "joint_6"
    for j in (4, 5):  # rows of joints 5 and 6
        extras[:, j] += (
            motor["rotor_inertia"] * (ddq[:, 4] + ddq[:, 5])
            + motor["viscous"] * (dq[:, 4] + dq[:, 5])
            + motor["coulomb"] * np.sign(dq[:, 4] + dq[:, 5])
        )
    np.testing.assert_allclose(
        rnea + extras, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max()
    )
    # URDF <dynamics> holds the joint friction; Pinocchio reads it
    index = {n: i for i, n in enumerate(pm.names)}
    np.testing.assert_allclose(new.damping, [theta[index[f"fv{j}"]] for j in range(1, 7)])
    np.testing.assert_allclose(new.friction, [theta[index[f"fs{j}"]] for j in range(1, 7)])
    json_text = __import__("json").dumps(side)  # the sidecar is JSON-ready
    assert "rotor_inertia" in json_text


def test_whole_model_write_back_loads_in_yourdfpy_and_mujoco(tmp_path):
    import re

    import yourdfpy

    mujoco = pytest.importorskip("mujoco")

    from ident.identify.model_files.urdf_update import write_identified_model

    _, pm = _tx40_parameter_model()
    theta = _consistent_theta(pm, seed=1)
    text = write_identified_model(URDF.read_text(), JOINTS, theta, pm.names, pm.nominal).text
    path = tmp_path / "identified.urdf"
    path.write_text(text)
    robot = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False)
    index = {n: i for i, n in enumerate(pm.names)}
    assert robot.link_map["link_3"].inertial.mass == pytest.approx(theta[index["m3"]])
    # the meshes of this URDF are not shipped: MuJoCo reads the dynamics without geometry
    bare = re.sub(r"<(visual|collision)>.*?</\1>", "", text, flags=re.S)
    mj = mujoco.MjModel.from_xml_string(bare)
    body = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, "link_3")
    assert mj.body_mass[body] == pytest.approx(theta[index["m3"]])
    dof = mj.jnt_dofadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, "joint_3")]
    assert mj.dof_damping[dof] == pytest.approx(theta[index["fv3"]])
    assert mj.dof_frictionloss[dof] == pytest.approx(theta[index["fs3"]])


def test_whole_model_write_back_refuses_an_inconsistent_estimate():
    from ident.errors import ModelError
    from ident.identify.model_files.urdf_update import write_identified_model

    _, pm = _tx40_parameter_model()
    theta = pm.nominal.copy()
    theta[pm.names.index("Izz3")] = -1.0
    with pytest.raises(
        ModelError, match=r"link_3.*not physically consistent|not physically consistent.*link_3"
    ):
        write_identified_model(URDF.read_text(), JOINTS, theta, pm.names, pm.nominal)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ('<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY m "1.0">]><robot name="r"/>', "DOCTYPE"),
        ("<robot name='r'><link name='a'></robot>", "malformed URDF XML"),
        ("<sdf/>", "not <robot>"),
    ],
)
def test_odd_xml_is_refused_with_a_message(text, match):
    from ident.errors import ModelError
    from ident.identify.model_files.urdf_update import write_identified_model

    _, pm = _tx40_parameter_model()
    with pytest.raises(ModelError, match=match):
        write_identified_model(text, JOINTS, pm.nominal, pm.names, pm.nominal)
    with pytest.raises(ModelError, match=match):
        update_urdf_inertials(text, JOINTS, _nominal(), {})


# ---- write-back on real files: transmissions, welded and locked bodies ----------------------
import robots  # noqa: E402  (tests/robots.py: example-robot-data paths)

ROBOTS = {  # name: (URDF, Robot.from_urdf options)
    "paper6r": (ROOT / "robot" / "urdf" / "paper6r.urdf", {}),
    "ur5": (ROOT / "robot" / "urdf" / "ur5.urdf", {}),  # <transmission> blocks
    "panda-hand-locked": (
        ROOT / "robot" / "urdf" / "panda.urdf",
        {"lock_joints": {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.03}},
    ),
    "tx40": (URDF, {}),
    # example-robot-data: transmissions and a gripper welded by fixed joints
    "erd-ur5-gripper": (robots.ERD_ROBOTS / "ur_description/urdf/ur5_gripper.urdf", {}),
    # transmissions and a locked gripper joint
    "erd-z1-gripper-locked": (
        robots.ERD_ROBOTS / "z1_description/urdf/z1.urdf",
        {"lock_joints": {"jointGripper": -0.5}},
    ),
    # transmissions, continuous joints, fingers welded by fixed joints
    "erd-kinova": (robots.ERD_ROBOTS / "kinova_description/robots/kinova.urdf", {}),
    "erd-panda-hand-locked": (
        robots.PANDA_URDF,
        {"lock_joints": {"panda_finger_joint1": 0.01, "panda_finger_joint2": 0.04}},
    ),
    # a mobile manipulator's torso and arm: transmissions, the base (continuous wheels), head
    # and gripper locked (40 joints), a prismatic torso joint
    "erd-tiago-torso-arm": (
        robots.ERD_ROBOTS / "tiago_description/robots/tiago.urdf",
        {"base_link": "torso_fixed_link", "tip_link": "arm_7_link"},
    ),
}


def robot_under_test(key):
    from ident.model import Robot

    path, options = ROBOTS[key]
    return Robot.from_urdf(path, **options)


def _extras_names(n):
    return tuple(f"{label}{j}" for j in range(1, n + 1) for label in ("Ia", "fv", "fs", "off"))


def perturbed_theta(robot, seed, *, scale=None):
    """A consistent estimate: each nominal body plus a random box, or times ``scale``; extras
    random positive (offsets any sign). Returns (theta, names)."""
    import pinocchio as pin

    rng = np.random.default_rng(seed)
    pin.seed(seed)
    bodies = robot.parameters().reshape(-1, 10).copy()
    for j, body in enumerate(bodies):
        if scale is not None and j in scale:
            bodies[j] = body * scale[j]
            continue
        box = pin.Inertia.FromBox(rng.uniform(0.05, 0.5), *rng.uniform(0.02, 0.2, size=3))
        placement = pin.SE3(pin.SE3.Random().rotation, rng.uniform(-0.05, 0.05, size=3))
        if consistency_problems(body):  # a real file's impossible link: the box alone
            body = np.zeros(10)
        bodies[j] = body + np.asarray(placement.act(box).toDynamicParameters())
        assert consistency_problems(bodies[j]) == []
    extras = rng.uniform(0.01, 1.0, size=4 * robot.n_bodies)
    extras[3::4] = rng.normal(size=robot.n_bodies)
    names = robot.parameter_names() + _extras_names(robot.n_bodies)
    return np.concatenate([bodies.reshape(-1), extras]), names


def _without_edited_elements(text):
    """The text minus every top-level link's <inertial> and joint's <dynamics>, no blanks."""
    from ident.identify.model_files.urdf_edit import spans

    found = spans(text)
    cuts = [s.inertial for s in found.links.values() if s.inertial is not None]
    cuts += [s.dynamics for s in found.joints.values() if s.dynamics is not None]
    data = found.data
    kept, at = [], 0
    for cut in sorted(cuts, key=lambda c: c.start):
        kept.append(data[at : cut.start])
        at = cut.end
    kept.append(data[at:])
    return b"".join(b"".join(kept).split())


def _reload_parity(robot, written_text, theta, tmp_path):
    """Pinocchio RNEA of the reloaded file (same locks) against regressor @ theta."""
    from ident.model import Robot

    path = tmp_path / "identified.urdf"
    path.write_text(written_text)
    new = Robot.from_urdf(path, lock_joints=robot.locked_joints or None)
    assert new.joint_names == robot.joint_names
    q, dq, ddq = robot.random_configurations(40, rng=7)
    expected = robot.regressor(q, dq, ddq) @ theta[: 10 * robot.n_bodies]
    got = new.rnea(q, dq, ddq)
    scale = np.abs(expected).max()
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9 * scale)
    # and the wrong answer is far: the nominal model
    assert np.abs(robot.rnea(q, dq, ddq) - expected).max() > 1e-4 * scale
    return new


@pytest.mark.parametrize("key", list(ROBOTS))
def test_whole_model_write_back_reload_parity(key, tmp_path):
    from ident.identify.model_files.urdf_update import identified_urdf

    robot = robot_under_test(key)
    theta, names = perturbed_theta(robot, seed=len(key))
    written = identified_urdf(
        robot.urdf_text, robot.model, theta, names, nominal=robot.parameters()
    )
    new = _reload_parity(robot, written.text, theta, tmp_path)
    # every link keeps a positive mass (welded links kept here: the boxes only add mass)
    assert written.welded_scale == {}
    # the rest of the file is unchanged: transmissions, gazebo blocks, meshes, comments
    assert _without_edited_elements(written.text) == _without_edited_elements(robot.urdf_text)
    assert written.text.count("<transmission") == robot.urdf_text.count("<transmission")
    # Pinocchio reads the friction written into <dynamics>
    index = {n: i for i, n in enumerate(names)}
    np.testing.assert_allclose(
        new.model.damping, [theta[index[f"fv{j}"]] for j in range(1, robot.n_bodies + 1)]
    )
    np.testing.assert_allclose(
        new.model.friction, [theta[index[f"fs{j}"]] for j in range(1, robot.n_bodies + 1)]
    )


@pytest.mark.parametrize("key", ["panda-hand-locked", "erd-panda-hand-locked"])
def test_a_light_body_scales_its_welded_links_never_a_negative_mass(key, tmp_path):
    """A body lighter than its welded hand/gripper: the carrying link cannot take body minus
    nominal hand (negative mass); the welded links are scaled down, the sum stays exact."""
    from ident.identify.model_files.fused_bodies import link_inertial, parse_urdf
    from ident.identify.model_files.urdf_update import identified_urdf

    robot = robot_under_test(key)
    last = robot.n_bodies - 1
    theta, names = perturbed_theta(robot, seed=3, scale={last: 0.1})
    written = identified_urdf(robot.urdf_text, robot.model, theta, names)
    (carrier,) = written.welded_scale
    assert 0.0 <= written.welded_scale[carrier] < 1.0
    _reload_parity(robot, written.text, theta, tmp_path)
    root = parse_urdf(written.text)
    for link in root.findall("link"):
        own = link_inertial(link)
        assert own[0] >= 0.0, link.get("name")
        if own[0] > 0:
            assert consistency_problems(own) == [], link.get("name")


def test_write_back_refuses_a_model_with_other_locks():
    from ident.errors import ModelError
    from ident.identify.model_files.urdf_update import write_identified_model

    robot = robot_under_test("panda-hand-locked")
    theta, names = perturbed_theta(robot, seed=0)
    with pytest.raises(ModelError, match="lock the same joints"):
        write_identified_model(
            robot.urdf_text, robot.joint_names, theta, names, theta
        )  # the fingers not locked: nine joints, not seven
    # locked at other positions: the nominal fused hand differs
    nominal = np.concatenate([robot.parameters(), np.zeros(len(names) - 10 * robot.n_bodies)])
    with pytest.raises(ModelError, match="not the sum of its links"):
        write_identified_model(
            robot.urdf_text,
            robot.joint_names,
            theta,
            names,
            nominal,
            locked={"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0},
        )
    # with the identification's locks it is written
    write_identified_model(
        robot.urdf_text, robot.joint_names, theta, names, nominal, locked=robot.locked_joints
    )


def test_cautious_copy_composes_the_welded_hand(tmp_path):
    """The cautious copy changes the fused body by the candidates only (the hand stays)."""
    robot = robot_under_test("erd-panda-hand-locked")
    nominal = robot.parameters()
    names = robot.parameter_names()
    k = names.index("mcx7")
    identified = {"mcx7": (nominal[k] + 0.01, 1.0)}
    update = update_urdf_inertials(
        robot.urdf_text, robot.joint_names, nominal, identified, model=robot.model
    )
    assert set(update.written) == {"mcx7"}
    (link7,) = [link for link in update.links if link.joint == "panda_joint7"]
    assert "panda_hand" in link7.welded
    assert link7.welded_scale == 1.0
    path = tmp_path / "cautious.urdf"
    path.write_text(update.text)
    from ident.model import Robot

    values = Robot.from_urdf(path, lock_joints=robot.locked_joints).parameters()
    expected = nominal.copy()
    expected[k] += 0.01
    np.testing.assert_allclose(values, expected, rtol=1e-12, atol=1e-12)


ODD_URDF = """<?xml version="1.0"?>
<!-- a comment that stays -->
<robot name="odd">
  <transmission name="t1">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="j1"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
    <actuator name="m1"><mechanicalReduction>100</mechanicalReduction></actuator>
  </transmission>
  <link name="base"/>
  <joint name="j1" type="continuous">
    <parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/>
  </joint>
  <link name="l1">
    <visual><geometry><mesh filename="package://missing/l1.stl"/></geometry></visual>
  </link>
  <joint name="j2" type="revolute">
    <parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0" rpy="1.5707963267948966 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="10" velocity="3"/>
    <dynamics damping="0.5" friction="0.1" simulator_only='a &gt; b'/>
  </joint>
  <link name="l2"><inertial><mass value="2"/><origin xyz="0.1 0 0" rpy="0.3 0.2 0.1"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.04"/></inertial></link>
  <joint name="tool_joint" type="fixed">
    <parent link="l2"/><child link="tool"/><origin xyz="0.2 0 0" rpy="0 0.5 0"/>
  </joint>
  <link name="tool"><inertial><mass value="0.5"/><origin xyz="0 0 0.05"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.0005"/></inertial></link>
  <gazebo reference="l2"><link name="not_a_link"/><joint name="j2"/></gazebo>
</robot>
"""


def test_write_back_of_an_odd_file(tmp_path):
    """Transmission before the joints, a continuous joint, a moving link without <inertial>
    and a missing mesh, a <dynamics> with a simulator attribute, a welded tool, a gazebo
    block naming a link and a joint: the reloaded bodies are the estimate's, the rest stays."""
    import pinocchio as pin

    from ident.identify.model_files.urdf_update import identified_urdf
    from ident.model import Robot

    source = tmp_path / "odd.urdf"
    source.write_text(ODD_URDF)
    robot = Robot.from_urdf(source, inertia_check=False)
    assert robot.joint_names == ("j1", "j2")
    bodies = []
    for j in range(2):
        box = pin.Inertia.FromBox(1.0 + j, 0.1, 0.2, 0.3)
        placement = pin.SE3(pin.utils.rotate("x", 0.4 * j), np.array([0.05, 0.02, -0.01]))
        base = robot.parameters()[10 * j : 10 * j + 10]
        bodies.append(base + np.asarray(placement.act(box).toDynamicParameters()))
    theta = np.concatenate(bodies + [np.array([0.2, 0.3])])
    names = robot.parameter_names() + ("fv1", "fs2")
    written = identified_urdf(ODD_URDF, robot.model, theta, names)
    path = tmp_path / "written.urdf"
    path.write_text(written.text)
    new = Robot.from_urdf(path)
    np.testing.assert_allclose(new.parameters(), theta[:20], rtol=1e-12, atol=1e-15)
    text = written.text
    for kept in (
        "<!-- a comment that stays -->",
        ODD_URDF[ODD_URDF.index("  <transmission") : ODD_URDF.index('  <link name="base"/>')],
        '<gazebo reference="l2"><link name="not_a_link"/><joint name="j2"/></gazebo>',
        '<mesh filename="package://missing/l1.stl"/>',
        "simulator_only='a &gt; b'",
        '<joint name="j1" type="continuous">',
        ODD_URDF[ODD_URDF.index('  <link name="tool">') : ODD_URDF.index("  <gazebo")],
    ):
        assert kept in text
    assert new.model.damping.tolist() == [0.2, 0.0]  # absent extras are 0
    assert new.model.friction.tolist() == [0.0, 0.3]
    assert written.links == ("l1", "l2")


def test_compose_body_keeps_as_much_of_the_welded_links_as_it_can():
    """s = 1 when body minus the welded links is consistent; else the largest s that keeps the
    carrying link consistent (a rule that always put s = 0 would also be exact: it is not it)."""
    import pinocchio as pin

    from ident.identify.model_files.urdf_update import compose_body

    hand = np.asarray(
        pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.1]))
        .act(pin.Inertia.FromBox(0.7, 0.1, 0.2, 0.05))
        .toDynamicParameters()
    )
    link = np.asarray(pin.Inertia.FromBox(1.5, 0.1, 0.1, 0.3).toDynamicParameters())
    own, s = compose_body(link + hand, hand)
    assert s == 1.0
    np.testing.assert_allclose(own, link, atol=1e-15)
    light = 0.3 * (link + hand)  # lighter than the hand alone
    own, s = compose_body(light, hand)
    assert 0.0 < s < 1.0
    np.testing.assert_allclose(own + s * hand, light, rtol=1e-15, atol=1e-15)
    assert consistency_problems(own) == []
    assert consistency_problems(light - min(1.0, s + 1e-3) * hand) != []
