"""A fleet of simulated UR5 units identified jointly on a Dask LocalCluster: per-unit
friction error, friction-rise detection and false alarms, throughput per core.

The fleet (:mod:`ident.measure.fleet_sim`): the UR5 of ``configs/ur5.yaml`` (its rotor
inertias), each unit doing its own routine motion (a 10 s 4-harmonic Fourier cycle, repeated)
with viscous and Coulomb friction drawn within +-10 % of the config's, torque offsets of a few
tenths of N*m, torque noise 1 % of each joint's RMS torque and 2^19-count encoders, at 1 kHz.

1. **Accuracy and detection** (``--units 20 --seconds S``): every unit logs ``S`` seconds; one
   unit's friction rises by 10 % for its last ``--window`` seconds (60 s). The logs are
   identified jointly (:mod:`ident.identify.streaming.fleet`, the ``ident fleet`` defaults)
   on a LocalCluster of 2 worker processes. Printed: each unit's largest friction error
   (target: within 3 %), whether the rise window is flagged, the false alarms over every
   other window (target: at most 1 %), and the throughput (raw samples per second per core).
2. **Throughput** (``--hours H``): ``H`` robot-hours over the same units (10-minute logs,
   simulated on the workers), the same pass; the wall time, the throughput per core, the
   simulation's own share (measured apart) and the extrapolation to 100 robot-hours.

3. **The command** (``--npz DIR``): the case of 1 written as npz logs with a config into
   ``DIR``, and ``ident fleet`` run on them: its terminal lines and ``drift.md``.
4. **Robot-hours from disk** (``--npz DIR --hours H``): each unit's ``--distinct`` 10-minute
   npz logs (its cycle continued, fresh noise) written into ``DIR``, each listed
   ``H / (units x distinct x 10 min)`` times in the unit's logs (disk is limited: 100
   robot-hours of 1 kHz logs are 37 GB; the compute is the same, each log is read and every
   chunk identified again), and ``ident fleet`` run on them in a child process: its wall
   time, the CPU time of the whole process tree (reading included), the throughput per core
   and the load average during the run.
5. **Coverage and false alarms** (``--coverage-seeds N [--seed-start S] [--save-z F]
   [--sums-cache DIR]``): ``N``
   fleets of ``--units`` change-free units in this process: the share of the 95 % intervals
   holding the truth and the change-free windows' false-alarm rate at alpha 0.01 with its
   Wilson 95 % interval (all windows, the baseline's own, the later ones).

Run: ``nice -n 10 python benchmarks/bench_fleet.py [--units 20] [--seconds 600] [--hours 0]
[--npz DIR]``.
"""

from __future__ import annotations

import argparse
import os
import pickle
import resource
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import yaml
from scipy.stats import norm
from typer.testing import CliRunner

from ident.cli import app
from ident.config import read_yaml
from ident.errors import NotIdentifiable
from ident.identify.streaming.fleet import (
    ChunkSettings,
    FleetColumns,
    chunk_equations,
    scaled_covariances,
    solve_fleet,
    window_sums,
)
from ident.identify.streaming.fleet import fleet_columns as columns_of
from ident.identify.streaming.fleet_drift import (
    fleet_window_tests,
    rise_threshold,
    window_factors,
)
from ident.identify.streaming.fleet_run import fleet_client, fleet_sums, plan_chunks
from ident.identify.streaming.normal import NormalEquations
from ident.measure.fleet_sim import SimulatedUnitLog
from ident.model.selection import RobotSelection, load_robot

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))
from bench_payload import reference  # noqa: E402

CONFIG = REPO / "configs" / "ur5.yaml"


def ur5() -> tuple:
    """The UR5 of configs/ur5.yaml and its measurement section (friction, rotor inertia)."""
    raw = read_yaml(CONFIG)
    robot = load_robot(RobotSelection.model_validate(raw["robot"]).resolved(CONFIG.parent))
    return robot, raw["measurement"]


