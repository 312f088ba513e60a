"""Generate the small example logs of data/examples/ from a simulated 3-joint arm.

    python data/examples/make_examples.py

The arm (``arm3.urdf``) follows a joint-space Fourier trajectory for 16 s; torques are the
Pinocchio RNEA torques of the URDF's inertials plus viscous and Coulomb friction (values in
``TRUE_FRICTION``) plus white noise. The same motion is written in every format
``ident identify`` reads, each with its config in ``configs/examples/``:

============================  ==============================================================
``wide.csv``                  one row per sample: ``t,q_j*,tau_j*,tau_cmd_j*`` (rad, N*m),
                              as the simulator writes it
``wide_jitter.csv``           the same, sampled with +-25 % jittered steps (resampled on read)
``long.csv.gz``               one row per sample and joint: ``time_ms,joint,pos_deg,cur_mA``
                              (milliseconds, degrees, milliamperes; torque constants 0.05 N*m/mA
                              scaled by ``1e3``)
``lines/{q,tau}{1,2,3}.txt``  one value per line, one file per signal, no header, no time
``bag/``                      ROS 2 bag (sqlite3) with ``sensor_msgs/JointState`` on
                              ``/joint_states`` at jittered stamps (first 12 s)
``joint_states.mcap``         a bare MCAP file with the same messages
============================  ==============================================================

Every file stays below 300 KB. Deterministic (fixed seed).
"""

from __future__ import annotations

import gzip
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pinocchio as pin

HERE = Path(__file__).resolve().parent
URDF = HERE / "arm3.urdf"
RATE_HZ = 100.0
DURATION_S = 16.0
TRUE_FRICTION = {"fv": [0.8, 0.6, 0.3], "fs": [1.5, 1.0, 0.5]}  # N*m*s/rad, N*m
NOISE_STD = [0.05, 0.05, 0.03]  # N*m
TORQUE_CONSTANT = [0.05, 0.05, 0.04]  # N*m/A at the joint (current logged in mA)
SEED = 7
BAG_SAMPLES = 1200


def fourier(t: np.ndarray, rng: np.random.Generator, nv: int) -> tuple[np.ndarray, ...]:
    """Sum of 5 harmonics of 0.125 Hz per joint: positions, velocities, accelerations."""
    w = 2.0 * np.pi * 0.125 * np.arange(1, 6)
    a = rng.normal(scale=0.5, size=(5, nv)) / np.arange(1, 6)[:, None]
    b = rng.normal(scale=0.5, size=(5, nv)) / np.arange(1, 6)[:, None]
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q = s @ a + c @ b
    dq = (c * w) @ a - (s * w) @ b
    ddq = -(s * w**2) @ a - (c * w**2) @ b
    return q, dq, ddq


def simulate(t: np.ndarray, seed: int = SEED) -> dict[str, np.ndarray]:
    """Positions [rad], velocities [rad/s] and measured torques [N*m] at the times ``t``."""
    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    rng = np.random.default_rng(seed)
    q, dq, ddq = fourier(t, rng, model.nv)
    tau = np.array([pin.rnea(model, data, q[k], dq[k], ddq[k]) for k in range(t.size)])
    tau += np.asarray(TRUE_FRICTION["fv"]) * dq + np.asarray(TRUE_FRICTION["fs"]) * np.sign(dq)
    noise = np.random.default_rng(seed + 1).normal(size=tau.shape) * NOISE_STD
    return {"q": q, "dq": dq, "tau": tau + noise, "tau_cmd": tau}


def jittered_times(n: int, rate_hz: float, jitter: float, seed: int) -> np.ndarray:
    """``n`` increasing times whose steps are ``(1 + U(-jitter, jitter)) / rate_hz``."""
    steps = (1.0 + np.random.default_rng(seed).uniform(-jitter, jitter, n - 1)) / rate_hz
    return np.concatenate([[0.0], np.cumsum(steps)])


def _fmt(x: float) -> str:
    return f"{x:.7g}"


