"""Warnings a user must see: each triggered by a case and absent from a good one."""

from pathlib import Path

import numpy as np
import pinocchio as pin

from ident.identify.assessment.sanity import joint_units, result_warnings

JOINTS = ("j1", "j2")


def _call(**change):
    rng = np.random.default_rng(0)
    tau = rng.normal(size=(200, 2)) * [10.0, 5.0]
    args = {
        "joint_names": JOINTS,
        "units": ("N*m", "N"),
        "names": ("m2", "fv1", "Ixy2"),
        "x": np.array([2.0, 0.5, -0.1]),
        "std": np.array([0.01, 0.01, 0.01]),
        "relative_std": np.array([0.5, 2.0, 10.0]),
        "projection": np.eye(3),
        "all_names": ("m2", "fv1", "Ixy2"),
        "column_norms": np.array([10.0, 10.0, 10.0]),
        "tau_norm": 100.0,
        "tau_validate": tau,
        "tau_pred": tau + rng.normal(size=tau.shape) * 0.1,
        "keep_validate": np.ones((200, 2), dtype=bool),
    }
    args.update(change)
    return result_warnings(**args)


def test_good_result_has_no_warning():
    assert _call() == []


def test_worse_than_zero_torque_in_the_joint_unit():
    tau = np.ones((50, 2))
    pred = tau.copy()
    pred[:, 1] = -2.0  # joint 2 (prismatic) predicted with the wrong sign
    (w,) = _call(tau_validate=tau, tau_pred=pred, keep_validate=np.ones((50, 2), dtype=bool))
    assert w.startswith("joint j2: held-out prediction is worse than predicting zero torque")
    assert "(residual RMS 3 N > torque RMS 1 N)" in w


def test_joint_at_noise_level():
    rng = np.random.default_rng(1)
    tau = rng.normal(size=(400, 2))
    pred = tau.copy()
    pred[:, 0] = 0.05 * tau[:, 0]  # explains little of joint 1
    (w,) = _call(tau_validate=tau, tau_pred=pred, keep_validate=np.ones((400, 2), dtype=bool))
    assert w.startswith("joint j1: torques at the noise level")
    assert "N*m" in w


def test_negative_mass_and_friction():
    warnings = _call(x=np.array([-2.0, -0.5, -0.1]))
    assert len(warnings) == 2  # Ixy may be negative
    assert warnings[0].startswith("m2 = -2 is negative")
    assert warnings[1].startswith("fv1 = -0.5 is negative")
    # within two standard deviations of zero: not significant, no warning
    assert _call(x=np.array([-0.01, 0.5, -0.1]), std=np.array([0.01, 0.01, 0.01])) == []
    # a regrouped parameter (a sum) is not checked alone
    projection = np.array([[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    assert len(_call(x=np.array([-2.0, 0.5, -0.1]), projection=projection)) == 0


def test_significant_parameter_with_large_std():
    (w,) = _call(relative_std=np.array([80.0, 2.0, 10.0]))
    assert w.startswith("base parameter(s) m2 (80 %, 20.0 % of the torques)")
    # the same std on a parameter that carries nothing: left to the essential parameters
    assert (
        _call(relative_std=np.array([80.0, 2.0, 10.0]), column_norms=np.array([0.1, 10, 10])) == []
    )


def test_units_of_revolute_and_prismatic_joints():
    model = pin.buildModelFromUrdf("tests/data/urdf/rp2.urdf")
    assert joint_units(model) == ("N*m", "N")


def _example_with_torque_sign(tmp_path, sign):
    """configs/examples/wide-csv.yaml on a copy of its log with joint 3's torque times sign."""
    import yaml

    from ident.identify.config import load_identify_config

    root = Path(__file__).resolve().parents[1]
    lines = (root / "data/examples/wide.csv").read_text().splitlines()
    k = lines[0].split(",").index("tau_j3")
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:
        row[k] = repr(sign * float(row[k]))
    log = tmp_path / "wide.csv"
    log.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    cfg = yaml.safe_load((root / "configs/examples/wide-csv.yaml").read_text())
    cfg["robot"]["urdf"] = str(root / "data/examples/arm3.urdf")
    for key in ("time", "position", "torque"):
        cfg["log"][key]["path"] = str(log)
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(cfg))
    return load_identify_config(tmp_path / "config.yaml")


def test_impossible_links_only_when_no_consistent_fit_exists(tmp_path):
    from ident.identify.pipeline.real import identify

    # the simulated arm is a physical body: the WLS estimate completed with the URDF's values
    # makes link2 violate the triangle inequality, but a consistent set fits as well: no warning
    good = identify(_example_with_torque_sign(tmp_path, 1.0))
    assert not good.consistent.estimates["wls"].consistent  # the completion is impossible...
    assert not any("physically consistent" in w for w in good.warnings)  # ...the data are not
    # joint 3's torque logged with the wrong sign: no physical body explains it
    bad = identify(_example_with_torque_sign(tmp_path, -1.0))
    (warning,) = [w for w in bad.warnings if "no physically consistent parameters" in w]
    assert "link3" in warning
    assert "wrong sign" in warning
    increase = float(warning.split("(+")[1].split(" %")[0])
    assert increase > 20.0  # measured +54 %