def fleet_columns(robot) -> FleetColumns:  # noqa: ANN001
    """The ``ident fleet`` default columns of a robot."""
    return columns_of(robot.model)


def make_units(
    robot, measurement: dict, n_units: int, seed: int, spread: float = 0.1
) -> list[dict]:  # noqa: ANN001
    """Each unit's cycle and truth: ``{cycle: (q, dq, tau_rigid), fv, fs, offset, noise}``."""
    rng = np.random.default_rng(seed)
    fv0 = np.asarray(measurement["friction"]["viscous"], dtype=float)
    fs0 = np.asarray(measurement["friction"]["coulomb"], dtype=float)
    armature = np.asarray(measurement["armature"], dtype=float)
    units = []
    for _ in range(n_units):
        _, q, dq, ddq = reference(robot, 1000.0, 10.0, rng, amplitude=0.35)
        tau = robot.rnea(q, dq, ddq) + armature * ddq
        rms = np.sqrt(np.mean(tau**2, axis=0))
        units.append(
            {
                "cycle": (q, dq, tau),
                "fv": fv0 * rng.uniform(1 - spread, 1 + spread, robot.nv),
                "fs": fs0 * rng.uniform(1 - spread, 1 + spread, robot.nv),
                "offset": rng.uniform(-0.3, 0.3, robot.nv),
                "noise": 0.01 * rms,
            }
        )
    return units


def unit_log(
    unit: dict, names: tuple, seconds: float, seed: int, **kw: float | None
) -> SimulatedUnitLog:
    """A :class:`SimulatedUnitLog` of a unit of :func:`make_units`."""
    q, dq, tau = unit["cycle"]
    return SimulatedUnitLog(
        q=q,
        dq=dq,
        tau_rigid=tau,
        rate_hz=1000.0,
        seconds=seconds,
        fv=unit["fv"],
        fs=unit["fs"],
        offset=unit["offset"],
        noise_std=unit["noise"],
        seed=seed,
        joint_names=names,
        **kw,
    )  # type: ignore[arg-type]


def friction_errors(sol, cols: FleetColumns, units: list[dict]) -> np.ndarray:  # noqa: ANN001
    """Relative error [%] of every unit's fv and fs per joint, shape (n_units, 2 nv)."""
    out = []
    for u, truth in zip(sol.units, units, strict=True):
        row = []
        for i, (kind, j) in enumerate(zip(cols.kind, cols.owner, strict=True)):
            if kind in ("fv", "fs"):
                row.append(100 * (u.x[i] / truth[kind][j] - 1.0))
        out.append(row)
    return np.array(out)


def coverage(sol, cols: FleetColumns, units: list[dict], skip: int | None) -> list[bool]:  # noqa: ANN001
    """Whether each fv and fs 95 % interval (``sol``'s covariance, as result.json) of the
    units but ``skip`` holds the truth."""
    inside = []
    for k, (u, truth) in enumerate(zip(sol.units, units, strict=True)):
        if k == skip:
            continue
        for i, (kind, j) in enumerate(zip(cols.kind, cols.owner, strict=True)):
            if kind in ("fv", "fs"):
                inside.append(bool(abs(u.x[i] - truth[kind][j]) <= 1.959964 * u.std[i]))
    return inside


def reported(sums, cols: FleetColumns, baseline_s: float) -> tuple:  # noqa: ANN001
    """As ``ident fleet`` reports: the solve, the windows' noise factor per joint, the
    solution with result.json's covariances, every unit's window tests."""
    sol = solve_fleet(sums.units, cols)
    kappa, _ = window_factors(sums.windows, sol, cols)
    scaled = scaled_covariances(
        sol, sums.units, cols, np.maximum(np.nan_to_num(kappa, nan=1.0), 1.0)
    )
    tests = fleet_window_tests(sums.windows, sums.log_offsets, sol, cols, baseline_s, kappa)
    return sol, kappa, scaled, tests


