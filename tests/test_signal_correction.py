"""``signals:``: torque gains against a payload of known mass, the delay removed at the edge, and
bad values rejected before anything is written.

References: the gains, delay and payload given to the MuJoCo source, its exact states, and its
commanded torque (the true one, before delay, gain, offset and noise).
"""

import json

import numpy as np
import pytest
import yaml
from robots import UR5_URDF
from test_mujoco_sim import fourier_reference
from threadpoolctl import threadpool_limits
from typer.testing import CliRunner

from ident.cli import app
from ident.dynamics.chain import chain_from_model
from ident.dynamics.friction import ExtraTerms
from ident.dynamics.parameter_model import build_parameter_model
from ident.identify.config import ModelConfig, PreprocessConfig, SignalsConfig
from ident.identify.corrections import signal_correction
from ident.identify.corrections.signal_correction import (
    correct_log,
    correct_payload_logs,
    estimate_log_delay,
    shift_torque,
)
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.payload.payload_gain import GainColumns, estimate_payload_gains
from ident.measure.logs import RobotLog
from ident.measure.mujoco_config import load_mujoco_measurement
from ident.measure.mujoco_sim import simulate, write_log
from ident.model import Robot

GAINS = np.array([1.03, 0.97, 1.03, 0.97, 1.03, 0.97])
OFFSETS = np.array([0.3, -0.2, 0.1, 0.05, -0.05, 0.02])
PAYLOAD = {"mass": 2.0, "com": [0.03, -0.02, 0.07], "inertia": [0.01, 0.0, 0.01, 0.0, 0.0, 0.006]}


@pytest.fixture(scope="module")
def ur5():
    return Robot.from_urdf(UR5_URDF)


@pytest.fixture(autouse=True)
def one_blas_thread():
    """Small QR and least-squares problems: BLAS threads only wait on a loaded machine."""
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def simulated(robot, signals, *, payload=None, noise=0.0, counts=None, n_periods=1, seed=0):
    t, q, dq, ddq = fourier_reference(robot, period=2.0, seed=2)
    rms = np.sqrt(np.mean(robot.rnea(q, dq, ddq) ** 2, axis=0))
    config = {
        "armature": 0.1,
        "friction": {"viscous": 0.5, "coulomb": 1.0},
        "signals": signals,
        "n_periods": n_periods,
        "payload": payload,
        "torque_noise_std": (noise * rms).tolist(),
        "encoder_counts_per_rev": counts,
    }
    return simulate(robot, t, q, dq, ddq, load_mujoco_measurement(config), rng=seed)


def as_log(sim, *, exact=False):
    return RobotLog(
        t=sim.t - sim.t[0],
        q=np.array(sim.q_true if exact else sim.q),
        tau=np.array(sim.tau_measured),
        sampling_rate_hz=sim.rate_hz,
        joint_names=sim.joint_names,
    )


@pytest.fixture(scope="module")
def pair(ur5):
    """Logs with and without the payload: gains, offsets, no delay, no noise."""
    signals = {"torque_gain": GAINS.tolist(), "torque_offset": OFFSETS.tolist()}
    return simulated(ur5, signals, payload=PAYLOAD), simulated(ur5, signals, seed=1)


def test_gains_against_a_known_payload_mass_exact_states(ur5, pair):
    """Exact states: every gain to 1e-7 and the payload's parameters, the mass setting the scale
    (twice the mass: half every gain); a gain taken as its inverse or ignoring the reference
    fails by 3 %."""
    pm = build_parameter_model(ur5.model, ExtraTerms.from_options(ur5.nv))
    chain = chain_from_model(ur5.model)
    red = None
    for sim, loaded in zip(pair, (True, False), strict=True):
        Y = GainColumns(chain, pm, with_payload=loaded)(sim.q_true, sim.dq_true, sim.ddq_true)
        part = ReducedObservations.from_samples(Y[:, :, :-1], sim.tau_measured)
        red = part if red is None else red.merge(part)
    n_arm = red.n_params - 10
    found = estimate_payload_gains(red, n_arm, PAYLOAD["mass"])
    np.testing.assert_allclose(found.gains, GAINS, rtol=1e-7)
    truth = load_mujoco_measurement({"payload": PAYLOAD}).payload.parameters()
    np.testing.assert_allclose(found.phi, truth, rtol=1e-6, atol=1e-9)
    assert np.all(found.gain_std < 1e-6)
    assert np.all(found.payload_torque_rms > 0.01)  # every joint is loaded by the payload
    doubled = estimate_payload_gains(red, n_arm, 2 * PAYLOAD["mass"])
    np.testing.assert_allclose(doubled.gains, GAINS / 2, rtol=1e-7)


