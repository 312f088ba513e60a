"""Meshes are found the way ROS finds them (ident.robot.meshes.resolve_mesh_path), by every
loader, and are optional where they are not needed (safety.self_collision: false)."""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml
from robots import ERD_SHARE, UR5_URDF

from ident.errors import ModelError
from ident.excitation.safety import _kinematic_model_and_geometry, collision_geometry_problem
from ident.model import Robot
from ident.viz.replay import load_visual_robot

ROOT = Path(__file__).resolve().parents[1]
HOSTILE = ROOT / "tests" / "data" / "hostile" / "mesh"
ERD_PREFIX = "package://example-robot-data/robots/ur_description/"
UR5_MESHES = ERD_SHARE / "example-robot-data" / "robots" / "ur_description" / "meshes"
PARTS = ("base", "shoulder", "upperarm", "forearm", "wrist1", "wrist2", "wrist3")


def _reference(kind=pin.GeometryType.COLLISION):
    """Pinocchio's own model and geometry of the example-robot-data UR5 (its package dirs)."""
    model = pin.buildModelFromUrdf(str(UR5_URDF))
    geom = pin.buildGeomFromUrdf(model, str(UR5_URDF), kind, package_dirs=[str(ERD_SHARE)])
    return model, geom


def _ur5_copy(urdf: Path, uri: str, meshes: Path | None, kinds=("collision",), upper=False):
    """The UR5 URDF at ``urdf`` with its mesh URIs' prefix ``meshes/`` replaced by ``uri``;
    its mesh files copied into ``meshes`` (None: nowhere), ``.STL`` when ``upper``."""
    urdf.parent.mkdir(parents=True, exist_ok=True)
    urdf.write_text(UR5_URDF.read_text().replace(ERD_PREFIX + "meshes/", uri), encoding="utf-8")
    for kind in kinds if meshes is not None else ():
        (meshes / "ur5" / kind).mkdir(parents=True, exist_ok=True)
        for f in (UR5_MESHES / "ur5" / kind).iterdir():
            name = f.stem + f.suffix.upper() if upper else f.name
            shutil.copy(f, meshes / "ur5" / kind / name)
    return Robot.from_urdf(urdf)


def _layout(case: str, tmp: Path) -> tuple[Robot, list[Path], Path]:
    """A UR5 whose meshes only the ROS rules find: (robot, package dirs, meshes folder)."""
    urdf = tmp / "robot" / "urdf" / "ur5.urdf"
    if case == "file_uri_of_another_machine":  # the Kinova Gen3 of ros2_kortex: /root/...
        uri = "file:///root/ws/install/ur_description/share/ur_description/meshes/"
        meshes = tmp / "pkgs" / "ur_description" / "meshes"
        return _ur5_copy(urdf, uri, meshes, upper=True), [tmp / "pkgs"], meshes
    if case == "relative_to_the_urdf":
        meshes = tmp / "robot" / "meshes"
        return _ur5_copy(urdf, "../meshes/", meshes), [], meshes
    if case == "unicode_package_dir_is_the_package":
        meshes = tmp / "données_ロボット" / "ur_description" / "meshes"
        robot = _ur5_copy(urdf, "package://ur_description/meshes/", meshes)
        return robot, [meshes.parent], meshes
    if case == "package_below_a_workspace":  # ROS crawls its package path
        meshes = tmp / "ws" / "src" / "universal_robot" / "ur_description" / "meshes"
        return _ur5_copy(urdf, "package://ur_description/meshes/", meshes), [tmp / "ws"], meshes
    assert case == "missing_file_found_by_its_tail"
    meshes = tmp / "robot" / "meshes"  # beside the URDF's folder, no package dir given
    return _ur5_copy(urdf, "file:///gone/robots/ur5/meshes/", meshes), [], meshes


