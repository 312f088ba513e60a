"""Long logs in bounded memory: one hour at 1 kHz of a 7-joint arm, end to end.

    PYTHONPATH=src python benchmarks/bench_identify_long.py [--minutes 60] [--rate 1000]
        [--mcap-minutes 60] [--csv-minutes 60] [--skip-npz]

1. Generates the log of a Franka Panda with its fingers removed (7 joints): a random
   joint-space Fourier trajectory (5 harmonics of 0.1 Hz), ideal rigid-body torques (the
   numba regressor times the URDF's inertial parameters, checked against ``pinocchio.rnea``)
   plus viscous and Coulomb friction and white noise, written as a numpy archive
   (``format: npz``).
2. Runs ``ident identify`` on it in a subprocess (the log is longer than
   ``preprocess.max_regressor_mb`` allows in memory, so the chunked path runs) and prints
   its wall time and peak resident memory (targets, issue 25: < 60 s and < 1 GB on 2 cores;
   measured for one hour on an idle machine: 26 s wall, 41 s of CPU, peak 900 MiB: the
   interpreter and its libraries, ~0.3 GB, the log's t, q, tau, 0.43 GB, two chunks in
   flight, ~0.1 GB each; before the chunks' regressor was streamed through the decimation
   filters, 52 s and 1.5 GB; see docs/benchmarks.md).
3. Per sample: the chunked path (regressor kernel + extra columns + base columns +
   reduction) against a Python loop over ``pinocchio.computeJointTorqueRegressor`` plus the
   matrix product ``Y^T Y``, measured in this run (target: >= 8x).
4. On a short log (``--compare-minutes``), the chunked estimate against the in-memory one
   (target: equal to 1e-10 relative).
5. The same kind of log as a bare MCAP file of ``sensor_msgs/JointState`` messages at 1 kHz
   (``--mcap-minutes``; 0 skips it), identified by ``ident identify`` in a subprocess: wall
   time and peak memory (target: bounded like the numpy log, i.e. the log's columns plus the
   chunked identification, not the decoded messages. Measured for one hour: 28 s wall, peak
   within 20 MB of the numpy log's; the reader before held every message of the file as an
   object, ~800 bytes each, and decoded 70 us per message; the one before that kept a dict
   per message and reached 5.4 GB).
6. The same kind of log as a wide ``.csv.gz`` (``t, q/0..6, tau/0..6``) and as a long CSV
   (``t, joint, q, tau``: one row per sample and joint, 25.2 million rows for an hour;
   ``--csv-minutes``; 0 skips them), identified by ``ident identify`` in a subprocess: wall
   time and peak memory (target: < 1 GB, i.e. the columns plus a block of text, not the text
   nor its rows as Python objects).
"""

from __future__ import annotations

import argparse
import gzip
import importlib.metadata
import json
import os
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

from ident.dynamics.chain import chain_from_model
from ident.dynamics.friction import ExtraTerms
from ident.dynamics.parameters import parameters_from_model
from ident.dynamics.regressor import joint_torque_regressor

