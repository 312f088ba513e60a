"""Time the README's quickstart jobs and print them beside the times the README states.

Each job is the command a user types (``ident run CONFIG --no-replay``, a fresh process, so
Python start-up, imports and the report are included), timed by wall clock and by the CPU
time of the child process (``resource.getrusage(RUSAGE_CHILDREN)``): on a shared machine the
wall time depends on the load, the CPU time much less, and an idle machine takes about the
CPU time. The README's number for each config (``CONFIG`` followed by ``NN s``) is read from
README.md and printed with the ratio measured / stated, so a stale documented time shows.

    python benchmarks/bench_quickstart.py                     # wrist.yaml, wrist.yaml --quick
    python benchmarks/bench_quickstart.py wrist-fourier.yaml arm.yaml
    python benchmarks/bench_quickstart.py --newcomer URDF [--package-dir DIR]  # init + full run

``--newcomer`` times the first hour of a robot the configs do not ship: ``ident init URDF``
then the full ``ident run CONFIG`` it wrote, as ``docs/your-robot.md`` tells a newcomer to.

``--zoo`` runs ``ident init`` then ``ident run CONFIG --quick`` on the example-robot-data arms
(:data:`ZOO`) and the fetched ones (:data:`FETCHED`: ``sh benchmarks/fetch_iiwa.sh DIR``, then
``--fetched DIR``; skipped with the reason when absent); ``--zoo NAME ...`` for some of
them. It prints per robot: the CPU of each,
``init``'s and ``run``'s estimates of the quick run against its CPU (the ratio, marked ``!``
outside [0.5, 2]; their worst cases, marked ``r``, when the run optimized again at a wider
safety margin), the verdict, the worst parameter error, the smallest clearance (from the
run folder's result.json) and the independent check: the run's ``trajectory.csv`` re-checked
with plain Pinocchio + coal by ``independent_safety.py`` (beside this file; none of ident's
safety code). About 2-5 min of CPU per robot. ``--full NAME ...`` does the same with the full
budget (``ident run CONFIG``, no ``--quick``; 2-15 min of CPU per robot); ``--keep DIR``
keeps the configs and run folders.

Budget: about 1.5 min for the default pair on a loaded 2-core machine; ``--zoo``: about
30 min of CPU for the eleven arms and the iiwa (--quick; several times that in wall time
on a shared machine).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The example-robot-data arms of ``--zoo``: name, URDF under robots/, extra ``init`` options.
ZOO: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("ur3", "ur_description/urdf/ur3_robot.urdf", ()),
    ("ur5", "ur_description/urdf/ur5_robot.urdf", ()),
    ("ur10", "ur_description/urdf/ur10_robot.urdf", ()),
    ("panda", "panda_description/urdf/panda.urdf", ()),
    ("kinova", "kinova_description/robots/kinova.urdf", ()),
    ("z1", "z1_description/urdf/z1.urdf", ()),
    ("xarm7", "xarm_description/urdf/xarm7.urdf", ()),
    ("so101", "so_arm_description/urdf/so101.urdf", ()),
    ("baxter_left", "baxter_description/urdf/baxter.urdf", ()),  # init picks the left arm
    ("tiago_arm", "tiago_description/robots/tiago.urdf", ("--tip-link", "arm_7_link")),
)

#: Robots of ``--zoo`` that example-robot-data lacks, fetched by a script beside this file into
#: the folder given as ``--fetched``: name, its description under that folder, the script;
#: ``init`` reads it with ``--package-dir`` that folder. The KUKA iiwa 14 is a ROS
#: workspace's xacro (IFL-CAMP/iiwa_stack's iiwa_description), as a ROS user has it.
FETCHED: tuple[tuple[str, str, str], ...] = (
    ("iiwa14", "iiwa_description/urdf/iiwa14.urdf.xacro", "fetch_iiwa.sh"),
)


def stated_seconds(readme: str, config: str) -> float | None:
    """The README's time for ``config``: the first "`CONFIG` ... NN s" of the quickstart."""
    quickstart = readme.split("## Quickstart", 1)[-1].split("\n## ", 1)[0]
    match = re.search(rf"`{re.escape(config)}` (\d+(?:\.\d+)?) s", quickstart)
    return None if match is None else float(match.group(1))