def test_correction_divides_the_gains_and_advances_the_torque(ur5, pair, monkeypatch):
    """From processed logs (30 Hz low-pass of positions and torques, differentiated, rows
    above 0.1 rad/s): the gains of the joints the payload loads to 0.3 % and the corrected
    torque is the true one plus offset / gain to 0.5 % of its RMS; multiplying by the gains or
    delaying the torque instead of advancing it misses by more. The wrist joint 5, which this
    payload barely loads (0.03 N*m RMS), gets a gain as uncertain as it says (within 3 std)."""
    delay = 0.005
    signals = {"torque_gain": GAINS.tolist(), "torque_offset": OFFSETS.tolist(), "delay_s": delay}
    sims = simulated(ur5, signals, payload=PAYLOAD), simulated(ur5, signals, seed=1)
    logs = [as_log(s, exact=True) for s in sims]
    pp = PreprocessConfig.model_validate(
        {
            "lowpass": {"cutoff_hz": 30.0},
            "torque_lowpass": {"cutoff_hz": 30.0},
            "trim_samples": 100,
            "decimation": [],
            "velocity_threshold": [0.1] * 6,
        }
    )
    config = SignalsConfig(delay_s=delay, gain_reference={"payload_mass_kg": PAYLOAD["mass"]})
    out = correct_payload_logs(config, ur5, pp, ModelConfig(), logs[0], logs[1])
    found = out.gains
    loaded = found.payload_torque_rms > 0.1
    np.testing.assert_array_equal(loaded, [True, True, True, True, False, True])
    np.testing.assert_allclose(found.gains[loaded], GAINS[loaded], rtol=3e-3)
    assert abs(found.gains[4] - GAINS[4]) < 3 * found.gain_std[4]
    inner = slice(100, -100)
    for sim, log in zip(sims, out.logs, strict=True):
        truth = sim.tau_cmd + OFFSETS / GAINS
        rms = np.sqrt(np.mean(sim.tau_cmd**2, axis=0))
        error = np.abs(log.tau - truth)[inner].max(axis=0)
        assert np.all(error[loaded] < 5e-3 * rms[loaded])
        assert log.records[-2]["delay_s"] == delay
        np.testing.assert_allclose(log.records[-1]["torque_gains"], found.gains)
    # a gain less determined than MAX_GAIN_STD is not applied: the joint keeps gain 1
    monkeypatch.setattr(signal_correction, "MAX_GAIN_STD", 0.5 * float(found.gain_std[4]))
    strict = correct_payload_logs(config, ur5, pp, ModelConfig(), logs[0], logs[1])
    expected = found.gains.copy()
    expected[4] = 1.0
    np.testing.assert_allclose(strict.logs[0].records[-1]["torque_gains"], expected, rtol=1e-12)
    assert "not applied (not determined) on joints [5]" in strict.line()
    # the wrong ways round
    rms = np.sqrt(np.mean(sims[0].tau_cmd ** 2, axis=0))
    multiplied = shift_torque(logs[0], delay).tau * GAINS - sims[0].tau_cmd - OFFSETS / GAINS
    assert np.all(np.abs(multiplied)[inner].max(axis=0)[loaded] > 1e-2 * rms[loaded])
    late = shift_torque(logs[0], -delay).tau / GAINS - sims[0].tau_cmd - OFFSETS / GAINS
    assert np.all(np.abs(late)[inner].max(axis=0)[loaded] > 1e-2 * rms[loaded])


def test_delay_auto_is_found_to_1_ms_on_a_short_measured_log(ur5):
    """6 s at 1 kHz (3 periods of 2 s; one period gave 3.5-3.9 ms), encoder positions (2^19
    counts), 1 % torque noise, offsets."""
    signals = {"delay_s": 0.005, "torque_offset": OFFSETS.tolist()}
    sim = simulated(ur5, signals, noise=0.01, counts=2**19, n_periods=3)
    pm = build_parameter_model(ur5.model, ExtraTerms.from_options(ur5.nv))
    found = estimate_log_delay(as_log(sim), pm, ur5, 0.02)
    assert found.delay_s == pytest.approx(0.005, abs=0.001)


