"""Write the hostile-input corpus of ``tests/test_hostile_cli.py`` (run from the repository root).

``python tests/data/hostile/generate.py`` rewrites every file of this folder from the tables
below, and ``manifest.yaml``: one entry per case with the command line that runs it
(``{data}`` is this folder, ``{tmp}`` an empty working folder that must stay empty) and
``isolate: true`` for the cases that run in a subprocess under memory and CPU limits.
Every case must end with exit code 2, one ``error:`` line and nothing written.
"""

from __future__ import annotations

import gzip
import json
import math
import shutil
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
PAPER_ROBOT = "../../../../configs/paper6r.yaml"  # from a file in HERE/<sub>/


# ---------------------------------------------------------------------------------------------
# Hostile YAML texts, applied to every command that reads a YAML config.

BOMB = "\n".join(
    [
        'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]',
        *(
            f"{c}: &{c} [" + ",".join([f"*{p}"] * 9) + "]"
            for p, c in zip("abcdefgh", "bcdefghi", strict=True)
        ),
    ]
)
GENERIC_YAML: dict[str, bytes] = {
    "bomb": BOMB.encode(),
    "bomb_merge": (
        "a: &a {x0: 1, x1: 1, x2: 1, x3: 1, x4: 1, x5: 1, x6: 1, x7: 1}\n"
        + "".join(
            f"{c}: &{c} [" + ",".join([f"*{p}"] * 10) + "]\n"
            for p, c in zip("abcde", "bcdef", strict=True)
        )
    ).encode(),
    "many_aliases": ("a: &a 1\nb: [" + ",".join(["*a"] * 500) + "]\n").encode(),
    "cyclic_alias": b"a: &a [1, *a]\nb: *a\n",
    "deep_flow": ("a: " + "[" * 3000 + "]" * 3000 + "\n").encode(),
    "deep_block": "".join(f"{'  ' * k}k{k}:\n" for k in range(200)).encode() + b"  " * 200 + b"v\n",
    "deep_mapping_flow": ("a: " + "{b: " * 2000 + "1" + "}" * 2000 + "\n").encode(),
    "int_5000_digits": ("name: x\nseed: " + "9" * 5000 + "\n").encode(),
    "int_hex_huge": ("seed: 0x" + "f" * 400 + "\n").encode(),
    "float_overflow": b"seed: 1.0e+999\n",
    "nan_value": b"seed: .nan\n",
    "inf_value": b"seed: -.inf\n",
    "binary": bytes(range(256)) * 4,
    "latin1": "name: caf\u00e9\nseed: 1\n".encode("latin-1"),
    "utf16": "name: x\nseed: 1\n".encode("utf-16"),
    "empty": b"",
    "only_comment": b"# nothing\n",
    "top_list": b"- 1\n- 2\n",
    "top_scalar": b"just a string\n",
    "duplicate_key": b"name: a\nname: b\n",
    "duplicate_nested": b"x:\n  y: 1\n  y: 2\n",
    "tabs": b"a:\n\t- 1\n",
    "unclosed": b"a: [1, 2\n",
    "python_tag": b"a: !!python/object/apply:os.system ['true']\n",
    "huge_key": ("k" * 50_000 + ": 1\n").encode(),
    "control_chars": b"name: \x07\x1b[31mred\n",
}
# Commands whose config takes the generic set: the config path is the first argument.
YAML_COMMANDS = {
    "run": ["run", "{case}", "--out", "{tmp}/runs"],
    "identify": ["identify", "{case}", "--out", "{tmp}/runs"],
    "urdf": ["urdf", "{case}", "-o", "{tmp}/robot.urdf"],
    "bench": ["bench", "{case}", "--out", "{tmp}/campaign", "--no-progress"],
}
RESOURCE_CASES = {"bomb", "bomb_merge", "deep_flow", "deep_mapping_flow", "int_5000_digits"}

# ---------------------------------------------------------------------------------------------
# Valid base inputs that single cases break.

