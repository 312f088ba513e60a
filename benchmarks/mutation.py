"""Mutation testing of the identification core: the share of mutants its focused tests kill.

For each core module (``--modules``, default all) this runs mutmut (pinned: the ``mutation``
extra of pyproject.toml) with that module as the only mutated code and its own focused test
files as the only tests, then prints one table: module, mutants, killed, survived, timeout,
no tests, killed share, minutes, and the total. The killed share is strict: killed mutants
over all mutants (a timeout, a mutant no focused test reaches and a survivor all count as not
killed), except the surviving mutants :data:`EQUIVALENT` lists with the reason no test can kill
them (column "equivalent", left out of the total). Usage::

    python benchmarks/mutation.py [--modules verdict base_parameters] [--max-children 2]
                                  [--fresh | --retest] [--survivors] [--deselect NODE_ID ...]
                                  [--functions NAME ...] [--table]

``--functions`` limits a run (and the module's counts) to the mutants of the named functions
or methods (``lowpass``, ``ranges``; ``least_squares._solve``: that module's only): on a
loaded machine a whole module can take too long, and the table then says ``(functions)``
after the module's name. ``--table`` prints the table
of the modules' last saved results without running anything.

mutmut 3 copies the tree into ``mutants/`` and imports it from there; each module gets its own
folder ``mutants/<module>/`` (a few symbolic links to the checkout), so the modules' results
the results (``mutants/<module>/results.json``) stay apart. A run tests every mutant;
``--retest`` re-runs only the ones the last run did not kill (after adding tests) and keeps
the others' results; ``--fresh`` starts from a clean copy. The whole
``src/ident`` package is copied, the files outside the module unmutated: a partial copy would
make ``mutants/src/ident`` a namespace portion and the tests would import the unmutated
package. The data the tests read (``also_copy`` of ``[tool.mutmut]``) is copied next to it.
Tests marked ``slow`` are not run (``--with-slow`` runs them); a test that spawns ``ident`` in
a subprocess imports the checkout, not the mutant, and cannot kill it.

``--survivors`` lists each surviving mutant's diff (``mutmut show``); from a module's folder,
``mutmut browse`` shows them interactively.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import tomllib  # Python 3.11+, as the venv the mutation extra is installed in

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = Path("src/ident")

# module name -> (mutated source files, focused test files), paths from the repository root
MODULES: dict[str, tuple[list[str], list[str]]] = {
    "verdict": (
        ["src/ident/identify/assessment/verdict.py"],
        ["tests/test_verdict.py", "tests/test_verdict_mutants.py"],
    ),
    "base_parameters": (
        ["src/ident/dynamics/base_parameters.py"],
        ["tests/test_base_parameters.py", "tests/test_base_parameters_mutants.py"],
    ),
    "estimate": (
        ["src/ident/identify/estimation/estimate.py"],
        ["tests/test_estimate.py", "tests/test_essential.py", "tests/test_estimate_mutants.py"],
    ),
    "preprocess": (
        ["src/ident/identify/estimation/preprocess.py"],
        ["tests/test_preprocess.py", "tests/test_preprocess_mutants.py"],
    ),
    "accumulate": (
        [
            "src/ident/identify/estimation/accumulate.py",
            "src/ident/identify/estimation/log_chunks.py",
        ],
        ["tests/test_accumulate.py", "tests/test_accumulate_mutants.py"],
    ),
    "estimators": (
        ["src/ident/identify/estimators/*.py"],
        ["tests/test_estimators*.py"],
    ),
}

# Equivalent mutants: module -> {mutant name pattern (fnmatch): why no test can kill it}. A
# matching mutant that survives is left out of the module's counts (column "equivalent"); one
# that is killed counts as killed (then the reason was wrong).
EQUIVALENT: dict[str, dict[str, str]] = {
    "estimate": {
        "*.x__wls__mutmut_1[3-6]": "np.errstate arguments only silence warnings",
        "*.x__wls__mutmut_2[5-8]": "np.errstate arguments only silence warnings",
        "*.x_least_squares_reduced__mutmut_11[0-3]": "np.errstate arguments only silence warnings",
        "*.x__covariance_unit__mutmut_[47]": "check_finite: _checked has refused NaN/inf",
        "*.x__covariance_unit__mutmut_10": "check_finite: _checked has refused NaN/inf",
        "*.x__wls__mutmut_8[145]": "check_finite: _checked has refused NaN/inf",
        "*.x_least_squares_reduced__mutmut_28": "check_finite: _checked has refused NaN/inf",
        "*.x_least_squares_reduced__mutmut_3[12]": "check_finite: _checked has refused NaN/inf",
        "*.x__covariance_unit__mutmut_9": "R is square: R.shape[0] == R.shape[1]",
        "*.x__wls__mutmut_3": "astype(None) of the int row counts is float64 too",
        "*.x_least_squares_reduced__mutmut_14": "astype(None) of the int row counts is float64",
        "*.x__wls__mutmut_8": "zero is reassigned in the first pass before any use",
        "*.x__wls__mutmut_1[02]": "zero is reassigned in the first pass before any use",
        "*.x__wls__mutmut_3[67]": "a factor common to every group's sigma cancels in x, the "
        "covariance (sigma_w^2 absorbs it) and the reported sigma * sigma_w",
        "*.x_least_squares_reduced__mutmut_35": "svd(compute_uv=None): None is falsy, the same",
        "*.x_least_squares_reduced__mutmut_104": "the clip's lower bound: diag(R^-1 R^-T) is a "
        "sum of squares, never negative",
    },
    "estimators": {
        "*.x_get_estimator__mutmut_8": "get_close_matches(n=3): only close[0] is shown",
        "*.x_get_estimator__mutmut_10": "get_close_matches(n=2): only close[0] is shown",
    },
}

# exit code of a mutant's test run -> status (mutmut's own table, mutmut.__main__)
KILLED, SURVIVED, TIMEOUT, NO_TESTS = "killed", "survived", "timeout", "no tests"


def expand(patterns: list[str]) -> list[str]:
    """The repository paths (sorted, relative to the root) that the glob patterns name."""
    out: set[str] = set()
    for pattern in patterns:
        found = sorted(str(p.relative_to(ROOT)) for p in ROOT.glob(pattern))
        if not found:
            raise SystemExit(f"error: {pattern!r} names no file; fix MODULES in {__file__}")
        out.update(found)
    return sorted(out)


def mutmut_settings() -> dict:
    """``[tool.mutmut]`` of pyproject.toml (``also_copy`` is what the folders need)."""
    with open(ROOT / "pyproject.toml", "rb") as f:
        return tomllib.load(f).get("tool", {}).get("mutmut", {})


def prepare_folder(name: str) -> Path:
    """``mutants/<name>/``: the working folder of one module's mutmut run, holding links to the
    checkout's pyproject.toml and top-level folders (mutmut copies from there)."""
    folder = ROOT / "mutants" / name
    folder.mkdir(parents=True, exist_ok=True)
    for entry in ["src", "tests", "pyproject.toml", *mutmut_settings().get("also_copy", [])]:
        entry = entry.rstrip("/")
        link = folder / entry
        if not link.is_symlink():
            link.symlink_to(ROOT / entry)
    return folder


