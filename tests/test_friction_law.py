"""The friction law carried into the written model (``ident.identify.friction.friction_law``).

References: the simulated law's true parameters and its closed form written in
``test_friction_models`` (not the registry's code), Pinocchio's regressor and MuJoCo's inverse
dynamics of the written MJCF.
"""

import dataclasses
import json

import mujoco
import numpy as np
import pytest
from robots import UR5_URDF
from test_friction_models import closed_form, exact_rows, simulated, values_of
from test_mjcf import _mj_inverse
from test_urdf_update import perturbed_theta

from ident.dynamics.chain import chain_from_model
from ident.dynamics.friction import ExtraTerms
from ident.dynamics.parameter_model import build_parameter_model
from ident.errors import DataError
from ident.identify.friction.friction_fit import fit_friction_model
from ident.identify.friction.friction_law import (
    applied_friction_torque,
    friction_law_entry,
    friction_law_torque,
    written_friction_law,
)
from ident.identify.model_files.files import model_files, reload_parity
from ident.model import Robot


@pytest.fixture(scope="module")
def ur5():
    robot = Robot.from_urdf(UR5_URDF)
    terms = ExtraTerms.from_options(robot.nv, viscous=False, coulomb=False, offset=False)
    return robot, terms, build_parameter_model(robot.model, terms), chain_from_model(robot.model)


@pytest.fixture(scope="module", params=["stribeck", "sigmoid"])
def law(request, ur5):
    """A noise-free simulated law's separable fit, as the written model carries it."""
    name = request.param
    log = simulated(ur5, name, period=0.5)
    rows = exact_rows(ur5, log)
    fit = fit_friction_model(name, rows)
    return name, written_friction_law(fit, rows, None, fit.rest, tuple(ur5[0].joint_names))


def test_file_holds_the_true_law_by_label_and_in_si(law):
    """The JSON section read back gives the simulated law (closed form, true values) on new
    velocities: a writer that swapped labels, wrote another unit (vs in deg/s) or dropped the
    law fails here."""
    name, written = law
    entry = json.loads(json.dumps(friction_law_entry(written)))
    truth = values_of(name)
    assert entry["model"] == name
    for label, values in truth.items():
        got = [entry["parameters"][j][label] for j in entry["joint_order"]]
        np.testing.assert_allclose(got, values, rtol=1e-6, atol=1e-9)
    units = {"stribeck": {"vs": "rad/s", "fst": "N*m"}, "sigmoid": {"phi2": "s/rad"}}[name]
    assert units.items() <= entry["units"].items()
    rng = np.random.default_rng(3)
    dq = rng.normal(scale=0.3, size=(40, 6))
    dq[0] = 0.0
    tau = friction_law_torque({"friction_law": entry}, dq)
    np.testing.assert_allclose(tau, closed_form(name, truth, dq, 0.0), rtol=1e-6, atol=1e-8)
    with pytest.raises(DataError, match="no 'friction_law'"):
        friction_law_torque({"joints": {}}, dq)