RUN_BASE = f"""robot: {PAPER_ROBOT}
stage: wrist
seed: 3
excitation:
  family: joint_fourier
  n_samples: 100
  options: {{n_harmonics: 3, amplitude_bound: 0.3}}
elites: {{n_particles: 6, n_elites: 2, maxiter: 4}}
emupso: {{n_particles: 8, maxiter: 2, stagnation: 3, n_runs: 1, n_report_elites: 1}}
measurement: {{torque_noise_std: 0.0}}
"""
RUN_CASES: dict[str, tuple[str, str] | str] = {
    # name: text, or (text, xfail reason)
    "n_samples_1e9": RUN_BASE.replace("n_samples: 100", "n_samples: 1000000000"),
    "n_samples_float": RUN_BASE.replace("n_samples: 100", "n_samples: 1e9"),
    "maxiter_huge": RUN_BASE.replace("maxiter: 2,", "maxiter: 100000000,"),
    "particles_huge": RUN_BASE.replace("n_particles: 8,", "n_particles: 10000000,"),
    "n_runs_huge": RUN_BASE.replace("n_runs: 1,", "n_runs: 100000000,"),
    "emupso_c1_nan_string": RUN_BASE.replace(
        "n_report_elites: 1}", "n_report_elites: 1, options: {c1: nan}}"
    ),
    "emupso_c1_string": RUN_BASE.replace(
        "n_report_elites: 1}", "n_report_elites: 1, options: {c1: fast}}"
    ),
    "emupso_unknown_option": RUN_BASE.replace(
        "n_report_elites: 1}", "n_report_elites: 1, options: {c7: 1.0}}"
    ),
    "quick_bad_option": RUN_BASE + "quick: {emupso: {options: {c1: [1, 2]}}}\n",
    "excitation_bad_option": RUN_BASE.replace(
        "amplitude_bound: 0.3", "amplitude_bound: 0.3, nonsense: 1"
    ),
    "excitation_option_string": RUN_BASE.replace("n_harmonics: 3", "n_harmonics: lots"),
    "noise_wrong_length": RUN_BASE.replace("torque_noise_std: 0.0", "torque_noise_std: [0.1, 0.2]"),
    "cutoff_above_nyquist": RUN_BASE.replace(
        "torque_noise_std: 0.0", "torque_noise_std: 0.1, filter_cutoff_hz: 100000.0"
    ),
    "encoder_counts_huge": RUN_BASE.replace(
        "torque_noise_std: 0.0", "torque_noise_std: 0.0, encoder_counts_per_rev: " + "9" * 30
    ),
    "harmonics_huge": RUN_BASE.replace("n_harmonics: 3", "n_harmonics: 1000000000"),
    "amplitude_nan": RUN_BASE.replace("amplitude_bound: 0.3", "amplitude_bound: .nan"),
    "noise_negative": RUN_BASE.replace("torque_noise_std: 0.0", "torque_noise_std: -1.0"),
    "noise_nan_string": RUN_BASE.replace("torque_noise_std: 0.0", "torque_noise_std: nan"),
    "sigma_inf_string": RUN_BASE.replace("n_runs: 1,", "n_runs: 1, sigma_fraction: inf,"),
    "seed_negative": RUN_BASE.replace("seed: 3", "seed: -1"),
    "stage_unknown": RUN_BASE.replace("stage: wrist", "stage: elbow"),
    "robot_missing": RUN_BASE.replace(PAPER_ROBOT, "nowhere.yaml"),
    "robot_traversal_dir": RUN_BASE.replace(PAPER_ROBOT, "../../../../"),
    "robot_binary": RUN_BASE.replace(PAPER_ROBOT, "../yaml/binary.yaml"),
    "robot_zero_joint_urdf": RUN_BASE.replace(PAPER_ROBOT, "../urdf/zero_joints.urdf"),
    "robot_three_joint_urdf": RUN_BASE.replace(PAPER_ROBOT, "../urdf/three_joints.urdf"),
    "robot_thirty_joint_urdf": RUN_BASE.replace(PAPER_ROBOT, "../urdf/thirty_joints.urdf"),
    "robot_dtd_urdf": RUN_BASE.replace(PAPER_ROBOT, "../urdf/dtd_entity.urdf"),
    "name_traversal_and_bad_key": RUN_BASE + "name: ../../escape\nsed: 1\n",
    "unknown_section": RUN_BASE + "filters: {}\n",
    "bounds_inverted": RUN_BASE.replace(
        "options: {n_harmonics", "bounds: {a_1_1: [1.0, -1.0]}\n  options: {n_harmonics"
    ),
}
RUN_FLAG_CASES: dict[str, list[str] | tuple[list[str], str]] = {
    "seed_flag_negative": ["run", "{data}/run/base.yaml", "--seed", "-1", "--out", "{tmp}/runs"],
    "seed_flag_text": ["run", "{data}/run/base.yaml", "--seed", "abc", "--out", "{tmp}/runs"],
    "out_is_file": ["run", "{data}/run/base.yaml", "--out", "{data}/run/base.yaml"],
    "out_under_proc": ["run", "{data}/run/base.yaml", "--out", "/proc/ident-runs"],
    "config_is_dir": ["run", "{data}/run", "--out", "{tmp}/runs"],
    "config_missing": ["run", "{data}/run/nope.yaml", "--out", "{tmp}/runs"],
}