def worker(spec: dict) -> None:
    """Run mutmut on one module in the current folder (a subprocess of :func:`main`, so that
    nothing of ``ident`` is imported before mutmut puts ``mutants/src`` first on the path)."""
    import _pytest.nodes
    import mutmut
    import mutmut.__main__ as mm

    # mutmut 3.3.1 maps tests to functions through ``item._nodeid``, which pytest 8.4 dropped
    if not hasattr(_pytest.nodes.Node, "_nodeid"):
        _pytest.nodes.Node._nodeid = property(lambda node: node.nodeid)  # type: ignore[attr-defined]

    mutated = set(spec["paths"])
    others = sorted(
        str(p)
        for p in PACKAGE.rglob("*.py")
        if str(p) not in mutated and "__pycache__" not in str(p)
    )
    mutmut.config = mm.Config(
        also_copy=[Path(p) for p in spec["also_copy"]] + [Path("tests/"), Path("pyproject.toml")],
        do_not_mutate=others,
        max_stack_depth=-1,
        debug=False,
        paths_to_mutate=[PACKAGE],
        tests_dir=spec["pytest_args"],
    )
    # mutmut's incremental stats run new tests by node id, without the selection (-m, --deselect)
    # of tests_dir: collect the map of tests to functions afresh (one run of the focused tests)
    Path("mutants/mutmut-stats.json").unlink(missing_ok=True)
    mm._run(spec["retest"], spec["max_children"])