PANDA = (
    Path(
        str(importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share"))
    )
    / "example-robot-data/robots/panda_description/urdf/panda.urdf"
)
FV = np.array([0.6, 0.6, 0.5, 0.5, 0.3, 0.3, 0.2])  # N*m*s/rad
FS = np.array([0.8, 0.8, 0.6, 0.6, 0.4, 0.4, 0.3])  # N*m
NOISE = 0.05  # N*m


def panda7(folder: Path) -> Path:
    """The Panda URDF without its two finger joints and links (7 revolute joints)."""
    tree = ET.parse(PANDA)
    root = tree.getroot()
    fingers = [j for j in root.findall("joint") if j.get("type") == "prismatic"]
    for joint in fingers:
        child = joint.find("child").get("link")
        root.remove(joint)
        for link in root.findall("link"):
            if link.get("name") == child:
                root.remove(link)
    path = folder / "panda7.urdf"
    tree.write(path)
    return path


def fourier(t: np.ndarray, coeffs: np.ndarray) -> tuple[np.ndarray, ...]:
    """q, dq, ddq of ``q = sum_k a_k sin(k w t) + b_k cos(k w t)`` (coeffs (2, 5, nv))."""
    w = 2 * np.pi * 0.1 * np.arange(1, 6)
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    a, b = coeffs
    return s @ a + c @ b, (c * w) @ a - (s * w) @ b, -(s * w**2) @ a - (c * w**2) @ b


def generate(urdf: Path, minutes: float, rate: float, path: Path, seed: int = 0) -> None:
    """Write the log (t, q, tau) as ``path`` (npz), computed in blocks of one minute."""
    model = pin.buildModelFromUrdf(str(urdf))
    chain = chain_from_model(model)
    phi = parameters_from_model(model)
    rng = np.random.default_rng(seed)
    coeffs = rng.normal(scale=0.4, size=(2, 5, model.nv)) / np.arange(1, 6)[None, :, None]
    n = int(minutes * 60 * rate)
    t = np.arange(n) / rate
    q = np.empty((n, model.nv))
    tau = np.empty((n, model.nv))
    block = int(60 * rate)
    for a in range(0, n, block):
        b = min(n, a + block)
        qa, dqa, ddqa = fourier(t[a:b], coeffs)
        q[a:b] = qa
        tau[a:b] = joint_torque_regressor(chain, qa, dqa, ddqa) @ phi + FV * dqa + FS * np.sign(dqa)
        if a == 0:  # the regressor's torques are Pinocchio's RNEA
            data = model.createData()
            for k in (0, 17, b - a - 1):
                rnea = pin.rnea(model, data, qa[k], dqa[k], ddqa[k])
                friction = FV * dqa[k] + FS * np.sign(dqa[k])
                assert np.allclose(rnea + friction, tau[a + k], atol=1e-9), "RNEA mismatch"
    tau += rng.normal(size=tau.shape) * NOISE
    np.savez(path, t=t, q=q, tau=tau)


def write_mcap(path: Path, npz: Path, joints: list[str]) -> int:
    """The numpy log ``npz`` as a bare MCAP of JointState messages on ``/joint_states``
    (header stamps from ``t``, recorded 0.2 ms later; zstd chunks of 1 MB); its size [bytes]."""
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    JointState = store.types["sensor_msgs/msg/JointState"]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    data = np.load(npz)
    t, q, tau = data["t"], data["q"], data["tau"]
    zero = np.zeros(q.shape[1])
    t0_ns = 1_700_000_000_000_000_000
    definition = (Path(__file__).parent / "joint_state.msg").read_bytes()
    with open(path, "wb") as f:
        writer = Writer(f, chunk_size=1 << 20, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="ident benchmark")
        schema = writer.register_schema("sensor_msgs/msg/JointState", "ros2msg", definition)
        channel = writer.register_channel("/joint_states", "cdr", schema)
        for k in range(t.size):
            ns = t0_ns + round(t[k] * 1e9)
            msg = JointState(
                header=Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=""),
                name=joints,
                position=q[k],
                velocity=zero,
                effort=tau[k],
            )
            raw = bytes(store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
            writer.add_message(channel, log_time=ns + 200_000, data=raw, publish_time=ns)
        writer.finish()
    return path.stat().st_size


def config(
    urdf: Path,
    log: Path,
    path: Path,
    *,
    position: list[str] | None = None,
    torque: list[str] | None = None,
    **preprocess: object,
) -> Path:
    nv = 7
    cfg = {
        "name": "panda-long",
        "robot": {"urdf": str(urdf)},
        "log": {
            "path": str(log),
            "position": {"columns": position or [f"q/{k}" for k in range(nv)]},
            "torque": {"columns": torque or [f"tau/{k}" for k in range(nv)]},
        },
        "preprocess": {
            "lowpass": {"cutoff_hz": 10.0, "order": 4},
            "trim_samples": 20,
            **preprocess,
        },
        "model": {"viscous": True, "coulomb": True, "offset": False, "rotor_inertia": False},
        "estimation": {"method": "wls", "essential": {"enabled": False}},
        "validation": {"identify_fraction": 0.9},
    }
    path.write_text(yaml.safe_dump(cfg))
    return path


#: ``peak_mb()`` in a child interpreter: its own peak resident set [MB], VmHWM. Not
#: ``ru_maxrss``, which a child started with ``subprocess`` inherits from its parent at exec
#: (measured: a child of a 1.2 GB parent reported 1170 MB by ru_maxrss, 11 MB by VmHWM).
PEAK_MB_SOURCE = """
def peak_mb():
    import resource
    try:
        with open("/proc/self/status") as f:
            return next(int(x.split()[1]) for x in f if x.startswith("VmHWM:")) / 1024
    except (OSError, StopIteration):  # not Linux
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
"""


def mcap_config(urdf: Path, mcap: Path, path: Path, joints: list[str]) -> Path:
    """:func:`config` for the MCAP of :func:`write_mcap` (its JointState columns by joint)."""
    return config(
        urdf,
        mcap,
        path,
        position=[f"/joint_states/position/{j}" for j in joints],
        torque=[f"/joint_states/effort/{j}" for j in joints],
        max_regressor_mb=256.0,
    )


_RUNNER = (
    PEAK_MB_SOURCE
    + """
import resource, sys, time, json
t0 = time.perf_counter()
from ident.cli import app
try:
    app(sys.argv[1:], standalone_mode=False)
finally:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    cpu = usage.ru_utime + usage.ru_stime
    print(json.dumps({"wall_s": time.perf_counter() - t0, "cpu_s": cpu, "peak_mb": peak_mb()}))
"""
)


def run_cli(cfg: Path, out: Path) -> dict:
    args = [sys.executable, "-c", _RUNNER, "identify", str(cfg), "--out", str(out), "--no-replay"]
    proc = subprocess.run(args, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise SystemExit(f"ident identify failed:\n{proc.stdout}\n{proc.stderr}")
    last = proc.stdout.strip().splitlines()[-1]
    return {**json.loads(last), "output": proc.stdout, "stderr": proc.stderr}


def per_sample(urdf: Path, n: int, trajectory: bool = False) -> tuple[float, float]:
    """CPU seconds per sample: the chunked path's regressor + reduction, and Pinocchio's loop.

    The states are random (normal), or with ``trajectory`` those of a Fourier excitation
    (:func:`fourier`, 100 Hz): its rows are worse conditioned, as a log's are, so more of the
    reduction takes the QR path (:mod:`ident.identify.estimation.accumulate`).

    CPU time of the process (``time.process_time``, every thread counted), not wall time: on
    a shared machine a wall-clock figure also counts the time the process waits for a core,
    more for a longer measurement, so ratios read from it drift with the load. BLAS on one
    thread, as the chunked path's workers run it: on a loaded 2-core machine a second OpenBLAS
    thread made the reduction many times slower.
    """
    from threadpoolctl import threadpool_limits

    from ident.identify.estimation.accumulate import BaseColumns, reduce_chunk
    from ident.identify.pipeline.real import build_parameter_model

    model = pin.buildModelFromUrdf(str(urdf))
    chain = chain_from_model(model)
    terms = ExtraTerms.from_options(7, rotor_inertia=False, offset=False)
    pm = build_parameter_model(model, terms)
    rng = np.random.default_rng(1)
    q, dq, ddq = rng.normal(size=(3, n, 7))
    if trajectory:
        coeffs = rng.normal(scale=0.4, size=(2, 5, 7)) / np.arange(1, 6)[None, :, None]
        q, dq, ddq = fourier(np.arange(n) / 100.0, coeffs)
    tau = rng.normal(size=(n, 7))
    keep = np.ones((n, 7), dtype=bool)
    columns = BaseColumns(chain, pm)
    with threadpool_limits(limits=1, user_api="blas"):
        # compile and warm up outside the timing
        m = min(n, 200)
        reduce_chunk(columns(q[:m], dq[:m], ddq[:m]), tau[:m], keep[:m])
        t0 = time.process_time()
        reduce_chunk(columns(q, dq, ddq), tau, keep)
        ours = (time.process_time() - t0) / n
        data = model.createData()
        gram = np.zeros((70, 70))
        t0 = time.process_time()
        for k in range(n):
            Y = pin.computeJointTorqueRegressor(model, data, q[k], dq[k], ddq[k])
            gram += Y.T @ Y
        theirs = (time.process_time() - t0) / n
    return ours, theirs


def compare(urdf: Path, folder: Path, minutes: float, rate: float) -> float:
    """Relative difference ``||x_chunked - x_memory|| / ||x_memory||`` on a short log."""
    from ident.identify.config import load_identify_config
    from ident.identify.pipeline.real import identify

    log = folder / "short.npz"
    generate(urdf, minutes, rate, log, seed=3)
    estimates = []
    for mode in ("never", "always"):
        cfg = load_identify_config(
            config(urdf, log, folder / f"short-{mode}.yaml", chunked=mode, chunk_samples=4096)
        )
        estimates.append(identify(cfg).estimate.x)
    a, b = estimates
    return float(np.linalg.norm(a - b) / np.linalg.norm(a))


def write_csvs(npz: Path, folder: Path) -> tuple[Path, Path]:
    """The numpy log as a wide ``.csv.gz`` and a long ``.csv`` (one row per sample and
    joint), written a minute of samples at a time."""
    data = np.load(npz)
    t, q, tau = data["t"], data["q"], data["tau"]
    nv = q.shape[1]
    wide, long = folder / "long-wide.csv.gz", folder / "long-long.csv"
    header = ",".join(["t"] + [f"q/{k}" for k in range(nv)] + [f"tau/{k}" for k in range(nv)])
    with gzip.open(wide, "wt", compresslevel=1) as fw, open(long, "w") as fl:
        fw.write(header + "\n")
        fl.write("t,joint,q,tau\n")
        for a in range(0, t.size, 60_000):
            b = min(t.size, a + 60_000)
            rows = np.column_stack([t[a:b], q[a:b], tau[a:b]])
            np.savetxt(fw, rows, delimiter=",", fmt="%.17g")
            joint = np.tile(np.arange(nv), b - a)
            stacked = np.column_stack([np.repeat(t[a:b], nv), q[a:b].ravel(), tau[a:b].ravel()])
            fl.writelines(
                f"{r[0]!r},j{j},{r[1]!r},{r[2]!r}\n"
                for r, j in zip(stacked.tolist(), joint, strict=True)
            )
    return wide, long


def csv_case(urdf: Path, folder: Path, minutes: float, rate: float) -> None:
    """Step 6: the log as a wide .csv.gz and a long CSV, identified in bounded memory."""
    npz = folder / "csv-source.npz"
    generate(urdf, minutes, rate, npz, seed=7)
    t0 = time.perf_counter()
    wide, long = write_csvs(npz, folder)
    npz.unlink()
    n = int(minutes * 60 * rate)
    print(
        f"CSV: {n} samples ({minutes:g} min at {rate:g} Hz, 7 joints) written in "
        f"{time.perf_counter() - t0:.0f} s: wide .csv.gz {wide.stat().st_size / 2**20:.0f} MB, "
        f"long .csv {long.stat().st_size / 2**20:.0f} MB"
    )
    cases = [
        ("wide csv.gz", wide, None, None),
        ("long csv", long, [f"q/j{k}" for k in range(7)], [f"tau/j{k}" for k in range(7)]),
    ]
    for what, path, position, torque in cases:
        cfg = config(
            urdf,
            path,
            folder / f"{path.stem}.yaml",
            position=position,
            torque=torque,
            max_regressor_mb=256.0,
        )
        if what == "long csv":
            text = yaml.safe_load(cfg.read_text())
            text["log"]["format"] = "csv_long"
            cfg.write_text(yaml.safe_dump(text))
        out = folder / f"runs-{path.stem}"
        run = run_cli(cfg, out)
        (rundir,) = out.iterdir()
        result = json.loads((rundir / "result.json").read_text())
        estimates = [x for x in run["stderr"].splitlines() if x.startswith("estimate:")]
        print(
            f"ident identify on the {what}: wall {run['wall_s']:.1f} s, CPU {run['cpu_s']:.1f} "
            f"s, peak memory {run['peak_mb']:.0f} MB (target < 1024 MB); relative residual "
            f"{result['relative_residual']:.4f}; load average {os.getloadavg()[0]:.1f}"
        )
        for line in estimates:
            print(f"  printed before the work: {line}")
        path.unlink()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--rate", type=float, default=1000.0)
    parser.add_argument("--compare-minutes", type=float, default=1.0)
    parser.add_argument("--per-sample", type=int, default=20000)
    parser.add_argument("--mcap-minutes", type=float, default=60.0)
    parser.add_argument("--csv-minutes", type=float, default=60.0)
    parser.add_argument("--skip-npz", action="store_true", help="only the MCAP and CSV cases")
    args = parser.parse_args()
    from threadpoolctl import threadpool_limits

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        urdf = panda7(folder)
        if args.mcap_minutes > 0:
            mcap_case(urdf, folder, args.mcap_minutes, args.rate)
        if args.csv_minutes > 0:
            csv_case(urdf, folder, args.csv_minutes, args.rate)
        if args.skip_npz:
            return
        t0 = time.perf_counter()
        log = folder / "long.npz"
        generate(urdf, args.minutes, args.rate, log)
        n = int(args.minutes * 60 * args.rate)
        print(
            f"generated {n} samples ({args.minutes:g} min at {args.rate:g} Hz, 7 joints) in "
            f"{time.perf_counter() - t0:.1f} s; log {log.stat().st_size / 2**20:.0f} MB"
        )
        run = run_cli(
            config(urdf, log, folder / "long.yaml", max_regressor_mb=256.0), folder / "runs"
        )
        (rundir,) = (folder / "runs").iterdir()
        result = json.loads((rundir / "result.json").read_text())
        print(
            f"ident identify (chunked): wall {run['wall_s']:.1f} s, CPU {run['cpu_s']:.1f} s, "
            f"peak memory {run['peak_mb']:.0f} MB (targets < 60 s, < 1024 MB); machine load "
            f"average {os.getloadavg()[0]:.1f}"
        )
        print(
            f"  relative residual {result['relative_residual']:.4f}; "
            f"timings {json.loads((rundir / 'run.json').read_text()).get('timings_s')}"
        )
        with threadpool_limits(limits=1, user_api="blas"):
            ours, theirs = per_sample(urdf, args.per_sample)
        print(
            f"per sample: chunked regressor + reduction {ours * 1e6:.2f} us, Pinocchio "
            f"computeJointTorqueRegressor + Y^T Y loop {theirs * 1e6:.2f} us: "
            f"{theirs / ours:.1f}x (target >= 8x)"
        )
        diff = compare(urdf, folder, args.compare_minutes, args.rate)
        print(
            f"chunked vs in-memory estimate on {args.compare_minutes:g} min: max relative "
            f"difference (norm) {diff:.2e} (target <= 1e-10)"
        )


def mcap_case(urdf: Path, folder: Path, minutes: float, rate: float) -> None:
    """Step 5: the log as a bare MCAP, identified in bounded memory."""
    model = pin.buildModelFromUrdf(str(urdf))
    joints = [model.names[i] for i in range(1, model.njoints)]
    npz = folder / "mcap-source.npz"
    generate(urdf, minutes, rate, npz, seed=5)
    t0 = time.perf_counter()
    path = folder / "long.mcap"
    size = write_mcap(path, npz, joints)
    npz.unlink()
    n = int(minutes * 60 * rate)
    print(
        f"MCAP: {n} JointState messages ({minutes:g} min at {rate:g} Hz, 7 joints) written in "
        f"{time.perf_counter() - t0:.1f} s; {size / 2**20:.0f} MB"
    )
    cfg = mcap_config(urdf, path, folder / "mcap.yaml", joints)
    out = folder / "runs-mcap"
    run = run_cli(cfg, out)
    (rundir,) = out.iterdir()
    result = json.loads((rundir / "result.json").read_text())
    estimates = [x for x in run["stderr"].splitlines() if x.startswith("estimate:")]
    print(
        f"ident identify on the MCAP: wall {run['wall_s']:.1f} s, CPU {run['cpu_s']:.1f} s, "
        f"peak memory {run['peak_mb']:.0f} MB ({run['peak_mb'] * 2**20 / n:.0f} bytes per "
        f"message); relative residual {result['relative_residual']:.4f}; load average "
        f"{os.getloadavg()[0]:.1f}"
    )
    for line in estimates:
        print(f"  printed before the work: {line}")
    path.unlink()


if __name__ == "__main__":
    main()