# identify: a 2-joint log of rp2.urdf
IDENTIFY_BASE = """name: hostile
robot: {urdf: ../base/rp2.urdf}
log:
  sampling_rate_hz: 100.0
  position: {path: ../base/q.csv}
  torque: {path: ../base/tau.csv}
validation: {identify_fraction: 0.7}
"""
IDENTIFY_CASES: dict[str, tuple[str, str] | str] = {
    "rate_inf_string": IDENTIFY_BASE.replace("sampling_rate_hz: 100.0", "sampling_rate_hz: inf"),
    "rate_zero": IDENTIFY_BASE.replace("sampling_rate_hz: 100.0", "sampling_rate_hz: 0"),
    "rate_huge_int": IDENTIFY_BASE.replace(
        "sampling_rate_hz: 100.0", "sampling_rate_hz: " + "9" * 400
    ),
    "empty_delimiter": IDENTIFY_BASE.replace(
        "{path: ../base/q.csv}", "{path: ../base/q.csv, delimiter: ''}"
    ),
    "log_binary": IDENTIFY_BASE.replace("../base/q.csv", "../base/binary.csv"),
    "log_latin1": IDENTIFY_BASE.replace("../base/q.csv", "../base/latin1.csv"),
    "log_damaged_gzip": IDENTIFY_BASE.replace("../base/q.csv", "../base/damaged.csv.gz"),
    "log_not_gzip": IDENTIFY_BASE.replace("../base/q.csv", "../base/plain_named.csv.gz"),
    "log_missing": IDENTIFY_BASE.replace("../base/q.csv", "../base/nope.csv"),
    "log_is_dir": IDENTIFY_BASE.replace("../base/q.csv", "../base"),
    "log_nan": IDENTIFY_BASE.replace("../base/q.csv", "../base/nan.csv"),
    "log_header_only": IDENTIFY_BASE.replace("../base/q.csv", "../base/header_only.csv"),
    "log_ragged": IDENTIFY_BASE.replace("../base/q.csv", "../base/ragged.csv"),
    "urdf_dtd": IDENTIFY_BASE.replace("../base/rp2.urdf", "../urdf/dtd_entity.urdf"),
    "urdf_binary": IDENTIFY_BASE.replace("../base/rp2.urdf", "../yaml/binary.yaml"),
    "urdf_zero_joints": IDENTIFY_BASE.replace("../base/rp2.urdf", "../urdf/zero_joints.urdf"),
    "urdf_thirty_joints": IDENTIFY_BASE.replace("../base/rp2.urdf", "../urdf/thirty_joints.urdf"),
    "fraction_nan": IDENTIFY_BASE.replace("identify_fraction: 0.7", "identify_fraction: nan"),
    "fraction_zero": IDENTIFY_BASE.replace("identify_fraction: 0.7", "identify_fraction: 0"),
    "max_samples_negative": IDENTIFY_BASE.replace(
        "sampling_rate_hz: 100.0", "sampling_rate_hz: 100.0\n  max_samples: -5"
    ),
    "lowpass_above_nyquist": IDENTIFY_BASE + "preprocess: {lowpass: {cutoff_hz: 400.0}}\n",
    "gear_ratio_string": IDENTIFY_BASE + "transmission: {gear_ratios: [x, y]}\n",
    "unknown_key": IDENTIFY_BASE + "estimaton: {method: ols}\n",
    "decimation_huge": IDENTIFY_BASE + "preprocess: {decimation: [1000000]}\n",
    "gear_ratios_zero": IDENTIFY_BASE + "transmission: {gear_ratios: [0, 0]}\n",
    "gear_ratios_wrong_length": IDENTIFY_BASE + "transmission: {gear_ratios: [1, 2, 3]}\n",
    "velocity_threshold_nan": IDENTIFY_BASE + "preprocess: {velocity_threshold: [nan, 1]}\n",
    "trim_all_samples": IDENTIFY_BASE + "preprocess: {trim_samples: 1000000}\n",
    "columns_missing": IDENTIFY_BASE.replace(
        "{path: ../base/q.csv}", "{path: ../base/q.csv, columns: [a, b]}"
    ),
}
IDENTIFY_FLAG_CASES = {
    "seed_negative": ["identify", "{data}/identify/base.yaml", "--seed", "-1", "--out", "{tmp}/r"],
    "out_under_proc": ["identify", "{data}/identify/base.yaml", "--out", "/proc/ident"],
    "out_is_file": ["identify", "{data}/identify/base.yaml", "--out", "{data}/base/rp2.urdf"],
    "package_dir_missing": [
        "identify",
        "{data}/identify/base.yaml",
        "--package-dir",
        "{data}/nope",
        "--out",
        "{tmp}/r",
    ],
}

