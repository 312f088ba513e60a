"""Shared pytest setup: every test runs from the repository root.

Tests name project files by their repository paths (``configs/paper6r.yaml``,
``robot/urdf/paper6r.urdf``), as a user would from a checkout; this makes ``pytest`` give the
same result whatever folder it is started from.
"""

import fcntl
import functools
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from threadpoolctl import threadpool_limits
from xdist.scheduler import LoadFileScheduling

REPO_ROOT = Path(__file__).resolve().parents[1]

# Some test modules load the paper robot at import time, during collection.
os.chdir(REPO_ROOT)

# pytest-xdist runs one worker per core: a second BLAS thread per worker only oversubscribes
# the cores (a 2000 x 6-row reduction took 7 s instead of 0.1 s on a loaded machine). The
# variables reach the CLI subprocesses; threadpoolctl limits the library already loaded.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
threadpool_limits(limits=1, user_api="blas")


#: The xdist work unit of every test file that reads :func:`shipped_run`'s folders.
SHIPPED_RUNS_UNIT = "tests/<files reading shipped runs>"
#: The xdist work unit of the test files that read :func:`tiago_identified`.
TIAGO_UNIT = "tests/<files reading the TIAGo identification>"


class _ShippedRunsTogether(LoadFileScheduling):
    """pytest-xdist's ``--dist loadfile``, except that the files reading the shipped runs are
    one work unit: one worker runs each shipped config once and its readers one after the
    other, instead of the second worker waiting on the first one's file lock (a full run
    takes minutes). That unit goes out first (the suite's longest chain), then the units with
    end-to-end tests (a ``slow`` mark: a few tests of tens of seconds each), then the rest,
    each group by its number of tests (xdist's order). Longest first: xdist orders by the
    number of tests only, so a file of three minute-long runs could start last and keep one
    worker busy while the other waits at the end."""

    _ordered = False

    def _split_scope(self, nodeid: str) -> str:
        path = nodeid.split("::", 1)[0]
        if _reads_shipped_runs(path):
            return SHIPPED_RUNS_UNIT
        # the readers of the TIAGo identification (a session fixture) on one worker too
        return TIAGO_UNIT if _mentions(path, "tiago_identified") else path

    def _assign_work_unit(self, node: object) -> None:
        if not self._ordered:  # the queue is complete at the first assignment
            for scope in sorted(self.workqueue, key=_cost_rank):
                self.workqueue.move_to_end(scope)
            self._ordered = True
        super()._assign_work_unit(node)  # type: ignore[arg-type]


def _cost_rank(scope: str) -> int:
    """0 the shipped runs, 1 a unit with a ``slow`` test, 2 the rest: the order the units
    go out in (a stable sort keeps xdist's order within a rank)."""
    if scope == SHIPPED_RUNS_UNIT:
        return 0
    return 1 if scope == TIAGO_UNIT or _mentions(scope, "mark.slow") else 2


def _reads_shipped_runs(path: str) -> bool:
    return _mentions(path, "shipped_run")


@functools.cache
def _mentions(path: str, name: str) -> bool:
    file = REPO_ROOT / path
    return file.suffix == ".py" and name in file.read_text(encoding="utf-8")


def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> LoadFileScheduling | None:
    if config.getoption("dist") != "loadfile":
        return None  # another mode asked for on the command line: xdist's own
    return _ShippedRunsTogether(config, log)  # type: ignore[arg-type]


#: Set by .ci/run: the type check starts beside the tests (:func:`pytest_sessionstart`).
TYPECHECK_VARIABLE = "IDENT_TYPECHECK_BESIDE_TESTS"
_TYPECHECK: list[subprocess.Popen] = []