def run_job(args: list[str]) -> tuple[float, float, int, str]:
    """Run ``ident`` with ``args``; wall time [s], child CPU time [s], exit code, verdict."""
    ident = shutil.which("ident") or str(Path(sys.executable).with_name("ident"))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([ident, *args], capture_output=True, text=True, check=False)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    lines = done.stdout.splitlines() + done.stderr.splitlines()
    folder = next((ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("Run folder:")), "")
    verdict = next((ln for ln in lines if ln.startswith("error:")), "")
    result = Path(folder) / "result.json"
    if folder and result.is_file():
        verdict = json.loads(result.read_text(encoding="utf-8"))["verdict"]["label"]
    return wall, cpu, done.returncode, verdict[:90]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("configs", nargs="*", default=["wrist.yaml"])
    parser.add_argument("--no-quick", action="store_true", help="skip the --quick run")
    parser.add_argument("--newcomer", type=Path, help="URDF: time ident init + the full run")
    parser.add_argument("--package-dir", type=Path, help="package:// folder of its meshes")
    parser.add_argument(
        "--zoo", nargs="*", metavar="NAME", help="init + run --quick on example-robot-data arms"
    )
    parser.add_argument(
        "--full", nargs="+", metavar="NAME", help="init + the full run (no --quick) on these arms"
    )
    parser.add_argument("--keep", type=Path, help="--zoo/--full: keep the run folders here")
    parser.add_argument(
        "--fetched", type=Path, help="--zoo/--full: the folder fetch_iiwa.sh filled (iiwa14)"
    )
    args = parser.parse_args()
    if args.zoo is not None or args.full is not None:
        zoo(args.full or args.zoo, quick=args.full is None, keep=args.keep, fetched=args.fetched)
        return
    if args.newcomer is not None:
        newcomer(args.newcomer, args.package_dir)
        return
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    load = os.getloadavg()[0]
    print(f"{os.cpu_count()} cores, load average {load:.1f} at start")
    jobs = [(c, []) for c in args.configs]
    if not args.no_quick:
        jobs.append(("wrist.yaml", ["--quick"]))
    print(
        f"{'job':32s} {'wall [s]':>9s} {'CPU [s]':>8s} {'README [s]':>10s} "
        f"{'wall/README':>11s}  exit  verdict"
    )
    with tempfile.TemporaryDirectory(prefix="ident-bench-") as out:
        for config, extra in jobs:
            wall, cpu, code, verdict = run_job(
                ["run", str(ROOT / "configs" / config), "--no-replay", "--out", out, *extra]
            )
            stated = None if extra else stated_seconds(readme, config)
            ratio = "—" if stated is None else f"{wall / stated:.2f}"
            shown = "—" if stated is None else f"{stated:g}"
            name = " ".join([config, *extra])
            print(
                f"{name:32s} {wall:9.1f} {cpu:8.1f} {shown:>10s} {ratio:>11s}  {code:4d}  {verdict}"
            )


def newcomer(urdf: Path, package_dir: Path | None) -> None:
    """``ident init URDF`` then ``ident run CONFIG --no-replay``: times and the verdict."""
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at start")
    with tempfile.TemporaryDirectory(prefix="ident-newcomer-") as out:
        config = Path(out) / f"{urdf.stem}.yaml"
        init = ["init", str(urdf), "-o", str(config)]
        if package_dir is not None:
            init += ["--package-dir", str(package_dir)]
        total_wall = total_cpu = 0.0
        for name, args in (
            ("ident init", init),
            ("ident run (full)", ["run", str(config), "--no-replay", "--out", out]),
        ):
            wall, cpu, code, verdict = run_job(args)
            total_wall, total_cpu = total_wall + wall, total_cpu + cpu
            print(f"{name:18s} wall {wall:7.1f} s  CPU {cpu:7.1f} s  exit {code}  {verdict}")
        print(f"{'first hour':18s} wall {total_wall:7.1f} s  CPU {total_cpu:7.1f} s")


