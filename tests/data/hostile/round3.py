"""Hardening, round three: the newer features' hostile inputs (``generate.py`` runs this).

LeRobot datasets (``meta/info.json`` broken, frames missing, NaN, ticks out of range), the
servo actuator section of ``ident identify``, the MuJoCo simulator's ``measurement:`` fields,
mimic joints, meshes (a folder, a unicode name, a lying STL header), config sections of the
wrong type, numbers as strings, absurd counts, ``ident logs inspect`` and damaged result.json
entries of ``ident report``; then an episode of no frames, ``--topic`` where there is none, an
existing ``ident init`` output and ``--package-dir`` not a folder. Every case is refused before
any work (each under 0.3 s in the corpus runner; a dataset with one empty episode is read, its
warning pinned in ``test_lerobot.py``); ``expect.match`` pins the file and the field the one
error line names where the cause is specific.
"""

from __future__ import annotations

import json
import math
import shutil
import struct
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

Add = Callable[..., None]


# ---------------------------------------------------------------------------------------------
# LeRobot datasets: the rp2 arm (shoulder, slider) plus a gripper, in servo ticks


def _episode(n: int, phase: float) -> dict[str, np.ndarray]:
    t = np.arange(n) / 30.0
    q = np.column_stack([np.sin(t + phase), 0.3 * np.sin(0.5 * t + phase)])
    ticks = np.rint(2048.0 + 651.9 * np.column_stack([q, q[:, :1]]))
    effort = np.column_stack([np.cos(t), np.sin(t), np.zeros_like(t)])
    return {"observation.state": ticks, "action": ticks + 3.0, "observation.effort": effort}


TICKS = {"unit": "ticks", "counts_per_rev": 4096, "zero_tick": 2048}
LEROBOT_LOG = {
    "position": {"columns": ["observation.state"], "exclude": ["gripper"], **TICKS},
    "command": {"columns": ["action"]},
    "torque": {"columns": ["observation.effort"], "exclude": ["gripper"]},
}
SERVO_LOG = {
    "position": LEROBOT_LOG["position"],
    "command": {"columns": ["action"], "exclude": ["gripper"], **TICKS},
}


def _config(log: dict, **sections: object) -> str:
    cfg = {"name": "hostile", "robot": {"urdf": "../../base/rp2.urdf"}, "log": log, **sections}
    cfg.setdefault("validation", {"identify_fraction": 0.7})
    return json.dumps(cfg, indent=1) + "\n"  # JSON is YAML


def _dataset(folder: Path, episodes: list[dict], info: dict | None = None) -> None:
    from lerobot_datasets import write_dataset

    shutil.rmtree(folder, ignore_errors=True)
    write_dataset(folder, episodes, fps=30.0, names=["shoulder", "slider", "gripper"], info=info)


