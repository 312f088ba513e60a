"""Payload identification on simulated UR5 and Panda logs (MuJoCo): mass and centre-of-mass errors.

For each robot (configs/ur5.yaml, configs/panda.yaml: the URDF, locked joints, the simulated
friction and rotor inertia of their ``measurement:`` sections) and each payload (1 to 5 kg, the
centre of mass 3-12 cm off the flange, a box-like inertia), MuJoCo simulates two closed-loop logs
of the same Fourier excitation (every joint moving, 20 s at 1 kHz): without and with the payload
welded to the last link (``measurement.payload``). The torque noise of each joint is an absolute
floor per robot (:data:`TORQUE_NOISE_FLOOR`: UR5 0.1 N*m, Panda 0.005 N*m, docs/payload.md says
where they come from) and 1 % of its RMS torque, added in variance (``--noise relative``: the 1 %
alone, as before the floor; ``--noise-floor NM``: one floor for every robot). ``ident payload``
is run on a config naming both logs, exactly as a user would; the
errors against the simulated payload are printed as a table (docs/payload.md holds the last one).

A last row uses the payload excitation instead (``configs/ur5-payload.yaml``: ``ident run``
designs a 5 s motion of the three wrist joints, the arm held, for the payload's 10 parameters,
certified safe with the payload's box): one log of that trajectory with the 2.5 kg payload, no
log without it, ``ident payload`` with the held joints' rows kept and friction terms for the wrist.

Run: ``python benchmarks/bench_payload.py [--quick]`` (about 2 min; ``--quick``: one robot, one
payload, the designed row).

``--coverage N [--robots ur5,panda,designed] [--seconds 10]`` measures instead whether the
reported 95 % intervals hold the truth: the 2.5 kg payload, the same motion, ``N`` noise seeds
(both logs re-simulated; ``designed``: one design, its log re-simulated); per case the share of
seeds whose true mass and each centre-of-mass component lie within ``1.96 σ``, by the reported σ
(the block bootstrap) and by the ordinary least-squares σ, and the RMS of error / σ (1 when
calibrated). About 4 s a seed for the UR5 with 10 s logs, 3 s for the Panda, 2 s for the
designed case (plus its 1 min design).

``--seeds N [--robots ur5,panda] [--seconds 20] [--cad-signs fixed|random]``: the arm handed to
``ident payload`` is a CAD URDF (every link's mass and inertia +10 %, its centre of mass +1 cm
in x; ``random``: each link's two signs drawn per seed), the simulation uses the true arm, the
payload is 2.5 kg at (0.02, 0.03, 0.08) m. Per seed ``k`` (its own motion and noise), three
cases: two logs; one log with the arm ``ident identify`` made from the log without payload
(its model files and covariance, no report); one log on the CAD URDF. Per case: median and
worst mass and centre-of-mass errors, the share of the reported 95 % intervals holding the
truth (mass, each CoM component, and the four pooled, counted over seeds, with the pooled
count's Wilson 95 % interval), the RMS of error / σ, the warning rate, the share of runs
whose model files were not written (``ident payload`` exit code 1); and the CPU per seed
(``time.process_time``, the whole seed: both simulations, the identification and the three
payload runs; about 20-30 s for either robot). The payload runs use ``method: wls`` (the
intervals are the WLS estimate's).
``--workdir DIR`` keeps each seed's logs and identified arm in ``DIR`` (``<robot>-seed-<k>``,
their ``case.json``); a seed found there is reused: only ``ident payload`` runs again (a change
of its intervals re-measured on the same seeds without the simulations and ``ident identify``).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from typer.testing import CliRunner

from ident.cli import app
from ident.cli.payload import EXIT_NO_MODEL_FILES
from ident.config import read_yaml
from ident.dynamics.parameters import parameter_names, parameters_from_model
from ident.excitation.fourier import fourier_series
from ident.identify.config import load_identify_config
from ident.identify.model_files.files import model_files, save_identified_model
from ident.identify.pipeline.real import identify as run_identify
from ident.measure.mujoco_config import load_mujoco_measurement
from ident.measure.mujoco_sim import simulate, write_log
from ident.model.selection import RobotSelection, load_robot
from ident.robot.inertia import com_and_inertia, parameters_from_com

REPO = Path(__file__).resolve().parents[1]

#: (mass [kg], centre of mass in the last link's frame [m], box sides [m]) of the payloads.
PAYLOADS = (
    (1.0, (0.02, -0.01, 0.05), (0.06, 0.06, 0.08)),
    (2.5, (-0.03, 0.02, 0.08), (0.10, 0.08, 0.12)),
    (5.0, (0.05, 0.04, 0.12), (0.15, 0.10, 0.20)),
)


def box_inertia(mass: float, sides: tuple[float, float, float]) -> list[float]:
    """Inertia of a solid box about its centre [kg*m^2], Pinocchio order."""
    a, b, c = sides
    return [mass * (b * b + c * c) / 12, 0.0, mass * (a * a + c * c) / 12, 0.0, 0.0,
            mass * (a * a + b * b) / 12]  # fmt: skip


def reference(robot, rate_hz: float, period_s: float, rng: np.random.Generator, amplitude: float):
    """One period of a 4-harmonic Fourier excitation about a posture with the arm up."""
    t = np.arange(int(round(period_s * rate_hz))) / rate_hz
    n_harm = 4
    a = rng.uniform(-amplitude, amplitude, (1, robot.nv, n_harm))
    b = rng.uniform(-amplitude, amplitude, (1, robot.nv, n_harm))
    lower, upper = np.clip(robot.q_lower, -np.pi, np.pi), np.clip(robot.q_upper, -np.pi, np.pi)
    q0 = 0.5 * (lower + upper)
    if robot.nv == 6:  # UR5: the upper arm raised
        q0[1] = -1.57
    q, dq, ddq = fourier_series(t, a, b, q0[None, :], 2.0 * np.pi / period_s)
    return t, q[0], dq[0], ddq[0]


#: Absolute floor of the simulated joint-torque noise per robot [N*m, 1 σ of each 1 kHz
#: sample], added in quadrature to the relative part (:data:`RELATIVE_NOISE` of each joint's
#: RMS torque): a real joint-torque signal has a floor however light the joint's load, and a
#: benchmark whose noise is below its simulator's own model error (integration, filtering)
#: measures the simulator. Panda: the datasheet's torque noise (RMS) 0.005 N*m (resolution
#: 0.02 N*m). UR5 (torques from motor currents): see docs/payload.md, "The benchmark's noise".
TORQUE_NOISE_FLOOR = {"ur5": 0.1, "panda": 0.005}
#: The relative part of the simulated torque noise: this share of each joint's RMS torque.
RELATIVE_NOISE = 0.01
#: The floors in use (``--noise relative``: none, the benchmark's noise before the floor).
noise_floors: dict[str, float] = dict(TORQUE_NOISE_FLOOR)


def torque_noise_std(rms: np.ndarray, floor: float) -> list[float]:
    """Per-joint torque noise σ [N*m]: ``sqrt(floor^2 + (RELATIVE_NOISE * rms)^2)`` of each
    joint's RMS torque ``rms`` (nv,) [N*m] (two independent sources add in variance)."""
    return np.sqrt(floor**2 + (RELATIVE_NOISE * np.asarray(rms)) ** 2).tolist()