@pytest.mark.parametrize(
    "case",
    [
        "file_uri_of_another_machine",
        "relative_to_the_urdf",
        "unicode_package_dir_is_the_package",
        "package_below_a_workspace",
        "missing_file_found_by_its_tail",
    ],
)
def test_safety_geometry_is_the_original_one_wherever_the_meshes_are(case, tmp_path):
    """The collision model holds the copied files (vertex for vertex the originals) and its
    distances equal those of Pinocchio's own model of the original URDF."""
    robot, dirs, meshes = _layout(case, tmp_path)
    model, geom, notes = _kinematic_model_and_geometry(robot, None, dirs)
    ref_model, ref = _reference()
    assert notes == ()
    assert [o.name for o in geom.geometryObjects] == [o.name for o in ref.geometryObjects]
    meshes_of = [o for o in ref.geometryObjects if o.meshPath.endswith(".stl")]
    assert len(meshes_of) == 7  # and the tool's box
    for obj, expected in zip(geom.geometryObjects, ref.geometryObjects, strict=True):
        if expected not in meshes_of:
            continue
        assert Path(obj.meshPath).parent == (meshes / "ur5" / "collision").resolve()
        assert Path(obj.meshPath).stem == Path(expected.meshPath).stem
        assert np.array_equal(obj.geometry.vertices(), expected.geometry.vertices())
    q = np.array([0.3, -1.2, 2.0, -0.5, 1.1, 0.4])
    distances = []
    for m, g in ((model, geom), (ref_model, ref)):
        g.addAllCollisionPairs()
        data, gdata = m.createData(), g.createData()
        pin.computeDistances(m, data, g, gdata, q)
        distances.append([r.min_distance for r in gdata.distanceResults])
    assert len(distances[0]) == 27  # 8 objects, pairs on different joints
    assert np.allclose(distances[0], distances[1], atol=1e-12)


def test_missing_meshes_one_line_with_the_first_three_their_count_and_the_fix(tmp_path):
    uri = "file:///root/ws/install/ur_description/share/ur_description/meshes/"
    robot = _ur5_copy(tmp_path / "ur5.urdf", uri, None)
    with pytest.raises(ModelError) as e:
        _kinematic_model_and_geometry(robot, None, [tmp_path])
    message = str(e.value)
    assert "\n" not in message
    assert message == (
        f"{tmp_path / 'ur5.urdf'}: 7 collision meshes not found: {uri}ur5/collision/base.stl, "
        f"{uri}ur5/collision/shoulder.stl, {uri}ur5/collision/upperarm.stl (and 4 more); give "
        "the folder that holds them with --package-dir / robot.package_dirs, or set "
        "safety.self_collision: false to design without self-collision checks."
    )
    assert collision_geometry_problem(robot, [tmp_path]) == message.split(";")[0]
    # opted out: the model builds, without geometry, and names each link left unchecked
    _, geom, notes = _kinematic_model_and_geometry(robot, None, [tmp_path], self_collision=False)
    assert [o.name for o in geom.geometryObjects] == ["ee_link_0"]  # the URDF's box stays
    links = [o.name[:-2] for o in _reference()[1].geometryObjects]
    assert [link for link, _ in notes] == links[:7]
    assert all(why.startswith("not checked against the floor") for _, why in notes)


def test_a_visual_mesh_stands_in_for_a_missing_collision_mesh(tmp_path):
    """The forearm's collision mesh is missing: its visual mesh (the one Pinocchio's visual
    model of the original loads) is used for collision, and said."""
    robot = _ur5_copy(
        tmp_path / "urdf" / "ur5.urdf", "../meshes/", tmp_path / "meshes", ("collision", "visual")
    )
    (tmp_path / "meshes" / "ur5" / "collision" / "forearm.stl").unlink()
    _, geom, notes = _kinematic_model_and_geometry(robot, None, [])
    assert notes == (("forearm_link", "visual mesh used for collision"),)
    visual = _reference(pin.GeometryType.VISUAL)[1]
    expected = visual.geometryObjects[visual.getGeometryId("forearm_link_0")]
    used = geom.geometryObjects[geom.getGeometryId("forearm_link_0")]
    assert Path(used.meshPath).name == "forearm.dae"
    assert np.array_equal(used.geometry.vertices(), expected.geometry.vertices())
    assert np.allclose(used.placement.homogeneous, expected.placement.homogeneous)