def _lerobot_datasets(d: Path) -> dict[str, tuple[str, dict, list[str]]]:
    """Write the datasets; name -> (dataset folder, log section changes, error parts)."""
    two = [_episode(60, 0.0), _episode(60, 1.0)]
    out: dict[str, tuple[str, dict, list[str]]] = {}
    _dataset(d / "good", two)
    for name, info, match in (
        ("fps_zero", {"fps": 0}, ["info.json", "fps"]),
        ("fps_negative", {"fps": -30}, ["info.json", "fps"]),
        ("fps_string", {"fps": "thirty"}, ["info.json", "fps"]),
        ("fps_huge", {"fps": 1e12}, ["info.json", "fps"]),
        ("fps_wrong", {"fps": 100}, ["info.json", "fps = 100"]),
        ("features_missing", {"features": None}, ["info.json", "features"]),
        ("features_list", {"features": ["observation.state"]}, ["info.json", "features"]),
    ):
        _dataset(d / name, two, info)
        out[name] = (name, {}, match)
    for name, text in (
        ("info_binary", bytes(range(256))),
        ("info_list", b"[]\n"),
        ("info_empty", b""),
        ("info_truncated", b'{"fps": 30, "features": {'),
    ):
        _dataset(d / name, two)
        (d / name / "meta" / "info.json").write_bytes(text)
        out[name] = (name, {}, ["info.json"])
    _dataset(d / "info_is_dir", two)
    (d / "info_is_dir" / "meta" / "info.json").unlink()
    (d / "info_is_dir" / "meta" / "info.json").mkdir()
    (d / "info_is_dir" / "meta" / "info.json" / ".keep").write_text("")
    out["info_is_dir"] = ("info_is_dir", {}, ["info.json", "is a folder"])
    names = json.loads((d / "good" / "meta" / "info.json").read_text())["features"]
    names["observation.state"]["names"] = ["shoulder", "slider"]  # 3 values per frame
    _dataset(d / "names_short", two, {"features": names})
    out["names_short"] = ("names_short", {}, ["observation.state"])
    # frames: none at all, the command shorter than the state
    _dataset(d / "all_zero_frames", [_episode(0, 0.0), _episode(0, 1.0)])
    out["all_zero_frames"] = ("all_zero_frames", {}, ["no frames", "episode_000001.parquet"])
    # one episode of no frames among others: skipped with a warning (logs inspect below)
    _dataset(d / "one_episode_empty", [two[0], _episode(0, 0.5), two[1]])
    short = [{**e, "action": e["action"][:, :2]} for e in two]
    _dataset(d / "action_shorter", short)
    out["action_shorter"] = ("action_shorter", {}, ["action"])
    nan = [dict(e) for e in two]
    nan[1]["observation.state"] = nan[1]["observation.state"].copy()
    nan[1]["observation.state"][17, 0] = math.nan
    _dataset(d / "state_nan", nan)
    out["state_nan"] = ("state_nan", {}, ["observation.state"])
    inf = [dict(e) for e in two]
    inf[0]["observation.effort"] = inf[0]["observation.effort"].copy()
    inf[0]["observation.effort"][5, 1] = math.inf
    _dataset(d / "effort_inf", inf)
    out["effort_inf"] = ("effort_inf", {}, ["observation.effort"])
    neg = [dict(e) for e in two]
    neg[0]["observation.state"] = neg[0]["observation.state"] - 9000.0  # below tick 0
    _dataset(d / "ticks_negative", neg)
    out["ticks_negative"] = ("ticks_negative", {}, ["tick"])
    stamps = [dict(e) for e in two]
    stamps[0]["timestamp"] = np.arange(60) / 30.0
    stamps[0]["timestamp"][30] = math.nan
    _dataset(d / "timestamp_nan", stamps)
    out["timestamp_nan"] = ("timestamp_nan", {}, ["timestamp"])
    # the episode files damaged
    for name, data in (
        ("parquet_garbage", bytes((k * 31 + 7) % 256 for k in range(2000))),
        ("parquet_empty", b""),
    ):
        _dataset(d / name, two)
        (d / name / "data" / "chunk-000" / "episode_000001.parquet").write_bytes(data)
        out[name] = (name, {}, ["episode_000001.parquet"])
    _dataset(d / "parquet_truncated", two)
    episode = d / "parquet_truncated" / "data" / "chunk-000" / "episode_000000.parquet"
    episode.write_bytes(episode.read_bytes()[:600])
    out["parquet_truncated"] = ("parquet_truncated", {}, ["episode_000000.parquet"])
    _dataset(d / "episode_is_dir", two)
    episode = d / "episode_is_dir" / "data" / "chunk-000" / "episode_000001.parquet"
    episode.unlink()
    episode.mkdir()
    (episode / ".keep").write_text("")
    out["episode_is_dir"] = ("episode_is_dir", {}, ["episode_000001.parquet"])
    _dataset(d / "no_data", two)
    shutil.rmtree(d / "no_data" / "data")
    out["no_data"] = ("no_data", {}, ["no_data"])
    # the config's conversion of ticks broken on a good dataset
    for name, position, match in (
        ("zero_tick_wrong_length", {"zero_tick": [2048] * 5}, ["zero_tick"]),
        ("zero_tick_string", {"zero_tick": "centre"}, ["zero_tick"]),
        ("zero_tick_nan", {"zero_tick": "nan"}, ["zero_tick"]),
        ("counts_per_rev_zero", {"counts_per_rev": 0}, ["counts_per_rev"]),
        ("counts_per_rev_negative", {"counts_per_rev": -4096}, ["counts_per_rev"]),
        ("counts_per_rev_missing", {"counts_per_rev": None}, ["counts_per_rev"]),
        ("unit_unknown", {"unit": "steps"}, ["unit"]),
        ("columns_unknown_feature", {"columns": ["observation.joints"]}, ["observation.joints"]),
        ("exclude_unknown", {"exclude": ["gripper", "wrist"]}, ["wrist"]),
    ):
        out[name] = ("good", {"position": position}, match)
    return out


