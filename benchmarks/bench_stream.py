"""Streaming payload identification on simulated UR5 logs (MuJoCo, 1 kHz): CPU per sample,
detection of a payload step, its estimate 1 s after the change, interval coverage, false alarms.

For each seed, MuJoCo simulates the UR5 of ``configs/ur5.yaml`` (its friction, rotor inertia
and encoder; torque noise 1 % of each joint's RMS torque) tracking the 4-harmonic Fourier
excitation of ``bench_payload.py`` twice: without a payload and with one drawn for the seed
(1-5 kg, centre of mass 3-12 cm from the last joint, a solid box). The streamed log is the
first one up to the change time (15-16 s, drawn) and the second one after it: a payload
attached while the arm moves. The streaming estimator (:mod:`ident.identify.streaming`, the
``ident stream`` defaults: 41-sample causal Savitzky-Golay rows, 60 s memory, 0.01 false alarms
per hour) is fed 100-sample blocks, as ``ident stream --speed 0`` does. Measured per seed:
detection delay, the onset's error, the estimate 1 s after the onset (mass error, centre of mass
error, whether the 95 % intervals hold the truth), and the CPU time per 1 kHz sample of the
update (filters, rows, sums, tests) and of the scheduled consistent solve (every 5 s). The log
without the payload is streamed too: alarms on it are false alarms, and its test statistics
show how the per-test tail compares with the chi-square law. In the step log an alarm counts
as false only when its test's samples all precede the change: a row describes the centre of
its causal filter's window, so a test at row time ``t`` holds samples up to ``t + delay``
(20 ms); the change-free time tested is both logs' after the warm-up (the step log's up to the
change).

``--friction N`` adds N logs whose viscous and Coulomb friction rise by 50 % at the change
(no payload): detected, and classified as friction?

Run: ``nice -n 10 python benchmarks/bench_stream.py [--seeds 20] [--friction 3]
[--more-changes 12 13.5 17 18.4] [--cache DIR]`` (about 30 s
of CPU a seed for the two MuJoCo logs, 1 s for the streams).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import chi2
from threadpoolctl import threadpool_limits

from ident.dynamics.chain import chain_from_model
from ident.dynamics.parameters import parameters_from_model
from ident.identify.config import ModelConfig
from ident.identify.streaming import detect
from ident.identify.streaming.estimator import StreamingEstimator, StreamSettings
from ident.measure.mujoco_config import load_mujoco_measurement
from ident.measure.mujoco_sim import simulate

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))
from bench_payload import box_inertia, simulation_setup  # noqa: E402

CONFIG = REPO / "configs" / "ur5.yaml"
SECONDS = 20.0
BLOCK = 100  # samples handed over at a time (0.1 s at 1 kHz)


def draw_payload(rng: np.random.Generator) -> tuple[float, np.ndarray, list[float]]:
    """A payload: mass 1-5 kg, centre of mass 3-12 cm from the last joint's origin, a box."""
    mass = float(rng.uniform(1.0, 5.0))
    direction = rng.normal(size=3)
    com = direction / np.linalg.norm(direction) * rng.uniform(0.03, 0.12)
    sides = rng.uniform(0.05, 0.15, 3)
    return mass, com, box_inertia(mass, tuple(sides))


def step_logs(seed: int, *, friction: bool = False) -> dict:
    """The two MuJoCo logs of a seed and the change time: ``{t, q, tau_without, tau_step,
    change_s, payload}`` (``friction``: the second log has 1.5 times the friction instead)."""
    rng = np.random.default_rng(1000 + seed)
    _, robot, (t, q, dq, ddq), measurement = simulation_setup(CONFIG, seconds=SECONDS, seed=seed)
    payload = draw_payload(rng)
    second = dict(measurement)
    if friction:
        f = dict(second["friction"])
        f["viscous"] = (1.5 * np.asarray(f["viscous"])).tolist()
        f["coulomb"] = (1.5 * np.asarray(f["coulomb"])).tolist()
        second["friction"] = f
    else:
        second["payload"] = {"mass": payload[0], "com": payload[1].tolist(),
                             "inertia": payload[2]}  # fmt: skip
    logs = [simulate(robot, t, q, dq, ddq, load_mujoco_measurement(m), rng=2 * seed + k)
            for k, m in enumerate((measurement, second))]  # fmt: skip
    change_s = float(rng.uniform(15.0, 16.0))
    t_log = logs[0].t - logs[0].t[0]
    k = int(round(change_s * 1000.0))
    tau_step = np.vstack([logs[0].tau_measured[:k], logs[1].tau_measured[k:]])
    return {"robot": robot, "t": t_log, "q": np.vstack([logs[0].q[:k], logs[1].q[k:]]),
            "q_without": logs[0].q, "tau_without": logs[0].tau_measured, "tau_step": tau_step,
            "q_with": logs[1].q, "tau_with": logs[1].tau_measured,
            "change_s": k / 1000.0, "payload": payload}  # fmt: skip


