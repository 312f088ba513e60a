"""``estimation.ellipsoids: true``: the links' bounding ellipsoids inside ``ident identify``."""

import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from ident.cli import app
from ident.errors import ConfigError
from ident.identify.config import load_identify_config
from ident.identify.estimation.consistency import pseudo_inertia
from ident.identify.pipeline.real import identify

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "configs" / "examples" / "wide-csv.yaml"
ARM3 = ROOT / "data" / "examples" / "arm3.urdf"
# boxes around each link's nominal centre of mass (link frame) [m]; link3's is too slim for
# its nominal inertia (radii of gyration 0.105 m along x, 0.032 m across), so the constraint
# acts there
BOXES = {
    "link1": ("0 0.02 0.08", "0.16 0.16 0.24"),
    "link2": ("0.15 0 0", "0.36 0.1 0.1"),
    "link3": ("0.12 0 0", "0.3 0.05 0.05"),
}


def _urdf(tmp_path: Path, links=tuple(BOXES)) -> Path:
    """arm3.urdf with a box <collision> on ``links``."""
    text = ARM3.read_text()
    for link in links:
        xyz, size = BOXES[link]
        collision = (
            f'<collision><origin xyz="{xyz}" rpy="0 0 0"/>'
            f'<geometry><box size="{size}"/></geometry></collision>'
        )
        text = re.sub(rf'(<link name="{link}">)', rf"\1{collision}", text)
    path = tmp_path / "arm3_boxes.urdf"
    path.write_text(text)
    return path


def _config(tmp_path: Path, urdf: Path, **estimation) -> Path:
    cfg = yaml.safe_load(EXAMPLE.read_text())
    cfg["robot"]["urdf"] = str(urdf)
    for key in ("time", "position", "torque"):
        cfg["log"][key]["path"] = str((EXAMPLE.parent / cfg["log"][key]["path"]).resolve())
    cfg["estimation"].update({"method": "lmi", **estimation})
    path = tmp_path / "arm3.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def test_identify_keeps_every_link_mass_inside_its_ellipsoid(tmp_path):
    urdf = _urdf(tmp_path)
    result = identify(load_identify_config(_config(tmp_path, urdf, ellipsoids=True)))
    c = result.consistent
    assert len(c.structure.ellipsoids) == 3
    assert all(e is not None for e in c.structure.ellipsoids)
    est = c.constrained
    assert est.success, est.message
    assert est.consistent
    margins = []
    for index, e in zip(c.structure.bodies, c.structure.ellipsoids, strict=True):
        J = pseudo_inertia(est.theta[index])
        margins.append(np.trace(J @ e.homogeneous_matrix()) / J[3, 3])
        # the centre of mass lies in the ellipsoid (implied by tr(J Q) >= 0)
        assert e.contains(est.theta[index][1:4] / est.theta[index][0], rtol=1e-6)
    assert min(margins) >= -1e-7
    # the constraint is what keeps them inside: without it a link leaves its ellipsoid
    free = identify(load_identify_config(_config(tmp_path, urdf, ellipsoids=False)))
    outside = [
        np.trace(pseudo_inertia(free.consistent.constrained.theta[index]) @ e.homogeneous_matrix())
        for index, e in zip(c.structure.bodies, c.structure.ellipsoids, strict=True)
    ]
    assert min(outside) < 0


def test_link_without_geometry_is_one_error_line(tmp_path):
    config = _config(tmp_path, _urdf(tmp_path, links=("link1", "link3")), ellipsoids=True)
    with pytest.raises(ConfigError, match=r"estimation\.ellipsoids: .* link\(s\) link2"):
        identify(load_identify_config(config))
    out = tmp_path / "runs"
    run = CliRunner().invoke(app, ["identify", str(config), "--out", str(out), "--no-replay"])
    assert run.exit_code == 2
    assert run.output.count("error:") == 1
    assert "link2" in run.output
    assert not out.exists() or not any(out.iterdir())


def test_ellipsoids_need_the_lmi_estimator(tmp_path):
    config = _config(tmp_path, _urdf(tmp_path), ellipsoids=True)
    cfg = yaml.safe_load(config.read_text())
    cfg["estimation"]["method"] = "log_cholesky"
    config.write_text(yaml.safe_dump(cfg))
    with pytest.raises(ConfigError, match="ellipsoids: true needs method: lmi"):
        load_identify_config(config)