def pytest_sessionstart(session: pytest.Session) -> None:
    """Under CI, ``mypy src`` in the background while the tests run (the controller only, not
    each xdist worker): its 47 s of one core ran alone after the tests; now .ci/run's own
    ``mypy src`` after them reads the warm cache (a few seconds) and prints what it finds."""
    if os.environ.get(TYPECHECK_VARIABLE) and not hasattr(session.config, "workerinput"):
        _TYPECHECK.append(
            subprocess.Popen(
                [sys.executable, "-m", "mypy", "src"],
                cwd=REPO_ROOT,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        )


def pytest_sessionfinish(session: pytest.Session) -> None:
    """Wait for the background type check (its cache is what .ci/run's check reads)."""
    for process in _TYPECHECK:
        process.wait()


@pytest.fixture(autouse=True)
def _run_from_repository_root(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(REPO_ROOT)


@pytest.fixture(scope="session")
def shipped_run(tmp_path_factory: pytest.TempPathFactory):
    """``shipped_run(name, exit_code=0)``: the folder of ``ident run configs/<name>.yaml
    --no-replay`` (its exit code asserted), run once per test session and shared by the tests
    that inspect it.

    Under pytest-xdist the workers share it too: the first worker that needs a config runs it
    in the session's common temporary folder under a file lock, the others wait and reuse it
    (the pattern of pytest-xdist's documentation; a full run takes minutes).
    """
    from typer.testing import CliRunner

    from ident.cli import app

    base = tmp_path_factory.getbasetemp()
    # a worker's folder is <session>/popen-gwN: the session's is shared by the workers
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base

    def run(name: str, exit_code: int = 0) -> Path:
        out = shared / f"shipped-{name}"
        with open(shared / f"shipped-{name}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
            if not (out / "done").exists():
                out.mkdir(exist_ok=True)
                config = REPO_ROOT / "configs" / f"{name}.yaml"
                result = CliRunner().invoke(
                    app, ["run", str(config), "--out", str(out), "--no-replay"]
                )
                assert result.exit_code == exit_code, result.output
                (out / "done").write_text(str(result.exit_code))
        # the exit code every caller expects (1: the run warns, e.g. the paper's arm is unsafe)
        assert (out / "done").read_text() == str(exit_code)
        (folder,) = [p for p in out.iterdir() if p.is_dir()]
        return folder

    return run


@pytest.fixture(scope="session")
def tiago_identified(tmp_path_factory: pytest.TempPathFactory):
    """``ident identify configs/examples/tiago.yaml --out TMP`` run once per test process for
    the files that read it (tests/test_tiago_example.py, tests/test_one_std.py: each ran the
    same identification, about 10 s of CPU): its terminal output, run folder, result.json and
    the :class:`IdentifyResult` it computed."""
    import json

    from typer.testing import CliRunner

    import ident.identify.pipeline.real
    from ident.cli import app

    out = tmp_path_factory.mktemp("tiago")
    seen = []
    original = ident.identify.pipeline.real.identify

    def keep(*args, **kwargs):
        seen.append(original(*args, **kwargs))
        return seen[-1]

    with pytest.MonkeyPatch.context() as mp:  # the CLI imports identify when it runs
        mp.setattr(ident.identify.pipeline.real, "identify", keep)
        config = REPO_ROOT / "configs" / "examples" / "tiago.yaml"
        cli = CliRunner().invoke(app, ["identify", str(config), "--out", str(out)])
    assert cli.exit_code == 0, cli.output
    (folder,) = out.iterdir()
    return cli.output, folder, json.loads((folder / "result.json").read_text()), seen[0]


@pytest.fixture
def ridge(monkeypatch: pytest.MonkeyPatch) -> None:
    """The toy estimator of docs/consistent-identification.md ("Extending"), registered by
    running the page's code (unconstrained: not consistent), for this test only."""
    from ident.identify.estimators import registry

    monkeypatch.setattr(registry, "ESTIMATORS", dict(registry.ESTIMATORS))
    monkeypatch.setattr(registry, "CONTRACTS", dict(registry.CONTRACTS))
    text = (REPO_ROOT / "docs" / "consistent-identification.md").read_text()
    section = text[text.index("## Extending") :]
    code = re.search(r"```python\n(.*?)```", section, re.S)
    assert code is not None, "the Extending section lost its code block"
    exec(code.group(1), {})
    assert not registry.get_contract("ridge").consistent