def _seconds(text: str, pattern: str) -> float:
    """The duration after ``pattern`` in ``text`` ("36 s", "2.88 min", "1.2 h") [s]; NaN."""
    match = re.search(pattern + r"(\d+(?:\.\d+)?(?:e[+-]?\d+)?) (s|min|h|days)\b", text)
    if match is None:
        return float("nan")
    scale = {"s": 1.0, "min": 60.0, "h": 3600.0, "days": 86400.0}[match.group(2)]
    return float(match.group(1)) * scale


def _cpu_job(args: list[str]) -> tuple[float, int, str]:
    """Run ``ident`` with ``args``: child CPU time [s], exit code, stdout + stderr."""
    ident = shutil.which("ident") or str(Path(sys.executable).with_name("ident"))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run([ident, *args], capture_output=True, text=True, check=False)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, done.returncode, done.stdout + done.stderr


def _run_folder(output: str) -> Path | None:
    """The run folder ``ident run`` printed ("Run folder: ..."), or None."""
    folder = next(
        (ln.split(":", 1)[1].strip() for ln in output.splitlines() if ln.startswith("Run folder:")),
        "",
    )
    return Path(folder) if folder else None


def _run_outcome(output: str) -> tuple[str, str, str]:
    """Verdict, worst parameter error and smallest clearance of a run, from its result.json
    (or the error line)."""
    folder = _run_folder(output)
    if folder is None or not (folder / "result.json").is_file():
        error = next((ln for ln in output.splitlines() if ln.startswith("error:")), "failed")
        return error[:60], "-", "-"
    data = json.loads((folder / "result.json").read_text(encoding="utf-8"))
    verdict = data.get("verdict", {})
    worst = verdict.get("worst_error_percent")
    match = re.search(
        r"clearance (-?\d+(?:\.\d+)?) m at", data.get("safety", {}).get("message", "")
    )
    ok = "" if data.get("safety", {}).get("ok", False) else " UNSAFE"
    return (
        str(verdict.get("label", data.get("status", "?"))),
        "-" if worst is None else f"{worst:.1f} %",
        ("-" if match is None else f"{float(match.group(1)) * 1e3:.1f} mm") + ok,
    )


def _retried(output: str) -> bool:
    """Whether the run optimized again at a wider safety margin (its result.json's safety
    message says so): the run's estimate is then its worst case ("up to ...")."""
    folder = _run_folder(output)
    if folder is None or not (folder / "result.json").is_file():
        return False
    data = json.loads((folder / "result.json").read_text(encoding="utf-8"))
    return "optimized again" in data.get("safety", {}).get("message", "")


def _independent(folder: Path | None) -> str:
    """The run's trajectory re-checked by :mod:`independent_safety` (plain Pinocchio + coal,
    none of ident's safety code): "pass 13.3 mm" (its smallest clearance), or what failed."""
    from independent_safety import check_run_folder  # beside this file

    if folder is None or not (folder / "trajectory.csv").is_file():
        return "- (no trajectory)"
    try:
        verdict = check_run_folder(folder)
    except Exception as e:  # a folder it cannot read: say so in the table
        return f"error: {type(e).__name__}: {e}"[:80]
    smallest = 1e3 * min(verdict.clearance_m, verdict.floor_m)
    text = f"pass {smallest:.1f} mm" if verdict.ok else "FAIL " + "; ".join(verdict.failures)
    unjustified = sum("excluded by ident, but" in n for n in verdict.notes)
    if unjustified:
        text += f" ({unjustified} exclusion(s) unjustified, checked)"
    if verdict.not_checked:
        text += " (not checked: " + "; ".join(verdict.not_checked) + ")"
    return text