def cached_step_logs(seed: int, *, friction: bool, cache: Path | None) -> dict:
    """:func:`step_logs`, read from (or written to) ``cache`` when given: the MuJoCo logs are
    most of a seed's CPU, and the same for every version of the stream."""
    if cache is None:
        return step_logs(seed, friction=friction)
    path = cache / f"{'friction' if friction else 'payload'}-{seed}.npz"
    keys = ("t", "q", "q_without", "tau_without", "tau_step", "q_with", "tau_with")
    if path.exists():
        data = np.load(path)
        _, robot, _, _ = simulation_setup(CONFIG, seconds=SECONDS, seed=seed)
        payload = (float(data["mass"]), data["com"], data["inertia"].tolist())
        return {"robot": robot, **{k: data[k] for k in keys},
                "change_s": float(data["change_s"]), "payload": payload}  # fmt: skip
    logs = step_logs(seed, friction=friction)
    cache.mkdir(parents=True, exist_ok=True)
    mass, com, inertia = logs["payload"]
    np.savez(path, **{k: logs[k] for k in keys}, change_s=logs["change_s"], mass=mass,
             com=com, inertia=np.asarray(inertia))  # fmt: skip
    return logs


#: Re-solves of a change's consistent estimate for its intervals (``--resolves``; 0: the least
#: squares' intervals about it, for comparison).
RESOLVES = [StreamSettings().interval_resolves]


def make_estimator(robot, consistent: bool = True) -> StreamingEstimator:  # noqa: ANN001
    """The ``ident stream`` defaults on the config's model terms."""
    terms = ModelConfig(viscous=True, coulomb=True, rotor_inertia=True,
                        offset=False).extra_terms(robot.nv, "bench")  # fmt: skip
    return StreamingEstimator(chain_from_model(robot.model), terms,
                              parameters_from_model(robot.model), 1000.0,
                              StreamSettings(consistent=consistent,
                                             interval_resolves=RESOLVES[0]))  # fmt: skip


def feed(est: StreamingEstimator, t: np.ndarray, q: np.ndarray, tau: np.ndarray) -> float:
    """Stream the log in :data:`BLOCK`-sample blocks; CPU seconds spent in the updates."""
    cpu = 0.0
    with threadpool_limits(limits=1, user_api="blas"):
        for a in range(0, t.size, BLOCK):
            c0 = time.process_time()
            est.push(t[a : a + BLOCK], q[a : a + BLOCK], tau[a : a + BLOCK])
            cpu += time.process_time() - c0
    return cpu


def free_tests(robot, t: np.ndarray, q: np.ndarray, tau: np.ndarray) -> tuple[int, list]:  # noqa: ANN001
    """Stream a change-free log; its alarms and every test's ``(T / kappa, dof)``."""
    est = make_estimator(robot, consistent=False)
    store: list = []
    original = detect.glr_statistic

    def wrapped(window, ref):  # noqa: ANN001, ANN202
        T, r = original(window, ref)
        store.append((T / est.kappa, r))
        return T, r

    detect.glr_statistic = wrapped  # type: ignore[assignment]
    try:
        feed(est, t, q, tau)
    finally:
        detect.glr_statistic = original  # type: ignore[assignment]
    return len(est.events), store


def more_change(logs: dict, change_s: float) -> dict:
    """The same seed's payload attached at ``change_s`` instead (the logs with and without
    it joined there): another second of motion after the change, other samples' noise; the
    change's figures (:func:`payload_figures`), or ``detected: False``."""
    k = int(round(change_s * 1000.0))
    q = np.vstack([logs["q_without"][:k], logs["q_with"][k:]])
    tau = np.vstack([logs["tau_without"][:k], logs["tau_with"][k:]])
    est = make_estimator(logs["robot"])
    feed(est, logs["t"], q, tau)
    seen_s = k / 1000.0 - est.filter.delay / est.rate_hz
    events = [e for e in est.events if e.t_alarm >= seen_s]
    if not events:
        return {"change_s": k / 1000.0, "detected": False}
    return {"change_s": k / 1000.0, "detected": True, "change_cpu_s": est.change_cpu_s,
            **payload_figures(events[0].after, logs["payload"])}  # fmt: skip


