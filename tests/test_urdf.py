from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml
import yourdfpy

from ident.errors import ModelError
from ident.robot.dh import DHTable
from ident.robot.inertia import transform_parameters
from ident.robot.robot_config import description_from_mapping, load_robot_config
from ident.robot.urdf import urdf_from_description, wrist_centre

DATA = Path("tests/data/robots")
CONFIGS = [Path("configs/paper6r.yaml"), DATA / "puma_modified.yaml", DATA / "rpr.yaml"]


def _dh_frame_in_link(dh, i):
    return dh.fixed_transform(i) if dh.convention == "standard" else np.eye(4)


def _random_q(robot, rng, n_samples):
    return rng.uniform(robot.q_lower, robot.q_upper, (n_samples, robot.n_joints))


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_pinocchio_frames_equal_dh_product(path):
    robot = load_robot_config(path)
    model = pin.buildModelFromXML(urdf_from_description(robot))
    data = model.createData()
    assert model.nq == robot.n_joints
    assert [model.names[j] for j in range(1, model.njoints)] == list(robot.joint_names)
    q = _random_q(robot, np.random.default_rng(0), 30)
    expected = robot.dh.forward_kinematics(q)
    flange = model.getFrameId("flange")
    links = [model.getFrameId(name) for name in robot.link_names]
    worst = 0.0
    for k in range(q.shape[0]):
        pin.framesForwardKinematics(model, data, q[k])
        worst = max(worst, np.abs(data.oMf[flange].homogeneous - expected[k, -1]).max())
        for i, frame in enumerate(links):
            dh_frame = data.oMf[frame].homogeneous @ _dh_frame_in_link(robot.dh, i)
            worst = max(worst, np.abs(dh_frame - expected[k, i + 1]).max())
    assert worst < 1e-9


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_pinocchio_inertias_map_back_to_config(path):
    robot = load_robot_config(path)
    model = pin.buildModelFromXML(urdf_from_description(robot))
    for i in range(robot.n_joints):
        in_link = model.inertias[i + 1].toDynamicParameters()
        link_in_dh = np.linalg.inv(_dh_frame_in_link(robot.dh, i))
        in_dh = transform_parameters(in_link, link_in_dh[:3, :3], link_in_dh[:3, 3])
        scale = np.abs(robot.parameters_dh[i]).max()
        np.testing.assert_allclose(in_dh, robot.parameters_dh[i], rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_yourdfpy_loads_and_agrees(path, tmp_path):
    robot = load_robot_config(path)
    urdf_file = tmp_path / "robot.urdf"
    urdf_file.write_text(urdf_from_description(robot))
    loaded = yourdfpy.URDF.load(str(urdf_file), load_meshes=False)
    assert loaded.actuated_joint_names == list(robot.joint_names)
    q = _random_q(robot, np.random.default_rng(1), 5)
    expected = robot.dh.forward_kinematics(q)[:, -1]
    for k in range(q.shape[0]):
        loaded.update_cfg(q[k])
        np.testing.assert_allclose(
            loaded.get_transform("flange", "base_link"), expected[k], atol=1e-9
        )
    # every moving link is drawn
    for name in robot.link_names:
        assert len(loaded.link_map[name].visuals) >= 1


def test_committed_paper_urdf_is_up_to_date():
    regenerated = urdf_from_description(load_robot_config("configs/paper6r.yaml"))
    committed = Path("robot/urdf/paper6r.urdf").read_text(encoding="utf-8")
    assert committed == regenerated, (
        "run: ident urdf configs/paper6r.yaml -o robot/urdf/paper6r.urdf"
    )


def test_limits_written_in_si():
    robot = load_robot_config("configs/paper6r.yaml")
    model = pin.buildModelFromXML(urdf_from_description(robot))
    np.testing.assert_allclose(model.lowerPositionLimit, robot.q_lower)
    np.testing.assert_allclose(model.upperPositionLimit, robot.q_upper)
    np.testing.assert_allclose(model.velocityLimit, robot.dq_max)
    np.testing.assert_array_equal(model.effortLimit, 0.0)  # unknown efforts are written as 0


@pytest.mark.parametrize("path", [Path("configs/paper6r.yaml"), DATA / "puma_modified.yaml"])
def test_wrist_centre_is_on_the_three_wrist_axes(path):
    robot = load_robot_config(path)
    model = pin.buildModelFromXML(urdf_from_description(robot))
    data = model.createData()
    centre = model.getFrameId("wrist_centre")
    q = _random_q(robot, np.random.default_rng(2), 10)
    frames = robot.dh.forward_kinematics(q)
    for k in range(q.shape[0]):
        pin.framesForwardKinematics(model, data, q[k])
        point = data.oMf[centre].translation
        # both robots: the wrist centre is the origin of DH frame 4
        np.testing.assert_allclose(point, frames[k, 4, :3, 3], atol=1e-12)
        for joint in (4, 5, 6):
            placement = data.oMi[joint]
            offset = point - placement.translation
            axis = placement.rotation[:, 2]
            assert np.linalg.norm(np.cross(offset, axis)) < 1e-12


def test_no_wrist_centre_without_spherical_wrist():
    planar = DHTable(
        "standard", [0.3, 0.2, 0.1], [0, 0, 0], [0, 0, 0], [0, 0, 0], ("revolute",) * 3
    )
    assert wrist_centre(planar) is None
    rpr = load_robot_config(DATA / "rpr.yaml")
    assert wrist_centre(rpr.dh) is None
    model = pin.buildModelFromXML(urdf_from_description(rpr))
    assert not model.existFrame("wrist_centre")
    assert model.existFrame("flange")


def test_name_clash_with_generated_frames():
    data = yaml.safe_load((DATA / "planar2r.yaml").read_text())
    data["links"][1]["name"] = "flange"
    with pytest.raises(ModelError, match="flange"):
        urdf_from_description(description_from_mapping(data, "x.yaml"))


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_collision_geometry_is_the_visual_geometry_plus_nothing_else(path):
    """Every visual cylinder is repeated as a collision primitive (same pose and size), and
    the pedestal is a base_link column standing on z = 0 around joint 1's axis."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(urdf_from_description(load_robot_config(path)))
    for link in root.findall("link"):
        visuals, collisions = link.findall("visual"), link.findall("collision")
        assert len(visuals) == len(collisions)
        for v, c in zip(visuals, collisions, strict=True):
            assert v.find("origin").attrib == c.find("origin").attrib
            assert v.find("geometry/cylinder").attrib == c.find("geometry/cylinder").attrib
    base = root.find("link[@name='base_link']/collision")
    z = float(base.find("origin").get("xyz").split()[2])
    length = float(base.find("geometry/cylinder").get("length"))
    assert z - 0.5 * length == pytest.approx(0.0, abs=1e-12)  # stands on the base plane
    model = pin.buildModelFromXML(ET.tostring(root, encoding="unicode"))
    geom = pin.buildGeomFromUrdfString(
        model, ET.tostring(root, encoding="unicode"), pin.GeometryType.COLLISION
    )
    assert geom.ngeoms == len(root.findall("link/collision"))