def _ratio(estimate: float, measured: float) -> str:
    """``estimate / measured``, flagged with ``!`` outside [0.5, 2]; "-" without an estimate."""
    if estimate != estimate or measured <= 0:
        return "-"
    ratio = estimate / measured
    return f"{ratio:.2f}" + ("" if 0.5 <= ratio <= 2.0 else "!")


def zoo_robots(
    names: list[str], fetched: Path | None
) -> list[tuple[str, Path | None, tuple[str, ...], str]]:
    """The arms of :data:`ZOO` and :data:`FETCHED` named in ``names`` (all when empty): name,
    description file (None when absent), extra ``init`` options, and why it is absent."""
    import importlib.metadata

    share = importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share")
    robots = Path(str(share)) / "example-robot-data/robots"
    out: list[tuple[str, Path | None, tuple[str, ...], str]] = [
        (name, robots / path, extra, "") for name, path, extra in ZOO if not names or name in names
    ]
    for name, path, script in FETCHED:
        if names and name not in names:
            continue
        if fetched is None or not (fetched / path).is_file():
            where = "no --fetched DIR" if fetched is None else f"no {path} in {fetched}"
            why = f"not fetched ({where}; sh benchmarks/{script} DIR, then --fetched DIR)"
            out.append((name, None, (), why))
        else:
            out.append((name, fetched / path, ("--package-dir", str(fetched)), ""))
    return out


def zoo(
    names: list[str], quick: bool = True, keep: Path | None = None, fetched: Path | None = None
) -> None:
    """``ident init`` then ``ident run --quick`` (the full run when not ``quick``) on each arm
    of :data:`ZOO` and :data:`FETCHED` (all, or ``names``; a fetched one is looked for in
    ``fetched``): CPU, estimates against the CPU, verdict, worst error, smallest clearance; the
    run folders are kept in ``keep`` when given."""
    chosen = zoo_robots(names, fetched)
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at start")
    print(
        f"{'robot':12s} {'init CPU':>9s} {'run CPU':>9s} {'init est':>8s} {'ratio':>6s} "
        f"{'run est':>8s} {'ratio':>6s}  {'verdict':24s} {'worst err':>9s}  {'clearance':>10s}  "
        "independent check"
    )
    with tempfile.TemporaryDirectory(prefix="ident-zoo-") as tmp:
        out = tmp if keep is None else str(keep)
        for name, path, extra, why in chosen:
            if path is None:
                print(f"{name:12s} skipped: {why}", flush=True)
                continue
            config = Path(out) / f"{name}.yaml"
            init_cpu, code, text = _cpu_job(["init", str(path), "-o", str(config), *extra])
            if code != 0:
                print(
                    f"{name:12s} {init_cpu:9.1f}  init failed: {text.strip().splitlines()[-1][:90]}"
                )
                continue
            init_est = _seconds(text, r"--quick' about " if quick else r"yaml' about ")
            budget = ["--quick"] if quick else []
            run_cpu, _, output = _cpu_job(
                ["run", str(config), *budget, "--no-replay", "--out", str(Path(out) / "runs")]
            )
            run_est = _seconds(output, r"estimate: run: .*?memory and ")
            verdict, worst, clearance = _run_outcome(output)
            if _retried(output):  # the estimate of what ran: its worst case, marked r
                run_est = _seconds(output, r"estimate: run: .*?memory and .*?up to ")
                init_est = _seconds(text, r"; up to " if quick else r"; up to \d+ s and ")
            # ident run prints its estimate only above a minute (the same model as init's)
            shown = "-" if run_est != run_est else f"{run_est:.0f}" + "r" * _retried(output)
            print(
                f"{name:12s} {init_cpu:9.1f} {run_cpu:9.1f} "
                f"{f'{init_est:.0f}' + 'r' * _retried(output):>8s} "
                f"{_ratio(init_est, run_cpu):>6s} {shown:>8s} {_ratio(run_est, run_cpu):>6s}  "
                f"{verdict[:24]:24s} {worst:>9s}  {clearance:>10s}  "
                f"{_independent(_run_folder(output))}",
                flush=True,
            )


if __name__ == "__main__":
    main()
