"""FIGAROH's UR10 truth fixture (data/figaroh-ur10-truth) and ident's figure on it."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from conftest import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "benchmarks"))
import peer_ur10_truth as ur10  # noqa: E402

# FIGAROH's standard-parameter names: <param>_<joint>, Pinocchio's dynamic parameters of the
# body the joint moves (m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz about the joint frame)
_ORDER = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def test_the_shipped_urdf_is_their_truth():
    """The dynamics-only URDF reproduces ten of the fixture's published true base parameters
    (each a single standard parameter) to 1e-9 (their printed digits): catches a mistyped
    inertial, a dropped link or a wrong joint frame in the extraction."""
    model = ur10.truth_model()
    prot = ur10.protocol()
    checked = 0
    for name, value in prot["base_truth"].items():
        param, joint = name.split("_", 1)
        body = model.getJointId(joint)
        dynamic = model.inertias[body].toDynamicParameters()
        assert dynamic[_ORDER.index(param)] == pytest.approx(value, rel=1e-9, abs=1e-15), name
        checked += 1
    assert checked == 10


def test_protocol_series_respect_the_fixture_bounds():
    """A generated series stays within 1.2 rad of home, 0.7 of the velocity limits and 0.8 of
    the effort limits, lasts 1000 rows at 100 Hz and is periodic (the fixture's protocol)."""
    model = ur10.truth_model()
    prot = ur10.protocol()
    s = ur10.random_series(model, prot["train"], prot, np.random.default_rng(4))
    assert s is not None
    assert s.q.shape == (1000, 6)
    assert np.abs(s.q - np.asarray(prot["home_rad"])).max() <= 1.2 + 1e-12
    assert np.all(np.abs(s.dq).max(axis=0) <= 0.7 * model.velocityLimit + 1e-12)
    assert np.all(np.abs(ur10.torques(model, s)).max(axis=0) <= 0.8 * model.effortLimit)
    # the series closes on itself: the sample after the last equals the first
    dt = 1.0 / prot["train"]["rate_hz"]
    assert np.abs(s.q[-1] + s.dq[-1] * dt - s.q[0]).max() < 0.02


@pytest.mark.slow
def test_ident_model_within_half_their_tolerance_of_the_truth():
    """ident's written model (reloaded URDF), fitted on FIGAROH's training series with their
    `low` noise, predicts the noise-free validation torques within 0.05 N*m on every joint:
    half FIGAROH's 0.1 N*m tolerance, and within their per-joint acceptance. Measured over 5
    seeds: 0.019 N*m worst joint (shoulder lift); FIGAROH's base OLS on the same samples:
    0.027 N*m, outside its own acceptance on the wrists."""
    text = ur10.table(n_seeds=1)
    rows = [line for line in text.splitlines() if line.startswith("| ident")]
    assert len(rows) == 2  # analytic states and from q
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert float(cells[2]) <= 0.05, row
        assert cells[4] == "yes", row
        assert cells[5] == "yes", row
