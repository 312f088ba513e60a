"""``ident fleet``: the joint solve against a dense least squares, per-unit friction on a
3-unit toy fleet through dask.distributed, a planted friction rise flagged (none elsewhere),
the test across units, and a bad config as one error line."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from ident.cli import app
from ident.errors import DataError
from ident.identify.streaming.fleet import (
    ChunkSettings,
    FleetSolution,
    UnitSolution,
    WindowSums,
    chunk_equations,
    scaled_covariances,
    schur_solve,
    solve_fleet,
    window_sums,
)
from ident.identify.streaming.fleet_drift import (
    fleet_window_tests,
    rise_threshold,
    unit_outliers,
    window_factors,
    window_tests,
)
from ident.identify.streaming.fleet_run import fleet_client, fleet_sums, plan_chunks
from ident.identify.streaming.normal import NormalEquations
from ident.measure.logs import RobotLog

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))
from bench_fleet import fleet_columns, friction_errors, make_units, unit_log, ur5, wilson  # noqa: E402

distributed = pytest.importorskip("distributed")
dask = pytest.importorskip("dask")


@pytest.fixture(scope="module")
def setup() -> tuple:
    robot, meas = ur5()
    names = tuple(str(robot.model.names[i]) for i in range(1, robot.model.njoints))
    return robot, meas, fleet_columns(robot), names


def _random_units(cols, rng: np.random.Generator, n_units: int = 3) -> tuple[list, list]:  # noqa: ANN001
    """Random rows per unit: ``(equations, rows)`` with rows ``(X (n, nv, p), y, keep)``."""
    units, rows = [], []
    for _ in range(n_units):
        X = rng.normal(size=(150, 6, cols.p))
        y = rng.normal(size=(150, 6))
        keep = rng.random((150, 6)) > 0.2
        eq = NormalEquations(6, cols.p)
        eq.add_rows(X, y, keep)
        units.append(eq)
        rows.append((X, y, keep))
    return units, rows


def test_schur_solve_equals_dense_weighted_least_squares(setup: tuple) -> None:
    """The block elimination against ``lstsq`` on the stacked rows (shared columns once, each
    unit's local columns in its own block), per-unit per-joint weights."""
    cols = setup[2]
    rng = np.random.default_rng(0)
    units, rows = _random_units(cols, rng)
    weights = [rng.uniform(0.5, 4.0, 6) for _ in units]
    S, L = cols.shared, cols.local
    n_col = S.size + len(units) * L.size
    blocks, rhs = [], []
    for u, ((X, y, keep), v) in enumerate(zip(rows, weights, strict=True)):
        for j in range(6):
            k = keep[:, j]
            G = np.zeros((int(k.sum()), n_col))
            G[:, : S.size] = X[k, j][:, S]
            G[:, S.size + u * L.size : S.size + (u + 1) * L.size] = X[k, j][:, L]
            blocks.append(np.sqrt(v[j]) * G)
            rhs.append(np.sqrt(v[j]) * y[k, j])
    G, b = np.vstack(blocks), np.concatenate(rhs)
    ref = np.linalg.lstsq(G, b, rcond=None)[0]
    cov = np.linalg.inv(G.T @ G)
    x_S, C_SS, local = schur_solve(units, weights, cols)
    assert np.allclose(x_S, ref[: S.size], rtol=0, atol=1e-9 * np.abs(ref).max())
    for u, (x_L, C_LL) in enumerate(local):
        sl = slice(S.size + u * L.size, S.size + (u + 1) * L.size)
        assert np.allclose(x_L, ref[sl], rtol=0, atol=1e-9 * np.abs(ref).max())
        assert np.allclose(C_LL, cov[sl, sl], rtol=1e-9, atol=1e-12 * np.abs(cov).max())
    assert np.allclose(C_SS, cov[: S.size, : S.size], rtol=1e-9, atol=1e-12 * np.abs(cov).max())


def worker_settings(cfg: dict) -> tuple:
    """A dask config's worker profiler, work stealing, malloc trim and BLAS threads."""
    env = cfg["nanny"]["pre-spawn-environ"]
    return (
        cfg["worker"]["profile"]["enabled"],
        cfg["scheduler"]["work-stealing"],
        "MALLOC_TRIM_THRESHOLD_" in env,
        env["OPENBLAS_NUM_THREADS"],
    )


@pytest.fixture(scope="module")
def toy_fleet(setup: tuple) -> tuple:
    """3 simulated UR5 units, 100 s each; unit 0's friction rises by 10 % at 80 s."""
    robot, meas, cols, names = setup
    units = make_units(robot, meas, 3, seed=1)
    sources = [
        [unit_log(u, names, 100.0, 10 + k, **({"rise": 0.1, "rise_at_s": 80.0} if k == 0 else {}))]
        for k, u in enumerate(units)
    ]
    with fleet_client(None, 2, processes=False) as client:
        sums = fleet_sums(client, sources, cols, ChunkSettings(), window_s=20.0)
        # the values, not the config dict (restored in place when the cluster closes)
        settings = client.run(lambda: worker_settings(dask.config.get("distributed")))
    # the workers ran under fleet_client's settings: no profiler thread, no malloc trim
    assert set(settings.values()) == {(False, False, False, 1)}, settings
    return units, sums, solve_fleet(sums.units, cols), cols


def test_toy_fleet_recovers_each_units_friction(toy_fleet: tuple) -> None:
    """Units 1 and 2 (no change): every fv and fs within 1 % (their spread is +-10 %); the
    samples summed are every raw sample of the logs."""
    units, sums, sol, cols = toy_fleet
    err = friction_errors(sol, cols, units)
    assert np.abs(err[1:]).max() < 1.0, err
    assert sums.samples == 3 * 100_000
    assert all(len(w) == 5 for w in sums.windows)


def test_planted_rise_flagged_and_no_alarm_elsewhere(toy_fleet: tuple) -> None:
    """Unit 0's last 20 s window alarms with a rise near 10 %; no other window does."""
    _, sums, sol, cols = toy_fleet
    kappa, _ = window_factors(sums.windows, sol, cols)
    tests = fleet_window_tests(sums.windows, sums.log_offsets, sol, cols, 60.0, kappa)
    thr = rise_threshold(0.01)
    last = tests[0][-1]
    assert last.time_s == pytest.approx(80.0)
    assert last.z > thr
    assert abs(last.rise - 0.1) < 0.01
    others = [t for unit in tests for t in unit if t is not last and np.isfinite(t.z)]
    assert len(others) >= 12
    assert all(t.z < thr for t in others)


def test_coulomb_column_as_filtered_as_the_torque(setup: tuple) -> None:
    """A noise-free unit without quantization (20 s, two chunks): its rows fit the simulated
    torques to 1e-5 N*m (the bare sign(dq) column, with the torque's Coulomb step spread by
    the low-pass and not the column's, left a residual of 5e-4 N*m rms)."""
    robot, meas, cols, names = setup
    unit = make_units(robot, meas, 1, seed=0)[0]
    unit["noise"] = 0.0 * unit["noise"]
    log = unit_log(unit, names, 20.0, 0, counts_per_rev=None)()
    eq = NormalEquations(6, cols.p)
    for r0, r1, span, _, _ in plan_chunks(log, 10.0, ChunkSettings()):
        eq.iadd(chunk_equations(log.q[r0:r1], log.tau[r0:r1], 1000.0, span, cols, ChunkSettings()))
    x = np.linalg.lstsq(eq.A.sum(axis=0), eq.c.sum(axis=0), rcond=None)[0]
    assert np.sqrt(eq.residual_ss(x).sum() / eq.sw.sum()) < 1e-5


def test_simulated_cycles_quantized_each_their_own_way(setup: tuple) -> None:
    """A unit's 30 s (three 10 s cycles): every position within 1.5 counts of the cycle's
    (the wandering offset is under one count), and the quantized positions of one cycle and
    the next differ (they were identical sample for sample: an error every window repeats)."""
    robot, meas, _, names = setup
    unit = make_units(robot, meas, 1, seed=0)[0]
    log = unit_log(unit, names, 30.0, 0)()
    count = 2 * np.pi / 524288
    truth = np.tile(unit["cycle"][0], (3, 1))
    assert np.abs(log.q - truth).max() < 1.5 * count
    assert np.mean(log.q[:10_000] != log.q[10_000:20_000]) > 0.1


def _windows(cols, rng: np.random.Generator, theta: float, rise: float = 0.0) -> tuple:  # noqa: ANN001
    """A unit's 10 windows of 200 rows each: slowly varying regressors, friction and offsets
    of its own, MA(1) noise ``u_i + theta u_(i-1)`` along the rows (a long-run variance
    ``(1 + theta)^2 / (1 + theta^2)`` times the rows'); ``rise`` on the last window's rows."""
    x = np.zeros(cols.p)
    x[cols.local] = rng.uniform(1.0, 2.0, cols.local.size)
    i = np.arange(2000)[:, None, None]
    X = np.cos(2 * np.pi * rng.uniform(0.001, 0.01, (1, 6, cols.p)) * i + rng.uniform(0, 6, cols.p))
    X[:, :, cols.local] *= np.arange(6)[:, None] == cols.owner  # a local column: its joint only
    u = rng.normal(size=(2001, 6))
    y = X @ x + (u[1:] + theta * u[:-1])
    y[1800:] += rise * (X[1800:] @ np.where(np.isin(np.arange(cols.p), cols.local), x, 0.0))
    eqs, wins = NormalEquations(6, cols.p), []
    for w in range(10):
        eq = NormalEquations(6, cols.p)
        eq.add_rows(X[200 * w : 200 * (w + 1)], y[200 * w : 200 * (w + 1)], np.ones((200, 6), bool))
        eqs.iadd(eq)
        wins.append(window_sums(eq, cols, (w, w + 1.0, 0)))
    return eqs, wins


def test_window_factors_measure_the_rows_correlated_noise(setup: tuple) -> None:
    """16 units of MA(1)-noise rows (theta 0.5): the windows' noise factor averaged over the
    joints within 6 % of ``(1 + theta)^2 / (1 + theta^2) = 1.8`` (chi^2 with W instead of
    W - 1 degrees of freedom would read 10 % low, the white-noise covariance 44 %), one
    unit's 30 % rise in a window not moving it; the covariances for a factor 2 are twice
    those for 1."""
    cols, theta = setup[2], 0.5
    rng = np.random.default_rng(7)
    units = [_windows(cols, rng, theta, rise=0.3 if k == 0 else 0.0) for k in range(16)]
    sol = solve_fleet([u[0] for u in units], cols)
    kappa, n = window_factors([u[1] for u in units], sol, cols)
    assert np.all(n == 16)
    assert np.mean(kappa) == pytest.approx((1 + theta) ** 2 / (1 + theta**2), rel=0.06)
    one, two = (scaled_covariances(sol, [u[0] for u in units], cols, np.full(6, f)) for f in (1, 2))
    assert np.allclose(two.units[3].covariance, 2 * one.units[3].covariance, rtol=1e-9)


def _local_windows(cols, rng: np.random.Generator, n: int, noise: float) -> list[WindowSums]:  # noqa: ANN001
    """``n`` windows of one unit drawn directly as normal equations (the shared columns zero):
    per joint ``N = G G^T`` alike from window to window (a routine motion), ``c = N phi + L e``
    (``L L^T = N noise^2``: the sums of rows with white noise ``noise``); friction 1-2, offsets
    near 0; window ``w`` starts at ``60 w`` s."""
    L = cols.local.size
    phi = np.where(np.isin(cols.kind, ["fv", "fs"]), 1.0, 0.1) * rng.uniform(1.0, 2.0, L)
    same = np.equal.outer(cols.owner, cols.owner)
    G = rng.normal(size=(L, 3))
    out = []
    for w in range(n):
        Gw = G + 0.1 * rng.normal(size=G.shape)
        N = np.where(same, Gw @ Gw.T + 4 * np.eye(L), 0.0) * 100
        A = np.zeros((L, cols.p))
        A[:, cols.local] = N
        c = N @ phi + np.linalg.cholesky(N) @ rng.normal(size=L) * noise
        out.append(WindowSums(A=A, c=c, n=np.full(6, 100.0), t0=60.0 * w, t1=60.0 * w + 60, log=0))
    return out


def test_window_factors_median_is_consistent_for_any_window_count(setup: tuple) -> None:
    """200 units of 2 or 3 windows, noise 0.6 where the white-noise covariance says 1 (kappa
    0.36): the factor, averaged over the joints, within 6 % of 0.36. The median over the units
    of ``Q / (k (W - 1))`` (each unit's ratio over its law's mean, not its median) reads 15 %
    low here (the median of chi^2(nu) / nu is 0.79 for nu = 3, 0.89 for 6), inflating z."""
    cols = setup[2]
    rng = np.random.default_rng(11)
    wins = [_local_windows(cols, rng, 2 + k % 2, 0.6) for k in range(200)]
    unit = UnitSolution(x=np.zeros(cols.local.size), covariance=np.eye(1), sigma=np.ones(6),
                        n_rows=np.ones(6))  # fmt: skip
    sol = FleetSolution(x=np.zeros(cols.shared.size), covariance=np.eye(1), units=(unit,) * 200)
    kappa, n = window_factors(wins, sol, cols)
    assert np.all(n == 200)
    assert np.mean(kappa) == pytest.approx(0.36, rel=0.06), kappa


def test_rise_z_standard_normal_whatever_the_units_own_noise_factor(setup: tuple) -> None:
    """60 change-free units of 10 windows (baseline: the first 5) whose true noise variance is
    0.3 or 3 times the stated one (a fleet's factor does not fit every unit): the rise's ``z``
    (calibrated on each unit's own baseline windows, Student-t with 3 or 4 degrees of freedom
    as a normal score) has standard deviation within 0.1 of 1, and 5 % +- 2.5 % of the
    windows exceed the normal quantile of 0.95. With the stated noise taken as exact (``z =
    s / std(s)``, the fleet's factor for every unit) the standard deviation is 1.32; with the
    calibration but ``t`` read as normal, 1.56."""
    cols = setup[2]
    rng = np.random.default_rng(5)
    z = []
    for k in range(60):
        wins = _local_windows(cols, rng, 10, np.sqrt((0.3, 3.0)[k % 2]))
        tests = window_tests(wins, np.zeros(cols.shared.size), np.ones(6), cols, 300.0, [0.0])
        z += [t.z for t in tests]
        assert [t.df for t in tests] == [3] * 5 + [4] * 5
    z_ = np.array(z)
    assert abs(z_.std() - 1) < 0.1, z_.std()
    assert abs(np.mean(z_ > rise_threshold(0.05)) - 0.05) < 0.025


def test_unit_outliers_flags_the_unit_off_the_fleets_spread(setup: tuple) -> None:
    """20 units within +-10 % of nominal and one at +60 %: only that one is flagged."""
    cols = setup[2]
    rng = np.random.default_rng(3)
    nominal = rng.uniform(1.0, 5.0, cols.local.size)
    units = [
        UnitSolution(
            x=nominal * rng.uniform(0.9, 1.1, nominal.size),
            covariance=np.eye(nominal.size) * 1e-8,
            sigma=np.ones(6),
            n_rows=np.ones(6),
        )
        for _ in range(20)
    ]
    units[7] = UnitSolution(
        x=1.6 * nominal, covariance=units[7].covariance, sigma=np.ones(6), n_rows=np.ones(6)
    )
    rows = unit_outliers(
        FleetSolution(x=np.zeros(1), covariance=np.eye(1), units=tuple(units)), cols, 0.01
    )
    flagged = [k for k, r in enumerate(rows[:-1]) if r["flagged"]]
    assert flagged == [7]


@pytest.mark.parametrize(
    ("fleet", "key"),
    [
        ({}, "units[0].logs[0]"),
        # two baseline windows: neither could be calibrated on two others (the drift test
        # would silently test nothing in the baseline)
        ({"window_s": 60.0, "baseline_s": 120.0}, "fleet.baseline_s = 120 s"),
    ],
)
def test_bad_config_one_error_line_nothing_written(tmp_path: Path, fleet: dict, key: str) -> None:
    """A unit's missing log, a baseline shorter than 3 windows: one `error:` line naming the
    file and the key, exit 2."""
    cfg = {
        "robot": {"urdf": str(REPO / "robot/urdf/ur5.urdf")},
        "log": {"time": {"column": "t"}, "position": {"columns": ["q/0"]}},
        "units": [{"name": "u1", "logs": ["missing.npz"]}],
        "fleet": fleet,
    }
    path = tmp_path / "fleet.yaml"
    path.write_text(yaml.safe_dump(cfg))
    out = tmp_path / "runs"
    res = CliRunner().invoke(app, ["fleet", str(path), "--out", str(out)])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("error: ")
    assert key in lines[0]
    assert "fleet.yaml" in lines[0]
    assert not out.exists()


def test_unreadable_log_on_a_worker_is_one_error_line(tmp_path: Path) -> None:
    """A log without the named torque columns, read on a worker: the reader's error as one
    `error:` line (no worker traceback), exit 2, no run folder."""
    t = np.arange(3000) / 1000.0
    np.savez(tmp_path / "u1.npz", t=t, q=np.zeros((3000, 6)), torque=np.zeros((3000, 6)))
    cfg = {"robot": {"urdf": str(REPO / "robot/urdf/ur5.urdf")},
           "log": {"time": {"column": "t"}, "position": {"columns": [f"q/{j}" for j in range(6)]},
                   "torque": {"columns": [f"tau/{j}" for j in range(6)]}},
           "units": {"folder": ".", "glob": "u*.npz"},
           "fleet": {"workers": 1, "processes": False}}  # fmt: skip
    (tmp_path / "fleet.yaml").write_text(yaml.safe_dump(cfg))
    out = tmp_path / "runs"
    res = CliRunner().invoke(app, ["fleet", str(tmp_path / "fleet.yaml"), "--out", str(out)])
    assert res.exit_code == 2
    assert "Traceback" not in res.output
    errors = [line for line in res.output.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1
    assert "u1.npz: column 'tau/0' not found" in errors[0]
    assert not out.exists()


def test_cutoff_above_the_row_rate_is_a_data_error() -> None:
    """A cut-off at or above half the row rate would alias the rows' noise: refused."""
    log = RobotLog(t=np.arange(2000) / 1000.0, q=np.zeros((2000, 6)), tau=np.zeros((2000, 6)),
                   sampling_rate_hz=1000.0, joint_names=tuple("abcdef"))  # fmt: skip
    with pytest.raises(DataError, match="fleet.cutoff_hz = 25 Hz"):
        plan_chunks(log, 1.0, ChunkSettings(cutoff_hz=25.0, decimation=20))
    assert plan_chunks(log, 1.0, ChunkSettings(cutoff_hz=20.0, decimation=20))


def test_cli_on_npz_logs_through_a_scheduler_address(setup: tuple, tmp_path: Path) -> None:
    """Two units' npz logs identified by `ident fleet` on a running scheduler: the friction in
    result.json within 2 % of the truth, its 95 % intervals present, the test across units
    named as not run (2 units), the folder complete."""
    robot, meas, cols, names = setup
    units = make_units(robot, meas, 2, seed=5)
    for k, u in enumerate(units):
        log = unit_log(u, names, 30.0, k)()
        np.savez(tmp_path / f"u{k}.npz", t=log.t, q=log.q, tau=log.tau)
    cfg = {
        "name": "toy",
        "robot": {"urdf": str(REPO / "robot/urdf/ur5.urdf")},
        "log": {
            "time": {"column": "t"},
            "position": {"columns": [f"q/{j}" for j in range(6)]},
            "torque": {"columns": [f"tau/{j}" for j in range(6)]},
        },
        "units": {"folder": ".", "glob": "u*.npz"},
        "fleet": {"window_s": 10.0, "baseline_s": 30.0},
    }
    with distributed.LocalCluster(n_workers=1, processes=False, dashboard_address=":0") as lc:
        cfg["fleet"]["scheduler"] = lc.scheduler_address
        (tmp_path / "fleet.yaml").write_text(yaml.safe_dump(cfg))
        res = CliRunner().invoke(
            app, ["fleet", str(tmp_path / "fleet.yaml"), "--out", str(tmp_path / "runs")]
        )
    assert res.exit_code == 0, res.output
    (folder,) = (tmp_path / "runs").iterdir()
    result = json.loads((folder / "result.json").read_text())
    drift = json.loads((folder / "drift.json").read_text())
    assert json.loads((folder / "run.json").read_text())["status"] == "complete"
    for u, entry in zip(units, result["per_unit"], strict=True):
        for j in range(6):
            p = entry["parameters"][f"fv{j + 1}"]
            assert abs(p["value"] / u["fv"][j] - 1) < 0.02
            assert p["interval_95"][0] < p["value"] < p["interval_95"][1]
    assert drift["across_units"]["status"] == "not run"
    assert "samples/s per core" in res.output


def test_wilson_interval_closed_forms() -> None:
    """bench_fleet's false-alarm interval: Wilson's closed forms at ``k = 0`` (upper
    ``z^2 / (n + z^2)``) and ``k = n`` (lower ``n / (n + z^2)``), and an interval about
    ``k / n`` pulled towards 1/2 (not the Wald interval ``p +- z sqrt(p (1 - p) / n)``)."""
    z2 = 1.959963984540054**2
    assert wilson(0, 100)[0] == pytest.approx(0.0, abs=1e-15)
    assert wilson(0, 100)[1] == pytest.approx(z2 / (100 + z2))
    assert wilson(50, 50)[0] == pytest.approx(50 / (50 + z2))
    lo, hi = wilson(15, 1500)
    assert lo < 0.01 < hi
    assert hi - 0.01 > 0.01 - lo  # skewed towards 1/2