# ------------------------------------------------------------------------------- bad values
@pytest.fixture(scope="module")
def logs_on_disk(pair, tmp_path_factory):
    folder = tmp_path_factory.mktemp("signals")
    sections = []
    for name, sim in zip(("with", "without"), pair, strict=True):
        files = write_log(folder / name, sim)
        log = yaml.safe_load(files.yaml.read_text())["log"]
        for key in ("time", "position", "torque"):
            log[key]["path"] = str(folder / name / log[key]["path"])
        sections.append(log)
    return sections


@pytest.mark.parametrize(
    ("command", "signals", "without", "expected"),
    [
        ("payload", {"delay_s": -0.001}, True, "signals.delay_s"),
        ("payload", {"delay_s": 0.05}, True, "max_delay_s"),
        ("payload", {"delay_s": "soon"}, True, "signals.delay_s"),
        ("payload", {"max_delay_s": 0.0}, True, "signals.max_delay_s"),
        ("payload", {"gain_reference": {"payload_mass_kg": -1.0}}, True, "payload_mass_kg"),
        ("payload", {"gain_reference": {"payload_mass_kg": 2.0}}, False, "payload.without"),
        ("payload", {"gain_refernce": None}, True, "gain_reference"),
        ("identify", {"gain_reference": {"payload_mass_kg": 2.0}}, False, "ident payload"),
    ],
)
def test_bad_signals_are_one_error_line_and_nothing_written(
    logs_on_disk, tmp_path, command, signals, without, expected
):
    config = {"name": "x", "robot": {"urdf": str(UR5_URDF)}, "log": logs_on_disk[0]}
    if without:
        config["payload"] = {"without": logs_on_disk[1]}
    config["signals"] = signals
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(config))
    out = tmp_path / "runs"
    result = CliRunner().invoke(app, [command, str(path), "--out", str(out)])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    assert lines[0].startswith("error: ")
    assert str(path) in lines[0]
    assert expected in lines[0]
    assert not out.exists() or not any(out.iterdir())


def test_signals_default_changes_nothing(ur5, pair):
    log = as_log(pair[0])
    out = correct_payload_logs(SignalsConfig(), ur5, PreprocessConfig(), ModelConfig(), log, None)
    assert out.logs[0] is log
    assert not out.changed


def test_identify_edge_advances_the_torque_by_the_given_delay(ur5, pair):
    """``ident identify``'s edge: the log's torque at t is the measured one at t + delay, and
    the processing record carries the delay (report table, result.json)."""
    log = as_log(pair[1])
    out = correct_log(SignalsConfig(delay_s=0.003), ur5, PreprocessConfig(), ModelConfig(), log)
    (shifted,) = out.logs
    np.testing.assert_allclose(shifted.tau[:-3], log.tau[3:], rtol=1e-12, atol=1e-12)
    assert shifted.records[-1]["step"] == "signals.delay_s"
    assert shifted.records[-1]["delay_s"] == 0.003
    assert "3.00 ms (given)" in shifted.records[-1]["detail"]


def test_ident_payload_removes_the_gains_and_reports_them(logs_on_disk, tmp_path):
    """End to end: the payload's mass comes out as the reference (the gains make it so), the
    gains of the loaded joints are in payload.json, and the terminal has one signals line."""
    config = {
        "name": "x",
        "robot": {"urdf": str(UR5_URDF)},
        "log": logs_on_disk[0],
        "payload": {"without": logs_on_disk[1], "method": "wls"},
        "model": {"offset": True},
        "preprocess": {
            "lowpass": {"cutoff_hz": 30.0},
            "torque_lowpass": {"cutoff_hz": 30.0},
            "trim_samples": 100,
            "decimation": [],
            "velocity_threshold": [0.1] * 6,
        },
        "signals": {"gain_reference": {"payload_mass_kg": PAYLOAD["mass"]}},
    }
    path = tmp_path / "payload.yaml"
    path.write_text(yaml.safe_dump(config))
    result = CliRunner().invoke(app, ["payload", str(path), "--out", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    assert sum(line.startswith("signals: ") for line in result.output.splitlines()) == 1
    (run,) = (tmp_path / "runs").iterdir()
    summary = json.loads((run / "payload.json").read_text())
    gains = np.asarray(summary["signals"]["torque_gains"]["gains"])
    loaded = [0, 1, 2, 3, 5]
    np.testing.assert_allclose(gains[loaded], GAINS[loaded], rtol=3e-3)
    assert summary["mass_kg"] == pytest.approx(PAYLOAD["mass"], rel=0.01)