def _lerobot(here: Path, add: Add) -> None:
    d = here / "round3" / "lerobot"
    for name, (folder, change, match) in _lerobot_datasets(d).items():
        log = json.loads(json.dumps({**LEROBOT_LOG, "path": folder}))
        for key, values in change.items():
            log[key].update(values)
            log[key] = {k: v for k, v in log[key].items() if v is not None}
        (d / f"identify_{name}.yaml").write_text(_config(log))
        add(
            f"identify-lerobot-{name}",
            ["identify", f"{{data}}/round3/lerobot/identify_{name}.yaml", "--out", "{tmp}/r"],
            expect={"match": match} if match else {},
        )
    for args, name in (
        (["{data}/round3/lerobot/fps_zero"], "fps_zero"),
        (["{data}/round3/lerobot/info_binary"], "info_binary"),
        (["{data}/round3/lerobot/parquet_garbage"], "parquet_garbage"),
    ):
        add(f"logs-inspect-lerobot-{name}", ["logs", "inspect", *args])
    # an empty episode is skipped (exit 0, its warning pinned in test_lerobot.py); --topic is a
    # feature of a dataset: one that is none is refused, listing the features
    episode_empty = "{data}/round3/lerobot/one_episode_empty"
    add("logs-inspect-lerobot-one_episode_empty", ["logs", "inspect", episode_empty],
        expect={"exit": 0})  # fmt: skip
    add(
        "logs-inspect-lerobot-topic_unknown",
        ["logs", "inspect", episode_empty, "--topic", "observation.joints"],
        expect={"match": ["observation.joints", "features are its topics", "observation.state"]},
    )
    add(
        "logs-inspect-lerobot-all_zero_frames",
        ["logs", "inspect", "{data}/round3/lerobot/all_zero_frames"],
        expect={"match": ["all_zero_frames", "no frames"]},
    )


# ---------------------------------------------------------------------------------------------
# The servo actuator section of ident identify (a LeRobot dataset logging no torque)

ACTUATOR_CASES: dict[str, tuple[dict, list[str]]] = {
    "kind_unknown": ({"kind": "stepper"}, ["actuator.kind", "stepper"]),
    "kind_list": ({"kind": ["position"]}, ["actuator.kind"]),
    "kp_negative": ({"kind": "position", "kp": -5.0}, ["actuator.kp"]),
    "kp_string": ({"kind": "position", "kp": "stiff"}, ["actuator.kp"]),
    "kp_nan": ({"kind": "position", "kp": "nan", "scale_from": "kp"}, ["actuator.kp"]),
    "kp_wrong_length": ({"kind": "position", "kp": [1.0, 2.0, 3.0]}, ["kp"]),
    "forcerange_zero": ({"kind": "position", "forcerange": 0.0}, ["actuator.forcerange"]),
    "forcerange_wrong_length": ({"kind": "position", "forcerange": [1.0] * 4}, ["forcerange"]),
    "delay_negative": ({"kind": "position", "delay": -0.01}, ["actuator.delay"]),
    "delay_huge": ({"kind": "position", "delay": 10.0}, ["actuator.delay"]),
    "delay_string": ({"kind": "position", "delay": "soon"}, ["actuator.delay"]),
    "max_delay_zero": ({"kind": "position", "max_delay_s": 0.0}, ["max_delay_s"]),
    "scale_from_kp_without_kp": ({"kind": "position", "scale_from": "kp"}, ["scale_from"]),
    "scale_from_unknown": ({"kind": "position", "scale_from": "torque"}, ["scale_from"]),
    "kp_on_motor": ({"kind": "motor", "kp": 10.0}, ["actuator.kp"]),
    "section_list": (["position"], ["actuator"]),  # type: ignore[dict-item]
}


def _actuator(here: Path, add: Add) -> None:
    d = here / "round3" / "actuator"
    d.mkdir(parents=True, exist_ok=True)
    servo = {**SERVO_LOG, "path": "../lerobot/good"}
    for name, (section, match) in ACTUATOR_CASES.items():
        (d / f"{name}.yaml").write_text(_config(servo, actuator=section))
        add(
            f"identify-actuator-{name}",
            ["identify", f"{{data}}/round3/actuator/{name}.yaml", "--out", "{tmp}/r"],
            expect={"match": match},
        )
    for name, log, section, match in (
        # a servo logs no torque; a motor logs one; a servo needs its command
        ("position_with_torque", {**LEROBOT_LOG, "path": "../lerobot/good"}, "position", "torque"),
        ("motor_without_torque", servo, "motor", "log.torque"),
        (
            "position_without_command",
            {"position": SERVO_LOG["position"], "path": "../lerobot/good"},
            "position",
            "command",
        ),
    ):
        (d / f"{name}.yaml").write_text(_config(log, actuator={"kind": section}))
        add(
            f"identify-actuator-{name}",
            ["identify", f"{{data}}/round3/actuator/{name}.yaml", "--out", "{tmp}/r"],
            expect={"match": [match]},
        )


