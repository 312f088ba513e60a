"""Hostile logs of the readers and of time: files and their cases.

``python tests/data/hostile/logs/generate_logs.py`` (from the repository root) rewrites the
files of this folder and prints the manifest entries; ``tests/data/hostile/generate.py``
appends :func:`cases` to ``manifest.yaml``. Every file stays small: a bomb is small on disk by
nature (the 11 kB MCAP holds two 160 MB messages); the large bombs (3 GiB of gzip text,
100 million samples) are made at test time in ``tests/test_readers.py``.

Every case must end with one ``error:`` line and exit code 2. The valid inputs of the same
families (a backwards jump, duplicated stamps, messages without stamps) identify with a
warning: see ``tests/test_readers.py`` and ``tests/test_logs_inspect.py``.
"""

from __future__ import annotations

import gzip
import io
import json
import os
import shutil
import sqlite3
import sys
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[4]
#: the folder written (``IDENT_HOSTILE_DIR``: a copy of the corpus, see ``../generate.py``)
HERE = Path(os.environ.get("IDENT_HOSTILE_DIR") or Path(__file__).resolve().parents[1]) / "logs"
URDF = "../base/rp2.urdf"
JOINTS = ("shoulder", "slider")
N, RATE = 200, 100.0


def _signals(n: int = N) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(n) / RATE
    q = np.column_stack([np.sin(t), 0.3 * np.sin(0.5 * t)])
    tau = np.column_stack([3.0 * np.cos(t), 9.0 + np.sin(t)])
    return t, q, tau


def _csv(path: Path, header: list[str], *columns: np.ndarray) -> None:
    rows = np.column_stack(columns)
    text = (
        ",".join(header) + "\n" + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in rows)
    )
    path.write_text(text)


def _config(name: str, log: dict) -> str:
    cfg = {
        "name": "hostile",
        "robot": {"urdf": URDF},
        "log": log,
        "validation": {"identify_fraction": 0.7},
    }
    return json.dumps(cfg, indent=1) + "\n"  # JSON is YAML


WIDE = {
    "position": {"columns": ["q1", "q2"]},
    "torque": {"columns": ["tau1", "tau2"]},
    "time": {"column": "t"},
}
ROS = {
    "position": {"columns": [f"/joint_states/position/{j}" for j in JOINTS]},
    "torque": {"columns": [f"/joint_states/effort/{j}" for j in JOINTS]},
}


def _files() -> dict[str, dict]:
    """Write the data files; return case name -> log section."""
    sys.path.insert(0, str(ROOT / "tests"))
    import ros_logs

    t, q, tau = _signals()
    header = ["t", "q1", "q2", "tau1", "tau2"]
    logs: dict[str, dict] = {}

    logs["dev_zero"] = {**WIDE, "path": "/dev/zero", "format": "csv"}
    # mtime=0: the same bytes at every regeneration
    with gzip.GzipFile(HERE / "long_line.csv.gz", "wb", compresslevel=9, mtime=0) as f:
        f.write(b"t,q1,q2,tau1,tau2\n")
        f.write(b"0" * (8 << 20))  # one 8 MB line, no line break
    logs["csv_gz_long_line"] = {**WIDE, "path": "long_line.csv.gz"}

    for name, bad in (("time_nan", np.nan), ("time_inf", np.inf)):
        tb = t.copy()
        tb[120] = bad
        _csv(HERE / f"{name}.csv", header, tb, q, tau)
        logs[name] = {**WIDE, "path": f"{name}.csv"}
    tb = np.full_like(t, 5.0)
    _csv(HERE / "time_constant.csv", header, tb, q, tau)
    logs["time_constant"] = {**WIDE, "path": "time_constant.csv"}
    _csv(HERE / "good.csv", header, t, q, tau)
    logs["time_unit_ns_on_seconds"] = {
        **WIDE,
        "path": "good.csv",
        "time": {"column": "t", "unit": "ns"},
    }
    logs["windows_beyond"] = {
        **WIDE,
        "path": "good.csv",
        "windows": [{"start_s": 10.0, "end_s": 20.0}],
    }
    logs["windows_inverted"] = {
        **WIDE,
        "path": "good.csv",
        "windows": [{"start_s": 1.5, "end_s": 0.5}],
    }
    logs["windows_negative"] = {
        **WIDE,
        "path": "good.csv",
        "windows": [{"start_s": -1.0, "end_s": 1.0}],
    }

    # two files joined on time: the second has a NaN stamp, or goes back
    _csv(HERE / "q_t.csv", ["t", "q1", "q2"], t, q)
    t2 = t + 0.003
    t2[50] = np.nan
    _csv(HERE / "tau_t_nan.csv", ["t", "tau1", "tau2"], t2, tau)
    logs["files_second_nan_stamp"] = {
        **WIDE,
        "files": [{"path": "q_t.csv"}, {"path": "tau_t_nan.csv"}],
    }
    t3 = t + 0.003
    t3[100:] -= 0.5
    _csv(HERE / "tau_t_back.csv", ["t", "tau1", "tau2"], t3, tau)
    logs["files_second_goes_back"] = {
        **WIDE,
        "files": [{"path": "q_t.csv"}, {"path": "tau_t_back.csv"}],
    }

    # numpy archives
    np.savez(HERE / "empty.npz")
    (HERE / "not_zip.npz").write_bytes(b"not a zip archive\n" * 8)
    np.savez(HERE / "object.npz", t=np.array([0.0, "a", None], dtype=object), q1=t[:3])
    np.savez(HERE / "string.npz", t=np.array(["0", "1", "2"]), q1=t[:3])
    with zipfile.ZipFile(HERE / "declares_100M.npz", "w", zipfile.ZIP_DEFLATED) as z:
        buf = io.BytesIO()
        np.lib.format.write_array_header_1_0(
            buf, {"descr": "<f8", "fortran_order": False, "shape": (100_000_000,)}
        )
        member = zipfile.ZipInfo("t.npy", date_time=(1980, 1, 1, 0, 0, 0))  # fixed bytes
        z.writestr(member, buf.getvalue() + bytes(8 * 1000), zipfile.ZIP_DEFLATED)
    for name in ("empty", "not_zip", "object", "string", "declares_100M"):
        logs[f"npz_{name}"] = {**WIDE, "path": f"{name}.npz"}

    # ROS 2: an 11 kB MCAP bomb, flipped bytes, a repeated joint name, a bag lying about
    # its compression
    ros_logs.float_array_bomb(HERE / "zstd_bomb.mcap")
    logs["mcap_zstd_bomb"] = {**ROS, "path": "zstd_bomb.mcap"}
    stamps = 1.0 + t[:100]
    plain = ros_logs.joint_states(
        HERE / "plain.mcap", q[:100], stamps, names=JOINTS, compression="none"
    )
    ros_logs.flip_bytes(plain, HERE / "flipped.mcap", n=60, seed=3)
    plain.unlink()
    logs["mcap_flipped_bytes"] = {**ROS, "path": "flipped.mcap"}
    ros_logs.joint_states(
        HERE / "repeated_name.mcap",
        np.column_stack([q[:50], q[:50, :1]]),
        stamps[:50],
        names=["shoulder", "shoulder", "shoulder"],
    )
    logs["mcap_repeated_joint_name"] = {**ROS, "path": "repeated_name.mcap"}
    bag = HERE / "bag_zstd_declared"
    shutil.rmtree(bag, ignore_errors=True)
    ros_logs.joint_state_bag(bag, q[:40], stamps[:40], names=JOINTS)
    meta = (bag / "metadata.yaml").read_text()
    meta = meta.replace("compression_format: ''", "compression_format: zstd")
    meta = meta.replace("compression_mode: ''", "compression_mode: file")
    (bag / "metadata.yaml").write_text(meta)
    with sqlite3.connect(next(bag.glob("*.db3"))) as db:
        db.execute("VACUUM")
    logs["bag_declares_missing_compression"] = {**ROS, "path": "bag_zstd_declared"}
    logs.update(_lerobot_files())
    return logs