def test_written_files_carry_the_law_and_mujoco_applies_it(law, ur5):
    """URDF/MJCF hold the law's native viscous + Coulomb part; MuJoCo's inverse dynamics of the
    MJCF plus its friction loss plus ``applied_friction_torque`` is RNEA + rotor inertia + the
    true law. The reload check reads the law back to rounding and fails on a wrong file."""
    name, written = law
    robot = ur5[0]
    theta, names = perturbed_theta(robot, seed=4)
    files = model_files(robot, theta, names, friction_law=written)
    extras = json.loads(files.extras_json)
    assert extras["friction_law"]["model"] == name
    assert "law_j" in extras["torque_model"]
    native = written.native
    assert np.all(native >= 0.0)
    joints = robot.joint_names
    np.testing.assert_array_equal([extras["joints"][j]["viscous"] for j in joints], native[:, 0])
    np.testing.assert_array_equal([extras["joints"][j]["coulomb"] for j in joints], native[:, 1])

    model = mujoco.MjModel.from_xml_string(files.mjcf)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    q, dq, ddq = robot.random_configurations(30, rng=1)
    got, dof = _mj_inverse(model, joints, q, dq, ddq)
    np.testing.assert_array_equal(model.dof_damping[dof], native[:, 0])
    np.testing.assert_array_equal(model.dof_frictionloss[dof], native[:, 1])
    index = {n: i for i, n in enumerate(names)}
    ia = np.array([theta[index[f"Ia{j}"]] for j in range(1, 7)])
    rigid = robot.regressor(q, dq, ddq) @ theta[:60] + ia * ddq  # the written bodies
    total = got + model.dof_frictionloss[dof] * np.sign(dq) + applied_friction_torque(extras, dq)
    want = rigid + closed_form(name, values_of(name), dq, 0.0)
    np.testing.assert_allclose(total, want, rtol=0, atol=1e-6 * np.abs(want).max())

    parity = reload_parity(robot, files, theta, names, friction_law=written)
    assert parity.friction_law_relative_error < 1e-12
    assert max(parity.urdf_relative_error, parity.mjcf_relative_error) < 1e-9
    # the check reads the file: two parameters swapped (or a unit changed) are caught
    first = extras["friction_law"]["joint_order"][0]
    params = extras["friction_law"]["parameters"][first]
    a, b = list(params)[:2]
    params[a], params[b] = params[b], params[a]
    wrong = dataclasses.replace(files, extras_json=json.dumps(extras))
    assert (
        reload_parity(robot, wrong, theta, names, friction_law=written).friction_law_relative_error
        > 1e-3
    )


def _ur5_run_config(tmp_path, law):
    from pathlib import Path

    import yaml

    from ident.run.config import load_run_config

    root = Path(__file__).resolve().parents[1]
    data = yaml.safe_load((root / "configs" / "ur5.yaml").read_text())
    data["robot"]["urdf"] = str(root / "robot" / "urdf" / "ur5.urdf")
    data["robot"]["package_dirs"] = [str(root / "robot" / "meshes")]
    if law is not None:
        data["measurement"]["friction"]["law"] = law
    path = tmp_path / f"ur5-{law and law['model']}.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_run_config(path)


def test_run_truth_maps_a_linear_law_and_leaves_out_a_nonlinear_one(tmp_path):
    """``ident run`` with a MuJoCo friction law: a viscous + Coulomb law adds to the truth of
    fv/fs (the simulated torque is their sum); a Stribeck law has no fv/fs truth: the base
    parameters holding friction are never major (out of the truth verdict) and the stage says
    why. A run that compared fv/fs with the configured viscous/coulomb alone fails here."""
    from ident.run.log_measurement import log_stage_info, true_parameters

    robot = Robot.from_urdf(UR5_URDF)
    plain = _ur5_run_config(tmp_path, None)
    info_plain, pm = log_stage_info(plain, robot)
    linear = _ur5_run_config(
        tmp_path, {"model": "viscous_coulomb", "values": {"fv": 0.2, "fc": 0.7}}
    )
    index = {n: i for i, n in enumerate(pm.names)}
    truth = true_parameters(pm, linear)
    viscous = plain.measurement.friction.viscous
    coulomb = plain.measurement.friction.coulomb
    for j in range(6):
        assert truth[index[f"fv{j + 1}"]] == pytest.approx(viscous[j] + 0.2)
        assert truth[index[f"fs{j + 1}"]] == pytest.approx(coulomb[j] + 0.7)
    info_linear, _ = log_stage_info(linear, robot)
    assert "truth verdict" not in info_linear.known_bodies_note

    law = {"model": "stribeck", "values": {"fv": 0.5, "fc": 1.0, "fst": 0.8, "vs": 0.2}}
    info, _ = log_stage_info(_ur5_run_config(tmp_path, law), robot)
    assert "'stribeck' law" in info.known_bodies_note
    assert "left out of the truth verdict" in info.known_bodies_note
    friction = np.array([n.rstrip("0123456789") in ("fv", "fs") for n in pm.base.base_names])
    assert friction.any()
    share, before = np.asarray(info.reference_share), np.asarray(info_plain.reference_share)
    assert np.all(share[friction] == 0.0)
    assert np.any(before[friction] > 0.0)
    np.testing.assert_array_equal(share[~friction], before[~friction])