URDF_BASE = (ROOT / "tests/data/robots/planar2r.yaml").read_text()
URDF_CASES: dict[str, tuple[str, str] | str] = {
    "limit_inf_string": URDF_BASE.replace("upper: 2.5, velocity: 3.0", "upper: inf, velocity: 3.0"),
    "limit_1e400": URDF_BASE.replace("upper: 2.5, velocity: 3.0", "upper: 1e400, velocity: 3.0"),
    "mass_nan_string": URDF_BASE.replace("mass: 2.0", "mass: nan"),
    "mass_string": URDF_BASE.replace("mass: 2.0", "mass: heavy"),
    "dh_row_huge": URDF_BASE.replace("[0.4, 0.0, 0.0, 0.0]", "[1e308, 0.0, 0.0, 0.0]"),
    "thirty_rows_two_joints": URDF_BASE.replace(
        "    - [0.3, 0.0, 0.0, 0.0]\n", "    - [0.3, 0.0, 0.0, 0.0]\n" * 30
    ),
    "no_joints": URDF_BASE.split("joints:")[0] + "joints: []\nlinks: []\n",
    "units_unknown": URDF_BASE.replace("length: m", "length: furlong"),
    "gravity_nan": URDF_BASE.replace("[0.0, -9.81, 0.0]", "[0.0, nan, 0.0]"),
    "duplicate_joint_key": URDF_BASE.replace(
        "{name: shoulder, lower", "{name: shoulder, name: elbow, lower"
    ),
}
URDF_FLAG_CASES = {
    "output_under_proc": ["urdf", "{data}/urdf/base.yaml", "-o", "/proc/ident.urdf"],
    "output_is_dir": ["urdf", "{data}/urdf/base.yaml", "-o", "{tmp}"],
    "output_parent_is_file": [
        "urdf",
        "{data}/urdf/base.yaml",
        "-o",
        "{data}/urdf/base.yaml/x.urdf",
    ],
}

BENCH_BASE = """name: hostile
seed: 1
runs: 2
popsize: 10
max_nfev: 100
methods: [pso]
functions: [sphere]
curve_points: 5
"""
BENCH_CASES: dict[str, tuple[str, str] | str] = {
    "runs_huge": BENCH_BASE.replace("runs: 2", "runs: 100000000"),
    "popsize_huge": BENCH_BASE.replace("popsize: 10", "popsize: 1000000000"),
    "max_nfev_huge": BENCH_BASE.replace("max_nfev: 100", "max_nfev: 900000000"),
    "max_nfev_too_long": BENCH_BASE.replace("runs: 2", "runs: 1000")
    .replace("max_nfev: 100", "max_nfev: 100000000")
    .replace("popsize: 10", "popsize: 4"),
    "curve_points_huge": BENCH_BASE.replace("curve_points: 5", "curve_points: 1000000000"),
    "c1_nan": BENCH_BASE + "method_options: {pso: {c1: .nan}}\n",
    "c1_nan_string": BENCH_BASE + "method_options: {pso: {c1: nan}}\n",
    "c1_string": BENCH_BASE + "method_options: {pso: {c1: fast}}\n",
    "c1_list": BENCH_BASE + "method_options: {pso: {c1: [1, 2]}}\n",
    "c1_bool": BENCH_BASE + "method_options: {pso: {c1: true}}\n",
    "option_unknown": BENCH_BASE + "method_options: {pso: {c9: 1}}\n",
    "option_other_method": BENCH_BASE + "method_options: {de: {F: 0.5}}\n",
    "method_unknown": BENCH_BASE.replace("methods: [pso]", "methods: [psoo]"),
    "function_unknown": BENCH_BASE.replace("functions: [sphere]", "functions: [../../etc]"),
    "alpha_nan_string": BENCH_BASE + "alpha: nan\n",
    "name_list": BENCH_BASE.replace("name: hostile", "name: [a, b]"),
    "name_traversal_with_error": BENCH_BASE.replace("name: hostile", "name: ../../x") + "runs: 3\n",
}
BENCH_FLAG_CASES = {
    "workers_1000": ["bench", "{data}/bench/base.yaml", "--workers", "1000", "--out", "{tmp}/c"],
    "workers_zero": ["bench", "{data}/bench/base.yaml", "--workers", "0", "--out", "{tmp}/c"],
    "workers_negative": ["bench", "{data}/bench/base.yaml", "--workers", "-3", "--out", "{tmp}/c"],
    "out_under_proc": ["bench", "{data}/bench/base.yaml", "--out", "/proc/ident-bench"],
    "out_is_file": ["bench", "{data}/bench/base.yaml", "--out", "{data}/bench/base.yaml"],
    "out_not_empty": ["bench", "{data}/bench/base.yaml", "--out", "{data}/bench"],
}