# ---------------------------------------------------------------------------------------------
# ident run with the MuJoCo simulator: measurement fields refused before the design

MUJOCO_CASES: dict[str, tuple[str, list[str]]] = {
    "source_unknown": ("{source: gazebo}", ["measurement"]),
    "semantics_unknown": ("{source: mujoco, friction: {semantics: coulomb}}", ["semantics"]),
    "semantics_list": ("{source: mujoco, friction: {semantics: [mujoco]}}", ["semantics"]),
    "semantics_mujoco_with_law": (
        "{source: mujoco, friction: {semantics: mujoco, law: {model: stribeck, values: "
        "{fv: 0.5, fc: 1.0, fst: 0.5, vs: 0.05}}}}",
        ["friction.law"],
    ),
    "friction_viscous_negative": ("{source: mujoco, friction: {viscous: -0.5}}", ["viscous"]),
    "friction_coulomb_nan": ("{source: mujoco, friction: {coulomb: .nan}}", ["coulomb"]),
    "friction_viscous_wrong_length": (
        "{source: mujoco, friction: {viscous: [0.1, 0.2, 0.3]}}",
        ["viscous"],
    ),
    "friction_law_unknown": (
        "{source: mujoco, friction: {law: {model: magic, values: {}}}}",
        ["magic"],
    ),
    "friction_law_value_nan": (
        "{source: mujoco, friction: {law: {model: stribeck, values: "
        "{fv: .nan, fc: 1.0, fst: 0.5, vs: 0.05}}}}",
        ["fv"],
    ),
    "actuator_kp_negative": ("{source: mujoco, actuator: {kind: position, kp: -2000}}", ["kp"]),
    "actuator_position_without_kp": ("{source: mujoco, actuator: {kind: position}}", ["kp"]),
    "actuator_motor_with_kp": ("{source: mujoco, actuator: {kind: motor, kp: 10}}", ["kp"]),
    "actuator_kind_unknown": ("{source: mujoco, actuator: {kind: velocity}}", ["kind"]),
    "actuator_delay_steps_huge": (
        "{source: mujoco, actuator: {delay_steps: 1000000000}}",
        ["delay_steps"],
    ),
    "actuator_delay_steps_negative": ("{source: mujoco, actuator: {delay_steps: -1}}", ["delay"]),
    "actuator_delay_steps_float": ("{source: mujoco, actuator: {delay_steps: 2.5}}", ["delay"]),
    "actuator_forcerange_zero": ("{source: mujoco, actuator: {forcerange: 0}}", ["forcerange"]),
    "position_with_controller": (
        "{source: mujoco, actuator: {kind: position, kp: 2000}, controller: {kind: "
        "computed_torque, kp: 100.0, kd: 20.0}}",
        ["controller"],
    ),
    "substeps_zero": ("{source: mujoco, substeps: 0}", ["substeps"]),
    "substeps_huge": ("{source: mujoco, substeps: 100000}", ["substeps"]),
    "rate_zero": ("{source: mujoco, rate_hz: 0}", ["rate_hz"]),
    "rate_string": ("{source: mujoco, rate_hz: fast}", ["rate_hz"]),
    "armature_negative": ("{source: mujoco, armature: -0.1}", ["armature"]),
    "encoder_counts_one": ("{source: mujoco, encoder_counts_per_rev: 1}", ["encoder"]),
    "n_periods_zero": ("{source: mujoco, n_periods: 0}", ["n_periods"]),
    "settle_negative": ("{source: mujoco, settle_periods: -1}", ["settle_periods"]),
    "payload_not_rigid": (
        "{source: mujoco, payload: {mass: 1.0, com: [0, 0, 0], inertia: [1, 0, 0.01, 0, 0, 0.01]}}",
        ["payload"],
    ),
    "payload_mass_zero": ("{source: mujoco, payload: {mass: 0, com: [0, 0, 0]}}", ["mass"]),
    "payload_com_two": ("{source: mujoco, payload: {mass: 1, com: [0, 0]}}", ["com"]),
    "torque_constants_zero": (
        "{source: mujoco, current: {torque_constants: 0}}",
        ["torque_constants"],
    ),
    "signals_delay_negative": ("{source: mujoco, signals: {delay_s: -0.01}}", ["delay_s"]),
    "signals_gain_zero": ("{source: mujoco, signals: {torque_gain: 0}}", ["torque_gain"]),
    "controller_kind_unknown": ("{source: mujoco, controller: {kind: pid}}", ["controller"]),
    "load_law_with_servo": (
        "{source: mujoco, actuator: {kind: position, kp: 2000}, friction: {law: {model: "
        "load_dependent, values: {}}}}",
        ["friction.law"],
    ),
}


