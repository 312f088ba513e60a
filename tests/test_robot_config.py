from pathlib import Path

import numpy as np
import pytest
import yaml

from ident.errors import ConfigError
from ident.robot.inertia import com_and_inertia
from ident.robot.robot_config import description_from_mapping, load_robot_config

DATA = Path("tests/data/robots")
PAPER = Path("configs/paper6r.yaml")


def test_paper_units_are_converted_once():
    robot = load_robot_config(PAPER)
    assert robot.name == "paper6r"
    assert robot.joint_names == tuple(f"joint_{i}" for i in range(1, 7))
    np.testing.assert_allclose(robot.dh.a, [0.3, 0.7, 0, 0, 0, 0], rtol=1e-15)
    np.testing.assert_allclose(robot.dh.d, [0.32, 0, 0, 0.6975, 0, 0.1275], rtol=1e-15)
    np.testing.assert_allclose(robot.dh.alpha, np.array([-1, 0, -1, 1, -1, 0]) * np.pi / 2)
    np.testing.assert_allclose(np.rad2deg(robot.q_upper), [165, 110, 70, 160, 120, 242])
    np.testing.assert_allclose(np.rad2deg(robot.q_lower), [-165, -110, -110, -160, -120, -242])
    np.testing.assert_allclose(np.rad2deg(robot.dq_max), [150, 160, 170, 320, 400, 460])
    assert np.all(np.isinf(robot.effort_max))
    np.testing.assert_array_equal(robot.gravity, [0, 0, -9.81])


def test_paper_inertials_round_trip():
    """Parameters about the DH origin give back eq. 25-32 (kg, kg*mm, kg*mm^2)."""
    robot = load_robot_config(PAPER)
    mass, com, inertia_com = com_and_inertia(robot.parameters_dh)
    np.testing.assert_allclose(
        mass,
        [5.029912009, 4.530794148, 3.05678343, 1.815211338, 0.990530741, 0.186899621],
        rtol=1e-15,
    )
    first_moment_kg_mm = mass[:, None] * com * 1e3
    np.testing.assert_allclose(first_moment_kg_mm[1], [-44.1094, 93.9465, 183.7506], rtol=1e-13)
    np.testing.assert_allclose(first_moment_kg_mm[5], [0.004296, 0.000028941, 4.9163], rtol=1e-12)
    np.testing.assert_allclose(
        np.diagonal(inertia_com[5]) * 1e6, [103.8927, 103.8903, 204.5344], rtol=1e-10
    )
    off_diagonal = inertia_com * (1 - np.eye(3))
    np.testing.assert_allclose(off_diagonal, 0.0, atol=1e-15)
    # about the DH origin (not the COM) link 6's Izz exceeds the COM value by m*(cx^2+cy^2)
    assert robot.parameters_dh[5, 9] > inertia_com[5, 2, 2]


def test_prismatic_uses_length_units_and_default_names():
    robot = load_robot_config(DATA / "rpr.yaml")
    assert robot.dh.joint_types == ("revolute", "prismatic", "revolute")
    np.testing.assert_allclose(robot.q_lower, [np.deg2rad(-170), -0.2, -np.pi])
    np.testing.assert_allclose(robot.dq_max[:2], [np.deg2rad(120), 0.5])
    assert np.isinf(robot.dq_max[2])
    assert np.isinf(robot.ddq_max[2])
    np.testing.assert_allclose(robot.effort_max[1], 500.0)
    np.testing.assert_allclose(robot.dh.theta, np.deg2rad([0, 90, 30]))
    np.testing.assert_allclose(robot.dh.d, [0.4, 0.1, 0.05])
    assert robot.link_names == ("link_1", "link_2", "link_3")
    # first_moment in kg*cm: m*c = [-10, 0.5, 0] kg*cm -> [-0.1, 0.005, 0] kg*m
    np.testing.assert_allclose(robot.parameters_dh[2, 1:4], [-0.1, 0.005, 0.0])
    # com in cm: c = [0, 0, -8] cm with m = 2 kg -> m*c = [0, 0, -0.16] kg*m
    np.testing.assert_allclose(robot.parameters_dh[1, 1:4], [0.0, 0.0, -0.16])