VERIFY_CASES: dict[str, list[str] | tuple[list[str], str]] = {
    "tolerance_nan": ["--urdf", "{data}/base/rp2.urdf", "--tolerance", "nan"],
    "tolerance_negative": ["--urdf", "{data}/base/rp2.urdf", "--tolerance", "-1"],
    "tolerance_inf": ["--urdf", "{data}/base/rp2.urdf", "--tolerance", "inf"],
    "samples_zero": ["--urdf", "{data}/base/rp2.urdf", "--samples", "0"],
    "samples_huge": ["--urdf", "{data}/base/rp2.urdf", "--samples", "1000000000"],
    "samples_text": ["--urdf", "{data}/base/rp2.urdf", "--samples", "many"],
    "seed_negative": ["--urdf", "{data}/base/rp2.urdf", "--seed", "-1"],
    "seed_huge": ["--urdf", "{data}/base/rp2.urdf", "--seed", "9" * 40],
    "unknown_option": ["--urdf", "{data}/base/rp2.urdf", "--colour"],
    "lock_nan": ["--urdf", "{data}/base/rp2.urdf", "--lock", "slider=nan"],
    "lock_unknown": ["--urdf", "{data}/base/rp2.urdf", "--lock", "elbow=0"],
    "urdf_binary": ["--urdf", "{data}/yaml/binary.yaml"],
    "urdf_latin1": ["--urdf", "{data}/urdf/latin1.urdf"],
    "urdf_dtd": ["--urdf", "{data}/urdf/dtd_entity.urdf"],
    "urdf_external_entity": ["--urdf", "{data}/urdf/external_entity.urdf"],
    "urdf_zero_joints": ["--urdf", "{data}/urdf/zero_joints.urdf"],
    "urdf_truncated": ["--urdf", "{data}/urdf/truncated.urdf"],
    "urdf_not_robot": ["--urdf", "{data}/urdf/not_robot.urdf"],
    "urdf_inf_limit": ["--urdf", "{data}/urdf/inf_limit.urdf"],
    "urdf_dir": ["--urdf", "{data}/urdf"],
    "urdf_missing": ["--urdf", "{data}/urdf/nope.urdf"],
    "robot_bomb": ["--robot", "{data}/yaml/bomb.yaml"],
    "robot_300_joints": ["--robot", "{data}/urdf/many_joints.yaml"],  # above the job ceilings
    "robot_and_urdf": ["--robot", "{data}/urdf/base.yaml", "--urdf", "{data}/base/rp2.urdf"],
    "neither": [],
}