def run_seed(
    seed: int, *, friction: bool = False, cache: Path | None = None, more_changes: tuple = ()
) -> dict:
    """Stream one seed's step log and its change-free log; the row of figures."""
    logs = cached_step_logs(seed, friction=friction, cache=cache)
    robot, t = logs["robot"], logs["t"]
    feed(make_estimator(robot), t[:2000], logs["q"][:2000], logs["tau_step"][:2000])  # compile
    est = make_estimator(robot)
    cpu = feed(est, t, logs["q"], logs["tau_step"])
    row: dict = {"seed": seed, "change_s": logs["change_s"], "kind": "friction" if friction
                 else "payload", "cpu_us": 1e6 * (cpu - est.solve_cpu_s) / t.size,
                 "solve_cpu_us": 1e6 * (est.solve_cpu_s - est.change_cpu_s) / t.size,
                 "change_cpu_s": est.change_cpu_s,
                 "n_solves": len(est.timeline)}  # fmt: skip
    # a test at row time t holds samples up to t + delay / rate (each row describes the centre
    # of its causal filter's window): an alarm from then on has seen the change
    seen_s = logs["change_s"] - est.filter.delay / est.rate_hz
    events = [e for e in est.events if e.t_alarm >= seen_s]
    row["false_alarms_before_change"] = len(est.events) - len(events)
    row["pre_change_seconds"] = max(0.0, seen_s - est.s.warmup_s)
    row["detected"] = bool(events)
    if events:
        e = events[0]
        row.update(delay_s=e.t_alarm - logs["change_s"], onset_error_s=e.t_onset - logs["change_s"],
                   classified=e.kind, estimate_after_s=e.after.t - e.t_onset)  # fmt: skip
        if not friction:
            row.update(payload_figures(e.after, logs["payload"]))
    row["more"] = [more_change(logs, c) for c in more_changes] if not friction else []
    row["free_alarms"], tests = free_tests(robot, t, logs["q_without"], logs["tau_without"])
    row["free_seconds"] = float(t[-1] - est.s.warmup_s)
    row["free_tests"] = tests
    return row


def payload_figures(after, payload: tuple) -> dict:  # noqa: ANN001
    """Mass and centre-of-mass errors of the estimate and whether its intervals hold them."""
    mass, com, _ = payload
    lo, hi = after.mass_interval()
    z = 1.959963984540054
    return {"mass": mass, "mass_error_pct": 100 * (after.mass - mass) / mass,
            "com_error_mm": 1e3 * float(np.linalg.norm(after.com - com)),
            "mass_std_pct": 100 * after.mass_std / mass,
            "com_std_mm": (1e3 * after.com_std).tolist(),
            "mass_covered": bool(lo <= mass <= hi),
            "com_covered": (np.abs(after.com - com) <= z * after.com_std).tolist()}  # fmt: skip


def tail_table(tests: list) -> list[str]:
    """Per-test exceedance of the chi-square quantiles on change-free logs against their
    nominal probability."""
    T = np.array([x[0] for x in tests])
    r = np.array([x[1] for x in tests])
    lines = []
    for alpha in (0.1, 0.01, 0.001, 1e-4):
        frac = float(np.mean(T > chi2.isf(alpha, r))) if T.size else float("nan")
        lines.append(f"  per-test exceedance at alpha {alpha:g}: {frac:.4f} ({T.size} tests)")
    return lines


def _row_line(r: dict) -> str:
    """One seed's line of the table."""
    if not r["detected"]:
        return f"{r['seed']:4d}  not detected"
    com_in = "".join("y" if c else "n" for c in r["com_covered"])
    return (
        f"{r['seed']:4d}  {r['mass']:7.2f} {r['change_s']:8.2f} {r['delay_s']:8.3f} "
        f"{r['onset_error_s']:+11.3f} {r['mass_error_pct']:+10.2f} {r['com_error_mm']:10.2f} "
        f"{'yes' if r['mass_covered'] else 'no':>7} {com_in:>14} {r['cpu_us']:7.1f}"
    )


def _largest(rows: list[dict], key: str) -> float:
    return max((abs(r[key]) for r in rows), default=float("nan"))