def simulation_setup(
    config: Path, *, seconds: float, seed: int, noise_floor: float = 0.0
) -> tuple[dict, Any, tuple[np.ndarray, ...], dict]:
    """The robot of a run config, the reference motion (:func:`reference`, 10 s periods) and
    the config's MuJoCo ``measurement`` section for ``seconds`` of log, its torque noise
    :func:`torque_noise_std` (1 % of each joint's RMS torque and ``noise_floor`` [N*m]):
    ``(raw config, robot, (t, q, dq, ddq), measurement)``. Shared with bench_signals.py."""
    raw = read_yaml(config)
    selection = RobotSelection.model_validate(raw["robot"]).resolved(config.parent)
    robot = load_robot(selection)
    measurement = {k: v for k, v in raw["measurement"].items() if k != "source"}
    t, q, dq, ddq = reference(robot, 1000.0, 10.0, np.random.default_rng(seed), amplitude=0.35)
    rms = np.sqrt(np.mean(robot.rnea(q, dq, ddq) ** 2, axis=0))
    measurement.update(
        torque_noise_std=torque_noise_std(rms, noise_floor),
        n_periods=int(round(seconds / 10.0)),
        settle_periods=1,
        payload=None,
    )
    return raw, robot, (t, q, dq, ddq), measurement


def payload_section(payload: tuple) -> dict:
    """A MuJoCo ``measurement.payload`` of ``(mass [kg], com (3,) [m], box sides (3,) [m])``."""
    mass, com, sides = payload
    return {"mass": mass, "com": list(com), "inertia": box_inertia(mass, sides)}


def ident_payload(folder: Path, payload_cfg: dict) -> tuple[dict, float]:
    """Write ``payload_cfg`` and run ``ident payload`` on it: its ``payload.json`` and the
    command's wall time [s]. Exit code 1 (the estimate written, the model files not: its
    ``model_files`` entry and a warning say why) is a result too."""
    path = folder / "payload.yaml"
    path.write_text(yaml.safe_dump(payload_cfg, sort_keys=False))
    t0 = time.perf_counter()
    result = CliRunner().invoke(app, ["payload", str(path), "--out", str(folder / "runs")])
    elapsed = time.perf_counter() - t0
    if result.exit_code not in (0, EXIT_NO_MODEL_FILES):
        raise RuntimeError(result.output)
    (summary_path,) = (folder / "runs").glob("*/payload.json")
    return json.loads(summary_path.read_text()), elapsed