REPLAY_CASES: dict[str, list[str] | tuple[list[str], str]] = {
    "speed_tiny": ["{data}/runfolder/good", "--speed", "1e-6", "--html", "{tmp}/r.html"],
    "speed_nan": ["{data}/runfolder/good", "--speed", "nan", "--html", "{tmp}/r.html"],
    "speed_negative": ["{data}/runfolder/good", "--speed", "-1", "--html", "{tmp}/r.html"],
    "speed_inf": ["{data}/runfolder/good", "--speed", "inf", "--html", "{tmp}/r.html"],
    "port_negative": ["{data}/runfolder/good", "--port", "-1"],
    "port_huge": ["{data}/runfolder/good", "--port", "70000"],
    "html_under_proc": ["{data}/runfolder/good", "--html", "/proc/ident.html"],
    "html_is_dir": ["{data}/runfolder/good", "--html", "{tmp}"],
    "result_json_list": ["{data}/runfolder/result_list", "--html", "{tmp}/r.html"],
    "result_json_binary": ["{data}/runfolder/result_binary", "--html", "{tmp}/r.html"],
    "result_json_deep": ["{data}/runfolder/result_deep", "--html", "{tmp}/r.html"],
    "no_trajectory": ["{data}/runfolder/no_trajectory", "--html", "{tmp}/r.html"],
    "not_a_folder": ["{data}/base/rp2.urdf", "--html", "{tmp}/r.html"],
    "trajectory_binary": [
        "--urdf",
        "{data}/base/rp2.urdf",
        "--trajectory",
        "{data}/base/binary.csv",
        "--html",
        "{tmp}/r.html",
    ],
    "trajectory_latin1": [
        "--urdf",
        "{data}/base/rp2.urdf",
        "--trajectory",
        "{data}/base/latin1.csv",
        "--html",
        "{tmp}/r.html",
    ],
    "trajectory_long_span": [
        "--urdf",
        "{data}/base/rp2.urdf",
        "--trajectory",
        "{data}/base/long_span.csv",
        "--html",
        "{tmp}/r.html",
    ],
    "trajectory_nan": [
        "--urdf",
        "{data}/base/rp2.urdf",
        "--trajectory",
        "{data}/base/traj_nan.csv",
        "--html",
        "{tmp}/r.html",
    ],
    "trajectory_header_only": [
        "--urdf",
        "{data}/base/rp2.urdf",
        "--trajectory",
        "{data}/base/header_only.csv",
        "--html",
        "{tmp}/r.html",
    ],
    "trajectory_wrong_joints": [
        "--urdf",
        "{data}/base/rp2.urdf",
        "--trajectory",
        "{data}/base/traj_wrong_joints.csv",
        "--html",
        "{tmp}/r.html",
    ],
    "urdf_dtd": [
        "--urdf",
        "{data}/urdf/dtd_entity.urdf",
        "--trajectory",
        "{data}/base/traj.csv",
        "--html",
        "{tmp}/r.html",
    ],
    "urdf_binary": [
        "--urdf",
        "{data}/yaml/binary.yaml",
        "--trajectory",
        "{data}/base/traj.csv",
        "--html",
        "{tmp}/r.html",
    ],
    "only_urdf": ["--urdf", "{data}/base/rp2.urdf"],
}

REPORT_CASES: dict[str, list[str] | tuple[list[str], str]] = {
    "run_json_list": ["{data}/runfolder/run_json_list"],
    "run_json_binary": ["{data}/runfolder/run_json_binary"],
    "run_json_latin1": ["{data}/runfolder/run_json_latin1"],
    "no_run_json": ["{data}/runfolder/no_trajectory_no_state"],
    "not_a_folder": ["{data}/base/rp2.urdf"],
    "missing": ["{data}/runfolder/nope"],
    "result_json_list": ["{data}/runfolder/result_list"],
    "result_json_missing_keys": ["{data}/runfolder/result_missing_keys"],
}


def _urdf_chain(n: int, *, dtd: str = "", extra: str = "", name: str = "chain") -> str:
    links = ['  <link name="l0"/>']
    joints = []
    for k in range(1, n + 1):
        links.append(
            f'  <link name="l{k}"><inertial><mass value="1.0"/>'
            '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'
            "</inertial></link>"
        )
        joints.append(
            f'  <joint name="j{k}" type="revolute"><parent link="l{k - 1}"/>'
            f'<child link="l{k}"/><origin xyz="0 0 0.1"/><axis xyz="0 {k % 2} {(k + 1) % 2}"/>'
            f'<limit lower="-1" upper="1" velocity="1" effort="10"/></joint>'
        )
    return (
        '<?xml version="1.0"?>\n'
        + dtd
        + f'<robot name="{name}">\n'
        + "\n".join(links + joints)
        + extra
        + "\n</robot>\n"
    )


def _write(path: Path, data: str | bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, str):
        data = data.encode("utf-8")
    path.write_bytes(data)


def _csv(header: list[str], rows: list[list[float]]) -> str:
    return ",".join(header) + "\n" + "".join(",".join(repr(v) for v in r) + "\n" for r in rows)