def wilson(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson's 95 % interval of a proportion ``k / n``."""
    p, d = k / n, 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / d
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return centre - half, centre + half


def coverage_line(title: str, rows: list[dict]) -> None:
    """How often the rows' 95 % intervals hold the truth (mass, CoM components, all), with
    Wilson's interval of the whole (the components of one estimate are not independent)."""
    mass_in = [r["mass_covered"] for r in rows]
    com_in = [c for r in rows for c in r["com_covered"]]
    every = mass_in + com_in
    lo, hi = wilson(int(np.sum(every)), len(every))
    print(
        f"{title}: mass {np.mean(mass_in):.3f}, CoM components {np.mean(com_in):.3f}, all "
        f"{np.mean(every):.3f} ({int(np.sum(every))} of {len(every)} intervals; Wilson 95 % "
        f"[{lo:.3f}, {hi:.3f}])"
    )


def report(rows: list[dict]) -> None:
    """Print the table and the summary figures."""
    pay = [r for r in rows if r["kind"] == "payload"]
    print("seed  mass[kg] change[s] delay[s] onset_err[s] mass_err[%] com_err[mm] "
          "mass_in com_in(x,y,z) cpu[us]")  # fmt: skip
    for r in pay:
        print(_row_line(r))
    det = [r for r in pay if r["detected"]]
    print(
        f"detected {len(det)}/{len(pay)}; delay max {_largest(det, 'delay_s'):.3f} s; mass error "
        f"|max| {_largest(det, 'mass_error_pct'):.2f} %; CoM error max "
        f"{_largest(det, 'com_error_mm'):.2f} mm"
    )
    coverage_line("95 % interval coverage (the bench's change times)", det)
    more = [m for r in pay for m in r.get("more", [])]
    if more:
        found = [m for m in more if m["detected"]]
        print(
            f"more change times: detected {len(found)}/{len(more)}; mass error |max| "
            f"{_largest(found, 'mass_error_pct'):.2f} %; CoM error max "
            f"{_largest(found, 'com_error_mm'):.2f} mm; over 2 % or 5 mm: "
            f"{sum(abs(m['mass_error_pct']) > 2 or m['com_error_mm'] > 5 for m in found)}"
        )
        coverage_line("95 % interval coverage (more change times)", found)
        coverage_line("95 % interval coverage (all)", det + found)
    print(f"CPU of a change's estimate and intervals: median "
          f"{np.median([r['change_cpu_s'] for r in det]):.2f} s")  # fmt: skip
    cpu = np.array([r["cpu_us"] for r in rows])
    print(
        f"CPU per 1 kHz sample, update: median {np.median(cpu):.1f} us, max {cpu.max():.1f} us; "
        f"scheduled consistent solve: {np.median([r['solve_cpu_us'] for r in rows]):.1f} us "
        "per sample amortized"
    )
    free_s = sum(r["free_seconds"] + r["pre_change_seconds"] for r in rows)
    alarms = sum(r["free_alarms"] + r["false_alarms_before_change"] for r in rows)
    print(f"false alarms: {alarms} in {free_s / 3600:.3f} h of change-free tested log "
          "(stated 0.01 / h)")  # fmt: skip
    for line in tail_table([x for r in rows for x in r["free_tests"]]):
        print(line)
    for r in (r for r in rows if r["kind"] == "friction"):
        found = (
            f", delay {r['delay_s']:.3f} s, classified {r['classified']}" if r["detected"] else ""
        )
        print(f"friction rise seed {r['seed']}: detected {r['detected']}{found}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--friction", type=int, default=3)
    parser.add_argument("--json", type=Path, default=None, help="write the rows here")
    parser.add_argument("--more-changes", type=float, nargs="*", default=[],
                        help="more change times [s] a payload seed (coverage)")  # fmt: skip
    parser.add_argument("--cache", type=Path, default=None,
                        help="folder of the seeds' MuJoCo logs (read, else written)")  # fmt: skip
    parser.add_argument("--resolves", type=int, default=RESOLVES[0],
                        help="re-solves of a change's intervals (0: least squares')")  # fmt: skip
    args = parser.parse_args()
    RESOLVES[0] = args.resolves
    rows = []
    for seed in range(args.seeds):
        rows.append(run_seed(seed, cache=args.cache, more_changes=tuple(args.more_changes)))
        print(f"seed {seed} done", flush=True)
    for seed in range(args.friction):
        rows.append(run_seed(100 + seed, friction=True, cache=args.cache))
    report(rows)
    if args.json is not None:
        slim = [{k: v for k, v in r.items() if k != "free_tests"} for r in rows]
        args.json.write_text(json.dumps(slim, indent=1))


if __name__ == "__main__":
    main()