def statuses(folder: Path, paths: list[str], *, saved: bool = True) -> dict[str, str]:
    """Mutant name -> status: this script's ``results.json`` of the module's last run, else
    mutmut's result files of the module's sources."""
    from mutmut.__main__ import status_by_exit_code

    results = folder / "results.json"
    if saved and results.exists():
        return dict(json.loads(results.read_text()))
    out: dict[str, str] = {}
    for path in paths:
        meta = folder / "mutants" / (path + ".meta")
        if not meta.exists():
            continue
        for key, code in json.loads(meta.read_text())["exit_code_by_key"].items():
            out[key] = status_by_exit_code.get(code, f"exit {code}")
    return out


def function_patterns(functions: list[str]) -> list[str]:
    """mutmut's name patterns (``fnmatch``) of the mutants of the named functions or methods:
    ``<module>.x_<name>__mutmut_<k>`` for a function, ``<module>.xǁ<Class>ǁ<name>__mutmut_<k>``
    for a method. ``least_squares._solve`` names the one of that module only."""
    out = []
    for f in functions:
        module, _, name = f.rpartition(".")
        prefix = f"*{module}." if module else "*."
        out += [f"{prefix}x_{name}__mutmut_*", f"{prefix}xǁ*ǁ{name}__mutmut_*"]
    return out


def only_functions(status: dict[str, str], functions: list[str]) -> dict[str, str]:
    """The entries of ``status`` that are mutants of ``functions`` (all when it is empty)."""
    if not functions:
        return status
    patterns = function_patterns(functions)
    return {k: v for k, v in status.items() if any(fnmatch.fnmatch(k, p) for p in patterns)}