def _base_files() -> None:
    base = HERE / "base"
    _write(base / "rp2.urdf", (ROOT / "tests/data/urdf/rp2.urdf").read_bytes())
    n = 200
    t = [k / 100.0 for k in range(n)]
    q = [[0.5 * math.sin(2 * s), 0.1 * math.sin(3 * s)] for s in t]
    tau = [[3.0 * math.cos(2 * s), 9.0 + math.sin(3 * s)] for s in t]
    _write(base / "q.csv", _csv(["shoulder", "slider"], q))
    _write(base / "tau.csv", _csv(["shoulder", "slider"], tau))
    _write(base / "nan.csv", _csv(["shoulder", "slider"], q).replace("0.0,", "nan,", 1))
    _write(base / "header_only.csv", "shoulder,slider\n")
    _write(base / "ragged.csv", "shoulder,slider\n1.0,2.0\n3.0\n4.0,5.0,6.0\n")
    _write(base / "binary.csv", bytes(range(256)) * 8)
    _write(base / "latin1.csv", "shoulder,slid\u00e9r\n1.0,2.0\n3.0,4.0\n".encode("latin-1"))
    good_gz = gzip.compress(_csv(["shoulder", "slider"], q).encode(), mtime=0)
    _write(base / "damaged.csv.gz", good_gz[: len(good_gz) // 2] + b"\x00garbage" * 10)
    _write(base / "plain_named.csv.gz", _csv(["shoulder", "slider"], q))
    traj = _csv(["t", "q_shoulder", "q_slider"], [[s, *qq] for s, qq in zip(t, q, strict=True)])
    _write(base / "traj.csv", traj)
    _write(base / "traj_nan.csv", traj.replace("0.0,", "nan,", 1))
    _write(base / "traj_wrong_joints.csv", traj.replace("q_shoulder", "q_elbow", 1))
    _write(base / "long_span.csv", "t,q_shoulder,q_slider\n0.0,0.0,0.0\n1.0e7,0.1,0.1\n")


def _urdf_files() -> None:
    d = HERE / "urdf"
    _write(d / "zero_joints.urdf", _urdf_chain(0))
    _write(d / "three_joints.urdf", _urdf_chain(3))
    _write(d / "thirty_joints.urdf", _urdf_chain(30))
    _write(
        d / "dtd_entity.urdf",
        _urdf_chain(2, dtd='<!DOCTYPE robot [<!ENTITY m "1.0">]>\n').replace(
            'mass value="1.0"', 'mass value="&m;"'
        ),
    )
    _write(
        d / "external_entity.urdf",
        _urdf_chain(2, dtd='<!DOCTYPE robot [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n').replace(
            'name="l0"', 'name="&x;"'
        ),
    )
    _write(d / "latin1.urdf", _urdf_chain(2, name="caf\u00e9").encode("latin-1"))
    _write(d / "truncated.urdf", _urdf_chain(2)[:300])
    _write(d / "not_robot.urdf", '<?xml version="1.0"?>\n<html><body/></html>\n')
    _write(d / "inf_limit.urdf", _urdf_chain(2).replace('upper="1"', 'upper="inf"'))
    _write(d / "base.yaml", URDF_BASE)
    n = 300
    _write(
        d / "many_joints.yaml",
        "name: many\nunits: {length: m, angle: rad, mass: kg}\n"
        "dh:\n  convention: standard\n  columns: [a, d, alpha, theta]\n  rows:\n"
        + "    - [0.1, 0.0, 0.0, 0.0]\n" * n
        + "joints:\n"
        + "".join(
            f"  - {{name: j{k}, lower: -1.0, upper: 1.0, velocity: 1.0, acceleration: 1.0}}\n"
            for k in range(n)
        )
        + "links:\n"
        + "  - {mass: 1.0, com: [0.0, 0.0, 0.0], inertia_com: {xx: 0.01, yy: 0.01, zz: 0.01}}\n"
        * n,
    )


def _run_folders() -> None:
    d = HERE / "runfolder"
    good = d / "good"
    _write(good / "robot.urdf", (HERE / "base/rp2.urdf").read_text())
    _write(good / "trajectory.csv", (HERE / "base/traj.csv").read_text())
    _write(good / "run.json", json.dumps({"status": "complete"}) + "\n")
    for name, result in {
        "result_list": "[1, 2, 3]\n",
        "result_binary": bytes(range(256)),
        "result_deep": "[" * 20_000 + "]" * 20_000,
        "result_missing_keys": "{}\n",
    }.items():
        shutil.copytree(good, d / name, dirs_exist_ok=True)
        _write(d / name / "result.json", result)
    for name, state in {
        "run_json_list": "[]\n",
        "run_json_binary": bytes(range(256)),
        "run_json_latin1": '{"status": "compl\u00e9te"}'.encode("latin-1"),
    }.items():
        shutil.copytree(good, d / name, dirs_exist_ok=True)
        _write(d / name / "run.json", state)
    _write(d / "no_trajectory" / "robot.urdf", (HERE / "base/rp2.urdf").read_text())
    _write(d / "no_trajectory" / "run.json", json.dumps({"status": "complete"}) + "\n")
    _write(d / "no_trajectory_no_state" / "robot.urdf", (HERE / "base/rp2.urdf").read_text())


def _log_cases() -> list[dict]:
    """Readers and time stamps (logs/generate_logs.py writes those files)."""
    import runpy

    return runpy.run_path(str(HERE / "logs" / "generate_logs.py"))["cases"]()


def main() -> None:
    for sub in ("base", "urdf", "runfolder", "yaml", "run", "identify", "bench"):
        shutil.rmtree(HERE / sub, ignore_errors=True)
    _base_files()
    _urdf_files()
    _run_folders()
    cases: list[dict] = []

    def add(case_id: str, args: list[str], *, isolate: bool = False, xfail: str = "") -> None:
        entry: dict = {"id": case_id, "args": args}
        if isolate:
            entry["isolate"] = True
        if xfail:
            entry["xfail"] = xfail
        cases.append(entry)

    for name, data in GENERIC_YAML.items():
        _write(HERE / "yaml" / f"{name}.yaml", data)
    for command, template in YAML_COMMANDS.items():
        for name in GENERIC_YAML:
            args = [a.replace("{case}", f"{{data}}/yaml/{name}.yaml") for a in template]
            add(f"{command}-yaml-{name}", args, isolate=name in RESOURCE_CASES)

    for command, base, table, template in (
        ("run", RUN_BASE, RUN_CASES, YAML_COMMANDS["run"]),
        ("identify", IDENTIFY_BASE, IDENTIFY_CASES, YAML_COMMANDS["identify"]),
        ("urdf", URDF_BASE, URDF_CASES, YAML_COMMANDS["urdf"]),
        ("bench", BENCH_BASE, BENCH_CASES, YAML_COMMANDS["bench"]),
    ):
        _write(HERE / command / "base.yaml", base)
        for name, spec in table.items():
            text, reason = (spec, "") if isinstance(spec, str) else spec
            _write(HERE / command / f"{name}.yaml", text)
            args = [a.replace("{case}", f"{{data}}/{command}/{name}.yaml") for a in template]
            add(f"{command}-{name}", args, isolate=True, xfail=reason)
    for table in (RUN_FLAG_CASES, IDENTIFY_FLAG_CASES, URDF_FLAG_CASES, BENCH_FLAG_CASES):
        for name, spec in table.items():
            args, reason = (spec, "") if isinstance(spec, list) else spec
            add(f"{args[0]}-{name}", args, xfail=reason)
    for name, spec in VERIFY_CASES.items():
        args, reason = (spec, "") if isinstance(spec, list) else spec
        add(f"verify-{name}", ["verify", *args], xfail=reason)
    for command, table in (("replay", REPLAY_CASES), ("report", REPORT_CASES)):
        for name, spec in table.items():
            args, reason = (spec, "") if isinstance(spec, list) else spec
            add(f"{command}-{name}", [command, *args], xfail=reason)

    cases += _log_cases()
    lines = [
        "# Generated by generate.py: hostile inputs and the command line of each.",
        "# {data} = this folder, {tmp} = an empty working folder that must stay empty.",
        "# isolate: run in a subprocess under memory/CPU limits; xfail: a known gap (why).",
    ]
    for c in cases:
        lines.append(f"- id: {c['id']}")
        lines.append(f"  args: {json.dumps(c['args'])}")
        if c.get("isolate"):
            lines.append("  isolate: true")
        if c.get("xfail"):
            lines.append(f"  xfail: {json.dumps(c['xfail'])}")
    _write(HERE / "manifest.yaml", "\n".join(lines) + "\n")
    print(f"{len(cases)} cases")


if __name__ == "__main__":
    main()
