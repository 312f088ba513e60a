"""Every example log of data/examples/ (one per supported format) identifies through its
config in configs/examples/; the jittered log identifies as well as its uniform twin."""

from pathlib import Path

import numpy as np
import pytest

from ident.identify.config import load_identify_config
from ident.identify.pipeline.real import identify

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "configs" / "examples"
# data/examples/make_examples.py: the simulated friction
TRUE = {"fv1": 0.8, "fv2": 0.6, "fv3": 0.3, "fs1": 1.5, "fs2": 1.0, "fs3": 0.5}


def _run(name):
    return identify(load_identify_config(EXAMPLES / f"{name}.yaml"))


@pytest.mark.parametrize(
    "name", ["wide-csv", "wide-jitter", "long-csv", "lines", "rosbag", "mcap", "two-logs"]
)
def test_example_identifies(name):
    result = _run(name)
    assert result.warnings == ()
    assert result.predictions["identified"].metrics.total_relative_residual < 0.03
    x = dict(zip(result.estimate.names, result.estimate.x, strict=True))
    for key, value in TRUE.items():  # friction is identified within 6 %
        assert x[key] == pytest.approx(value, rel=0.06), key


def test_formats_of_one_motion_agree():
    # wide CSV, long CSV (deg, mA, ms) and one file per signal hold the same samples
    ref = _run("wide-csv").estimate.x
    for name in ("long-csv", "lines"):
        np.testing.assert_allclose(_run(name).estimate.x, ref, rtol=1e-5, atol=1e-6)
    # the bag and the MCAP file hold the same messages
    np.testing.assert_allclose(_run("mcap").estimate.x, _run("rosbag").estimate.x, rtol=1e-12)


def test_jittered_log_identifies_as_well_as_uniform_twin():
    uniform, jitter = _run("wide-csv"), _run("wide-jitter")
    assert any(r["step"] == "resample" for r in jitter.records)
    assert not any(r["step"] == "resample" for r in uniform.records)
    held_u = uniform.predictions["identified"].metrics.total_relative_residual
    held_j = jitter.predictions["identified"].metrics.total_relative_residual
    assert held_j < 1.1 * held_u
    # both logs have their own noise: each friction estimate within 4 of its standard
    # deviations of the truth, and the deviations of the same size
    for result in (uniform, jitter):
        est = result.estimate
        for key, value in TRUE.items():
            k = est.names.index(key)
            assert abs(est.x[k] - value) < 4 * est.std[k], (key, est.x[k], est.std[k])
    ku = [uniform.estimate.names.index(k) for k in TRUE]
    kj = [jitter.estimate.names.index(k) for k in TRUE]
    ratio = jitter.estimate.std[kj] / uniform.estimate.std[ku]
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio


def test_example_files_are_small():
    data = ROOT / "data" / "examples"
    for path in data.rglob("*"):
        if path.is_file():
            assert path.stat().st_size < 300_000, path


def test_two_logs_merge_into_one_identification():
    both = _run("two-logs")
    assert len(both.log.segments) == 2
    assert any(r["step"] == "chunked accumulation" for r in both.records)
    single = _run("wide-csv")
    k = [both.estimate.names.index(n) for n in TRUE]
    # twice the rows: standard deviations shrink by about sqrt(2)
    ratio = both.estimate.std[k] / single.estimate.std[k]
    assert np.all((ratio > 0.55) & (ratio < 0.85)), ratio
