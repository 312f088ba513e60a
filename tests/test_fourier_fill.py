"""``JointFourierFamily(fill_limits=True)``: every design scaled onto its joints' limits.

Checked against an independent dense evaluation of the documented series (not the family's fill
grid): the scaled motion touches one of each moving joint's limits and exceeds none, between the
family's samples too.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from robots import ur5_with_limits
from typer.testing import CliRunner

from ident.excitation.fourier import (
    FILL_SAMPLES_PER_HARMONIC,
    JointFourierFamily,
    fill_margin,
    fourier_series,
)

N_HARMONICS = 4
W = 2.0 * np.pi / 4.0  # 4 s: the 4th harmonic's acceleration can bind before the velocity
MOVING = (0, 1, 2, 3)


def _family(fill: bool, n_samples: int = 200) -> JointFourierFamily:
    return JointFourierFamily(
        ur5_with_limits(),
        MOVING,
        n_harmonics=N_HARMONICS,
        base_frequency=W,
        n_samples=n_samples,
        fill_limits=fill,
    )


def _designs(family: JointFourierFamily) -> np.ndarray:
    """Random designs of the box, plus one whose joints are bound by, in turn, the position
    (q0 0.3 rad below the elbow's upper limit), the acceleration (4th harmonic only), the
    velocity (2nd harmonic only) and a mix."""
    rng = np.random.default_rng(7)
    x = rng.uniform(family.bounds[:, 0], family.bounds[:, 1], (6, family.bounds.shape[0]))
    per = 2 * N_HARMONICS - 1  # q0, a2..a4, b2..b4
    crafted = np.zeros(family.bounds.shape[0])
    crafted[0 * per + 1] = 0.1  # joint 0: a2 only -> velocity binds
    crafted[1 * per + 3] = 0.1  # joint 1: a4 only -> acceleration binds (4 w dq > 10 / 3.15)
    crafted[2 * per] = family.limits.q_upper[2] - 0.3  # joint 2: near its upper limit
    crafted[2 * per + 1] = 0.1
    crafted[3 * per + 1 : 3 * per + per] = 0.05
    return np.vstack([x, crafted])


def _dense(family: JointFourierFamily, x: np.ndarray, n: int) -> tuple[np.ndarray, ...]:
    """The family's motion at ``n`` uniform times of one period, from the documented series
    (rest conditions eliminating the first harmonic), times the family's gains."""
    per = x.reshape(x.shape[0], len(MOVING), 2 * N_HARMONICS - 1)
    q0, a_free, b_free = per[:, :, 0], per[:, :, 1:N_HARMONICS], per[:, :, N_HARMONICS:]
    a = np.concatenate([-a_free.sum(axis=2, keepdims=True), a_free], axis=2)
    l = np.arange(2, N_HARMONICS + 1)
    b = np.concatenate([-(b_free * l).sum(axis=2, keepdims=True), b_free], axis=2)
    gain = family.fill_gains(a, b, q0)[:, :, None] if family.fill_limits else 1.0
    t = np.arange(n) * (2.0 * np.pi / W / n)
    return fourier_series(t, a * gain, b * gain, q0, W)


def _ratios(family: JointFourierFamily, q, dq, ddq) -> np.ndarray:
    """Per particle and moving joint, the worst of the four limit ratios (1 = on a limit):
    (q - q0) / (upper - q0), (q0 - q) / (q0 - lower), |dq| / dq_max, |ddq| / ddq_max."""
    lim = family.limits
    m = list(MOVING)
    q0 = q.mean(axis=1)  # the series has zero mean over a period
    up = (q.max(axis=1) - q0) / (lim.q_upper[m] - q0)
    down = (q0 - q.min(axis=1)) / (q0 - lim.q_lower[m])
    vel = np.abs(dq).max(axis=1) / lim.dq_max[m]
    acc = np.abs(ddq).max(axis=1) / lim.ddq_max[m]
    return np.stack([up, down, vel, acc], axis=2)


@pytest.fixture(scope="module")
def filled():
    return _family(True)


def test_filled_motion_touches_a_limit_of_every_joint_and_exceeds_none(filled):
    x = _designs(filled)
    batch = filled.trajectories(x)
    lim = filled.limits
    # at the family's own samples: within every limit, no violation reported
    assert batch.violations.feasible().all()
    eps = fill_margin(N_HARMONICS, FILL_SAMPLES_PER_HARMONIC * N_HARMONICS)
    assert eps < 1e-4
    # 10x denser than the samples, and 100x (the true peaks to ~1e-6)
    for n in (10 * filled.n_samples, 20_000):
        q, dq, ddq = _dense(filled, x, n)
        ratios = _ratios(filled, q, dq, ddq)
        assert ratios.max() <= 1.0, ratios.max()
        assert np.all(q <= lim.q_upper[list(MOVING)])
        assert np.all(q >= lim.q_lower[list(MOVING)])
    worst = ratios.max(axis=2)  # the true peaks, (n_particles, n_moving)
    # touched: the gain leaves only the stated between-samples margin (position: relative to the
    # joint's whole swing, at most 2x the room here)
    assert worst.min() >= 1.0 - 3.0 * eps - 1e-9, worst.min()
    # the crafted design's joints are bound by velocity, acceleration, position (up)
    kind = ratios[-1].argmax(axis=1)
    np.testing.assert_array_equal(kind[:3], [2, 3, 0])
    # the trajectories are the gained series (not the design's raw coefficients)
    q, dq, ddq = _dense(filled, x, filled.n_samples)
    m = list(MOVING)
    np.testing.assert_allclose(batch.q[:, :, m], q, atol=1e-12)
    np.testing.assert_allclose(batch.dq[:, :, m], dq, atol=1e-12)
    np.testing.assert_allclose(batch.ddq[:, :, m], ddq, atol=1e-12)


def test_fill_gain_makes_the_certified_peak_equal_the_limit(filled):
    """The documented bound of :meth:`fill_gains`, recomputed here on the fill grid, equals the
    binding limit to 1e-9 (a gain computed from another quantity, or applied twice, does not)."""
    x = _designs(filled)
    a, b, q0 = filled.coefficients(x)  # gained
    n = FILL_SAMPLES_PER_HARMONIC * N_HARMONICS
    t = np.arange(n) * (filled.period / n)
    g, dq, ddq = fourier_series(t, a, b, np.zeros_like(q0), W)
    eps = fill_margin(N_HARMONICS, n)
    lim, m = filled.limits, list(MOVING)
    spread = np.abs(g).max(axis=1)
    certified = np.stack(
        [
            (g.max(axis=1) + eps * spread) / (lim.q_upper[m] - q0),
            (-g.min(axis=1) + eps * spread) / (q0 - lim.q_lower[m]),
            (1 + eps) * np.abs(dq).max(axis=1) / lim.dq_max[m],
            (1 + eps) * np.abs(ddq).max(axis=1) / lim.ddq_max[m],
        ],
        axis=2,
    )
    np.testing.assert_allclose(certified.max(axis=2), 1.0, atol=1e-9)
    # the gain does not depend on the sampling: the same motion at any rate
    dense = filled.with_samples(1000).coefficients(x)
    np.testing.assert_array_equal(dense[0], a)
    # a design scaled as a whole gives the same motion (only its shape matters)
    per = x.reshape(x.shape[0], len(MOVING), -1).copy()
    per[:, :, 1:] *= 3.7
    np.testing.assert_allclose(filled.coefficients(per.reshape(x.shape))[0], a, rtol=1e-12)


def test_without_the_option_the_family_is_unchanged(monkeypatch):
    """Default off; the motion is the design's own series, bit for bit, and no gain is
    computed (an always-on or leaking scale changes it)."""
    family = _family(False)
    assert not family.fill_limits
    assert not JointFourierFamily(ur5_with_limits(), MOVING).fill_limits

    def fail(*args):
        raise AssertionError("fill_gains called without fill_limits")

    monkeypatch.setattr(JointFourierFamily, "fill_gains", fail)
    x = _designs(family)
    batch = family.trajectories(x)
    q, dq, ddq = _dense(family, x, family.n_samples)
    m = list(MOVING)
    np.testing.assert_array_equal(batch.q[:, :, m], q)
    np.testing.assert_array_equal(batch.dq[:, :, m], dq)
    np.testing.assert_array_equal(batch.ddq[:, :, m], ddq)
    # the raw designs' peaks are what the box gives (some far inside, some beyond the limits)
    worst = _ratios(family, q, dq, ddq).max(axis=2)
    assert worst.min() < 0.5
    assert worst.max() > 1.5


def test_fill_limits_must_be_a_boolean():
    with pytest.raises(ValueError, match="fill_limits must be true or false"):
        JointFourierFamily(ur5_with_limits(), MOVING, fill_limits="yes")


QUICK = Path(__file__).parent / "data" / "run" / "quick-wrist.yaml"


@pytest.mark.slow
def test_quick_run_with_fill_limits_passes_the_dense_check(tmp_path):
    """``ident run --quick`` of the wrist stage with ``fill_limits: true``: the exported
    trajectory keeps every limit at 1 kHz, and lies on one (the option reached the family)."""
    from ident.cli import app

    text = QUICK.read_text(encoding="utf-8")
    text = text.replace("../../../configs/", str(QUICK.parents[3] / "configs") + "/")
    text = text.replace("amplitude_bound: 0.3,", "fill_limits: true,")
    text += "safety: {floor: {enabled: false}, self_collision: false, torque_limits: true}\n"
    assert "fill_limits: true" in text
    config = tmp_path / "fill.yaml"
    config.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(app, ["run", str(config), "--quick", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    run_dir = next(d for d in tmp_path.iterdir() if d.is_dir())
    data = json.loads((run_dir / "result.json").read_text())
    assert data["safety"]["ok"]
    series = data["elites"][0]["safety_series"]
    assert series["usable"]
    assert series["rate_hz"] >= 1000.0
    worst = series["worst_checks"][0]  # the constraint closest to its limit
    assert worst["ok"]
    assert worst["excess"] > -1e-3 * max(abs(worst["limit"]), 1.0), worst  # on the limit
