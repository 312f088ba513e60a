"""Write the hostile-input corpus of ``tests/test_hostile_cli.py`` (run from the repository root).

``python tests/data/hostile/generate.py [--refresh-run]`` rewrites every file of this folder
from the tables below (``logs/`` through ``logs/generate_logs.py``), and ``manifest.yaml``: one
entry per case with the command line that runs it (``{data}`` is this folder, ``{tmp}`` an
empty working folder that must stay empty) and ``isolate: true`` for the cases that run in a
subprocess under memory and CPU limits. Every case must end with exit code 2, one ``error:``
line and nothing written. ``tests/test_hostile_corpus_generated.py`` checks that the committed
corpus is what this script writes: add cases here, never by hand.
"""

from __future__ import annotations

import gzip
import json
import math
import os
import runpy
import shutil
import struct
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
#: the corpus folder written; ``IDENT_HOSTILE_DIR`` writes a copy elsewhere (the test that the
#: committed corpus is what this script writes)
HERE = Path(os.environ.get("IDENT_HOSTILE_DIR") or Path(__file__).resolve().parent)
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
    "payload": ["payload", "{case}", "--out", "{tmp}/runs"],
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
    # the URDF's limits are read once for every command: swapped, a guess that is not one
    "urdf_swapped_limit": RUN_BASE.replace(PAPER_ROBOT, "../urdf/swapped_limit.urdf").replace(
        "stage: wrist", "stage: whole"
    ),
    "limits_override_swapped": RUN_BASE.replace(
        f"robot: {PAPER_ROBOT}",
        "robot: {urdf: ../urdf/three_joints.urdf, limits: {j1: {lower: 1.0, upper: -1.0}}}",
    ).replace("stage: wrist", "stage: whole"),
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
    "robot_mimic_urdf": RUN_BASE.replace(PAPER_ROBOT, "../urdf/mimic.urdf"),  # not yet
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