def accuracy(args: argparse.Namespace) -> None:
    """Part 1 of the module docstring."""
    robot, meas = ur5()
    cols = fleet_columns(robot)
    names = tuple(str(robot.model.names[i]) for i in range(1, robot.model.njoints))
    units = make_units(robot, meas, args.units, seed=args.seed)
    rise_at = args.seconds - args.window
    sources = [
        [
            unit_log(
                u,
                names,
                args.seconds,
                100 + k,
                **({"rise": 0.1, "rise_at_s": rise_at} if k == args.rise_unit else {}),
            )
        ]
        for k, u in enumerate(units)
    ]
    settings = ChunkSettings()
    with fleet_client(None, args.workers) as client:
        sums = fleet_sums(client, sources, cols, settings, window_s=args.window)
    t0 = time.process_time()
    sol = solve_fleet(sums.units, cols)
    solve_s = time.process_time() - t0
    # the rise unit's rows after the rise bias its fleet estimate: truth = before the rise
    err = friction_errors(sol, cols, units)
    print(f"units {args.units}, {args.seconds:g} s each at 1 kHz; joint solve {solve_s:.2f} s CPU")
    for k, e in enumerate(err):
        tag = " (friction +10 % in its last window)" if k == args.rise_unit else ""
        print(
            f"unit {k:2d}: friction error |max| {np.abs(e).max():5.2f} %, "
            f"rms {np.sqrt(np.mean(e**2)):5.2f} %{tag}"
        )
    clean = np.delete(err, args.rise_unit, axis=0)
    print(f"clean units: |max| friction error {np.abs(clean).max():.2f} % (target 3 %)")
    _, kappa, scaled, tests = reported(sums, cols, args.baseline)
    inside = coverage(scaled, cols, units, args.rise_unit)
    print(f"windows' noise factor per joint: {np.round(kappa, 3).tolist()}")
    print(f"95 % intervals holding the truth (clean units): {np.mean(inside):.3f}")
    detection(tests, args)
    throughput_line(sums, "accuracy case")


def detection(tests: list, args: argparse.Namespace) -> None:
    """The rise window flagged? False alarms over every other window."""
    thr = rise_threshold(0.01)
    rise_at = args.seconds - args.window
    hits, clean = [], []
    for k, unit in enumerate(tests):
        for t in unit:
            if not np.isfinite(t.z):
                continue
            (hits if k == args.rise_unit and t.time_s >= rise_at - 1e-9 else clean).append(t)
    fa = sum(t.z > thr for t in clean)
    print(f"rise test: threshold z > {thr:.2f} (alpha 0.01, one-sided)")
    for t in hits:
        print(
            f"  rise window at {t.time_s:.0f} s ({t.duration_s:.0f} s): rise {100 * t.rise:+.2f} "
            f"+- {100 * t.std:.2g} % (t {t.rise / t.std:.4g}, {t.df} degrees of freedom), "
            f"z {t.z:.1f} -> {'DETECTED' if t.z > thr else 'missed'}"
        )
    print(
        f"  false alarms: {fa} of {len(clean)} change-free windows "
        f"({100 * fa / max(1, len(clean)):.2f} %; "
        f"largest z {max(t.z for t in clean):.2f}, std of z {np.std([t.z for t in clean]):.3f})"
    )


