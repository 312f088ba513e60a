"""The identification core: one function (``ident.identify.pipeline.core.identify_measurements``)
behind ``ident run`` and ``ident identify``; whole-log and chunked accumulation are one code
path."""

import json
import re

import numpy as np
import pytest
import yaml
from conftest import REPO_ROOT
from pydantic import ValidationError
from typer.testing import CliRunner

from ident.cli import app
from ident.identify.config import FilterConfig, load_identify_config
from ident.identify.estimators import registry
from ident.identify.pipeline.core import identify_measurements
from ident.measure.logs import read_log


def _wide_log(**preprocess):
    cfg = load_identify_config(REPO_ROOT / "configs" / "examples" / "wide-csv.yaml")
    cfg = cfg.model_copy(update={"preprocess": cfg.preprocess.model_copy(update=preprocess)})
    joints = ["j1", "j2", "j3"]
    return cfg, read_log(cfg.log, cfg.transmission, joints)


def _with(cfg, **preprocess):
    return cfg.model_copy(update={"preprocess": cfg.preprocess.model_copy(update=preprocess)})


@pytest.mark.parametrize(
    "filters",
    [
        {"lowpass": None, "decimation": []},
        {"lowpass": None, "decimation": [4]},
        {"lowpass": FilterConfig(cutoff_hz=8.0, order=4), "decimation": [2]},
        {
            "lowpass": None,
            "torque_lowpass": FilterConfig(cutoff_hz=20.0, order=2),
            "decimation": [3],
        },
    ],
)
def test_chunked_equals_whole_log_for_every_chunk_size(filters):
    # whole log (one chunk per segment) against chunks from far below the filter margins to
    # a few per log: the same estimate and the same reduced normal equations, 1e-9 relative.
    # No consistent model: it is solved from the reduction compared here, and its 30
    # bootstrap re-solves were half of the test's CPU (36 -> 18 s for the four cases)
    cfg, log = _wide_log(trim_samples=5, **filters)
    cfg = cfg.model_copy(
        update={"urdf_update": cfg.urdf_update.model_copy(update={"model": "none"})}
    )
    whole = identify_measurements(_with(cfg, chunked="never"), log)
    gram = np.einsum("gki,gkj->ij", whole.reduction.R, whole.reduction.R)
    rhs = np.einsum("gki,gk->i", whole.reduction.R, whole.reduction.z)
    for size in (16, 50, 137, 400):
        part = identify_measurements(_with(cfg, chunked="always", chunk_samples=size), log)
        n_chunks = re.search(r"in (\d+) chunks", part.records[-3]["detail"])
        assert n_chunks
        assert int(n_chunks.group(1)) > 3
        scale = np.abs(gram).max()
        g = np.einsum("gki,gkj->ij", part.reduction.R, part.reduction.R)
        r = np.einsum("gki,gk->i", part.reduction.R, part.reduction.z)
        np.testing.assert_allclose(g, gram, rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(r, rhs, rtol=0, atol=1e-9 * np.abs(rhs).max())
        # relative to the largest parameter (a parameter near 1e-5 moves by round-off only)
        x = whole.estimate.x
        np.testing.assert_allclose(part.estimate.x, x, rtol=0, atol=1e-9 * np.abs(x).max())
        std = whole.estimate.std
        np.testing.assert_allclose(part.estimate.std, std, rtol=0, atol=1e-9 * std.max())
        for label in ("identified", "URDF nominal"):
            np.testing.assert_allclose(
                part.predictions[label].tau_pred,
                whole.predictions[label].tau_pred,
                rtol=0,
                atol=1e-9 * np.abs(whole.tau_validate).max(),
            )


def test_estimate_is_the_registry_least_squares_once():
    # the result's estimate is the registry's WLS (the same object the consistency table
    # shows), not a second least-squares solve
    cfg, log = _wide_log()
    result = identify_measurements(cfg, log)
    assert result.estimate is result.consistent.estimates["wls"]
    # closed form: WLS from the reduction, solved here independently
    red = result.reduction
    sigma = result.estimate.sigma
    Rs = np.concatenate([red.R[j] / sigma[j] for j in range(red.n_groups)])
    zs = np.concatenate([red.z[j] / sigma[j] for j in range(red.n_groups)])
    x = np.linalg.lstsq(Rs, zs, rcond=None)[0]
    np.testing.assert_allclose(result.estimate.x, x, rtol=1e-8)


# ---- the documented toy estimator, unconstrained, end to end ---------------------------------
# (the `ridge` fixture: tests/conftest.py)
@pytest.mark.slow
def test_run_then_identify_its_log_same_estimate_with_an_unconstrained_toy(ridge, tmp_path):
    # ident run (ur5, quick, the documented toy estimator) then ident identify on the log the
    # run wrote: both exit 0 with complete folders and the same estimate to 1e-12
    data = yaml.safe_load((REPO_ROOT / "configs" / "ur5.yaml").read_text())
    data["robot"]["urdf"] = str(REPO_ROOT / "robot" / "urdf" / "ur5.urdf")
    data["robot"]["package_dirs"] = [str(REPO_ROOT / "robot" / "meshes")]
    data["identification"]["estimation"]["method"] = "ridge"
    # the floor and self-collision distances at 1 kHz are most of a run's CPU and not what is
    # compared here (the estimate of the log the run wrote)
    data["safety"]["floor"]["enabled"] = False
    data["safety"]["self_collision"] = False
    config = tmp_path / "ur5-ridge.yaml"
    config.write_text(yaml.safe_dump(data))
    runner = CliRunner()
    out = runner.invoke(
        app, ["run", str(config), "--quick", "--seed", "0", "--out", str(tmp_path / "r")]
    )
    assert out.exit_code == 0, out.output
    (run_dir,) = (tmp_path / "r").iterdir()
    assert json.loads((run_dir / "run.json").read_text())["status"] == "complete"
    run_json = json.loads((run_dir / "result.json").read_text())
    run_x = run_json["elites"][0]["estimates"]
    out = runner.invoke(
        app,
        [
            "identify",
            str(run_dir / "elites" / "elite_1" / "identify.yaml"),
            "--out",
            str(tmp_path / "i"),
        ],
    )
    assert out.exit_code == 0, out.output
    (id_dir,) = (tmp_path / "i").iterdir()
    assert json.loads((id_dir / "run.json").read_text())["status"] == "complete"
    result = json.loads((id_dir / "result.json").read_text())
    x = np.array([p["value"] for p in result["base_parameters"]])
    # the run's estimate is the least-squares one (WLS beside the toy), as identify's
    assert set(run_x) == {"wls"}
    np.testing.assert_allclose(np.array(run_x["wls"]["x"]), x, rtol=1e-12, atol=0)
    # the run's verdict shows the warnings identify gives on the same log (was "Warnings: none")
    assert set(result["warnings"]) <= set(run_json["verdict"]["warnings"])
    cons = result["consistency"]
    assert cons["method"] == "ridge"
    assert "ridge" in cons["estimators"]
    # no promise of consistency: the model is the default consistent estimator's, not ridge's
    assert result["model"]["method"] == "lmi"
    assert result["model"]["written"]


def test_contract_decides_what_is_reported_not_the_name(ridge):
    # the toy promises no consistency: its estimate is reported beside WLS, checked for
    # consistency, and no model file is built from it (the contract is read, not the name)
    from ident.identify.estimators.summary import model_identification
    from ident.identify.pipeline.core import MODEL_METHOD

    cfg, log = _wide_log()
    cfg = cfg.model_copy(
        update={"estimation": cfg.estimation.model_copy(update={"method": "ridge"})}
    )
    result = identify_measurements(cfg, log)
    cons = result.consistent
    assert result.estimate is cons.estimates["wls"]  # the least-squares estimate stays
    assert cons.constrained is cons.estimates["ridge"]
    assert "ridge" in result.predictions
    # ridge with a 1e-9 shrink is WLS-weighted least squares: same fit to 1e-6
    np.testing.assert_allclose(cons.constrained.x, result.estimate.x, rtol=0, atol=1e-6)
    # no model file is built from it: the model is the consistent estimator's, beside
    model = model_identification(result)
    assert model is not cons
    assert model.method == MODEL_METHOD == "lmi"
    assert model.constrained.consistent
    assert "lmi" in result.predictions
    registry.register_estimator(
        "rows_only",
        registry.get_estimator("ridge"),
        contract=registry.Contract(consistent=False, needs_prior=False, supports_chunks=False),
    )
    with pytest.raises(ValidationError, match="supports_chunks"):
        type(cfg.estimation).model_validate({"method": "rows_only"})