def _lerobot_files() -> dict[str, dict]:
    """LeRobot datasets (parquet, servo ticks): a column the config names missing, a
    timestamp going back in an episode, ticks declared as radians."""
    from lerobot_datasets import write_dataset

    t, q, _ = _signals(60)
    ticks = np.rint(2048.0 + 651.9 * np.column_stack([q, q[:, :1]]))  # shoulder, slider, gripper
    effort = np.column_stack([np.cos(t), np.sin(t), np.zeros_like(t)])
    episode = {"observation.state": ticks, "action": ticks + 3.0, "observation.effort": effort}
    names = [*JOINTS, "gripper"]
    log = {
        "position": {
            "columns": ["observation.state"],
            "exclude": ["gripper"],
            "unit": "ticks",
            "counts_per_rev": 4096,
            "zero_tick": 2048,
        },
        "command": {"columns": ["action"]},
        "torque": {"columns": ["observation.effort"], "exclude": ["gripper"]},
    }
    out: dict[str, dict] = {}
    for name in ("missing_column", "timestamp_back", "ticks_as_rad"):
        folder = HERE / f"lerobot_{name}"
        shutil.rmtree(folder, ignore_errors=True)
        episodes = [dict(episode), dict(episode)]
        if name == "missing_column":
            episodes = [{k: v for k, v in e.items() if k != "observation.effort"} for e in episodes]
        if name == "timestamp_back":
            stamps = np.arange(60) / 30.0
            stamps[40] = stamps[38]
            episodes[1]["timestamp"] = stamps
        write_dataset(folder, episodes, fps=30.0, names=names)
        section = json.loads(json.dumps({**log, "path": folder.name}))
        if name == "ticks_as_rad":
            section["position"] = {"columns": ["observation.state"], "exclude": ["gripper"]}
        out[f"lerobot_{name}"] = section
    return out


def cases() -> list[dict]:
    """The manifest entries of this folder (files as written by :func:`main`)."""
    names = sorted(p.stem.removeprefix("identify-") for p in HERE.glob("identify-*.yaml"))
    return [
        {
            "id": f"identify-log-{name}",
            "args": ["identify", f"{{data}}/logs/identify-{name}.yaml", "--out", "{tmp}/runs"],
            "isolate": True,
        }
        for name in names
    ]


def write() -> None:
    """Rewrite the files of this folder and their configs."""
    for p in HERE.glob("identify-*.yaml"):
        p.unlink()
    for name, log in _files().items():
        (HERE / f"identify-{name}.yaml").write_text(_config(name, log))


def main() -> None:
    write()
    for c in cases():
        print(f"- id: {c['id']}\n  args: {json.dumps(c['args'])}\n  isolate: true")


if __name__ == "__main__":
    main()