def throughput_line(sums, label: str, load_cpu_per_sample: float = 0.0) -> None:  # noqa: ANN001
    """Samples per second per core of the Dask pass: by the wall clock (the machine's load
    included) and by the chunk tasks' CPU time; 100 robot-hours extrapolated from the latter
    (plus ``load_cpu_per_sample`` [s], producing the logs) on the cluster's cores."""
    per_core = sums.samples / sums.wall_s / sums.cores
    per_cpu = sums.samples / sums.chunk_cpu_s
    cpu_per_sample = 1.0 / per_cpu + load_cpu_per_sample
    hours = 100 * 3600 * 1000 * cpu_per_sample / sums.cores
    print(
        f"{label}: {sums.samples} samples ({sums.samples / 3.6e6:.2f} robot-hours at 1 kHz) "
        f"in {sums.wall_s:.1f} s wall on {sums.cores} cores: {per_core:,.0f} samples/s per core "
        f"by the wall clock; {per_cpu:,.0f} samples per CPU second of the chunk tasks"
    )
    print(
        f"  100 robot-hours on {sums.cores} idle cores: {hours / 60:.1f} min "
        f"({1e6 * cpu_per_sample:.2f} us CPU per sample, producing the logs included); "
        f"at this run's wall-clock rate: {100 * 3600 * 1000 / (per_core * sums.cores) / 60:.1f} min"
    )


def throughput(args: argparse.Namespace) -> None:
    """Part 2 of the module docstring."""
    robot, meas = ur5()
    cols = fleet_columns(robot)
    names = tuple(str(robot.model.names[i]) for i in range(1, robot.model.njoints))
    units = make_units(robot, meas, args.units, seed=args.seed)
    log_s = 600.0
    n_logs = max(1, int(round(args.hours * 3600 / log_s / args.units)))
    sources = [
        [unit_log(u, names, log_s, 1000 * k + m, start_s=m * log_s) for m in range(n_logs)]
        for k, u in enumerate(units)
    ]
    c0 = time.process_time()
    sources[0][0]()
    sim_per_sample = (time.process_time() - c0) / (log_s * 1000)
    with fleet_client(None, args.workers) as client:
        sums = fleet_sums(client, sources, cols, ChunkSettings(), window_s=args.window)
    sol = solve_fleet(sums.units, cols)
    err = friction_errors(sol, cols, units)
    print(
        f"throughput case: {args.units} units x {n_logs} logs of {log_s:g} s; friction error |max| "
        f"{np.abs(err).max():.3f} %"
    )
    throughput_line(sums, "throughput case (the logs simulated on the workers)", sim_per_sample)
    print(
        f"  the simulation's own share: {1e6 * sim_per_sample:.2f} us CPU per sample "
        f"({100 * sim_per_sample * sums.samples / (sums.wall_s * sums.cores):.0f} % of the "
        "workers' time)"
    )


def cli_case(args: argparse.Namespace) -> None:
    """Part 3: the accuracy case's logs written as npz files into ``--npz DIR`` with a config,
    and ``ident fleet`` run on them (reading included); its terminal output and drift.md."""
    robot, meas = ur5()
    names = tuple(str(robot.model.names[i]) for i in range(1, robot.model.njoints))
    units = make_units(robot, meas, args.units, seed=args.seed)
    folder = args.npz
    (folder / "logs").mkdir(parents=True, exist_ok=True)
    rise_at = args.seconds - args.window
    for k, u in enumerate(units):
        kw = {"rise": 0.1, "rise_at_s": rise_at} if k == args.rise_unit else {}
        log = unit_log(u, names, args.seconds, 100 + k, **kw)()
        np.savez(folder / "logs" / f"u{k:02d}.npz", t=log.t, q=log.q, tau=log.tau)
    cfg = {"name": "bench-fleet", "robot": {"urdf": str(REPO / "robot/urdf/ur5.urdf")},
           "log": {"time": {"column": "t"}, "position": {"columns": [f"q/{j}" for j in range(6)]},
                   "torque": {"columns": [f"tau/{j}" for j in range(6)]}},
           "units": {"folder": "logs", "glob": "u*.npz"},
           "fleet": {"workers": args.workers, "window_s": args.window,
                     "baseline_s": args.baseline}}  # fmt: skip
    (folder / "fleet.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    res = CliRunner().invoke(
        app, ["fleet", str(folder / "fleet.yaml"), "--out", str(folder / "runs")]
    )
    print(res.output)
    if res.exit_code == 0:
        (run,) = sorted((folder / "runs").iterdir())[-1:]
        print((run / "drift.md").read_text())