def test_modified_convention_and_column_order():
    robot = load_robot_config(DATA / "puma_modified.yaml")
    assert robot.dh.convention == "modified"
    np.testing.assert_allclose(robot.dh.a, [0, 0, 0.4318, 0.0203, 0, 0])
    np.testing.assert_allclose(robot.dh.d, [0, 0, 0.15005, 0.4318, 0, 0])
    np.testing.assert_allclose(np.rad2deg(robot.dh.alpha), [0, -90, 0, -90, 90, -90])


def test_grams_are_converted():
    data = yaml.safe_load((DATA / "planar2r.yaml").read_text())
    data["units"]["mass"] = "g"
    for link in data["links"]:
        link["mass"] *= 1e3
        link["inertia_com"] = {k: v * 1e3 for k, v in link["inertia_com"].items()}
    grams = description_from_mapping(data, "grams.yaml")
    kilograms = load_robot_config(DATA / "planar2r.yaml")
    np.testing.assert_allclose(grams.parameters_dh, kilograms.parameters_dh, rtol=1e-14)


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("bad_columns.yaml", r"dh.rows\[1\] has 3 values but dh.columns lists 4"),
        ("bad_rows.yaml", r"dh.rows has 1 rows, joints has 2 entries"),
        ("bad_key.yaml", r"unknown key 'links\[0\].inertia_cm'; did you mean 'inertia_com'"),
        ("bad_mass.yaml", r"links\[1\].mass' = -1.0: mass must be > 0"),
        ("bad_triangle.yaml", r"links\[1\].inertia_com: .*triangle inequality"),
        ("bad_limits.yaml", r"joints\[1\].*lower = 2.5 must be below upper = -2.5"),
    ],
)
def test_bad_configs_name_file_field_and_fix(name, expected):
    with pytest.raises(ConfigError, match=expected) as info:
        load_robot_config(DATA / name)
    assert str(DATA / name) in str(info.value)


def test_unknown_dh_column_suggests_closest():
    data = yaml.safe_load((DATA / "planar2r.yaml").read_text())
    data["dh"]["columns"] = ["a", "d", "alpah", "theta"]
    with pytest.raises(ConfigError, match="unknown DH column 'alpah' .did you mean 'alpha'"):
        description_from_mapping(data, "x.yaml")


def test_com_and_first_moment_are_exclusive():
    data = yaml.safe_load((DATA / "planar2r.yaml").read_text())
    data["links"][0]["first_moment"] = [0.0, 0.0, 0.0]
    with pytest.raises(ConfigError, match="exactly one of 'first_moment'"):
        description_from_mapping(data, "x.yaml")


def test_duplicate_joint_names():
    data = yaml.safe_load((DATA / "planar2r.yaml").read_text())
    data["joints"][1]["name"] = "shoulder"
    with pytest.raises(ConfigError, match=r"joints\[1\].name = 'shoulder' is used twice"):
        description_from_mapping(data, "x.yaml")


def test_missing_file():
    with pytest.raises(ConfigError, match="not found"):
        load_robot_config(DATA / "nope.yaml")


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("first_moment", [float("nan"), 0.0, 0.0]),
        ("com", [0.0, float("inf"), 0.0]),
        ("inertia_com", {"xx": 0.001, "yy": float("nan"), "zz": 0.0277}),
        ("mass", float("inf")),
    ],
)
def test_non_finite_values_name_their_field(field, value):
    data = yaml.safe_load((DATA / "planar2r.yaml").read_text())
    if field == "first_moment":
        del data["links"][1]["com"]
    data["links"][1][field] = value
    with pytest.raises(
        ConfigError, match=rf"x.yaml: links\[1\].{field}(\.\w+)?: values are not finite"
    ):
        description_from_mapping(data, "x.yaml")