def run_module(name: str, args: argparse.Namespace) -> dict:
    """Run mutmut on one module (subprocess in its folder); its counts and wall time [s]."""
    patterns, test_patterns = MODULES[name]
    paths = expand(patterns)
    tests = expand([t for t in test_patterns if any(ROOT.glob(t))])
    # in-process (-n 0): mutmut maps tests to the functions they run, which xdist workers hide
    pytest_args = [*tests, "-p", "no:cacheprovider", "-n", "0"]
    if not args.with_slow:
        pytest_args += ["-m", "not slow"]
    for node in args.deselect:
        pytest_args += ["--deselect", node]
    spec = {
        "paths": paths,
        "also_copy": mutmut_settings().get("also_copy", []),
        "pytest_args": pytest_args,
        "max_children": args.max_children,
    }
    folder = prepare_folder(name)
    if args.fresh and (folder / "mutants").exists():
        shutil.rmtree(folder / "mutants")
        (folder / "results.json").unlink(missing_ok=True)
    before = statuses(folder, paths)
    # the mutants to run: all ([]), those of --functions, or (--retest) those not killed before
    chosen = only_functions(before, args.functions)
    if args.retest:
        to_run = sorted(k for k, v in chosen.items() if v != KILLED)
    elif args.functions:  # by name when known, else by pattern (mutmut names them on a run)
        to_run = sorted(chosen) if before else function_patterns(args.functions)
    else:
        to_run = []
    spec["retest"] = to_run
    print(f"== {name}: {', '.join(paths)} against {', '.join(tests)}", flush=True)
    if args.retest:
        print(f"   retesting the {len(to_run)} mutants not killed before", flush=True)
    start = time.perf_counter()
    log = folder / "mutmut.log"
    if (args.retest or args.functions) and before and not to_run:
        log.write_text("nothing to run\n")
        return summary(name, before, 0.0, ok=True, args=args, folder=folder)
    with open(log, "w") as out:
        # one BLAS thread per mutant: mutmut limits each mutant's CPU time (RLIMIT_CPU, all
        # threads counted), and BLAS threads spinning on a loaded machine ran it out (numpy
        # code then read "timeout"); also no BLAS thread pool inherited across mutmut's fork
        threads = {k: "1" for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
        proc = subprocess.run(
            [sys.executable, __file__, "--worker", json.dumps(spec)],
            env={**os.environ, **threads},
            cwd=folder,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    seconds = time.perf_counter() - start
    status = statuses(folder, paths, saved=False)
    if before and to_run:  # mutmut 3.3.1 rewrites its result files: keep the others' results
        status = {**before, **{k: status.get(k, before[k]) for k in to_run}}
    (folder / "results.json").write_text(json.dumps(status, indent=1, sort_keys=True))
    ok = proc.returncode == 0 and bool(status)
    if not ok:
        print(f"   mutmut failed (exit {proc.returncode}); its output: {log}", flush=True)
    return summary(name, status, seconds, ok=ok, args=args, folder=folder)


def summary(
    name: str,
    status: dict[str, str],
    seconds: float,
    *,
    ok: bool,
    args: argparse.Namespace,
    folder: Path,
) -> dict:
    """The table row of one module; with ``--survivors``, print each survivor's diff."""
    status = only_functions(status, args.functions)
    reasons = EQUIVALENT.get(name, {})
    equivalent = {
        k for k, v in status.items() if v != KILLED and any(fnmatch.fnmatch(k, p) for p in reasons)
    }
    status = {k: v for k, v in status.items() if k not in equivalent}
    counts = {s: sum(1 for v in status.values() if v == s) for s in set(status.values())}
    survivors = sorted(k for k, v in status.items() if v != KILLED)
    if args.survivors:
        for key in survivors:
            shown = subprocess.run(
                [sys.executable, "-m", "mutmut", "show", key],
                cwd=folder,
                capture_output=True,
                text=True,
            )
            print(f"-- {status[key]}: {key}\n{shown.stdout.strip()}\n", flush=True)
    return {
        "module": name + (" (functions)" if args.functions else ""),
        "mutants": len(status),
        KILLED: counts.get(KILLED, 0),
        SURVIVED: counts.get(SURVIVED, 0),
        TIMEOUT: counts.get(TIMEOUT, 0),
        NO_TESTS: counts.get(NO_TESTS, 0),
        "equivalent": len(equivalent),
        "seconds": seconds,
        "ok": ok,
    }


def share(killed: int, total: int) -> str:
    return f"{100.0 * killed / total:.1f} %" if total else "-"


def print_table(rows: list[dict]) -> None:
    """module, killed/total, killed share, then the other counts (total: mutants left after
    the equivalent ones are set aside) and the minutes."""
    counts = (KILLED, SURVIVED, TIMEOUT, NO_TESTS, "equivalent")
    header = ("module", "killed/total", "killed share", *counts, "min")
    total = {k: sum(r[k] for r in rows) for k in ("mutants", *counts, "seconds")}
    lines = [header]
    for r in [*rows, {**total, "module": "total", "ok": True}]:
        lines.append(
            (
                r["module"] + ("" if r["ok"] else " (failed)"),
                f"{r[KILLED]}/{r['mutants']}",
                share(r[KILLED], r["mutants"]),
                *(str(r[k]) for k in counts),
                f"{r['seconds'] / 60:.1f}",
            )
        )
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    for k, line in enumerate(lines):
        cells = [line[0].ljust(widths[0])]
        cells += [c.rjust(w) for c, w in zip(line[1:], widths[1:], strict=True)]
        print("  ".join(cells))
        if k == 0 or k == len(lines) - 2:
            print("  ".join("-" * w for w in widths))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modules", nargs="+", choices=list(MODULES), default=list(MODULES))
    parser.add_argument("--max-children", type=int, default=2, help="parallel mutant runs")
    parser.add_argument("--survivors", action="store_true", help="print each survivor's diff")
    parser.add_argument("--fresh", action="store_true", help="forget the module's last results")
    parser.add_argument(
        "--retest", action="store_true", help="re-run only the mutants not killed last time"
    )
    parser.add_argument("--with-slow", action="store_true", help="also run tests marked slow")
    parser.add_argument(
        "--deselect", action="append", default=[], metavar="NODE_ID", help="a test not to run"
    )
    parser.add_argument(
        "--functions", nargs="+", default=[], metavar="NAME", help="only these functions' mutants"
    )
    parser.add_argument(
        "--table", action="store_true", help="print the last saved results, run nothing"
    )
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        worker(json.loads(args.worker))
        return
    if args.max_children < 1:
        parser.error("--max-children must be at least 1")
    if args.table:
        rows = []
        for name in args.modules:
            folder = ROOT / "mutants" / name
            if (folder / "results.json").exists():
                status = statuses(folder, expand(MODULES[name][0]))
                rows.append(summary(name, status, 0.0, ok=True, args=args, folder=folder))
        print_table(rows)
        return
    rows = [run_module(name, args) for name in args.modules]
    print()
    print_table(rows)


if __name__ == "__main__":
    main()
