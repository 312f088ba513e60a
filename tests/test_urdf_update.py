"""Writing identified inertial parameters back into a URDF copy: threshold, consistency, values."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from ident.dynamics.parameters import parameter_names, parameters_from_model
from ident.identify.real import load_robot_model
from ident.identify.urdf_update import update_urdf_inertials
from ident.robot.inertia import consistency_problems

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
    from ident.identify.real import identify

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