def test_replay_loads_the_visual_meshes_relative_to_the_urdf(tmp_path):
    _ur5_copy(tmp_path / "urdf" / "ur5.urdf", "../meshes/", tmp_path / "meshes", ("visual",))
    _, visual, fallback = load_visual_robot(tmp_path / "urdf" / "ur5.urdf")
    reference = _reference(pin.GeometryType.VISUAL)[1]
    assert not fallback
    assert len(visual.geometryObjects) == len(reference.geometryObjects) == 7
    for obj, expected in zip(visual.geometryObjects, reference.geometryObjects, strict=True):
        assert np.array_equal(obj.geometry.vertices(), expected.geometry.vertices())


def test_init_writes_self_collision_false_when_the_meshes_are_missing(tmp_path):
    from ident.run.init_config import init_config

    urdf = tmp_path / "arm.urdf"
    urdf.write_text((HOSTILE / "collision_flat.urdf").read_text().replace("flat.stl", "gone.stl"))
    text = init_config(urdf, tmp_path / "arm.yaml").text
    assert yaml.safe_load(text)["safety"]["self_collision"] is False
    assert "# self-collision not checked: " in text
    assert "1 collision mesh not found: gone.stl" in text


def _run(config: Path, out: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    return subprocess.run(
        [sys.executable, "-c", "from ident.cli import main; main()", "run", str(config)]
        + ["--out", str(out)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
        check=False,
    )


@pytest.mark.slow
def test_run_without_meshes_needs_self_collision_false_and_then_says_it(tmp_path):
    """A mesh nowhere: one error line (file, count, fix), exit 2, nothing written; with
    ``self_collision: false`` the run designs and every place names what was not checked."""
    urdf = (HOSTILE / "collision_flat.urdf").read_text().replace("flat.stl", "gone/part.stl")
    (tmp_path / "arm.urdf").write_text(urdf)
    config = (HOSTILE / "run_flat.yaml").read_text().replace("collision_flat.urdf", "arm.urdf")
    (tmp_path / "run.yaml").write_text(config)
    refused = _run(tmp_path / "run.yaml", tmp_path / "refused")
    assert refused.returncode == 2, refused.stderr
    (line,) = [x for x in refused.stderr.splitlines() if x.startswith("error:")]
    assert "1 collision mesh not found: gone/part.stl; give the folder" in line
    assert "safety.self_collision: false" in line
    assert not (tmp_path / "refused").exists()
    (tmp_path / "run.yaml").write_text(
        config.replace("self_collision: true", "self_collision: false")
    )
    done = _run(tmp_path / "run.yaml", tmp_path / "runs")
    assert done.returncode == 0, done.stderr
    (run_dir,) = (tmp_path / "runs").iterdir()
    data = json.loads((run_dir / "result.json").read_text())
    said = "self-collision not checked (safety.self_collision: false)"
    assert data["safety"]["ok"]
    assert said in data["safety"]["message"]
    assert said in data["verdict"]["reason"]
    not_checked = data["elites"][0]["safety_series"]["not_checked"]
    assert {"pair": "self-collision", "reason": "not checked (safety.self_collision: false)"} in (
        not_checked
    )
    assert any(e["pair"] == "link2" and "mesh is missing" in e["reason"] for e in not_checked)
    (row,) = [
        r for r in (run_dir / "report.md").read_text().splitlines() if "Trajectory safety |" in r
    ]
    assert said in row
    assert re.search(r"link2 not checked against the floor", row)


def _box_stl(half: float) -> bytes:
    """A binary STL of the cube of half side ``half`` [m] about the origin (12 triangles)."""
    import struct

    c = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
             (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]  # fmt: skip
    out = b"box".ljust(80, b" ") + struct.pack("<I", len(faces))
    for f in faces:
        out += struct.pack("<12f", 0, 0, 0, *c[list(f)].ravel()) + b"\0\0"
    return out


def test_run_and_verify_take_package_dir_for_package_meshes(tmp_path, monkeypatch):
    """One --package-dir (ident.cli._common) on ident run and ident verify: the run's safety
    geometry is the mesh Pinocchio loads with the same folder; without it, one error line."""
    from typer.testing import CliRunner

    import ident.cli.verify
    import ident.run.pipeline
    from ident.cli import app
    from ident.errors import IdentError

    share = tmp_path / "share"
    (share / "boxpkg" / "meshes").mkdir(parents=True)
    (share / "boxpkg" / "meshes" / "box.stl").write_bytes(_box_stl(0.03))
    mesh = '<collision><geometry><mesh filename="package://boxpkg/meshes/box.stl"/></geometry>'
    urdf = tmp_path / "arm" / "rp2.urdf"
    urdf.parent.mkdir()
    text = (HOSTILE.parent / "base" / "rp2.urdf").read_text()
    urdf.write_text(text.replace('<link name="link2">', f'<link name="link2">{mesh}</collision>'))
    config = tmp_path / "arm" / "run.yaml"
    config.write_text(
        (HOSTILE.parent / "round3" / "mesh" / "run_missing.yaml")
        .read_text()
        .replace("collision_missing.urdf, package_dirs: [.]", "rp2.urdf")
    )
    runs = tmp_path / "runs"
    res = CliRunner().invoke(app, ["run", str(config), "--out", str(runs)])
    assert res.exit_code == 2, res.output
    (line,) = [s for s in res.output.splitlines() if s.startswith("error:")]
    assert "package://boxpkg/meshes/box.stl" in line
    assert "--package-dir" in line
    seen = {}

    def stop(setup, progress=None):  # the checked setup, before any optimization
        seen["setup"] = setup
        raise IdentError("stopped by the test")

    monkeypatch.setattr(ident.run.pipeline, "feasible_start", stop)
    res = CliRunner().invoke(app, ["run", str(config), "--out", str(runs), "--package-dir",
                                   str(share)])  # fmt: skip
    assert "error: stopped by the test" in res.output, res.output
    assert not runs.exists()
    model = pin.buildModelFromUrdf(str(urdf))
    reference = pin.buildGeomFromUrdf(
        model, str(urdf), pin.GeometryType.COLLISION, package_dirs=[str(share)]
    )
    setup = seen["setup"]
    assert setup.config.robot.package_dirs[0] == share.resolve()
    paths = {Path(g.meshPath).resolve() for g in setup.safety.exact_geometry_model.geometryObjects}
    assert Path(reference.geometryObjects[0].meshPath).resolve() in paths
    # verify reads the same option (a folder that is none: one line)
    res = CliRunner().invoke(app, ["verify", "--urdf", str(urdf), "--samples", "3",
                                   "--package-dir", str(share / "nothing")])  # fmt: skip
    assert res.exit_code == 2
    assert res.output.startswith(f"error: --package-dir {share / 'nothing'}: not a folder")

    def selected(selection, **kwargs):  # what verify would load, before its 3 s of checks
        seen["selection"] = selection
        raise IdentError("stopped by the test")

    monkeypatch.setattr(ident.cli.verify, "run_verification", selected)
    res = CliRunner().invoke(app, ["verify", "--urdf", str(urdf), "--package-dir", str(share)])
    assert "error: stopped by the test" in res.output, res.output
    assert seen["selection"].package_dirs == [share.resolve()]
