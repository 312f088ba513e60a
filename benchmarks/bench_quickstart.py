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

Budget: about 1.5 min for the default pair on a loaded 2-core machine.
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
    args = parser.parse_args()
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


if __name__ == "__main__":
    main()