# payload: the identify base plus a payload section (the planar rp2 arm's log does not
# determine a payload: the base itself is the not-identifiable case)
PAYLOAD_BASE = """name: hostile
robot: {urdf: ../base/rp2.urdf}
log:
  sampling_rate_hz: 100.0
  position: {path: ../base/q.csv}
  torque: {path: ../base/tau.csv}
payload: {link: tool, method: wls}
"""
PAYLOAD_WITHOUT = (
    "payload:\n  link: tool\n  without:\n    sampling_rate_hz: 100.0\n"
    "    position: {path: ../base/q.csv}\n    torque: {path: ../base/tau.csv}\n"
)
PAYLOAD_WITH_WITHOUT = PAYLOAD_BASE.replace("payload: {link: tool, method: wls}\n", PAYLOAD_WITHOUT)
PAYLOAD_CASES: dict[str, tuple[str, str] | str] = {
    "not_identifiable": PAYLOAD_BASE,
    "link_unknown": PAYLOAD_BASE.replace("link: tool", "link: nowhere"),
    "link_not_on_last_joint": PAYLOAD_BASE.replace("link: tool", "link: link1"),
    "link_empty": PAYLOAD_BASE.replace("link: tool", "link: ''"),
    "link_list": PAYLOAD_BASE.replace("link: tool", "link: [tool]"),
    "method_unknown": PAYLOAD_BASE.replace("method: wls", "method: ols"),
    "unknown_key": PAYLOAD_BASE.replace("method: wls", "method: wls, mass: 1.0"),
    "section_list": PAYLOAD_BASE.replace("{link: tool, method: wls}", "[tool, wls]"),
    "without_missing": PAYLOAD_WITH_WITHOUT.replace(
        "    position: {path: ../base/q.csv}", "    position: {path: ../base/nope.csv}"
    ),
    "without_binary": PAYLOAD_WITH_WITHOUT.replace(
        "    position: {path: ../base/q.csv}", "    position: {path: ../base/binary.csv}"
    ),
    "without_nan": PAYLOAD_WITH_WITHOUT.replace(
        "    position: {path: ../base/q.csv}", "    position: {path: ../base/nan.csv}"
    ),
    "without_more": PAYLOAD_WITH_WITHOUT + "    more:\n      - {sampling_rate_hz: 100.0}\n",
    "without_rate_zero": PAYLOAD_WITH_WITHOUT.replace(
        "    sampling_rate_hz: 100.0", "    sampling_rate_hz: 0"
    ),
    "velocity_threshold_wrong_length": PAYLOAD_BASE
    + "preprocess: {velocity_threshold: [0.1, 0.1, 0.1]}\n",
    "log_missing": PAYLOAD_BASE.replace("../base/tau.csv", "../base/nope.csv"),
    "robot_missing": PAYLOAD_BASE.replace("../base/rp2.urdf", "../base/nope.urdf"),
}
PAYLOAD_FLAG_CASES = {
    "out_under_proc": ["payload", "{data}/payload/base.yaml", "--out", "/proc/ident"],
    "out_is_file": ["payload", "{data}/payload/base.yaml", "--out", "{data}/base/rp2.urdf"],
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
    "urdf_swapped_limit": ["--urdf", "{data}/urdf/swapped_limit.urdf"],
    "urdf_nan_limit": ["--urdf", "{data}/urdf/nan_limit.urdf"],
    "urdf_huge_velocity": ["--urdf", "{data}/urdf/huge_velocity.urdf"],
    "urdf_negative_effort": ["--urdf", "{data}/urdf/negative_effort.urdf"],
    "urdf_loop": ["--urdf", "{data}/urdf/loop.urdf"],
    "urdf_xacro_no_package": ["--urdf", "{data}/urdf/arm.urdf.xacro"],
    "urdf_xacro_bad_expression": ["--urdf", "{data}/urdf/bad_expression.urdf.xacro"],
    "urdf_xacro_in_urdf": ["--urdf", "{data}/urdf/unexpanded.urdf"],
    "urdf_dir": ["--urdf", "{data}/urdf"],
    "urdf_missing": ["--urdf", "{data}/urdf/nope.urdf"],
    # mimic joints ident does not take: a follower of a follower, a follower above its leader,
    # a follower locked while its leader moves
    "urdf_mimic_of_mimic": ["--urdf", "{data}/urdf/mimic_of_mimic.urdf"],
    "urdf_mimic_above_leader": ["--urdf", "{data}/urdf/mimic_above_leader.urdf"],
    "urdf_mimic_follower_locked": ["--urdf", "{data}/urdf/mimic.urdf", "--lock", "j3=0.1"],
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
    mimic = '<mimic joint="{}" multiplier="-0.5" offset="0.1"/></joint>'
    for name, pairs in (
        ("mimic", (("j3", "j2"),)),
        ("mimic_of_mimic", (("j3", "j2"), ("j2", "j1"))),
        ("mimic_above_leader", (("j2", "j3"),)),
    ):
        text = _urdf_chain(3)
        for follower, leader in pairs:
            start = text.index(f'<joint name="{follower}"')
            end = text.index("</joint>", start) + len("</joint>")
            text = (
                text[:start]
                + text[start:end].replace("</joint>", mimic.format(leader))
                + (text[end:])
            )
        _write(d / f"{name}.urdf", text)
    _write(
        d / "swapped_limit.urdf",
        _urdf_chain(2).replace('lower="-1" upper="1"', 'lower="1" upper="-1"'),
    )
    _write(d / "nan_limit.urdf", _urdf_chain(2).replace('lower="-1"', 'lower="nan"'))
    _write(d / "huge_velocity.urdf", _urdf_chain(2).replace('velocity="1"', 'velocity="1e999"'))
    _write(d / "negative_effort.urdf", _urdf_chain(2).replace('effort="10"', 'effort="-10"'))
    _write(d / "loop.urdf", _urdf_chain(3).replace('<child link="l3"/>', '<child link="l1"/>'))
    xacro = _urdf_chain(2).replace(
        '<robot name="chain">',
        '<robot name="chain" xmlns:xacro="http://www.ros.org/wiki/xacro">'
        '<xacro:include filename="$(find nopkg)/parts.xacro"/>',
    )
    _write(d / "arm.urdf.xacro", xacro)
    _write(
        d / "bad_expression.urdf.xacro",
        _urdf_chain(2).replace('upper="1"', 'upper="${undefined_name / 2}"'),
    )
    _write(d / "unexpanded.urdf", _urdf_chain(2).replace('upper="1"', 'upper="${pi/2"'))
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


def _log_cases(*, write: bool = True) -> list[dict]:
    """Readers and time stamps (logs/generate_logs.py writes those files: ``write``)."""
    module = runpy.run_path(str(Path(__file__).resolve().parent / "logs" / "generate_logs.py"))
    if write:
        module["write"]()
    return module["cases"]()


# ---------------------------------------------------------------------------------------------
# Hardening, round two: meshes that crash native code, operating-system failures
# (full disk, read-only folder, permission) in every command that writes, and the inputs that
# gave tracebacks or silent wrong results. Cases may carry:
#   setup:  {copy: <folder of this corpus>, to: <name in {tmp}>[, run_json: {...}]}  copied
#           before the command (run_json: the copy's run.json content);
#   fault:  {errno: ENOSPC, file: <glob of a file name>, step: write|create}  the one write
#           primitive of ident.fileio fails so (write: the disk fills half way through);
#   expect: {exit: 0|2, left: none|dirs|keep, state: <run.json status>, warning: true}
#           (default: exit 2, nothing left); ``state`` also requires the failure in its message.

MESH_URDF = "../base/rp2.urdf"


def _stl(vertices: list[tuple[float, float, float]], faces: list[tuple[int, int, int]]) -> bytes:
    """A binary STL (any float, NaN included, packs as it is)."""
    out = b"hostile".ljust(80, b" ") + struct.pack("<I", len(faces))
    for face in faces:
        out += struct.pack("<3f", 0.0, 0.0, 0.0)
        for k in face:
            out += struct.pack("<3f", *vertices[k])
        out += b"\0\0"
    return out


BOX_V = [(x, y, z) for x in (-0.03, 0.03) for y in (-0.03, 0.03) for z in (0.0, 0.2)]
BOX_F = [
    (0, 1, 3),
    (0, 3, 2),
    (4, 6, 7),
    (4, 7, 5),
    (0, 4, 5),
    (0, 5, 1),
    (2, 3, 7),
    (2, 7, 6),
    (0, 2, 6),
    (0, 6, 4),
    (1, 5, 7),
    (1, 7, 3),
]
MESH_FILES: dict[str, bytes] = {
    "box.stl": _stl(BOX_V, BOX_F),
    "flat.stl": _stl([(0, 0, 0), (0.1, 0, 0), (0, 0.1, 0), (0.1, 0.1, 0)], [(0, 1, 2), (1, 3, 2)]),
    "flat_tilted.stl": _stl(
        [(0.1 * i, 0.1 * j, 0.05 * i + 0.02 * j) for i in range(4) for j in range(4)],
        [(4 * i + j, 4 * i + j + 1, 4 * i + j + 4) for i in range(3) for j in range(3)],
    ),
    "collinear.stl": _stl([(0.0, 0.0, 0.01 * k) for k in range(6)], [(0, 1, 2), (3, 4, 5)]),
    "point.stl": _stl([(0.1, 0.1, 0.1)] * 4, [(0, 1, 2), (1, 2, 3)]),
    "one_triangle.stl": _stl([(0, 0, 0), (0.1, 0, 0), (0, 0.1, 0.1)], [(0, 1, 2)]),
    "nan_vertex.stl": _stl([(math.nan, 0.0, 0.0), *BOX_V[1:]], BOX_F),
    "inf_vertex.stl": _stl([*BOX_V[:7], (0.0, math.inf, 0.0)], BOX_F),
    "millimetres.stl": _stl([tuple(1000.0 * c for c in v) for v in BOX_V], BOX_F),
    "empty_ascii.stl": b"solid empty\nendsolid empty\n",
    "zero_bytes.stl": b"",
    "garbage.stl": bytes((k * 97 + 13) % 256 for k in range(3000)),
    "flat.obj": b"v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0.1 0.1 0\nf 1 2 3\nf 2 4 3\n",
}
# name: (mesh file, scale attribute or None) for a mesh that must be refused
BAD_MESHES: dict[str, tuple[str, str | None]] = {
    "flat": ("flat.stl", None),
    "flat_tilted": ("flat_tilted.stl", None),
    "flat_obj": ("flat.obj", None),
    "collinear": ("collinear.stl", None),
    "point": ("point.stl", None),
    "one_triangle": ("one_triangle.stl", None),
    "nan_vertex": ("nan_vertex.stl", None),
    "inf_vertex": ("inf_vertex.stl", None),
    "millimetres_as_metres": ("millimetres.stl", None),
    "empty_ascii": ("empty_ascii.stl", None),
    "zero_bytes": ("zero_bytes.stl", None),
    "garbage": ("garbage.stl", None),
    "scale_zero": ("box.stl", "0 0 0"),
    "scale_one_zero": ("box.stl", "1 1 0"),
    "scale_nan": ("box.stl", "nan 1 1"),
    "scale_inf": ("box.stl", "inf 1 1"),
    "scale_huge": ("box.stl", "1e300 1e300 1e300"),
    "scale_two_numbers": ("box.stl", "1 1"),
    "scale_words": ("box.stl", "big big big"),
}
FLAT_ONLY = {"flat", "flat_tilted", "flat_obj", "collinear", "point", "one_triangle"}
MESH_RUN = """robot: {urdf: URDF, package_dirs: [.]}
seed: 1
excitation:
  family: joint_fourier
  n_samples: 50
  options: {n_harmonics: 2, amplitude_bound: 0.3}
elites: {n_particles: 6, n_elites: 2, maxiter: 4}
emupso: {n_particles: 6, maxiter: 2, stagnation: 3, n_runs: 1, n_report_elites: 1}
safety: {floor: {enabled: true, z: 0.0}, self_collision: true}
measurement: {torque_noise_std: 0.0}
"""


def _mesh_urdf(filename: str, scale: str | None, *, collision: bool, visual: bool) -> str:
    text = (HERE / "base" / "rp2.urdf").read_text()
    attr = f' scale="{scale}"' if scale is not None else ""
    geometry = f'<geometry><mesh filename="{filename}"{attr}/></geometry>'
    parts = ""
    if collision:
        parts += f"\n    <collision>{geometry}</collision>"
    if visual:
        parts += f"\n    <visual>{geometry}</visual>"
    return text.replace('<link name="link2">', '<link name="link2">' + parts)


# Operating-system failures: the errno a writer meets, per command.
OS_ERRNOS = ("ENOSPC", "EDQUOT", "EROFS", "EACCES", "EIO")
RUN_FOLDER_FILES = ("result.json", "elite_1.csv", "report.md", "report.html", "*.png")


def _real_run_folder(*, refresh: bool) -> None:
    """A real, small ``ident run`` folder for report/replay cases, made by ``ident run`` when
    missing or with ``refresh`` (``--refresh-run``: its floats differ in the last digits from
    machine to machine, so a plain regeneration keeps the committed one)."""
    real = HERE / "os" / "real_run"
    if real.is_dir() and not refresh:
        return
    shutil.rmtree(real, ignore_errors=True)
    out = HERE / "os" / "_runs"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    subprocess.run(
        [
            sys.executable,
            "-c",
            "from ident.cli import main; main()",
            "run",
            str(HERE / "run" / "base.yaml"),
            "--out",
            str(out),
            "--no-replay",
        ],
        env=env,
        check=False,
        capture_output=True,
        cwd=ROOT,
    )
    (made,) = out.iterdir()
    made.rename(real)
    shutil.rmtree(out)
    for name in ("report.md", "report.html", "figures"):
        path = real / name
        shutil.rmtree(path) if path.is_dir() else path.unlink(missing_ok=True)
    _write(real / "replay.html", "<!doctype html><title>replay placeholder</title>\n")
    for name in ("result.json", "config.yaml"):  # no path of this machine in the corpus
        text = (real / name).read_text().replace(str(ROOT), "<repository>")
        _write(real / name, text)
    state = json.loads((real / "run.json").read_text())
    state = {k: state[k] for k in ("status", "message", "seed", "started_at", "finished_at")}
    _write(real / "run.json", json.dumps(state, indent=2) + "\n")


def _hardening_files(*, refresh_run: bool = False) -> None:
    mesh = HERE / "mesh"
    for name, data in MESH_FILES.items():
        _write(mesh / name, data)
    _write(mesh / "pkg" / "hostile_description" / "meshes" / "flat.stl", MESH_FILES["flat.stl"])
    for name, (filename, scale) in BAD_MESHES.items():
        _write(
            mesh / f"collision_{name}.urdf",
            _mesh_urdf(filename, scale, collision=True, visual=False),
        )
        _write(
            mesh / f"visual_{name}.urdf", _mesh_urdf(filename, scale, collision=False, visual=True)
        )
        _write(mesh / f"run_{name}.yaml", MESH_RUN.replace("URDF", f"collision_{name}.urdf"))
    _write(
        mesh / "collision_package_flat.urdf",
        _mesh_urdf(
            "package://hostile_description/meshes/flat.stl", None, collision=True, visual=False
        ),
    )
    _write(
        mesh / "run_package_flat.yaml",
        MESH_RUN.replace("URDF", "collision_package_flat.urdf").replace("[.]", "[pkg]"),
    )
    _write(
        mesh / "run_package_flat_no_dir.yaml",
        MESH_RUN.replace("URDF", "collision_package_flat.urdf").replace(
            "package_dirs: [.]", "package_dirs: [pkg/hostile_description]"
        ),
    )
    _real_run_folder(refresh=refresh_run)
    os_dir = HERE / "os"
    _write(os_dir / "running_empty" / "run.json", json.dumps({"status": "running"}) + "\n")
    # identify: a reference table that is not UTF-8, binary, a folder, malformed
    _write(os_dir / "reference_latin1.csv", "m1 + caf\u00e9,1,2,3,4\n".encode("latin-1"))
    _write(os_dir / "reference_binary.csv", bytes(range(256)) * 4)
    _write(os_dir / "reference_fields.csv", "m1,1,2\n")
    for name, reference in {
        "reference_latin1": "reference_latin1.csv",
        "reference_binary": "reference_binary.csv",
        "reference_is_dir": ".",
        "reference_fields": "reference_fields.csv",
    }.items():
        for key in ("base_parameters", "essential_parameters"):
            _write(
                os_dir / f"{name}_{key}.yaml",
                IDENTIFY_BASE.replace("../base/", "../base/")
                + f"reference: {{{key}: {reference}}}\n",
            )
    for name, thresholds in {
        "velocity_threshold_negative": "[-0.1, 0.1]",
        "velocity_threshold_minus_inf": "[-.inf, 0.1]",
        "velocity_threshold_all_negative": "[-1, -1]",
        "velocity_threshold_inf": "[.inf, 0.1]",
    }.items():
        _write(
            os_dir / f"{name}.yaml",
            IDENTIFY_BASE + f"preprocess: {{velocity_threshold: {thresholds}}}\n",
        )
    _write(
        os_dir / "more_in_more.yaml",
        IDENTIFY_BASE.replace(
            "  torque: {path: ../base/tau.csv}\n",
            "  torque: {path: ../base/tau.csv}\n  more:\n"
            "    - {sampling_rate_hz: 100.0, more: [{sampling_rate_hz: 50.0}]}\n",
        ),
    )
    _write(
        os_dir / "more_in_more_deep.yaml",
        IDENTIFY_BASE.replace(
            "  torque: {path: ../base/tau.csv}\n",
            "  torque: {path: ../base/tau.csv}\n  more:\n    - {sampling_rate_hz: 100.0}\n"
            "    - {more: [{more: [{sampling_rate_hz: 50.0}]}]}\n",
        ),
    )
    _write(os_dir / "chunked.yaml", IDENTIFY_BASE + "preprocess: {chunked: always}\n")
    # replay: a run folder whose result.json is damaged where the replay reads it
    good = HERE / "runfolder" / "good"
    elite = (HERE / "base" / "traj.csv").read_text().replace("0.0,", "0.001,", 1)
    for name, result in {
        "elites_number": {"elites": 5},
        "elites_string": {"elites": "abc"},
        "elites_list_of_numbers": {"elites": [1, 2]},
        "closest_time_string": {
            "elites": [
                {
                    "rank": 1,
                    "safety_series": {
                        "closest_time": "x",
                        "closest_pair": "link1|floor",
                        "closest_clearance": 0.1,
                    },
                }
            ]
        },
        "closest_clearance_nan": {
            "elites": [
                {
                    "rank": 1,
                    "safety_series": {
                        "closest_time": 1.0,
                        "closest_pair": "link1|floor",
                        "closest_clearance": "nan",
                    },
                }
            ]
        },
        "floor_z_string": {"config": {"safety": {"floor": {"z": "low"}}}},
        "obstacles_not_list": {"config": {"safety": {"obstacles": 3}}},
        "obstacle_box_without_size": {"config": {"safety": {"obstacles": [{"box": {}}]}}},
        "obstacle_sphere_radius_text": {
            "config": {"safety": {"obstacles": [{"sphere": {"radius": "big"}}]}}
        },
        "obstacle_position_nan": {
            "config": {
                "safety": {"obstacles": [{"sphere": {"radius": 0.1, "position": ["nan", 0, 0]}}]}
            }
        },
        "no_elites_key": {"name": "x", "chosen_elite": 1},
    }.items():
        folder = os_dir / "replay" / name
        shutil.copytree(good, folder)
        _write(folder / "elites" / "elite_1.csv", elite)
        _write(folder / "result.json", json.dumps(result) + "\n")


def _hardening_cases(add) -> None:  # noqa: ANN001 - main's add()
    data_mesh = "{data}/mesh"
    for name in BAD_MESHES:  # the safety check's collision model: qhull builds hulls
        add(
            f"run-mesh-collision-{name}",
            ["run", f"{data_mesh}/run_{name}.yaml", "--out", "{tmp}/runs"],
        )
    for name in ("package_flat", "package_flat_no_dir"):
        add(
            f"run-mesh-collision-{name}",
            ["run", f"{data_mesh}/run_{name}.yaml", "--out", "{tmp}/runs"],
        )
    for name in BAD_MESHES:  # the replay's visual model: flat visuals are fine
        if name in FLAT_ONLY:
            continue
        for mode in ("static", "live"):
            args = [
                "replay",
                "--urdf",
                f"{data_mesh}/visual_{name}.urdf",
                "--trajectory",
                "{data}/base/traj.csv",
                "--package-dir",
                data_mesh,
            ]
            args += ["--html", "{tmp}/r.html"] if mode == "static" else ["--port", "0"]
            add(f"replay-mesh-visual-{name}-{mode}", args)

    # full disk, quota, read-only, permission, I/O error: at each file a command writes
    for errno_name in OS_ERRNOS:
        low = errno_name.lower()
        for step in ("write", "create"):
            fault = {"errno": errno_name, "file": "*", "step": step}
            add(
                f"urdf-{low}-{step}",
                ["urdf", "{data}/urdf/base.yaml", "-o", "{tmp}/r.urdf"],
                fault=fault,
            )
            add(
                f"replay-html-{low}-{step}",
                ["replay", "{data}/runfolder/good", "--html", "{tmp}/r.html"],
                fault=fault,
            )
        # ident report renders every figure first (seconds): one step per errno, the one
        # that happens (a read-only folder or no permission: creating; else: writing)
        step = "create" if errno_name in ("EROFS", "EACCES") else "write"
        add(
            f"report-{low}-{step}",
            ["report", "{tmp}/run"],
            setup={"copy": "os/real_run", "to": "run"},
            fault={"errno": errno_name, "file": "*", "step": step},
            expect={"left": "keep"},
        )
    for target in RUN_FOLDER_FILES[2:]:
        fault = {"errno": "ENOSPC", "file": target, "step": "write"}
        add(
            f"report-enospc-at-{target.replace('*', 'figure')}",
            ["report", "{tmp}/run"],
            setup={"copy": "os/real_run", "to": "run"},
            fault=fault,
            expect={"left": "keep"},
        )
    for errno_name in ("ENOSPC", "EROFS", "EACCES"):
        low = errno_name.lower()
        # ident run: the run folder keeps what finished and its run.json names the failure
        # (a whole run each: the full disk only; a folder turns read-only mid-run rarely)
        for target in ("result.json", "report.html") if errno_name == "ENOSPC" else ():
            add(
                f"run-{low}-at-{target}",
                ["run", "{data}/run/base.yaml", "--out", "{tmp}/runs", "--no-replay"],
                fault={"errno": errno_name, "file": target, "step": "write"},
                expect={"left": "keep", "state": "incomplete"},
            )
        add(
            f"run-{low}-at-run.json",
            ["run", "{data}/run/base.yaml", "--out", "{tmp}/runs"],
            fault={"errno": errno_name, "file": "run.json", "step": "create"},
            expect={"left": "dirs"},
        )
        for target in ("result.json", "report.md"):
            add(
                f"identify-{low}-at-{target}",
                ["identify", "{data}/identify/base.yaml", "--out", "{tmp}/runs", "--no-replay"],
                fault={"errno": errno_name, "file": target, "step": "write"},
                expect={"left": "keep", "state": "incomplete"},
            )
        add(
            f"bench-{low}",
            ["bench", "{data}/bench/base.yaml", "--out", "{tmp}/c", "--no-progress"],
            fault={"errno": errno_name, "file": "*", "step": "create"},
            expect={"left": "dirs"},
        )

    # ident report on a folder that did not finish: a warning, or one error when nothing
    # was saved
    add(
        "report-running-with-results",
        ["report", "{tmp}/run"],
        setup={
            "copy": "os/real_run",
            "to": "run",
            "run_json": {"status": "running", "started_at": "2026-01-01T00:00:00+00:00"},
        },
        expect={"exit": 0, "left": "keep", "warning": True},
    )
    add(
        "report-incomplete-with-results",
        ["report", "{tmp}/run"],
        setup={
            "copy": "os/real_run",
            "to": "run",
            "run_json": {"status": "incomplete", "message": "interrupted (Ctrl-C)"},
        },
        expect={"exit": 0, "left": "keep", "warning": True},
    )
    add(
        "report-running-nothing-saved",
        ["report", "{data}/os/running_empty"],
        expect={"warning": True},
    )

    # --scheduler addresses dask cannot parse, refused before any work
    for name, address in {
        "bogus_scheme_blank": "bogus://x y",
        "bogus_scheme": "bogus://127.0.0.1:8786",
        "http": "http://127.0.0.1:8786",
        "blank_in_host": "tcp://127.0.0.1 8786",
        "only_scheme": "tcp://",
        "empty": "",
        "spaces": "   ",
        "newline": "tcp://a\nb:1",
    }.items():
        add(
            f"identify-scheduler-{name}",
            ["identify", "{data}/os/chunked.yaml", "--scheduler", address, "--out", "{tmp}/r"],
        )
        add(
            f"bench-scheduler-{name}",
            [
                "bench",
                "{data}/bench/base.yaml",
                "--scheduler",
                address,
                "--out",
                "{tmp}/c",
                "--no-progress",
            ],
        )

    # identify configs: refused before the identification (no result to lose)
    for name in ("reference_latin1", "reference_binary", "reference_is_dir", "reference_fields"):
        for key in ("base_parameters", "essential_parameters"):
            add(
                f"identify-{name}-{key}",
                ["identify", f"{{data}}/os/{name}_{key}.yaml", "--out", "{tmp}/r"],
            )
    for name in (
        "velocity_threshold_negative",
        "velocity_threshold_minus_inf",
        "velocity_threshold_all_negative",
        "velocity_threshold_inf",
        "more_in_more",
        "more_in_more_deep",
    ):
        add(f"identify-{name}", ["identify", f"{{data}}/os/{name}.yaml", "--out", "{tmp}/r"])

    # replay: --package-dir that is no folder; result.json damaged where the replay reads it
    for name, folder in {"missing": "{data}/nope", "file": "{data}/base/rp2.urdf"}.items():
        add(
            f"replay-package-dir-{name}",
            ["replay", "{data}/runfolder/good", "--package-dir", folder, "--html", "{tmp}/r.html"],
        )
        add(
            f"replay-package-dir-{name}-urdf",
            [
                "replay",
                "--urdf",
                "{data}/base/rp2.urdf",
                "--trajectory",
                "{data}/base/traj.csv",
                "--package-dir",
                folder,
                "--html",
                "{tmp}/r.html",
            ],
        )
    for name in (
        "elites_number",
        "elites_string",
        "elites_list_of_numbers",
        "closest_time_string",
        "closest_clearance_nan",
    ):
        add(
            f"replay-result-{name}",
            ["replay", f"{{data}}/os/replay/{name}", "--elites", "--html", "{tmp}/r.html"],
        )
    add(
        "replay-result-no_elites_key",
        ["replay", "{data}/os/replay/no_elites_key", "--elites", "--html", "{tmp}/r.html"],
        expect={"exit": 0, "left": "keep"},
    )
    for name in (
        "floor_z_string",
        "obstacles_not_list",
        "obstacle_box_without_size",
        "obstacle_sphere_radius_text",
        "obstacle_position_nan",
    ):
        for extra in ([], ["--elites"]):
            suffix = "-elites" if extra else ""
            add(
                f"replay-result-{name}{suffix}",
                ["replay", f"{{data}}/os/replay/{name}", *extra, "--html", "{tmp}/r.html"],
            )


# Causes named right: a device, a FIFO-like or a folder given as a URDF or SRDF, a log whose
# joints never move, a config listing the wrong number of columns, every joint locked, a
# damaged result.json; init, payload and repeatability on bad input. Each error line must name
# the file and the field (expect.match).
CAUSE_IDENTIFY = {
    "urdf_dev_zero": IDENTIFY_BASE.replace("../base/rp2.urdf", "/dev/zero"),
    "urdf_is_dir": IDENTIFY_BASE.replace("../base/rp2.urdf", "../base"),
    "log_never_moves": IDENTIFY_BASE.replace("../base/q.csv", "../causes/q_still.csv"),
    "columns_three_for_two_joints": IDENTIFY_BASE.replace(
        "{path: ../base/q.csv}", "{path: ../causes/q3.csv, columns: [shoulder, slider, extra]}"
    ),
}


def _cause_files() -> None:
    causes = HERE / "causes"
    _write(causes / "q_still.csv", _csv(["shoulder", "slider"], [[0.3, 0.1]] * 200))
    rows = [[0.01 * k, 0.003 * k, 0.0] for k in range(200)]
    _write(causes / "q3.csv", _csv(["shoulder", "slider", "extra"], rows))
    for name, text in CAUSE_IDENTIFY.items():
        _write(causes / f"identify_{name}.yaml", text)
    _write(
        causes / "payload_urdf_dev_zero.yaml", PAYLOAD_BASE.replace("../base/rp2.urdf", "/dev/zero")
    )
    _write(
        causes / "payload_wrong_joint_names.yaml",
        PAYLOAD_BASE.replace("{path: ../base/q.csv}", "{path: ../base/q.csv, columns: [j1, j2]}"),
    )
    _write(causes / "payload_urdf_is_dir.yaml", PAYLOAD_BASE.replace("../base/rp2.urdf", "../base"))
    run = RUN_BASE
    _write(causes / "run_srdf_dev_zero.yaml", run + "safety: {srdf: /dev/zero}\n")
    _write(causes / "run_srdf_is_dir.yaml", run + "safety: {srdf: ../base}\n")
    # a result.json without its elites (the rest of a real run)
    damaged = HERE / "causes" / "no_elites"
    shutil.rmtree(damaged, ignore_errors=True)
    shutil.copytree(HERE / "os" / "real_run", damaged)
    data = json.loads((damaged / "result.json").read_text())
    data.pop("elites")
    _write(damaged / "result.json", json.dumps(data, indent=1) + "\n")


def _cause_cases(add) -> None:  # noqa: ANN001 - main's add()
    c = "{data}/causes"
    for name in CAUSE_IDENTIFY:
        match = {
            "urdf_dev_zero": ["/dev/zero", "is not a regular file"],
            "urdf_is_dir": ["is a folder"],
            "log_never_moves": ["identify_log_never_moves.yaml", "no joint moves", "shoulder"],
            "columns_three_for_two_joints": [
                "identify_columns_three_for_two_joints.yaml",
                "log.position.columns",
                "2 joints",
            ],
        }[name]
        add(
            f"identify-cause-{name}",
            ["identify", f"{c}/identify_{name}.yaml", "--out", "{tmp}/r"],
            expect={"match": match},
        )
    for name, match in (
        ("srdf_dev_zero", ["run_srdf_dev_zero.yaml", "safety.srdf", "is not a regular file"]),
        ("srdf_is_dir", ["run_srdf_is_dir.yaml", "safety.srdf", "is a folder"]),
    ):
        add(
            f"run-cause-{name}",
            ["run", f"{c}/run_{name}.yaml", "--out", "{tmp}/runs"],
            expect={"match": match},
        )
    add(
        "verify-cause-lock_every_joint",
        ["verify", "--urdf", "{data}/base/rp2.urdf", "--lock", "shoulder", "--lock", "slider"],
        expect={"match": ["rp2.urdf", "no joint is left to identify"]},
    )
    add(
        "report-cause-no_elites",
        ["report", "{tmp}/run"],
        setup={"copy": "causes/no_elites", "to": "run"},
        expect={"match": ["result.json", "no elites"], "left": "keep"},
    )
    for name, args, match in (
        ("urdf_dev_zero", ["/dev/zero"], ["/dev/zero", "is not a regular file"]),
        ("urdf_missing", ["{data}/base/nope.urdf"], ["nope.urdf", "not found"]),
        ("urdf_is_dir", ["{data}/base"], ["base", "is a folder"]),
        ("urdf_binary", ["{data}/yaml/binary.yaml"], ["binary.yaml", "binary"]),
        ("urdf_dtd", ["{data}/urdf/dtd_entity.urdf"], ["dtd_entity.urdf", "DOCTYPE"]),
        ("lock_unknown", ["{data}/base/rp2.urdf", "--lock", "elbow"], ["elbow"]),
    ):
        add(f"init-cause-{name}", ["init", *args, "-o", "{tmp}/c.yaml"], expect={"match": match})
    for name, match in (
        ("urdf_dev_zero", ["/dev/zero", "is not a regular file"]),
        ("wrong_joint_names", ["q.csv", "column 'j1' not found"]),
        ("urdf_is_dir", ["payload_urdf_is_dir.yaml", "is a folder"]),
    ):
        add(
            f"payload-cause-{name}",
            ["payload", f"{c}/payload_{name}.yaml", "--out", "{tmp}/r"],
            expect={"match": match},
        )
    for name, args, match in (
        ("one_config", ["{data}/identify/base.yaml"], ["at least two"]),
        ("config_missing", ["{data}/identify/base.yaml", "{data}/nope.yaml"], ["nope.yaml"]),
        (
            "log_missing",
            ["{data}/identify/base.yaml", "{data}/identify/log_missing.yaml"],
            ["nope.csv"],
        ),
        (
            "wrong_joint_count",
            ["{data}/identify/base.yaml", f"{c}/identify_columns_three_for_two_joints.yaml"],
            ["log.position.columns"],
        ),
    ):
        add(f"repeatability-cause-{name}", ["repeatability", *args], expect={"match": match})


def _clear() -> None:
    """Remove the generated folders (``os/real_run`` stays: see :func:`_real_run_folder`)."""
    subs = ("base", "urdf", "runfolder", "yaml", "run", "identify", "bench", "payload", "mesh")
    for sub in (*subs, "causes", "round3"):
        shutil.rmtree(HERE / sub, ignore_errors=True)
    for path in (HERE / "os").glob("*"):
        if path.name != "real_run":
            shutil.rmtree(path) if path.is_dir() else path.unlink()


def main(*, refresh_run: bool = False, logs: bool = True) -> None:
    """Rewrite the corpus and its manifest (``logs``: also the files of ``logs/``)."""
    _clear()
    _base_files()
    _urdf_files()
    _run_folders()
    cases: list[dict] = []

    def add(
        case_id: str, args: list[str], *, isolate: bool = False, xfail: str = "", **extra: dict
    ) -> None:
        entry: dict = {"id": case_id, "args": args}
        if isolate:
            entry["isolate"] = True
        if xfail:
            entry["xfail"] = xfail
        entry.update(extra)
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
        ("payload", PAYLOAD_BASE, PAYLOAD_CASES, YAML_COMMANDS["payload"]),
    ):
        _write(HERE / command / "base.yaml", base)
        for name, spec in table.items():
            text, reason = (spec, "") if isinstance(spec, str) else spec
            _write(HERE / command / f"{name}.yaml", text)
            args = [a.replace("{case}", f"{{data}}/{command}/{name}.yaml") for a in template]
            add(f"{command}-{name}", args, isolate=True, xfail=reason)
    flag_tables = (RUN_FLAG_CASES, IDENTIFY_FLAG_CASES, URDF_FLAG_CASES, BENCH_FLAG_CASES)
    for table in (*flag_tables, PAYLOAD_FLAG_CASES):
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

    cases += _log_cases(write=logs)
    _hardening_files(refresh_run=refresh_run)
    _hardening_cases(add)
    _cause_files()
    _cause_cases(add)
    # hardening, round three: the newer features (round3.py)
    round3 = runpy.run_path(str(Path(__file__).resolve().parent / "round3.py"))
    round3["generate"](HERE, globals(), add)
    # the environment is never excluded (the files in safety/ are written by hand)
    cases.append({"comment": "safety: the environment is never excluded; absurd sizes are refused"})
    for path in sorted((HERE / "safety").glob("*.yaml")):
        add(
            f"run-safety-{path.stem}",
            ["run", f"{{data}}/safety/{path.name}", "--out", "{tmp}/runs"],
        )

    lines = [
        "# Generated by generate.py: hostile inputs and the command line of each.",
        "# {data} = this folder, {tmp} = an empty working folder that must stay empty.",
        "# isolate: run in a subprocess under memory/CPU limits; xfail: a known gap (why).",
    ]
    for c in cases:
        if "comment" in c:
            lines.append(f"# {c['comment']}")
            continue
        lines.append(f"- id: {c['id']}")
        lines.append(f"  args: {json.dumps(c['args'])}")
        if c.get("isolate"):
            lines.append("  isolate: true")
        if c.get("xfail"):
            lines.append(f"  xfail: {json.dumps(c['xfail'])}")
        for key in ("setup", "fault", "expect"):
            if key in c:
                lines.append(f"  {key}: {json.dumps(c[key])}")
    _write(HERE / "manifest.yaml", "\n".join(lines) + "\n")
    print(f"{sum('id' in c for c in cases)} cases")


if __name__ == "__main__":
    main(refresh_run="--refresh-run" in sys.argv[1:])