def write_wide(path: Path, t: np.ndarray, s: dict[str, np.ndarray]) -> None:
    joints = ["j1", "j2", "j3"]
    header = ["t"] + [f"{k}_{j}" for k in ("q", "tau", "tau_cmd") for j in joints]
    rows = np.column_stack([t, s["q"], s["tau"], s["tau_cmd"]])
    lines = [",".join(header)] + [",".join(_fmt(v) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")


def write_long(path: Path, t: np.ndarray, s: dict[str, np.ndarray]) -> None:
    lines = ["time_ms,joint,pos_deg,cur_mA"]
    current_mA = s["tau"] / np.asarray(TORQUE_CONSTANT) * 1e3
    for k in range(t.size):
        for j, name in enumerate(["j1", "j2", "j3"]):
            lines.append(
                f"{_fmt(t[k] * 1e3)},{name},{_fmt(np.rad2deg(s['q'][k, j]))},"
                f"{_fmt(current_mA[k, j])}"
            )
    with gzip.open(path, "wt") as f:
        f.write("\n".join(lines) + "\n")


def write_lines(folder: Path, s: dict[str, np.ndarray]) -> None:
    folder.mkdir(exist_ok=True)
    for j in range(3):
        (folder / f"q{j + 1}.txt").write_text("\n".join(_fmt(v) for v in s["q"][:, j]) + "\n")
        (folder / f"tau{j + 1}.txt").write_text("\n".join(_fmt(v) for v in s["tau"][:, j]) + "\n")


def _joint_states(t: np.ndarray, s: dict[str, np.ndarray], typestore):  # noqa: ANN001, ANN202
    JointState = typestore.types["sensor_msgs/msg/JointState"]
    Header = typestore.types["std_msgs/msg/Header"]
    Time = typestore.types["builtin_interfaces/msg/Time"]
    t0_ns = 1_700_000_000_000_000_000  # an epoch stamp, as a robot would log
    for k in range(t.size):
        ns = t0_ns + int(round(t[k] * 1e9))
        header = Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="")
        yield (
            ns,
            JointState(
                header=header,
                name=["j1", "j2", "j3"],
                position=s["q"][k].copy(),
                velocity=s["dq"][k].copy(),
                effort=s["tau"][k].copy(),
            ),
        )


def write_bag(folder: Path, t: np.ndarray, s: dict[str, np.ndarray], storage: str) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(folder, version=9, storage_plugin=plugin) as writer:
        conn = writer.add_connection(
            "/joint_states", "sensor_msgs/msg/JointState", typestore=typestore
        )
        for ns, msg in _joint_states(t, s, typestore):
            writer.write(conn, ns, typestore.serialize_cdr(msg, conn.msgtype))


def main() -> None:
    n = int(DURATION_S * RATE_HZ)
    t = np.arange(n) / RATE_HZ
    uniform = simulate(t)
    write_wide(HERE / "wide.csv", t, uniform)
    t_jit = jittered_times(n, RATE_HZ, 0.25, SEED + 2)
    write_wide(HERE / "wide_jitter.csv", t_jit, simulate(t_jit))
    write_long(HERE / "long.csv.gz", t, uniform)
    write_lines(HERE / "lines", uniform)
    shutil.rmtree(HERE / "bag", ignore_errors=True)
    t_bag = t_jit[:BAG_SAMPLES]  # ROS messages are larger: fewer samples keep files < 300 KB
    write_bag(HERE / "bag", t_bag, simulate(t_bag), "sqlite3")
    with tempfile.TemporaryDirectory() as tmp:
        write_bag(Path(tmp) / "bag", t_bag, simulate(t_bag), "mcap")
        (mcap,) = (Path(tmp) / "bag").glob("*.mcap")
        shutil.copy(mcap, HERE / "joint_states.mcap")
    for path in sorted(HERE.rglob("*")):
        if path.is_file() and path.suffix not in (".py", ".urdf", ".md"):
            print(f"{path.relative_to(HERE)}: {path.stat().st_size / 1024:.0f} KB")


if __name__ == "__main__":
    main()
