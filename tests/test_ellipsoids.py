"""Bounding ellipsoids from URDF geometry and the "mass inside" LMI."""

import numpy as np
import pinocchio as pin
import pytest
import robots

from ident.identify.estimation.consistency import pseudo_inertia
from ident.identify.model_files.urdf_update import parse_urdf
from ident.robot.ellipsoids import Ellipsoid, link_ellipsoids, minimum_volume_ellipsoid

SIZE = np.array([0.4, 0.2, 0.1])
XYZ = np.array([0.1, -0.05, 0.3])
RPY = np.array([0.3, -0.2, 0.5])
URDF = f"""<robot name="r">
  <link name="base"/>
  <link name="box_link">
    <collision>
      <origin xyz="{XYZ[0]} {XYZ[1]} {XYZ[2]}" rpy="{RPY[0]} {RPY[1]} {RPY[2]}"/>
      <geometry><box size="{SIZE[0]} {SIZE[1]} {SIZE[2]}"/></geometry>
    </collision>
  </link>
  <link name="ball"><visual><geometry><sphere radius="0.2"/></geometry></visual></link>
  <link name="can">
    <collision><geometry><cylinder radius="0.1" length="0.5"/></geometry></collision>
  </link>
</robot>"""


def _box_points(n, rng):
    rotation = pin.rpy.rpyToMatrix(RPY)
    local = rng.uniform(-0.5, 0.5, size=(n, 3)) * SIZE
    return local @ rotation.T + XYZ


def test_box_ellipsoid_contains_the_box_and_is_the_minimum_one():
    (e,) = link_ellipsoids(parse_urdf(URDF), ["box_link"])
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * SIZE / 2
    rotation = pin.rpy.rpyToMatrix(RPY)
    assert e.contains(corners @ rotation.T + XYZ).all()
    assert e.contains(_box_points(500, np.random.default_rng(0))).all()
    # closed form: the minimum-volume ellipsoid of a box has semi-axes sqrt(3) * half sizes
    np.testing.assert_allclose(e.semi_axes, np.sort(np.sqrt(3) * SIZE / 2), rtol=1e-3)
    np.testing.assert_allclose(e.center, XYZ, atol=1e-6)


def test_constraint_accepts_the_box_and_rejects_a_point_mass_outside():
    (e,) = link_ellipsoids(parse_urdf(URDF), ["box_link"])
    Q = e.homogeneous_matrix()
    box = pin.Inertia.FromBox(3.0, *SIZE)
    placed = pin.SE3(pin.rpy.rpyToMatrix(RPY), XYZ).act(box)
    theta = np.asarray(placed.toDynamicParameters())
    assert np.trace(pseudo_inertia(theta) @ Q) > 0
    outside = XYZ + np.array([0.0, 0.0, 0.5])  # beyond every semi-axis
    assert not e.contains(outside)
    point = np.asarray(pin.Inertia(1.0, outside, np.zeros((3, 3))).toDynamicParameters())
    assert np.trace(pseudo_inertia(point) @ Q) < 0
    inside = np.asarray(pin.Inertia(1.0, XYZ, np.zeros((3, 3))).toDynamicParameters())
    assert np.trace(pseudo_inertia(inside) @ Q) > 0


def test_sphere_and_cylinder():
    ball, can = link_ellipsoids(parse_urdf(URDF), ["ball", "can"])
    np.testing.assert_allclose(ball.semi_axes, [0.2, 0.2, 0.2])
    rng = np.random.default_rng(1)
    angle = rng.uniform(0, 2 * np.pi, 200)
    rim = np.column_stack(
        [0.1 * np.cos(angle), 0.1 * np.sin(angle), rng.choice([-0.25, 0.25], 200)]
    )
    assert can.contains(rim).all()


def test_minimum_volume_ellipsoid_of_a_sphere_sample_is_the_sphere():
    rng = np.random.default_rng(2)
    v = rng.normal(size=(400, 3))
    points = 0.3 * v / np.linalg.norm(v, axis=1, keepdims=True) + 1.0
    e = minimum_volume_ellipsoid(points, tol=1e-9)
    np.testing.assert_allclose(e.semi_axes, 0.3, rtol=2e-2)
    assert e.contains(points).all()


def test_minimum_volume_ellipsoid_of_a_filled_box_is_its_circumscribed_ellipsoid():
    # a box's corners among 20 000 interior points (a mesh's count): the minimum-volume
    # ellipsoid is the box's, centred, semi-axes sqrt(3) times the half-sides (closed form);
    # only the 8 corners touch it, so the interior points must not change it
    rng = np.random.default_rng(0)
    half = np.array([0.1, 0.2, 0.4])
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
    points = np.vstack([corners, rng.uniform(-half, half, size=(20_000, 3))]) + 0.5
    e = minimum_volume_ellipsoid(points, tol=1e-9)
    np.testing.assert_allclose(e.center, 0.5, atol=1e-6)
    np.testing.assert_allclose(np.sort(e.semi_axes), np.sqrt(3) * half, rtol=1e-4)
    assert e.contains(points).all()


def test_ur5_meshes_give_ellipsoids_holding_the_link_mass_centre():
    text = robots.UR5_URDF.read_text()
    model = pin.buildModelFromUrdf(str(robots.UR5_URDF))
    links = ["shoulder_link", "upper_arm_link", "forearm_link"]
    ellipsoids = link_ellipsoids(parse_urdf(text), links, package_dirs=[robots.ERD_SHARE])
    for link, e in zip(links, ellipsoids, strict=True):
        assert isinstance(e, Ellipsoid), link
        frame = model.frames[model.getFrameId(link)]
        com = model.inertias[frame.parentJoint].lever
        assert e.contains(com), link


def test_unknown_link_and_missing_mesh():
    from ident.errors import ModelError

    with pytest.raises(ModelError, match="not found"):
        link_ellipsoids(parse_urdf(URDF), ["nope"])
    text = robots.UR5_URDF.read_text()
    assert link_ellipsoids(parse_urdf(text), ["forearm_link"]) == (None,)  # no package dirs