def result_row(label: str, mass: float, com: Any, summary: dict, seconds: float) -> dict:
    """One table row: ``ident payload``'s ``summary`` (payload.json) against the true ``mass``
    [kg] and centre of mass ``com`` (3,) [m, in the reported link's frame]."""
    com_error = np.asarray(summary["com_m"]) - np.asarray(com)
    return {
        "robot": label,
        "mass": mass,
        "mass_error_pct": 100.0 * (summary["mass_kg"] - mass) / mass,
        "mass_std_pct": 100.0 * summary["mass_std_kg"] / mass,
        "com_error_mm": 1e3 * float(np.linalg.norm(com_error)),
        "com_std_mm": 1e3 * float(np.linalg.norm(summary["com_std_m"])),
        "min_eig": summary["pseudo_inertia_min_eigenvalue"],
        "seconds": seconds,
        "summary": summary,
    }


def simulate_logs(
    config: Path,
    payload: tuple,
    folder: Path,
    *,
    seconds: float,
    seed: int,
    noise_seed: int | None = None,
) -> tuple[dict, Any, dict]:
    """Both MuJoCo logs (without and with ``payload``) of the config's arm: ``(raw config,
    robot, {"without": log section, "with": log section})``. ``seed`` draws the motion;
    ``noise_seed`` (default ``seed``) the simulated noise."""
    raw, robot, (t, q, dq, ddq), measurement = simulation_setup(
        config, seconds=seconds, seed=seed, noise_floor=noise_floors.get(config.stem, 0.0)
    )
    logs = {}
    for name, with_payload in (("without", False), ("with", True)):
        section = dict(measurement)
        if with_payload:
            section["payload"] = payload_section(payload)
        cfg = load_mujoco_measurement(section)
        rng = seed + with_payload if noise_seed is None else 1000 + 2 * noise_seed + with_payload
        sim = simulate(robot, t, q, dq, ddq, cfg, rng=rng)
        files = write_log(folder / name, sim)
        logs[name] = yaml.safe_load(files.yaml.read_text())["log"]
        for key in ("time", "position", "torque"):
            logs[name][key]["path"] = str(folder / name / logs[name][key]["path"])
    return raw, robot, logs


def run_case(
    config: Path,
    payload: tuple,
    folder: Path,
    *,
    seconds: float,
    seed: int,
    noise_seed: int | None = None,
) -> dict:
    """Simulate both logs, run ``ident payload`` and compare with the truth.

    ``seed`` draws the motion; ``noise_seed`` (default ``seed``) the simulated noise."""
    raw, _, logs = simulate_logs(
        config, payload, folder, seconds=seconds, seed=seed, noise_seed=noise_seed
    )
    mass, com, _ = payload
    payload_cfg = {
        "name": f"{config.stem}-payload",
        "robot": {**raw["robot"], "urdf": str((config.parent / raw["robot"]["urdf"]).resolve())},
        "log": logs["with"],
        "preprocess": raw["identification"]["preprocess"],
        "model": raw["identification"]["model"],
        "payload": {"without": logs["without"], "method": "lmi"},
    }
    payload_cfg["robot"].pop("package_dirs", None)
    summary, elapsed = ident_payload(folder, payload_cfg)
    return result_row(config.stem, mass, com, summary, elapsed)


#: The CAD arm handed to ``ident payload`` in ``--cad``: every link's mass and inertia x1.1
#: and its centre of mass +1 cm in x (the simulation uses the true arm): a CAD model's
#: systematic error, the same sign on every link.
CAD_MASS_FACTOR = 1.1
CAD_COM_SHIFT_M = (0.01, 0.0, 0.0)
#: The ``--cad`` cases: where ``ident payload`` gets the arm from.
CAD_MODES = ("two logs", "one log + identified arm", "one log + CAD")


def cad_urdf(robot: Any, folder: Path, signs: np.ndarray | None = None) -> Path:
    """The arm's URDF with the CAD errors (:data:`CAD_MASS_FACTOR`, :data:`CAD_COM_SHIFT_M`),
    written as ``folder/<stem>_cad.urdf``. ``signs`` (n_bodies, 2) of +-1: per link, the sign
    of its mass error and of its centre-of-mass shift (default: all +1, the issue's case)."""
    bodies = parameters_from_model(robot.model).reshape(-1, 10).copy()
    signs = np.ones((len(bodies), 2)) if signs is None else signs
    for k, body in enumerate(bodies):
        mass, com, inertia = com_and_inertia(body)
        if mass > 0:
            factor = 1.0 + signs[k, 0] * (CAD_MASS_FACTOR - 1.0)
            shift = signs[k, 1] * np.asarray(CAD_COM_SHIFT_M)
            bodies[k] = parameters_from_com(factor * mass, com + shift, factor * inertia)
    names = parameter_names(robot.n_bodies)
    text = model_files(robot, bodies.reshape(-1), names).urdf_text
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{Path(str(robot.urdf_path)).stem}_cad.urdf"
    path.write_text(text)
    return path