def _mujoco(here: Path, run_base: str, add: Add) -> None:
    d = here / "round3" / "mujoco"
    d.mkdir(parents=True, exist_ok=True)
    for name, (section, match) in MUJOCO_CASES.items():
        text = run_base.replace("../../../../configs/", "../../../../../configs/").replace(
            "measurement: {torque_noise_std: 0.0}", f"measurement: {section}"
        )
        (d / f"{name}.yaml").write_text(text)
        add(
            f"run-mujoco-{name}",
            ["run", f"{{data}}/round3/mujoco/{name}.yaml", "--out", "{tmp}/runs"],
            expect={"match": [f"{name}.yaml", *match]},
        )


# ---------------------------------------------------------------------------------------------
# Mimic joints, meshes


def _mimic(here: Path, chain: Callable[..., str], add: Add) -> None:
    d = here / "round3" / "mimic"
    d.mkdir(parents=True, exist_ok=True)
    for name, mimic, match in (
        ("multiplier_zero", '<mimic joint="j2" multiplier="0"/>', ["multiplier 0"]),
        ("multiplier_nan", '<mimic joint="j2" multiplier="nan"/>', ["multiplier"]),
        ("multiplier_words", '<mimic joint="j2" multiplier="twice"/>', ["multiplier"]),
        ("offset_inf", '<mimic joint="j2" offset="inf"/>', ["offset"]),
        ("leader_missing", '<mimic joint="j9"/>', ["j9"]),
        ("leader_self", '<mimic joint="j3"/>', ["j3"]),
        ("no_leader_attribute", "<mimic/>", ["mimic"]),
    ):
        text = chain(3).replace(
            '<limit lower="-1" upper="1" velocity="1" effort="10"/></joint>\n</robot>',
            f'<limit lower="-1" upper="1" velocity="1" effort="10"/>{mimic}</joint>\n</robot>',
        )
        assert mimic in text
        (d / f"{name}.urdf").write_text(text)
        add(
            f"verify-mimic-{name}",
            ["verify", "--urdf", f"{{data}}/round3/mimic/{name}.urdf"],
            expect={"match": [f"{name}.urdf", *match]},
        )
    add(
        "init-mimic-lock_follower",
        ["init", "{data}/urdf/mimic.urdf", "--lock", "j3", "-o", "{tmp}/c.yaml"],
    )


def _stl_lying(count: int) -> bytes:
    """A binary STL header declaring ``count`` triangles, followed by one."""
    tri = struct.pack("<12f", *([0.0] * 3), 0, 0, 0, 0.1, 0, 0, 0, 0.1, 0.1) + b"\0\0"
    return b"liar".ljust(80, b" ") + struct.pack("<I", count) + tri


def _meshes(here: Path, mesh_urdf: Callable[..., str], mesh_run: str, add: Add) -> None:
    d = here / "round3" / "mesh"
    d.mkdir(parents=True, exist_ok=True)
    (d / "folder.stl").mkdir(exist_ok=True)
    (d / "folder.stl" / ".keep").write_text("")
    flat = (here / "mesh" / "flat.stl").read_bytes()
    (d / "fl\u00e4che_\u5e73.stl").write_bytes(flat)  # a unicode name, a flat mesh
    (d / "liar.stl").write_bytes(_stl_lying(2_000_000_000))
    (d / "obj_bad_index.obj").write_bytes(b"v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 99\n")
    (d / "obj_words.obj").write_bytes(b"v zero zero zero\nf 1 1 1\n")
    # name: (mesh file, parts of the error line, the replay refuses it too: a visual mesh
    # not found is replaced by a stick figure with a warning, a flat one is drawn)
    for name, (filename, match, visual) in {
        "folder": ("folder.stl", ["folder.stl (a folder)"], False),
        "unicode_flat": ("fl\u00e4che_\u5e73.stl", ["fl\u00e4che_\u5e73.stl"], False),
        "missing": ("nowhere.stl", ["nowhere.stl"], False),
        "traversal": ("../../../../../../../../etc/passwd", ["/etc/passwd"], True),
        "dev_zero": ("/dev/zero", ["/dev/zero (not a regular file"], False),
        "liar_count": ("liar.stl", ["liar.stl"], True),
        "obj_bad_index": ("obj_bad_index.obj", ["obj_bad_index.obj"], True),
        "obj_words": ("obj_words.obj", ["obj_words.obj"], True),
        "package_unknown": ("package://no_such_pkg/meshes/a.stl", ["no_such_pkg"], False),
        "unknown_suffix": ("../../base/rp2.urdf", ["rp2.urdf"], True),
    }.items():
        (d / f"collision_{name}.urdf").write_text(
            mesh_urdf(filename, None, collision=True, visual=False)
        )
        (d / f"visual_{name}.urdf").write_text(
            mesh_urdf(filename, None, collision=False, visual=True)
        )
        (d / f"run_{name}.yaml").write_text(mesh_run.replace("URDF", f"collision_{name}.urdf"))
        add(
            f"run-mesh3-collision-{name}",
            ["run", f"{{data}}/round3/mesh/run_{name}.yaml", "--out", "{tmp}/runs"],
            expect={"match": [f"run_{name}.yaml", *match]},
        )
        if not visual:
            continue
        add(
            f"replay-mesh3-visual-{name}",
            [
                "replay",
                "--urdf",
                f"{{data}}/round3/mesh/visual_{name}.urdf",
                "--trajectory",
                "{data}/base/traj.csv",
                "--html",
                "{tmp}/r.html",
            ],
        )


