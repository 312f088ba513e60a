"""Streaming payload identification (``ident stream``): the normal equations with forgetting
against batch least squares and their closed form, the change test on planted payload steps,
the controllers' exports and their limits, the command's errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml
from robots import UR5_URDF
from threadpoolctl import threadpool_limits
from typer.testing import CliRunner

from ident.cli import app
from ident.dynamics.chain import chain_from_model
from ident.dynamics.parameters import parameters_from_model
from ident.identify.config import ModelConfig
from ident.identify.estimation.consistency import pseudo_inertia_min_eigenvalue
from ident.identify.payload.controller_load import (
    LoadLimits,
    check_load,
    franka_set_load,
    ur_set_payload,
)
from ident.identify.streaming.detect import onset_block
from ident.identify.streaming.estimator import StreamingEstimator, StreamSettings
from ident.identify.streaming.normal import NormalEquations, Solution
from ident.measure.ideal import NoiseModel, simulate_measurements

RATE_HZ = 1000.0
#: The planted payload: mass [kg], centre of mass in the last joint's frame [m], box sides [m].
PAYLOAD = (2.0, np.array([0.03, -0.02, 0.07]), (0.10, 0.08, 0.12))
VISCOUS = np.array([3.0, 3.0, 2.0, 0.5, 0.5, 0.5])
COULOMB = np.array([5.0, 5.0, 3.0, 1.0, 1.0, 1.0])
ARMATURE = np.array([0.5, 0.5, 0.3, 0.05, 0.05, 0.05])
TORQUE_STD = (0.5, 0.5, 0.3, 0.1, 0.1, 0.1)


def _with_payload(model: pin.Model) -> pin.Model:
    """``model`` with :data:`PAYLOAD` added to its last body (a solid box)."""
    mass, com, (a, b, c) = PAYLOAD
    inertia = np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) * mass / 12.0
    out = model.copy()
    out.inertias[-1] = out.inertias[-1] + pin.Inertia(mass, com, inertia)
    return out


def _ur5_log(seconds: float, step_s: float | None, seed: int = 0) -> tuple[np.ndarray, ...]:
    """An ideal 1 kHz UR5 log (Pinocchio's dynamics, the friction and rotor inertia above,
    Gaussian torque noise): ``(t, q, tau)``; from ``step_s`` on the payload is attached."""
    model = pin.buildModelFromUrdf(str(UR5_URDF))
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    rng = np.random.default_rng(seed)
    w = 2.0 * np.pi * np.array([0.2, 0.45, 0.7])
    amp = rng.choice([-0.4, 0.4], (3, 6)) / np.array([1.0, 2.0, 3.0])[:, None]
    q0 = np.array([0.0, -1.57, 1.0, -1.0, 1.0, 0.0])
    s, co = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q, dq, ddq = q0 + s @ amp, (co * w) @ amp, -(s * w**2) @ amp
    noise = NoiseModel(torque_std=TORQUE_STD)
    m = simulate_measurements(model, t, q, dq, ddq, noise, rng=seed)
    tau = m.tau
    if step_s is not None:
        after = simulate_measurements(_with_payload(model), t, q, dq, ddq, noise, rng=seed + 1)
        k = int(step_s * RATE_HZ)
        tau = np.vstack([tau[:k], after.tau[k:]])
    tau = tau + VISCOUS * dq + COULOMB * np.sign(dq) + ARMATURE * ddq
    return t, m.q, tau, model


def _estimator(model: pin.Model, **settings: float) -> StreamingEstimator:
    terms = ModelConfig(viscous=True, coulomb=True, rotor_inertia=True, offset=False).extra_terms(
        6, "test"
    )
    s = StreamSettings(**{"consistent": False, "solve_every_s": 1e9, **settings})
    return StreamingEstimator(chain_from_model(model), terms, parameters_from_model(model),
                              RATE_HZ, s)  # fmt: skip


def _feed(est: StreamingEstimator, t: np.ndarray, q: np.ndarray, tau: np.ndarray) -> None:
    with threadpool_limits(limits=1, user_api="blas"):
        for a in range(0, t.size, 100):
            est.push(t[a : a + 100], q[a : a + 100], tau[a : a + 100])


def test_no_forgetting_equals_batch_least_squares() -> None:
    """Summed block by block without forgetting, the solution is the batch weighted least
    squares of the stacked rows (lstsq on rows scaled by the returned 1 / sigma_j), and with
    one joint the ordinary one with covariance ``s^2 (X^T X)^-1``, ``s^2 = SS / (n - p)``. A
    forgetting factor left in, a block lost or a wrong degree-of-freedom count fails."""
    rng = np.random.default_rng(1)
    n, nv, p = 240, 3, 7
    X = rng.normal(size=(n, nv, p)) * np.logspace(-2, 2, p)  # columns of different units
    y = X @ rng.normal(size=p) + rng.normal(size=(n, nv)) * np.array([0.1, 1.0, 3.0])
    keep = rng.random((n, nv)) > 0.1
    eq = NormalEquations(nv, p)
    for a in range(0, n, 17):
        eq.decay(1.0)
        eq.add_rows(X[a : a + 17], y[a : a + 17], keep[a : a + 17])
    sol = eq.solve()
    Xw = np.concatenate([X[keep[:, j], j] / sol.sigma[j] for j in range(nv)])
    yw = np.concatenate([y[keep[:, j], j] / sol.sigma[j] for j in range(nv)])
    ref = np.linalg.lstsq(Xw, yw, rcond=None)[0]
    assert np.max(np.abs(sol.x - ref) / np.abs(ref)) < 1e-10
    one = NormalEquations(1, p)
    one.add_rows(X[:, :1], y[:, :1], np.ones((n, 1), bool))
    sol1 = one.solve()
    x1, ss = np.linalg.lstsq(X[:, 0], y[:, 0], rcond=None)[:2]
    cov = ss[0] / (n - p) * np.linalg.inv(X[:, 0].T @ X[:, 0])
    assert np.max(np.abs(sol1.x - x1) / np.abs(x1)) < 1e-10
    assert np.allclose(sol1.covariance, cov, rtol=1e-8, atol=0)


def test_forgetting_closed_form() -> None:
    """A constant observed in noise, one row a block, forgetting ``gamma``: the estimate is
    the weighted mean ``sum g^(n-1-k) y_k / sum g^(n-1-k)``, its variance ``s^2 sum w^2 /
    (sum w)^2`` (the sandwich, not ``s^2 / sum w``), the effective count tends to
    ``(1 + g) / (1 - g)`` and ``s^2`` is unbiased with ``sum w - sum w^2 / sum w`` degrees of
    freedom."""
    g, n = 0.9, 400
    y = np.random.default_rng(2).normal(3.0, 0.5, n)
    eq = NormalEquations(1, 1)
    for k in range(n):
        eq.decay(g)
        eq.add_rows(np.ones((1, 1, 1)), y[k : k + 1, None], np.ones((1, 1), bool))
    w = g ** np.arange(n - 1, -1, -1.0)
    mean = w @ y / w.sum()
    sol = eq.solve()
    assert sol.x[0] == pytest.approx(mean, rel=1e-12)
    assert eq.sw[0] == pytest.approx((1 - g**n) / (1 - g), rel=1e-12)
    assert sol.n_eff == pytest.approx((1 + g) / (1 - g), rel=1e-6)
    s2 = w @ (y - mean) ** 2 / (w.sum() - (w**2).sum() / w.sum())
    assert sol.sigma[0] ** 2 == pytest.approx(s2, rel=1e-9)
    assert sol.covariance[0, 0] == pytest.approx(s2 * (w**2).sum() / w.sum() ** 2, rel=1e-9)


def test_onset_search_scales_the_blocks_statistic_by_kappa() -> None:
    """One unknown, a reference at 0 known exactly, unit noise: a block with ``A = 1``, ``c =
    z`` has ``T = z^2`` (chi-square, 1 degree of freedom; 6.63 at 0.01). Blocks with z = 0, 3,
    3, 6: each of the last three alone is significant, so the onset is block 1; with the
    model-error factor 2 (T / 2 = 4.5, 4.5, 18) only the newest is (the alarm's own scaling)."""
    ref = Solution(
        x=np.zeros(1), covariance=np.zeros((1, 1)), sigma=np.ones(1), n_eff=1e3,
        residual_ss=np.zeros(1),
    )  # fmt: skip
    blocks = []
    for z in (0.0, 3.0, 3.0, 6.0):
        eq = NormalEquations(1, 1)
        eq.add_rows(np.ones((1, 1, 1)), np.array([[z]]), np.ones((1, 1), bool))
        blocks.append(eq)
    assert onset_block(blocks, ref) == 1
    assert onset_block(blocks, ref, kappa=2.0) == 3


@pytest.fixture(scope="module")
def step_log() -> tuple[np.ndarray, ...]:
    return _ur5_log(13.5, step_s=11.0)


def test_payload_step_detected_and_estimated(step_log: tuple[np.ndarray, ...]) -> None:
    """A 2 kg payload planted at 11 s (after the 10 s warm-up): one change, of kind payload,
    its onset within one block (0.164 s) of 11 s, detected within the test window plus a
    block (0.82 s); after 1 s of rows its mass within 2 % and centre of mass within 5 mm,
    both inside their 95 % intervals give or take a factor 1.5. With ``consistent`` that
    estimate is the LMI's (named ``lmi``; a realizable payload: pseudo-inertia positive
    semidefinite), not the least squares' (the scheduled solve is off here), and so are its
    intervals (its re-solves: ``interval_method``)."""
    t, q, tau, model = step_log
    est = _estimator(model, consistent=True)
    _feed(est, t, q, tau)
    assert len(est.events) == 1
    (event,) = est.events
    block = est.block_s
    assert event.kind == "payload"
    assert abs(event.t_onset - 11.0) <= block + 1e-9
    assert 0 < event.t_alarm - 11.0 <= (est.s.test_blocks + 1) * block
    a = event.after
    mass, com = PAYLOAD[0], PAYLOAD[1]
    assert abs(a.mass - mass) < 0.02 * mass
    assert np.linalg.norm(a.com - com) < 5e-3
    assert abs(a.mass - mass) < 1.5 * 1.96 * a.mass_std
    assert np.all(np.abs(a.com - com) < 1.5 * 1.96 * a.com_std)
    assert a.method == "lmi"
    # its intervals are the consistent re-solves' (a parametric bootstrap), not the WLS's
    assert a.interval_method.startswith("consistent re-solves"), a.interval_method
    assert event.summary(LoadLimits())["after"]["interval_method"] == a.interval_method
    assert event.before.method == "wls"
    assert pseudo_inertia_min_eigenvalue(a.x[:10]) >= -1e-9
    assert not est.timeline  # the LMI came from the change, not from the schedule


def test_no_change_no_alarm(step_log: tuple[np.ndarray, ...]) -> None:
    """The same motion up to the step: tests run and none raises an alarm."""
    t, q, tau, model = step_log
    k = int(11.0 * RATE_HZ)
    est = _estimator(model)
    _feed(est, t[:k], q[:k], tau[:k])
    assert est.n_tests > 0
    assert not est.events


def test_controller_exports_and_limits() -> None:
    """The UR line and the libfranka arguments carry the values in the controllers' orders
    (UR: Ixx, Iyy, Izz, Ixy, Ixz, Iyz; Franka: column-major 3x3); the limits refuse a mass
    over the rated payload (by the interval's upper end), a far centre of mass and an
    unphysical inertia, and an unknown limit is ``not run``."""
    inertia = np.array([[0.01, 0.001, 0.002], [0.001, 0.02, 0.003], [0.002, 0.003, 0.025]])
    com = np.array([0.01, -0.02, 0.05])
    ur = ur_set_payload(2.5, com, inertia)["set_target_payload"]
    assert ur == ("set_target_payload(2.5000, [0.010000, -0.020000, 0.050000], "
                  "[0.01, 0.02, 0.025, 0.001, 0.002, 0.003])")  # fmt: skip
    franka = franka_set_load(2.5, com, inertia)
    assert np.array_equal(np.reshape(franka["load_inertia"], (3, 3), order="F"), inertia)
    assert franka["F_x_Cload"] == com.tolist()
    status = {c.name: c.status for c in check_load(2.5, com, inertia, (2.4, 2.6), LoadLimits())}
    assert status == {"mass positive": "pass", "rated payload": "not run",
                      "centre of mass distance": "not run", "physical inertia": "pass"}  # fmt: skip
    limits = LoadLimits(max_mass_kg=2.55, max_com_distance_m=0.05)
    status = {c.name: c.status for c in check_load(2.5, com, inertia, (2.4, 2.6), limits)}
    assert status["rated payload"] == "fail"  # the mass is under, its interval is not
    assert status["centre of mass distance"] == "fail"  # 54.8 mm
    flat = np.diag([0.01, 0.01, 0.03])  # Izz > Ixx + Iyy: no body has it
    assert check_load(2.5, com, flat, (2.4, 2.6), limits)[-1].status == "fail"


def _write_config(tmp_path: Path, t: np.ndarray, q: np.ndarray, tau: np.ndarray, **stream) -> Path:
    names = [f"j{k}" for k in range(6)]
    header = ",".join(["t"] + [f"q_{n}" for n in names] + [f"tau_{n}" for n in names])
    log = tmp_path / "log.csv"
    np.savetxt(log, np.column_stack([t, q, tau]), delimiter=",", header=header, comments="",
               fmt="%.9g")  # fmt: skip
    cfg = {
        "name": "ur5-stream",
        "robot": {"urdf": str(UR5_URDF)},
        "log": {
            "path": str(log),
            "time": {"column": "t"},
            "position": {"columns": [f"q_{n}" for n in names]},
            "torque": {"columns": [f"tau_{n}" for n in names]},
        },
        "model": {"viscous": True, "coulomb": True, "rotor_inertia": True, "offset": False},
        "stream": {"link": "tool0", "controller": {"max_mass_kg": 5.0}, **stream},
    }
    path = tmp_path / "stream.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def test_cli_replays_a_log(tmp_path: Path, step_log: tuple[np.ndarray, ...]) -> None:
    """``ident stream --speed 0`` on the step log: the change in ``stream.json`` with the UR
    and Franka lines, the rated-payload check passed and the others named."""
    t, q, tau, _ = step_log
    path = _write_config(tmp_path, t, q, tau, solve_every_s=100.0, consistent=False)
    result = CliRunner().invoke(app, ["stream", str(path), "--speed", "0", "--out",
                                      str(tmp_path / "runs")])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "change (payload)" in result.output
    assert "set_target_payload(" in result.output
    (summary,) = (tmp_path / "runs").glob("*/stream.json")
    data = json.loads(summary.read_text())
    (change,) = data["changes"]
    assert change["after"]["mass_kg"] == pytest.approx(PAYLOAD[0], rel=0.02)
    checks = {c["name"]: c["status"] for c in change["limit_checks"]}
    assert checks["rated payload"] == "pass"
    assert checks["centre of mass distance"] == "not run"


def test_bad_config_is_one_error_line(tmp_path: Path) -> None:
    """An even ``stream.window``: one ``error:`` line naming the file and the key, exit 2,
    no run folder."""
    t = np.arange(100) / RATE_HZ
    path = _write_config(tmp_path, t, np.zeros((100, 6)), np.zeros((100, 6)), window=40)
    result = CliRunner().invoke(app, ["stream", str(path), "--speed", "0", "--out",
                                      str(tmp_path / "runs")])  # fmt: skip
    assert result.exit_code == 2
    lines = [x for x in result.output.splitlines() if x.strip()]
    assert len(lines) == 1, result.output
    assert lines[0].startswith("error:")
    assert "stream.yaml" in lines[0]
    assert "window" in lines[0]
    assert not (tmp_path / "runs").exists()