def identified_arm(raw: dict, urdf: Path, log: dict, folder: Path) -> Path:
    """``ident identify``'s estimate of ``urdf`` on the log section ``log`` (no payload): the
    ``<stem>_identified.urdf`` it writes (its ``_joint_extras.json`` beside it). The
    identification and the model files are ``ident identify``'s; its report (plots) is not
    written, which halves the benchmark's CPU."""
    cfg = {
        "name": "arm",
        "robot": {**raw["robot"], "urdf": str(urdf)},
        "log": log,
        "preprocess": raw["identification"]["preprocess"],
        "model": raw["identification"]["model"],
        "estimation": {"method": "lmi"},
    }
    cfg["robot"].pop("package_dirs", None)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "identify.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    entry = save_identified_model(run_identify(load_identify_config(path), rng=0), folder)
    if not entry["written"]:
        raise RuntimeError(f"no identified model: {entry['note']}")
    return folder / entry["files"]["urdf"]


#: The issue's payload of the CAD cases: (mass [kg], centre of mass [m], box sides [m]).
CAD_PAYLOAD = (2.5, (0.02, 0.03, 0.08), (0.10, 0.08, 0.12))


def run_cad_case(
    config: Path,
    folder: Path,
    *,
    seconds: float,
    seed: int,
    noise_seed: int | None = None,
    method: str = "lmi",
    signs: np.ndarray | None = None,
) -> list[dict]:
    """The :data:`CAD_PAYLOAD` on the config's arm with a CAD URDF (:func:`cad_urdf`, its
    error ``signs``), one row per :data:`CAD_MODES`: both logs; the payload log with the arm
    identified from the log without it (``ident identify`` of the CAD URDF); the payload log
    on the CAD URDF alone. ``method``: ``ident payload``'s estimator (``lmi`` or ``wls``)."""
    mass, com, _ = CAD_PAYLOAD
    raw, logs, cad, arm = _cad_inputs(config, folder, seconds, seed, noise_seed, signs)
    arms = {
        CAD_MODES[0]: (cad, logs["without"]),
        CAD_MODES[1]: (arm, None),
        CAD_MODES[2]: (cad, None),
    }
    rows = []
    for k, (mode, (urdf, without)) in enumerate(arms.items()):
        payload_cfg = {
            "name": f"{config.stem}-cad-{k}",
            "robot": {**raw["robot"], "urdf": str(urdf)},
            "log": logs["with"],
            "preprocess": raw["identification"]["preprocess"],
            "model": raw["identification"]["model"],
            "payload": {"without": without, "method": method},
        }
        payload_cfg["robot"].pop("package_dirs", None)
        shutil.rmtree(folder / f"mode-{k}", ignore_errors=True)  # a reused folder's last run
        (folder / f"mode-{k}").mkdir()
        summary, elapsed = ident_payload(folder / f"mode-{k}", payload_cfg)
        row = result_row(f"{config.stem}, {mode}", mass, com, summary, elapsed)
        row["z"] = normalized_errors(summary, mass, com)[summary["std_method"]]
        rows.append(row)
    return rows


def _cad_inputs(
    config: Path,
    folder: Path,
    seconds: float,
    seed: int,
    noise_seed: int | None,
    signs: np.ndarray | None,
) -> tuple[dict, dict, Path, Path]:
    """``(raw config, {"without", "with": log section}, CAD URDF, identified URDF)`` of a CAD
    case: simulated and identified into ``folder``, or read back from its ``case.json`` when
    an earlier run left it there (``--workdir``: the payload runs alone are repeated)."""
    saved = folder / "case.json"
    floor = noise_floors.get(config.stem, 0.0)
    if saved.exists():
        case = json.loads(saved.read_text())
        found = case.get("noise_floor", 0.0)  # a workdir from before the floor had none
        if found != floor:  # a workdir of another noise model
            raise SystemExit(f"{saved}: simulated with a noise floor of {found} N*m, not {floor}")
        return read_yaml(config), case["logs"], Path(case["cad"]), Path(case["arm"])
    raw, robot, logs = simulate_logs(
        config, CAD_PAYLOAD, folder, seconds=seconds, seed=seed, noise_seed=noise_seed
    )
    cad = cad_urdf(robot, folder / "cad", signs)
    arm = identified_arm(raw, cad, logs["without"], folder / "arm")
    saved.write_text(
        json.dumps({"logs": logs, "cad": str(cad), "arm": str(arm), "noise_floor": floor})
    )
    return raw, logs, cad, arm