# ---------------------------------------------------------------------------------------------
# Sections of the wrong type, numbers as strings, absurd counts


def _types(here: Path, identify_base: str, bench_base: str, add: Add) -> None:
    d = here / "round3" / "types"
    d.mkdir(parents=True, exist_ok=True)
    base = identify_base.replace("../base/", "../../base/")
    cases = {
        "robot_number": base.replace("robot: {urdf: ../../base/rp2.urdf}", "robot: 5"),
        "robot_urdf_list": base.replace("{urdf: ../../base/rp2.urdf}", "{urdf: [a.urdf]}"),
        "log_list": base.split("log:")[0] + "log: [../../base/q.csv]\n",
        "log_string": base.split("log:")[0] + "log: ../../base/q.csv\n",
        "position_list": base.replace("position: {path: ../../base/q.csv}", "position: [q]"),
        "preprocess_string": base + "preprocess: fast\n",
        "model_list": base + "model: [viscous, coulomb]\n",
        "estimation_method_list": base + "estimation: {method: [wls, ols]}\n",
        "validation_number": base.replace("validation: {identify_fraction: 0.7}", "validation: 1"),
        "name_mapping": base.replace("name: hostile", "name: {a: 1}"),
        "rate_numeric_string": base.replace("sampling_rate_hz: 100.0", "sampling_rate_hz: '1e2x'"),
        "rate_bool": base.replace("sampling_rate_hz: 100.0", "sampling_rate_hz: true"),
        "rate_negative": base.replace("sampling_rate_hz: 100.0", "sampling_rate_hz: -100"),
        "fraction_string": base.replace("identify_fraction: 0.7", "identify_fraction: 'most'"),
        "fraction_above_one": base.replace("identify_fraction: 0.7", "identify_fraction: 1.5"),
        "trim_negative": base + "preprocess: {trim_samples: -5}\n",
        "trim_float": base + "preprocess: {trim_samples: 2.5}\n",
        "decimation_zero": base + "preprocess: {decimation: [0]}\n",
        "decimation_negative": base + "preprocess: {decimation: [-2]}\n",
        "chunk_samples_zero": base + "preprocess: {chunked: always, chunk_samples: 0}\n",
        "chunk_samples_negative": base + "preprocess: {chunked: always, chunk_samples: -100}\n",
        "chunked_unknown": base + "preprocess: {chunked: sometimes}\n",
        "max_regressor_mb_negative": base + "preprocess: {max_regressor_mb: -1}\n",
        "lowpass_order_zero": base + "preprocess: {lowpass: {cutoff_hz: 5.0, order: 0}}\n",
        "lowpass_order_huge": base + "preprocess: {lowpass: {cutoff_hz: 5.0, order: 1000}}\n",
        "lowpass_cutoff_negative": base + "preprocess: {lowpass: {cutoff_hz: -5.0}}\n",
        "max_delay_huge": base + "signals: {delay_s: auto, max_delay_s: 100}\n",
        "signals_delay_beyond": base + "signals: {delay_s: 0.5}\n",
        "friction_model_unknown": base + "model: {friction: magic}\n",
    }
    for name, text in cases.items():
        (d / f"identify_{name}.yaml").write_text(text)
        add(
            f"identify-type-{name}",
            ["identify", f"{{data}}/round3/types/identify_{name}.yaml", "--out", "{tmp}/r"],
            expect={"match": [f"identify_{name}.yaml"]},
        )
    bench = {
        "runs_zero": bench_base.replace("runs: 2", "runs: 0"),
        "runs_negative": bench_base.replace("runs: 2", "runs: -3"),
        "popsize_one": bench_base.replace("popsize: 10", "popsize: 1"),
        "max_nfev_string": bench_base.replace("max_nfev: 100", "max_nfev: 'a hundred'"),
        "methods_empty": bench_base.replace("methods: [pso]", "methods: []"),
        "functions_string": bench_base.replace("functions: [sphere]", "functions: sphere"),
        "curve_points_zero": bench_base.replace("curve_points: 5", "curve_points: 0"),
        "seed_float": bench_base.replace("seed: 1", "seed: 1.5"),
    }
    for name, text in bench.items():
        (d / f"bench_{name}.yaml").write_text(text)
        add(
            f"bench-type-{name}",
            [
                "bench",
                f"{{data}}/round3/types/bench_{name}.yaml",
                "--out",
                "{tmp}/c",
                "--no-progress",
            ],
            expect={"match": [f"bench_{name}.yaml"]},
        )


