"""URDF meshes that crash qhull or coal are refused in Python (ident.robot.meshes)."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from ident.errors import ModelError
from ident.robot.meshes import check_urdf_meshes, mesh_problem, resolve_mesh_path

ROOT = Path(__file__).resolve().parents[1]
MESHES = ROOT / "tests" / "data" / "hostile" / "mesh"


def _rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q


@pytest.mark.parametrize("seed", range(5))
def test_flatness_agrees_with_an_independent_hull(seed):
    """Solid clouds pass and have a hull of positive volume (trimesh); a plane or a line, turned
    anywhere and stored in single precision as an STL stores it, is refused."""
    rng = np.random.default_rng(seed)
    rotation = _rotation(rng)
    solid = rng.uniform(-0.1, 0.1, size=(50, 3)) @ rotation.T + rng.normal(size=3)
    assert mesh_problem(solid, needs_volume=True) is None
    assert trimesh.convex.convex_hull(solid).volume > 1e-6
    plane = np.column_stack([rng.uniform(-0.1, 0.1, (50, 2)), np.zeros(50)]) @ rotation.T
    plane = plane.astype(np.float32).astype(float) + 0.3
    assert "one plane" in mesh_problem(plane, needs_volume=True)
    line = np.outer(rng.uniform(0, 0.2, 20), rotation[:, 0]).astype(np.float32).astype(float)
    assert "one line" in mesh_problem(line, needs_volume=True)
    # a visual may be flat; NaN never passes
    assert mesh_problem(plane, needs_volume=False) is None
    plane[3, 1] = np.nan
    assert "NaN" in mesh_problem(plane, needs_volume=False)


def test_a_thin_plate_is_no_flat_mesh():
    """A 1 mm plate 0.3 m long is a real part (thickness/length 3e-3, far above 1e-6)."""
    plate = trimesh.creation.box((0.3, 0.2, 0.001)).vertices
    assert mesh_problem(np.asarray(plate), needs_volume=True) is None


def test_mesh_paths_resolve_as_pinocchio_does(tmp_path, monkeypatch):
    (tmp_path / "a").mkdir()
    (tmp_path / "b" / "pkg" / "meshes").mkdir(parents=True)
    target = tmp_path / "b" / "pkg" / "meshes" / "m.stl"
    target.write_bytes(b"")
    dirs = [tmp_path / "a", tmp_path / "b"]
    assert resolve_mesh_path("package://pkg/meshes/m.stl", dirs) == target
    assert resolve_mesh_path("pkg/meshes/m.stl", dirs) == target
    assert resolve_mesh_path(f"file://{target}", []) == target
    assert resolve_mesh_path(str(target), []) == target
    assert resolve_mesh_path("package://pkg/meshes/m.stl", []) is None
    assert resolve_mesh_path("http://x/m.stl", dirs) is None
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "b"))
    assert resolve_mesh_path("package://pkg/meshes/m.stl", []) == target


def test_collision_and_visual_are_checked_apart():
    flat = MESHES / "collision_flat.urdf"
    with pytest.raises(ModelError, match="link 'link2', <collision> mesh 'flat.stl'.*one plane"):
        check_urdf_meshes(flat, [MESHES])
    check_urdf_meshes(flat, [MESHES], collision=False)  # not read: no error
    check_urdf_meshes(MESHES / "visual_flat.urdf", [MESHES])  # a flat visual is fine
    with pytest.raises(ModelError, match=r'scale="0 0 0"'):
        check_urdf_meshes((MESHES / "visual_scale_zero.urdf").read_text(), [MESHES])


@pytest.mark.parametrize("name", ["flat"])
def test_cli_never_segfaults_on_a_bad_collision_mesh(name, tmp_path):
    """This killed ``ident run`` with SIGSEGV (a negative return code here); the corpus
    (test_hostile_cli.py) runs every other bad mesh, a crash there kills its worker."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            "from ident.cli import main; main()",
            "run",
            str(MESHES / f"run_{name}.yaml"),
            "--out",
            str(tmp_path / "runs"),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
    )
    assert proc.returncode == 2, proc.stderr
    (line,) = [x for x in proc.stderr.splitlines() if x.startswith("error:")]
    assert "link 'link2'" in line
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "runs").exists() or not any((tmp_path / "runs").iterdir())


@pytest.mark.parametrize(
    ("name", "problem"),
    [("flat", "one plane"), ("nan_vertex", "NaN"), ("garbage", "cannot be read as a mesh")],
)
def test_without_trimesh_coal_reads_the_same_meshes(name, problem, tmp_path, monkeypatch):
    """trimesh is optional: coal's loader (Pinocchio's) gives the vertices, checked alike."""
    import shutil

    monkeypatch.setitem(sys.modules, "trimesh", None)
    for f in MESHES.glob("*.stl"):  # fresh paths: nothing from the per-file cache
        shutil.copy(f, tmp_path / f.name)
    urdf = (MESHES / f"collision_{name}.urdf").read_text()
    with pytest.raises(ModelError, match=problem):
        check_urdf_meshes(urdf, [tmp_path])
    check_urdf_meshes(
        (MESHES / "collision_flat.urdf").read_text().replace("flat", "box"), [tmp_path]
    )


def test_negative_scales_mirror_or_turn_the_mesh_and_are_accepted():
    """Real URDFs scale by negative factors: TIAGo ``"-1 -1 1"`` (a half turn), Centauro's left
    arm ``"0.001 -0.001 0.001"`` (a mirror of the right arm's meshes); zero stays refused."""
    text = (MESHES / "visual_scale_zero.urdf").read_text()
    for scale in ("-1 -1 1", "-1 1 1", "0.001 -0.001 0.001"):
        check_urdf_meshes(text.replace('scale="0 0 0"', f'scale="{scale}"'), [MESHES])
    with pytest.raises(ModelError, match=r'scale="1 0 1".*non-zero'):
        check_urdf_meshes(text.replace('scale="0 0 0"', 'scale="1 0 1"'), [MESHES])