def _cad_table(rows: list[dict], coverage_rows: dict[str, list] | None = None) -> None:
    """Print the ``--cad`` rows (and, with ``coverage_rows``, the share of seeds inside the
    95 % intervals per case: ``{case: [z (4,) per seed]}``)."""
    print("| case | arm from | mass error [%] (σ) | CoM error [mm] (σ) | residual [%] "
          "(floor) | σ factor | warning | time [s] |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for row in rows:
        s = row["summary"]
        floor = s["floor_relative_residual"]
        warn = "yes" if s["warnings"] else "no"
        floor_pct = "-" if floor is None else f"{100 * floor:.2f}"
        print(f"| {row['robot']} | {s['arm_from']} | {row['mass_error_pct']:+.2f} "
              f"({row['mass_std_pct']:.2f}) | {row['com_error_mm']:.1f} "
              f"({row['com_std_mm']:.1f}) | {100 * s['relative_residual']:.2f} ({floor_pct}) "
              f"| {s['interval_factor']:.1f} | {warn} | {row['seconds']:.1f} |",
              flush=True)  # fmt: skip
    if coverage_rows:
        print("\n| case | seeds | mass | CoM x | CoM y | CoM z | all | RMS error/σ |")
        print("|---|---|---|---|---|---|---|---|")
        for case, zs in coverage_rows.items():
            z = np.asarray(zs)
            inside = z <= 1.96
            cells = " | ".join(f"{100 * c:.0f} %" for c in inside.mean(axis=0))
            print(f"| {case} | {len(z)} | {cells} | {100 * inside.mean():.0f} % | "
                  f"{np.sqrt(np.mean(z**2)):.2f} |")  # fmt: skip


def cad_main(robots: list[str], n_seeds: int, seconds: float) -> int:
    """``--cad``: one table row per robot and mode; with ``n_seeds``, the coverage over that
    many noise seeds (the same motion). Exit 1 when a two-log or identified-arm case misses
    2 % / 5 mm, or a one-log CAD case misses them without a warning."""
    ok = True
    rows: list[dict] = []
    hits: dict[str, list] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in robots:
            config = REPO / "configs" / f"{name}.yaml"
            for k in range(max(1, n_seeds)):
                case = Path(tmp) / f"{name}-cad-{k}"
                found = run_cad_case(config, case, seconds=seconds, seed=1,
                                     noise_seed=k if n_seeds else None)  # fmt: skip
                for row in found:
                    hits.setdefault(row["robot"], []).append(row["z"])
                if k == 0:
                    rows += found
                    for row in found:
                        inside = abs(row["mass_error_pct"]) <= 2.0 and row["com_error_mm"] <= 5.0
                        ok &= inside or bool(row["summary"]["warnings"])
    _cad_table(rows, hits if n_seeds else None)
    return 0 if ok else 1


def seeds_main(
    robots: list[str],
    n_seeds: int,
    seconds: float,
    signs_mode: str,
    first: int = 0,
    workdir: Path | None = None,
) -> int:
    """``--seeds N``: the CAD cases (:func:`run_cad_case`, ``method: wls``) over ``N`` seeds
    from ``first``, each drawing its own motion and noise (and, with ``signs_mode`` ``random``,
    the sign of every link's CAD errors); the table of :func:`_seeds_table`. Exit 1 when a two-log
    or identified-arm case misses 2 % / 5 mm at any seed, or a one-log CAD case misses them
    without a warning. ``workdir``: the seeds' logs and identified arms are kept there (else
    in a temporary folder), and a seed found there is not simulated nor identified again."""
    cases: dict[str, list[dict]] = {}
    cpu: dict[str, list[float]] = {}
    ok = True
    with tempfile.TemporaryDirectory() as scratch:
        tmp = str(workdir.resolve() if workdir else scratch)  # the configs name absolute paths
        for k in range(first, first + n_seeds):  # the robots alternate: a cut-short run has both
            for name in robots:
                config = REPO / "configs" / f"{name}.yaml"
                n_bodies = load_robot(RobotSelection.model_validate(read_yaml(config)["robot"])
                                      .resolved(config.parent)).n_bodies  # fmt: skip
                signs = (np.random.default_rng(500 + k).choice([-1.0, 1.0], (n_bodies, 2))
                         if signs_mode == "random" else None)  # fmt: skip
                t0 = time.process_time()
                rows = run_cad_case(config, Path(tmp) / f"{name}-seed-{k}", seconds=seconds,
                                    seed=k, method="wls", signs=signs)  # fmt: skip
                cpu.setdefault(name, []).append(time.process_time() - t0)
                for row in rows:
                    cases.setdefault(row["robot"], []).append(row)
                    fields = ("robot", "mass_error_pct", "com_error_mm")
                    record = {**{f: row[f] for f in fields}, "seed": k, "z": row["z"].tolist(),
                              "warned": bool(row["summary"]["warnings"]),
                              "model_files": _model_files_written(row)}  # fmt: skip
                    print(json.dumps(record), file=sys.stderr, flush=True)  # per seed, to merge
                    inside = abs(row["mass_error_pct"]) <= 2.0 and row["com_error_mm"] <= 5.0
                    ok &= inside or bool(row["summary"]["warnings"])
                print(f"{name} seed {k}: {cpu[name][-1]:.0f} s CPU", file=sys.stderr, flush=True)
            _seeds_table(cases, cpu, seconds, signs_mode)  # so far (the last one is the result)
    return 0 if ok else 1


def _seeds_table(
    cases: dict[str, list[dict]], cpu: dict[str, list[float]], seconds: float, signs_mode: str
) -> None:
    """Per case: median and worst |mass error| [%] and CoM error [m m], the share of the
    reported 95 % intervals holding the truth (mass, each CoM component, and all four pooled:
    ``|error| <= 1.96 σ``, counted over seeds; the pooled count with its Wilson 95 % interval),
    the warning rate, the share of runs without model files and the CPU per seed."""
    errors = (
        "every link +10 % mass, +1 cm CoM in x"
        if signs_mode == "fixed"
        else ("every link +-10 % mass, +-1 cm CoM in x, signs drawn per link and seed")
    )
    print(
        f"CAD arm ({errors}), {CAD_PAYLOAD[0]} kg payload at CoM {CAD_PAYLOAD[1]} m, "
        f"{seconds:g} s logs, torque noise {_noise_line()}, method wls; seed k draws the "
        "motion and noise"
    )
    print("| case | seeds | mass error [%] median / worst | CoM error [mm] median / worst "
          "| 95 % coverage mass / CoM x / y / z / all | all: inside / intervals (Wilson 95 %) "
          "| RMS error/σ | warnings | no model files | target met |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    for case, rows in cases.items():
        mass = np.abs([r["mass_error_pct"] for r in rows])
        com = np.asarray([r["com_error_mm"] for r in rows])
        z = np.asarray([r["z"] for r in rows])  # (n_seeds, 4)
        inside = z <= 1.96
        cover = " / ".join(f"{100 * c:.0f}" for c in [*inside.mean(axis=0), inside.mean()])
        warned = np.mean([bool(r["summary"]["warnings"]) for r in rows])
        met = np.mean((mass <= 2.0) & (com <= 5.0))
        no_files = np.mean([not _model_files_written(r) for r in rows])
        lo, hi = wilson_interval(int(inside.sum()), inside.size)
        print(f"| {case} | {len(rows)} | {np.median(mass):.2f} / {mass.max():.2f} | "
              f"{np.median(com):.2f} / {com.max():.2f} | {cover} % | "
              f"{inside.sum()} / {inside.size} ({100 * lo:.0f}-{100 * hi:.0f} %) | "
              f"{np.sqrt(np.mean(z**2)):.2f} | {100 * warned:.0f} % | {100 * no_files:.0f} % | "
              f"{100 * met:.0f} % |")  # fmt: skip
    propagated = [r for rows in cases.values() for r in rows
                  if "is in the intervals" in r["summary"].get("arm_note", "")]  # fmt: skip
    print(f"identified arm's covariance propagated in {len(propagated)} cases")
    for name, seconds_cpu in cpu.items():
        print(
            f"{name}: CPU per seed (2 simulated logs, ident identify, 3 ident payload) "
            f"median {np.median(seconds_cpu):.1f} s, max {max(seconds_cpu):.1f} s"
        )


def _model_files_written(row: dict) -> bool:
    """Whether the run of ``row`` wrote its model files (``payload.json``'s ``model_files``;
    runs from before that entry wrote them or failed)."""
    return bool(row["summary"].get("model_files", {"written": True})["written"])


def _noise_line() -> str:
    """The simulated torque noise in words (:data:`noise_floors`, :data:`RELATIVE_NOISE`)."""
    floors = ", ".join(f"{k} {v:g} N*m" for k, v in noise_floors.items() if v > 0)
    relative = f"{100 * RELATIVE_NOISE:g} % of each joint's RMS torque"
    return f"{relative} and a floor ({floors}) in quadrature" if floors else relative


def wilson_interval(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a binomial share ``k / n`` (95 % by default): where the
    coverage lies given ``k`` of ``n`` intervals holding the truth (a calibrated 95 % interval
    over 80 independent draws: 76 expected, the spread sqrt(0.95 * 0.05 / 80) = 2.4 %)."""
    if n == 0:
        return 0.0, 1.0
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return float(centre - half), float(centre + half)


def normalized_errors(summary: dict, mass: float, com: tuple) -> dict:
    """Errors of the mass and of each centre-of-mass component over their standard deviation,
    by the reported σ (``std_method``) and by the ordinary σ: ``{method: (4,)}``; inside the
    95 % interval where ``|z| <= 1.96``."""
    error = np.abs(np.r_[summary["mass_kg"] - mass, np.asarray(summary["com_m"]) - com])
    reported = np.r_[summary["mass_std_kg"], summary["com_std_m"]]
    ordinary = np.r_[summary["ordinary_std"]["mass_kg"], summary["ordinary_std"]["com_m"]]
    return {summary["std_method"]: error / reported, "ordinary": error / ordinary}


def coverage(configs: list[Path], n_seeds: int, seconds: float, folder: Path) -> list[dict]:
    """95 % interval coverage of the 2.5 kg payload's mass and centre of mass over ``n_seeds``
    noise seeds (the same motion, both logs re-simulated): a row per robot."""
    mass, com, _ = payload = PAYLOADS[1]
    rows = []
    for config in configs:
        hits: dict[str, list] = {}
        t0 = time.perf_counter()
        for k in range(n_seeds):
            case = folder / f"{config.stem}-cov-{k}"
            row = run_case(config, payload, case, seconds=seconds, seed=1, noise_seed=k)
            for method, z in normalized_errors(row["summary"], mass, com).items():
                hits.setdefault(method, []).append(z)
        rows.append({
            "robot": config.stem,
            "n_seeds": n_seeds,
            "seconds": time.perf_counter() - t0,
            **{m: np.asarray(v) for m, v in hits.items()},
        })  # fmt: skip
    return rows


def _coverage_table(rows: list[dict], seconds: float) -> None:
    print(f"95 % interval coverage, 2.5 kg payload, 1 % torque noise, {seconds:g} s logs "
          "(designed: one 6 s log)")  # fmt: skip
    print("| robot | seeds | σ | mass | CoM x | CoM y | CoM z | all | RMS error/σ | time [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        for method in ("bootstrap", "ordinary"):
            if method in row:
                z = row[method]  # (n_seeds, 4)
                inside = z <= 1.96
                cells = " | ".join(f"{100 * c:.0f} %" for c in inside.mean(axis=0))
                print(f"| {row['robot']} | {row['n_seeds']} | {method} | {cells} | "
                      f"{100 * inside.mean():.0f} % | {np.sqrt(np.mean(z**2)):.2f} | "
                      f"{row['seconds']:.0f} |")  # fmt: skip


def designed_trajectory(folder: Path) -> tuple[np.ndarray, float]:
    """``ident run configs/ur5-payload.yaml``: its ``trajectory.csv`` table and wall time [s]."""
    config = REPO / "configs" / "ur5-payload.yaml"
    t0 = time.perf_counter()
    result = CliRunner().invoke(
        app, ["run", str(config), "--out", str(folder / "design"), "--no-replay"]
    )
    design_seconds = time.perf_counter() - t0
    if result.exit_code != 0:
        raise RuntimeError(result.output)
    (run,) = (folder / "design").iterdir()
    return np.loadtxt(run / "trajectory.csv", delimiter=",", skiprows=1), design_seconds


def run_designed_case(
    payload: tuple,
    folder: Path,
    *,
    seed: int,
    design: tuple[np.ndarray, float] | None = None,
) -> dict:
    """``ident run configs/ur5-payload.yaml`` -> one MuJoCo log with the payload -> ident payload.

    The payload's centre of mass is given in the flange frame ``tool0`` (inside the config's
    ``safety.payload_box``) and reported there (``payload.link: tool0``). ``design``: the
    :func:`designed_trajectory` already run (else it is run here).
    """
    config = REPO / "configs" / "ur5-payload.yaml"
    table, design_seconds = designed_trajectory(folder) if design is None else design
    raw = read_yaml(config)
    selection = RobotSelection.model_validate(raw["robot"]).resolved(config.parent)
    robot = load_robot(selection)
    nv = robot.nv
    t, q, dq, ddq = table[:, 0], *(table[:, 1 + k * nv : 1 + (k + 1) * nv] for k in range(3))
    mass, com_in_tool0, sides = payload
    tool0 = robot.model.frames[robot.model.getFrameId("tool0")]
    measurement = {k: v for k, v in read_yaml(REPO / "configs" / "ur5.yaml")["measurement"].items()
                   if k != "source"}  # fmt: skip
    rms = np.sqrt(np.mean(robot.rnea(q, dq, ddq) ** 2, axis=0))
    measurement.update(
        torque_noise_std=torque_noise_std(rms, noise_floors.get("ur5", 0.0)),
        settle_periods=0,
        n_periods=1,
        payload=payload_section(
            (mass, tool0.placement.act(np.asarray(com_in_tool0)).tolist(), sides)
        ),
    )
    sim = simulate(robot, t, q, dq, ddq, load_mujoco_measurement(measurement), rng=seed)
    files = write_log(folder / "with", sim)
    log = yaml.safe_load(files.yaml.read_text())["log"]
    for key in ("time", "position", "torque"):
        log[key]["path"] = str(folder / "with" / log[key]["path"])
    moving = [j + 1 for j in range(nv) if np.ptp(q[:, j]) > 0.0]
    preprocess = dict(read_yaml(REPO / "configs" / "ur5.yaml")["identification"]["preprocess"])
    preprocess["trim_samples"] = 300
    preprocess["velocity_threshold"] = [0.15 if j + 1 in moving else 0.0 for j in range(nv)]
    payload_cfg = {
        "name": "ur5-designed-payload",
        "robot": {"urdf": str(selection.urdf)},
        "log": log,
        "preprocess": preprocess,
        "model": {"viscous": moving, "coulomb": moving, "rotor_inertia": moving, "offset": False},
        "payload": {"link": "tool0", "method": "lmi", "arm": "model"},  # the arm is its URDF
    }
    summary, elapsed = ident_payload(folder, payload_cfg)
    label = f"ur5 designed, {len(moving)} joints {t[-1]:.0f} s, design {design_seconds:.0f} s"
    return result_row(label, mass, com_in_tool0, summary, elapsed)


#: The designed row's payload: (mass [kg], centre of mass in tool0's frame [m], box sides [m]).
DESIGNED = (2.5, (0.01, -0.015, 0.06), (0.10, 0.08, 0.12))


def designed_coverage(n_seeds: int, folder: Path) -> dict:
    """:func:`coverage` on the designed wrist-only case: one design, ``n_seeds`` noise seeds."""
    mass, com, _ = DESIGNED
    t0 = time.perf_counter()
    design = designed_trajectory(folder)
    hits: dict[str, list] = {}
    for k in range(n_seeds):
        row = run_designed_case(DESIGNED, folder / f"designed-{k}", seed=100 + k, design=design)
        for method, z in normalized_errors(row["summary"], mass, com).items():
            hits.setdefault(method, []).append(z)
    return {
        "robot": "ur5 designed",
        "n_seeds": n_seeds,
        "seconds": time.perf_counter() - t0,
        **{m: np.asarray(v) for m, v in hits.items()},
    }


def _row(row: dict) -> str:
    return (
        f"| {row['robot']} | {row['mass']:g} | {row['mass_error_pct']:+.3f} "
        f"({row['mass_std_pct']:.3f}) | {row['com_error_mm']:.3f} "
        f"({row['com_std_mm']:.3f}) | {row['seconds']:.1f} |"
    )


def main(argv: list[str] | None = None) -> int:
    """Print the table; exit 1 when a case misses the target (2 % mass, 5 mm centre of mass)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="UR5 and one payload only")
    parser.add_argument("--seconds", type=float, default=20.0, help="logged seconds per log")
    parser.add_argument(
        "--coverage",
        type=int,
        default=0,
        metavar="N",
        help="instead: 95 %% interval coverage over N noise seeds (of --robots)",
    )
    parser.add_argument(
        "--robots",
        default="ur5",
        help="--coverage's cases, comma-separated: ur5, panda (two logs, every joint moving), "
        "designed (the wrist-only payload excitation, one 6 s log)",
    )
    parser.add_argument(
        "--cad",
        action="store_true",
        help="the arm handed to ident payload is a CAD URDF (masses +10 %%, centres of mass "
        "+1 cm): two logs, one log + identified arm, one log + CAD (--robots ur5,panda)",
    )
    parser.add_argument(
        "--seeds",
        type=int,
        default=0,
        metavar="N",
        help="the CAD cases (--robots ur5,panda) over N seeds: errors, coverage, warnings",
    )
    parser.add_argument(
        "--cad-signs",
        choices=("fixed", "random"),
        default="fixed",
        help="--seeds: every link's CAD error +10 %% / +1 cm (fixed) or of random sign per link",
    )
    parser.add_argument("--first-seed", type=int, default=0, help="--seeds: the first seed")
    parser.add_argument(
        "--noise",
        choices=("floor", "relative"),
        default="floor",
        help="simulated torque noise: 1 %% of each joint's RMS torque and an absolute floor per "
        "robot in quadrature (floor: ur5 0.1, panda 0.005 N*m), or the 1 %% alone (relative: "
        "the benchmark's noise before the floor)",
    )
    parser.add_argument(
        "--noise-floor",
        type=float,
        default=None,
        metavar="NM",
        help="--noise floor: this floor [N*m] for every robot instead of the per-robot ones",
    )
    parser.add_argument(
        "--workdir",
        type=Path,
        default=None,
        help="--seeds: keep the simulated logs and identified arms here; a seed already there "
        "is reused (only ident payload runs again)",
    )
    args = parser.parse_args(argv)
    for name in noise_floors:  # the module's noise model for every case below
        floor = TORQUE_NOISE_FLOOR[name] if args.noise_floor is None else args.noise_floor
        noise_floors[name] = floor if args.noise == "floor" else 0.0
    if args.seeds > 0:
        robots = [r.strip() for r in args.robots.split(",")]
        return seeds_main(robots, args.seeds, args.seconds, args.cad_signs, args.first_seed,
                          args.workdir)  # fmt: skip
    if args.cad:
        return cad_main([r.strip() for r in args.robots.split(",")], args.coverage, args.seconds)
    if args.coverage > 0:
        names = [name.strip() for name in args.robots.split(",")]
        configs = [REPO / "configs" / f"{name}.yaml" for name in names if name != "designed"]
        with tempfile.TemporaryDirectory() as tmp:
            rows = coverage(configs, args.coverage, args.seconds, Path(tmp))
            if "designed" in names:
                rows.append(designed_coverage(args.coverage, Path(tmp) / "designed"))
            _coverage_table(rows, args.seconds)
        return 0
    configs = [REPO / "configs" / "ur5.yaml"]
    payloads = PAYLOADS[1:2] if args.quick else PAYLOADS
    if not args.quick:
        configs.append(REPO / "configs" / "panda.yaml")
    print("| robot | payload [kg] | mass error [%] (1 std) | CoM error [mm] (1 std) | time [s] |")
    print("|---|---|---|---|---|")
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        for config in configs:
            for k, payload in enumerate(payloads):
                folder = Path(tmp) / f"{config.stem}-{k}"
                row = run_case(config, payload, folder, seconds=args.seconds, seed=k)
                ok &= abs(row["mass_error_pct"]) <= 2.0 and row["com_error_mm"] <= 5.0
                print(_row(row), flush=True)
        # the payload excitation: wrist only, designed for the payload, one log
        row = run_designed_case(DESIGNED, Path(tmp) / "designed", seed=11)
        ok &= abs(row["mass_error_pct"]) <= 2.0 and row["com_error_mm"] <= 5.0
        print(_row(row), flush=True)
    print("target met (mass within 2 %, CoM within 5 mm)" if ok else "TARGET MISSED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