def _run_types(here: Path, run_base: str, add: Add) -> None:
    d = here / "round3" / "types"
    base = run_base.replace("../../../../configs/", "../../../../../configs/")
    cases = {
        "excitation_list": base.split("excitation:")[0] + "excitation: [joint_fourier]\n",
        "n_samples_string": base.replace("n_samples: 100", "n_samples: 'a hundred'"),
        "n_samples_zero": base.replace("n_samples: 100", "n_samples: 0"),
        "n_samples_negative": base.replace("n_samples: 100", "n_samples: -100"),
        "n_harmonics_zero": base.replace("n_harmonics: 3", "n_harmonics: 0"),
        "family_unknown": base.replace("family: joint_fourier", "family: chaos"),
        "emupso_string": base.split("emupso:")[0]
        + "emupso: fast\nmeasurement: {torque_noise_std: 0.0}\n",
        "seed_string": base.replace("seed: 3", "seed: three"),
        "controller_rate_zero": base + "controller: {rate_hz: 0}\n",
        "controller_export_unknown": base + "controller: {export: [matlab]}\n",
    }
    for name, text in cases.items():
        (d / f"run_{name}.yaml").write_text(text)
        add(
            f"run-type-{name}",
            ["run", f"{{data}}/round3/types/run_{name}.yaml", "--out", "{tmp}/runs"],
            expect={"match": [f"run_{name}.yaml"]},
        )


# ---------------------------------------------------------------------------------------------
# ident logs inspect, ident report on a damaged result.json, replay and init flags