def local_sums(sources: list, cols: FleetColumns, window_s: float) -> SimpleNamespace:
    """:func:`fleet_sums`' units, windows and log offsets computed in this process (one log
    per unit; the same chunks and sums, no cluster)."""
    settings = ChunkSettings()
    out = SimpleNamespace(units=[], windows=[], log_offsets=[[0.0] for _ in sources])
    for src in sources:
        log = src()
        eq, wins = NormalEquations(log.q.shape[1], cols.p), []
        for r0, r1, span, t0, t1 in plan_chunks(log, window_s, settings):
            part = chunk_equations(log.q[r0:r1], log.tau[r0:r1], 1000.0, span, cols, settings)
            eq.iadd(part)
            wins.append(window_sums(part, cols, (t0, t1, 0)))
        out.units.append(eq)
        out.windows.append(wins)
    return out


def cached_sums(
    args: argparse.Namespace, seed: int, sources: list, cols: FleetColumns
) -> SimpleNamespace:
    """:func:`local_sums` of one seed's fleet, kept in ``--sums-cache DIR`` (the simulation
    and the rows are most of part 5's CPU: a change of the drift test is measured again on the
    same fleets without them)."""
    if args.sums_cache is None:
        return local_sums(sources, cols, args.window)
    f = args.sums_cache / f"seed{seed}-units{args.units}-{args.seconds:g}s-{args.window:g}w.pkl"
    if f.exists():
        with f.open("rb") as fh:
            return pickle.load(fh)  # noqa: S301 (the benchmark's own files)
    sums = local_sums(sources, cols, args.window)
    args.sums_cache.mkdir(parents=True, exist_ok=True)
    with f.open("wb") as fh:
        pickle.dump(sums, fh)
    return sums


def seeds_case(args: argparse.Namespace) -> None:
    """Part 5: ``--coverage-seeds N`` fleets of ``--units`` change-free units (``--seconds``
    each; units, motions and noise drawn from each seed), in this process: the share of the
    95 % intervals of result.json holding the true fv and fs, and the change-free windows'
    rise statistic (its spread, the share above the alpha 0.01 threshold)."""
    robot, meas = ur5()
    cols = fleet_columns(robot)
    names = tuple(str(robot.model.names[i]) for i in range(1, robot.model.njoints))
    inside, z, kappas, in_base, unit_of = [], [], [], [], []
    c0 = time.process_time()
    for seed in range(args.seed_start, args.seed_start + args.coverage_seeds):
        units = make_units(robot, meas, args.units, seed=1000 + seed)
        sources = [unit_log(u, names, args.seconds, 10_000 * seed + k) for k, u in enumerate(units)]
        try:
            _, kappa, scaled, tests = reported(
                cached_sums(args, seed, sources, cols), cols, args.baseline
            )
        except NotIdentifiable as exc:  # a unit's motion left a joint below the threshold
            print(f"seed {seed}: skipped ({exc})")
            continue
        got = coverage(scaled, cols, units, None)
        inside += got
        z += [t.z for unit in tests for t in unit if np.isfinite(t.z)]
        in_base += [t.baseline for unit in tests for t in unit if np.isfinite(t.z)]
        unit_of += [
            len(kappas) * args.units + k for k, u in enumerate(tests) for t in u if np.isfinite(t.z)
        ]
        kappas.append(kappa)
        print(
            f"seed {seed}: intervals holding the truth {np.mean(got):.3f}; "
            f"kappa {np.round(kappa, 2)}"
        )
    z_ = np.array(z)
    if args.save_z is not None:
        np.savez(
            args.save_z, z=z_, baseline=np.array(in_base), kappa=np.array(kappas), unit=unit_of
        )
    print(
        f"{args.coverage_seeds} seeds x {args.units} units x {args.seconds:g} s "
        f"({time.process_time() - c0:.0f} s CPU): 95 % intervals holding the truth "
        f"{np.mean(inside):.3f} of {len(inside)}; windows' noise factor per joint (median over "
        f"seeds) {np.round(np.median(kappas, axis=0), 2).tolist()}; change-free windows' z: "
        f"{z_.size}, mean {z_.mean():+.3f}, standard deviation {z_.std():.3f}, above "
        f"{rise_threshold(0.01):.3f}: {np.mean(z_ > rise_threshold(0.01)):.4f} (stated 0.01)"
    )
    false_alarm_lines(z_, np.array(in_base))
    lo, hi = unit_bootstrap(z_ > rise_threshold(0.01), np.array(unit_of))
    print(f"  all windows, bootstrap over units (95 %): {100 * lo:.2f} - {100 * hi:.2f} %")


