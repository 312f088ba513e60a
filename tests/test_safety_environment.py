"""The environment is never excluded, absurd sizes are refused, exclusions come from the exact
geometry (ident.excitation.safety), checked through the CLI and against plain coal."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from ident.cli import app
from ident.errors import ConfigError
from ident.excitation.safety import build_safety_model
from ident.model import Robot

REPO = Path(__file__).resolve().parents[1]
HOSTILE = REPO / "tests" / "data" / "hostile" / "safety"
runner = CliRunner()


def _refused(tmp_path: Path, config: Path, needle: str) -> None:
    out = tmp_path / "runs"
    result = runner.invoke(app, ["run", str(config), "--out", str(out), "--no-replay"])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: "), result.stderr
    assert needle in lines[0], lines[0]
    assert "Traceback" not in result.output
    assert not out.exists()  # validated before anything is written


@pytest.mark.parametrize(
    ("name", "needle"),
    [
        ("floor_z5", "base_link is 5.000 m inside the floor"),
        ("box_10m_around", "base_link is 5.000 m inside 'cage'"),
        ("sphere_1e300", "safety.obstacles[0].sphere.radius"),
        ("clearance_1000", "safety.clearance_m"),
        ("clearance_beyond_reach", "larger than the robot's reach"),
        ("robot_inside_box", "inside 'crate'"),
        ("obstacle_through_robot", "link_1 is closer than clearance_m = 0.03 m to 'column'"),
        ("plane_above_robot", "inside 'wall'"),
        ("spheres_257", "at most 256"),
        ("srdf_missing", "safety.srdf"),
    ],
)
def test_hostile_environment_is_one_error_line(tmp_path, name, needle) -> None:
    _refused(tmp_path, HOSTILE / f"{name}.yaml", needle)


def test_eight_thousand_spheres_are_refused_at_once(tmp_path) -> None:
    base = (HOSTILE / "floor_z5.yaml").read_text().split("safety:")[0]
    base = base.replace("../../../../configs/paper6r.yaml", str(REPO / "configs/paper6r.yaml"))
    spheres = "".join(
        f"    - {{sphere: {{radius: 0.01, position: [{k * 1e-3:.3f}, 5.0, 5.0]}}}}\n"
        for k in range(8000)
    )
    config = tmp_path / "spheres.yaml"
    config.write_text(base + "safety:\n  obstacles:\n" + spheres)
    _refused(tmp_path, config, "at most 256")


@pytest.fixture(scope="module")
def paper():
    return Robot.from_config("configs/paper6r.yaml")


def test_home_posture_within_the_margin_of_an_obstacle_is_refused(paper) -> None:
    # a ball 10 cm over the flange at the home posture (arm up); elsewhere the arm is clear
    home = np.array([0.0, -0.8, -0.5, 0.0, 0.0, 0.0])
    flange = paper.frame_positions(home[None, :], "flange")[0]
    ball = {"name": "ball", "sphere": {"radius": 0.05, "position": list(flange + [0, 0, 0.1])}}
    cfg = {"obstacles": [ball]}
    build_safety_model(paper, cfg)  # without a home posture: a checked obstacle
    with pytest.raises(ConfigError, match=r"controller.home: the robot's \w+ is .* from 'ball'"):
        build_safety_model(paper, cfg, home_q=home)


def test_srdf_pairs_are_excluded_with_their_reason(paper, tmp_path) -> None:
    srdf = tmp_path / "paper.srdf"
    srdf.write_text(
        '<robot name="paper6r">'
        '<disable_collisions link1="link_5" link2="base_link" reason="Never"/>'
        '<disable_collisions link1="no_such_link" link2="base_link" reason="Never"/>'
        "</robot>"
    )
    plain = build_safety_model(paper)
    s = build_safety_model(paper, {"srdf": srdf})
    excluded = {e.pair: e.reason for e in s.excluded_pairs}
    assert excluded["base_link|link_5"] == "SRDF (Never)"
    assert "base_link|link_5" in plain.pair_names
    assert "base_link|link_5" not in s.pair_names
    assert set(plain.pair_names) - set(s.pair_names) == {"base_link|link_5"}


def _exact_contact_fraction(model, geom, a, b, q):
    """Plain Pinocchio + coal: fraction of postures where meshes a and b are in contact."""
    geom.removeAllCollisionPairs()
    geom.addCollisionPair(pin.CollisionPair(a, b))
    data, gdata = model.createData(), pin.GeometryData(geom)
    hits = [pin.computeCollisions(model, data, geom, gdata, qi, True) for qi in q]
    return float(np.mean(hits))


def test_ur5_exclusions_are_judged_on_the_meshes_not_on_the_hulls() -> None:
    """The UR5's forearm and wrist-2 hulls are within 2 cm in every posture, their meshes touch
    in a few percent of them: the pair is checked (the old hull rule dropped it, and a shipped
    trajectory drove one mesh into the other). Independent: coal on the meshes as loaded."""
    from ident.model.selection import load_robot
    from ident.run.config import load_run_config

    config = load_run_config("configs/ur5.yaml")
    robot = load_robot(config.robot)
    s = build_safety_model(robot, config.safety, package_dirs=robot.package_dirs)
    excluded = {e.pair: e.reason for e in s.excluded_pairs}
    assert set(excluded.values()) == {"adjacent"}
    assert "forearm_link|wrist_2_link" in s.pair_names
    assert "base_link|upper_arm_link" in s.pair_names
    assert "wrist_1_link|wrist_3_link" in s.pair_names
    assert {e.pair for e in s.constant_pairs} == {"base_link_0|floor"}
    model = robot.model
    geom = pin.buildGeomFromUrdfString(
        model, robot.urdf_text, pin.GeometryType.COLLISION, None,
        [str(d) for d in robot.package_dirs],
    )  # fmt: skip
    names = [o.name for o in geom.geometryObjects]
    a, b = names.index("forearm_link_0"), names.index("wrist_2_link_0")
    q = np.random.default_rng(7).uniform(robot.q_lower, robot.q_upper, (300, 6))
    fraction = _exact_contact_fraction(model, geom, a, b, q)
    assert 0.0 < fraction < 0.95  # meshes: sometimes in contact, so never excluded
    hull = s.geometry_model
    i = [o.name for o in hull.geometryObjects].index("forearm_link_0")
    j = [o.name for o in hull.geometryObjects].index("wrist_2_link_0")
    p = next(k for k, c in enumerate(hull.collisionPairs) if {c.first, c.second} == {i, j})
    data, gdata = model.createData(), pin.GeometryData(hull)
    for qi in q[:50]:  # the hulls: within the old 2 cm margin always (the old rule's reason)
        pin.updateGeometryPlacements(model, data, hull, gdata, qi)
        assert pin.computeDistance(hull, gdata, p).min_distance < 0.02


def test_a_margin_no_posture_keeps_is_refused_naming_the_pair() -> None:
    from ident.model.selection import load_robot
    from ident.run.config import load_run_config

    config = load_run_config("configs/ur5.yaml")
    robot = load_robot(config.robot)
    with pytest.raises(ConfigError, match="base_link and upper_arm_link are closer than that"):
        build_safety_model(robot, {"clearance_m": 0.02}, package_dirs=robot.package_dirs)


def test_the_default_margin_is_lowered_to_one_every_pair_keeps_and_says_so() -> None:
    """A user who gives no margin gets one the robot can keep (the UR5's wrist 1 and wrist 3
    meshes are at most 14.5 mm apart: 30 -> 15 -> 7.5 mm); a margin the user chose is never
    changed (the test above)."""
    from ident.model.selection import load_robot
    from ident.run.config import load_run_config

    config = load_run_config("configs/ur5.yaml")
    robot = load_robot(config.robot)
    safety = build_safety_model(
        robot, {"floor": {"enabled": False}}, package_dirs=robot.package_dirs
    )
    assert safety.clearance_m == pytest.approx(0.0075)
    assert "from the default 0.03 m to 0.0075 m" in safety.margin_note
    assert "wrist_1_link-wrist_3_link" in safety.margin_note
    # the lowered margin is the one every check uses: the optimizer's term and the dense check
    q = np.zeros((1, robot.nq))
    assert np.isfinite(safety.clearances(q)).all()
    kept = build_safety_model(
        robot, {"clearance_m": 0.0075, "floor": {"enabled": False}}, package_dirs=robot.package_dirs
    )
    assert kept.margin_note == ""
    assert kept.clearance_m == 0.0075


def test_srdf_of_a_run_config_is_read_relative_to_the_config(tmp_path) -> None:
    from ident.run.setup import load_run

    (tmp_path / "robot.srdf").write_text(
        '<robot name="paper6r"><disable_collisions link1="base_link" link2="link_5" '
        'reason="User"/></robot>'
    )
    base = (HOSTILE / "floor_z5.yaml").read_text().split("safety:")[0]
    base = base.replace("../../../../configs/paper6r.yaml", str(REPO / "configs/paper6r.yaml"))
    config = tmp_path / "run.yaml"
    config.write_text(base + "safety: {srdf: robot.srdf}\n")
    setup = load_run(config)
    excluded = {e.pair: e.reason for e in setup.safety.excluded_pairs}
    assert excluded["base_link|link_5"] == "SRDF (User)"
    assert "base_link|link_5" not in setup.safety.pair_names