def _commands(here: Path, add: Add) -> None:
    d = here / "round3" / "inspect"
    d.mkdir(parents=True, exist_ok=True)
    (d / "binary.csv").write_bytes(bytes(range(256)) * 8)
    (d / "empty.csv").write_bytes(b"")
    (d / "garbage.csv.gz").write_bytes(b"\x1f\x8b\x08\x00" + bytes(range(200)))
    (d / "garbage.mcap").write_bytes(b"\x89MCAP0\r\n" + bytes(range(100)))
    (d / "garbage.parquet").write_bytes(b"PAR1" + bytes(range(100)) + b"PAR1")
    for name, args in {
        "missing": ["{data}/round3/inspect/nope.csv"],
        "dev_zero": ["/dev/zero"],
        "binary": ["{data}/round3/inspect/binary.csv"],
        "empty": ["{data}/round3/inspect/empty.csv"],
        "gzip_garbage": ["{data}/round3/inspect/garbage.csv.gz"],
        "mcap_garbage": ["{data}/round3/inspect/garbage.mcap"],
        "parquet_garbage": ["{data}/round3/inspect/garbage.parquet"],
        "format_unknown": ["{data}/base/q.csv", "--format", "excel"],
        "format_wrong": ["{data}/base/q.csv", "--format", "mcap"],
        "max_columns_negative": ["{data}/base/q.csv", "--max-columns", "-1"],
        "folder_of_nothing": ["{data}/round3/mesh/folder.stl"],
        "npz_object": ["{data}/logs/object.npz"],
        "npz_bomb": ["{data}/logs/declares_100M.npz"],
        "topic_on_csv": ["{data}/base/q.csv", "--topic", "/joint_states"],
    }.items():
        match = {
            "dev_zero": ["/dev/zero", "not a regular file"],
            "topic_on_csv": ["--topic /joint_states", "q.csv", "no topics"],
        }.get(name)
        add(
            f"logs-inspect-{name}",
            ["logs", "inspect", *args],
            **({"expect": {"match": match}} if match else {}),
        )
    # ident report: the result.json of a run damaged where the report reads it
    real = json.loads((here / "os" / "real_run" / "result.json").read_text())
    for name, change in {
        "rollout_string": {"rollout": "not run"},
        "rollout_list": {"rollout": [1, 2]},
        "rollout_missing_keys": {"rollout": {"objective": 0.5}},
        "model_string": {"model": "files"},
        "elites_nan_cost": {"elites": [{"cost": "nan"}]},
        "stage_list": {"stage": ["wrist"]},
    }.items():
        folder = here / "round3" / "report" / name
        shutil.rmtree(folder, ignore_errors=True)
        shutil.copytree(here / "os" / "real_run", folder)
        (folder / "result.json").write_text(json.dumps({**real, **change}, indent=1) + "\n")
        add(
            f"report-result-{name}",
            ["report", "{tmp}/run"],
            setup={"copy": f"round3/report/{name}", "to": "run"},
            expect={"match": ["result.json"], "left": "keep"},
        )
    for name, args in {
        "speed_string": ["{data}/runfolder/good", "--speed", "fast", "--html", "{tmp}/r.html"],
    }.items():
        add(f"replay-flag-{name}", ["replay", *args])
    for name, args in {
        "out_is_dir": ["{data}/base/rp2.urdf", "-o", "{tmp}"],
        "out_under_proc": ["{data}/base/rp2.urdf", "-o", "/proc/ident.yaml"],
        "lock_nan": ["{data}/base/rp2.urdf", "--lock", "shoulder=nan", "-o", "{tmp}/c.yaml"],
        "lock_words": ["{data}/base/rp2.urdf", "--lock", "shoulder=up", "-o", "{tmp}/c.yaml"],
        "urdf_mimic_of_mimic": ["{data}/urdf/mimic_of_mimic.urdf", "-o", "{tmp}/c.yaml"],
    }.items():
        add(f"init-flag-{name}", ["init", *args])
    # an existing config is never overwritten without --force (it may hold the user's edits)
    (here / "round3" / "init").mkdir(parents=True, exist_ok=True)
    (here / "round3" / "init" / "mine.yaml").write_text("# my edited config\n")
    add(
        "init-flag-out_exists",
        ["init", "{data}/base/rp2.urdf", "-o", "{tmp}/cfg/mine.yaml"],
        setup={"copy": "round3/init", "to": "cfg"},
        expect={"match": ["--output", "mine.yaml: exists", "--force"], "left": "keep"},
    )
    # --package-dir, the one option of every command reading a URDF: a file is no folder
    for command, args in {
        "run": ["run", "{data}/round3/mesh/run_missing.yaml", "--out", "{tmp}/runs"],
        "verify": ["verify", "--urdf", "{data}/base/rp2.urdf"],
        "identify": ["identify", "{data}/identify/base.yaml", "--out", "{tmp}/r"],
        "init": ["init", "{data}/base/rp2.urdf", "-o", "{tmp}/c.yaml"],
    }.items():
        add(
            f"{command}-flag-package_dir_a_file",
            [*args, "--package-dir", "{data}/base/rp2.urdf"],
            expect={"match": ["--package-dir", "rp2.urdf: not a folder"]},
        )
    for name, args in {
        "second_log_a_list": [
            "{data}/identify/base.yaml",
            "{data}/round3/types/identify_log_list.yaml",
        ],
        "binary_config": ["{data}/identify/base.yaml", "{data}/yaml/binary.yaml"],
        "folder_config": ["{data}/identify/base.yaml", "{data}/base"],
    }.items():
        add(f"repeatability-{name}", ["repeatability", *args])


def generate(here: Path, ns: dict, add: Add) -> None:
    """Write the round-three files under ``here/round3`` and add their cases (``ns``: the
    bases and helpers of ``generate.py``)."""
    sys.path.insert(0, str(ns["ROOT"] / "tests"))
    shutil.rmtree(here / "round3", ignore_errors=True)
    _lerobot(here, add)
    _actuator(here, add)
    _mujoco(here, ns["RUN_BASE"], add)
    _mimic(here, ns["_urdf_chain"], add)
    mesh_run = ns["MESH_RUN"]
    _meshes(here, _mesh_urdf_for(here, ns), mesh_run, add)
    _types(here, ns["IDENTIFY_BASE"], ns["BENCH_BASE"], add)
    _run_types(here, ns["RUN_BASE"], add)
    _commands(here, add)


def _mesh_urdf_for(here: Path, ns: dict) -> Callable[..., str]:
    def mesh_urdf(filename: str, scale: str | None, *, collision: bool, visual: bool) -> str:
        return ns["_mesh_urdf"](filename, scale, collision=collision, visual=visual)

    return mesh_urdf