def wilson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a proportion ``k / n`` at ``level`` (two-sided)."""
    zq = float(norm.isf((1 - level) / 2))
    p, d = k / n, 1 + zq * zq / n
    centre = (p + zq * zq / (2 * n)) / d
    half = zq * np.sqrt(p * (1 - p) / n + zq * zq / (4 * n * n)) / d
    return centre - half, centre + half


def unit_bootstrap(
    alarm: np.ndarray, unit: np.ndarray, draws: int = 2000, seed: int = 0
) -> tuple[float, float]:
    """95 % interval of the alarm rate, the units resampled with replacement (a unit's
    windows share its baseline and its calibration: not independent, as Wilson assumes)."""
    ids, inv = np.unique(unit, return_inverse=True)
    k, n = np.bincount(inv, weights=alarm), np.bincount(inv)
    pick = np.random.default_rng(seed).integers(0, ids.size, (draws, ids.size))
    rate = k[pick].sum(axis=1) / n[pick].sum(axis=1)
    return float(np.quantile(rate, 0.025)), float(np.quantile(rate, 0.975))


def false_alarm_lines(z: np.ndarray, baseline: np.ndarray) -> None:
    """The change-free windows' false-alarm rate at alpha 0.01 with its Wilson 95 % interval:
    all windows, the baseline's own (each against the baseline without it) and the later ones
    (against the whole baseline). The windows of one unit share its baseline and noise factor,
    so they are not independent: the interval is that of independent windows, a lower bound
    on its width."""
    thr = rise_threshold(0.01)
    for label, zz in (("all", z), ("baseline", z[baseline]), ("after the baseline", z[~baseline])):
        k, n = int(np.sum(zz > thr)), zz.size
        lo, hi = wilson(k, n)
        print(
            f"false alarms ({label} windows): {k} of {n} = {100 * k / n:.2f} % "
            f"(Wilson 95 %: {100 * lo:.2f} - {100 * hi:.2f} %; stated 1 %); "
            f"z std {zz.std():.3f}"
        )


def hours_case(args: argparse.Namespace) -> None:
    """Part 4 of the module docstring."""
    robot, meas = ur5()
    names = tuple(str(robot.model.names[i]) for i in range(1, robot.model.njoints))
    units = make_units(robot, meas, args.units, seed=args.seed)
    log_s = 600.0
    reuse = max(1, int(round(args.hours * 3600 / (log_s * args.units * args.distinct))))
    (args.npz / "logs").mkdir(parents=True, exist_ok=True)
    listed = []
    for k, u in enumerate(units):
        files = []
        for m in range(args.distinct):
            f = args.npz / "logs" / f"u{k:02d}-{m}.npz"
            if not f.exists():
                log = unit_log(u, names, log_s, 1000 * k + m, start_s=m * log_s)()
                np.savez(f, t=log.t, q=log.q, tau=log.tau)
            files.append(f.name)
        listed.append({"name": f"u{k:02d}", "logs": [f"logs/{f}" for f in files * reuse]})
    size = sum(f.stat().st_size for f in (args.npz / "logs").glob("u*-*.npz"))
    print(
        f"{args.units} units x {args.distinct} distinct 10-minute logs ({size / 1e9:.2f} GB on "
        f"disk), each listed {reuse} times: {args.units * args.distinct * reuse * log_s / 3600:g} "
        "robot-hours read and identified (the same files reused: the compute is the same)"
    )
    cfg = {"name": "bench-fleet-hours", "robot": {"urdf": str(REPO / "robot/urdf/ur5.urdf")},
           "log": {"time": {"column": "t"}, "position": {"columns": [f"q/{j}" for j in range(6)]},
                   "torque": {"columns": [f"tau/{j}" for j in range(6)]}},
           "units": listed,
           "fleet": {"workers": args.workers, "window_s": args.window,
                     "baseline_s": args.baseline}}  # fmt: skip
    (args.npz / "fleet-hours.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    run_measured([sys.executable, "-c", "from ident.cli import app; app()", "fleet",
                  str(args.npz / "fleet-hours.yaml"), "--out", str(args.npz / "runs")],
                 samples=int(args.units * args.distinct * reuse * log_s * 1000))  # fmt: skip


def run_measured(command: list[str], samples: int, cores: int = 2) -> None:
    """Run ``command``; print its output, wall time, the CPU time of its process tree (user +
    system, the LocalCluster's workers included), the load average sampled every 10 s, and
    100 robot-hours at 1 kHz on ``cores`` idle cores extrapolated from that CPU time over
    ``samples`` (the start-up, a fixed cost, included as if per sample: an upper bound)."""
    loads: list[float] = []
    stop = threading.Event()

    def sample() -> None:
        while not stop.wait(10.0):
            loads.append(os.getloadavg()[0])

    thread = threading.Thread(target=sample, daemon=True)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    thread.start()
    res = subprocess.run(command, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    stop.set()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    print(res.stdout + res.stderr)
    mean = float(np.mean(loads)) if loads else float("nan")
    print(
        f"measured: {wall:.0f} s wall, {cpu:.0f} s CPU of the process tree "
        f"(user {after.ru_utime - before.ru_utime:.0f} s, system "
        f"{after.ru_stime - before.ru_stime:.0f} s; exit code {res.returncode}); load average "
        f"(1 min) during the run: {min(loads, default=float('nan')):.1f} - "
        f"{max(loads, default=float('nan')):.1f}, mean {mean:.1f}"
    )
    per_sample = cpu / samples
    print(
        f"  {1e6 * per_sample:.2f} us CPU per sample ({samples / cpu:,.0f} samples per CPU "
        f"second: the throughput per core, the core busy); 100 robot-hours on {cores} idle "
        f"cores, extrapolated: {3.6e8 * per_sample / cores / 60:.1f} min"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--units", type=int, default=20)
    parser.add_argument("--seconds", type=float, default=600.0)
    parser.add_argument("--window", type=float, default=60.0)
    parser.add_argument("--baseline", type=float, default=300.0)
    parser.add_argument("--rise-unit", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--hours", type=float, default=0.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--coverage-seeds", type=int, default=0, help="part 5: N fleets")
    parser.add_argument("--seed-start", type=int, default=0, help="part 5: first seed")
    parser.add_argument("--save-z", type=Path, default=None, help="part 5: z values to npz")
    parser.add_argument("--sums-cache", type=Path, default=None, help="part 5: fleets' sums here")
    parser.add_argument("--distinct", type=int, default=3, help="distinct logs per unit (part 4)")
    parser.add_argument("--npz", type=Path, default=None, help="run `ident fleet` on npz logs here")
    args = parser.parse_args()
    if args.coverage_seeds > 0:
        seeds_case(args)
        return
    if args.npz is not None and args.hours > 0:
        hours_case(args)
        return
    if args.npz is not None:
        cli_case(args)
        return
    if args.seconds > 0:
        accuracy(args)
    if args.hours > 0:
        throughput(args)


if __name__ == "__main__":
    main()
