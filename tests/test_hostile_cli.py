"""Every command on every hostile input of ``tests/data/hostile/``: one clear line, nothing left.

Each case of ``tests/data/hostile/manifest.yaml`` names a command line. Every case must end
with exit code 2, exactly one ``error:`` line on stderr, no traceback, and no file or folder
left in its (empty) working folder or in the corpus.

The cases run in worker subprocesses (this file run as a script) under an address-space and a
CPU-time limit, a few hundred cases per interpreter through typer's ``CliRunner`` so that the
start-up cost (Pinocchio, numpy) is paid once per worker; a case that hangs, crashes or blows
the limits kills only its worker, which is restarted for the remaining cases. Cases marked
``xfail`` in the manifest are known gaps (strict: they turn into failures once fixed, so the
mark is removed).
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest
import yaml

HERE = Path(__file__).resolve().parent
CORPUS = HERE / "data" / "hostile"
ROOT = HERE.parent

MEMORY_LIMIT_BYTES = 3 << 30  # address space of a worker
CPU_LIMIT_S = 300  # CPU seconds of a worker (all its cases)
CASE_TIMEOUT_S = 60  # wall time of one case
N_WORKERS = 2


def _manifest() -> list[dict]:
    # libyaml's loader: 0.08 s instead of 0.65 s for the 700 cases, paid by every process
    # that imports this file (pytest's, each xdist worker's at collection, each case worker)
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    return yaml.load((CORPUS / "manifest.yaml").read_text(encoding="utf-8"), Loader=loader)


def _expand(args: list[str], tmp: Path) -> list[str]:
    return [a.replace("{data}", str(CORPUS)).replace("{tmp}", str(tmp)) for a in args]


def _tree(folder: Path) -> dict[str, tuple[int, int]]:
    """Relative path -> (size, mtime_ns) of every file and folder under ``folder``."""
    # walked after each of some 700 cases: os.scandir's entries and plain strings, not Path
    # objects (40 ms a walk of the corpus's 900 entries with them, 11 ms with os.walk and
    # os.lstat, 7 ms so)
    out = {}
    start = len(str(folder)) + 1
    todo = [str(folder)]
    while todo:
        with os.scandir(todo.pop()) as entries:
            for entry in entries:
                st = entry.stat(follow_symlinks=False)
                out[entry.path[start:]] = (st.st_size, st.st_mtime_ns)
                if entry.is_dir(follow_symlinks=False):
                    todo.append(entry.path)
    return out


# ---------------------------------------------------------------------------------------------
# worker side (this file run as a script)


def _limit_resources() -> None:
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT_BYTES, MEMORY_LIMIT_BYTES))
    resource.setrlimit(resource.RLIMIT_CPU, (CPU_LIMIT_S, CPU_LIMIT_S))


def _inject_fault(fileio, primitives: dict, fault: dict) -> None:
    """Make ``ident.fileio``'s write primitive fail as a full disk, a read-only folder, ... do.

    ``fault``: ``errno`` (a name of :mod:`errno`), ``file`` (a glob on the name of the file
    being written), ``step``: ``write`` (the disk fills half way through the data) or
    ``create`` (the temporary file cannot be created: read-only folder, no permission).
    """
    import errno
    import fnmatch

    code = getattr(errno, fault["errno"])

    def hit(path) -> bool:
        return fnmatch.fnmatch(Path(path).name, fault["file"])

    if fault.get("step", "write") == "create":
        create = primitives["create"]

        def failing_create(path, tmp):
            if hit(path):
                raise OSError(code, os.strerror(code), str(path.parent))
            return create(path, tmp)

        fileio._create_temporary = failing_create
    else:
        write = primitives["write"]

        def failing_write(file, data, path):
            if hit(path):
                file.write(data[: len(data) // 2])
                raise OSError(code, os.strerror(code))
            return write(file, data, path)

        fileio._write_data = failing_write


def _worker_main() -> None:
    """Read one JSON case per line on stdin, answer one JSON result per line on stdout.

    A case runs the console entry point ``ident.cli.main`` in this process, as a user's
    shell would (argv, exit code, stderr), with stdout and stderr captured.
    """
    import contextlib
    import io
    import signal
    import traceback

    _limit_resources()
    sys.path.insert(0, str(ROOT / "src"))
    from ident.cli import main

    class _Timeout(BaseException):
        pass

    def _alarm(signum, frame):
        raise _Timeout

    signal.signal(signal.SIGALRM, _alarm)
    import ident.fileio as fileio

    primitives = {"write": fileio._write_data, "create": fileio._create_temporary}
    out = sys.stdout
    out.write(json.dumps({"ready": True}) + "\n")
    out.flush()
    for line in sys.stdin:
        case = json.loads(line)
        os.chdir(case["tmp"])
        err = io.StringIO()
        t0, c0 = time.perf_counter(), time.process_time()
        signal.alarm(CASE_TIMEOUT_S)
        if case.get("fault"):
            _inject_fault(fileio, primitives, case["fault"])
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                sys.argv = ["ident", *case["args"]]
                main()
            exit_code = 0
        except SystemExit as e:
            exit_code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
        except _Timeout:
            exit_code = -1
            err.write(f"timeout after {CASE_TIMEOUT_S} s")
        except BaseException as e:  # noqa: BLE001 - what a user would see as a traceback
            exit_code = 1
            err.write("".join(traceback.format_exception(e)))
        finally:
            signal.alarm(0)
            fileio._write_data = primitives["write"]
            fileio._create_temporary = primitives["create"]
        record = {
            "id": case["id"],
            "exit_code": exit_code,
            "stderr": err.getvalue()[-4000:],
            "seconds": time.perf_counter() - t0,
            "cpu": time.process_time() - c0,  # CPU seconds: what the case costs the suite
        }
        out.write(json.dumps(record) + "\n")
        out.flush()


# ---------------------------------------------------------------------------------------------
# pytest side


class _Worker:
    def __init__(self) -> None:
        env = {
            **os.environ,
            "PYTHONPATH": str(ROOT / "src"),
            "COLUMNS": "200",
            # ceilings of ident.inputs.check_job: a job planned beyond them is refused
            "IDENT_MAX_HOURS": "0.05",
            "IDENT_MAX_MEMORY_GB": "2",
        }
        self.proc = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve())],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            env=env,
            cwd=ROOT,
        )
        self._lines: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()
        self._next(120.0)  # {"ready": true}

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self._lines.put(line)
        self._lines.put(None)

    def _next(self, timeout: float) -> dict | None:
        try:
            line = self._lines.get(timeout=timeout)
        except queue.Empty:
            return None
        return None if line is None else json.loads(line)

    def run(self, case_id: str, args: list[str], tmp: Path, fault: dict | None) -> dict | None:
        assert self.proc.stdin is not None
        case = {"id": case_id, "args": args, "tmp": str(tmp), "fault": fault}
        self.proc.stdin.write(json.dumps(case) + "\n")
        self.proc.stdin.flush()
        return self._next(CASE_TIMEOUT_S + 30.0)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()


def _run_all(cases: list[dict], base: Path) -> dict[str, dict]:
    todo: queue.Queue[dict] = queue.Queue()
    for c in cases:
        todo.put(c)
    results: dict[str, dict] = {}

    def serve() -> None:
        worker = _Worker()
        # the corpus as this worker's previous case left it: one walk per case, after it (the
        # walk before a case would repeat the last one's; a change made meanwhile by the other
        # worker's case shows in both workers' next walk, as it did with a walk before)
        corpus = _tree(CORPUS)
        try:
            while True:
                try:
                    case = todo.get_nowait()
                except queue.Empty:
                    return
                tmp = base / case["id"]
                tmp.mkdir()
                setup = case.get("setup")
                if setup:
                    shutil.copytree(CORPUS / setup["copy"], tmp / setup["to"])
                    if "run_json" in setup:
                        (tmp / setup["to"] / "run.json").write_text(json.dumps(setup["run_json"]))
                try:
                    record = worker.run(
                        case["id"], _expand(case["args"], tmp), tmp, case.get("fault")
                    )
                except (BrokenPipeError, OSError):
                    record = None
                if record is None:  # crashed, killed by a limit or hung: a new worker
                    code = worker.proc.poll()
                    worker.close()
                    record = {
                        "id": case["id"],
                        "exit_code": -2,
                        "stderr": f"worker died (exit {code}) or hung",
                        "seconds": float("nan"),
                        "cpu": float("nan"),
                    }
                    worker = _Worker()
                record["left"] = sorted(_tree(tmp))
                record["left_files"] = sorted(
                    str(p.relative_to(tmp)) for p in tmp.rglob("*") if not p.is_dir()
                )
                record["states"] = [
                    json.loads(p.read_text(encoding="utf-8", errors="replace") or "null")
                    if p.stat().st_size < 1 << 20
                    else None
                    for p in sorted(tmp.rglob("run.json"))
                    if setup is None
                ]
                before, corpus = corpus, _tree(CORPUS)
                record["corpus_changed"] = sorted(
                    k for k, v in corpus.items() if before.get(k) != v
                ) + sorted(set(before) - set(corpus))
                results[case["id"]] = record
        finally:
            worker.close()

    threads = [threading.Thread(target=serve) for _ in range(N_WORKERS)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return results


CASES = _manifest()


@pytest.fixture(scope="module")
def outcomes():
    with tempfile.TemporaryDirectory(prefix="ident-hostile-") as base:
        t0 = time.perf_counter()
        results = _run_all(CASES, Path(base))
        wall = time.perf_counter() - t0
        slowest = sorted(results.values(), key=lambda r: -(r["cpu"] or 0))[:8]
        print(
            f"\n{len(results)} hostile cases in {wall:.1f} s on {N_WORKERS} workers; most CPU: "
            + ", ".join(f"{r['id']} {r['cpu']:.1f} s ({r['seconds']:.1f} s wall)" for r in slowest)
        )
        yield results


def test_corpus_is_large_and_covers_every_command():
    commands = {c["args"][0] for c in CASES}
    assert commands >= {"run", "identify", "verify", "urdf", "replay", "bench", "report", "init",
                        "payload", "repeatability"}  # fmt: skip
    assert len(CASES) >= 600
    writers = {c["args"][0] for c in CASES if c.get("fault")}
    assert writers >= {"run", "identify", "urdf", "replay", "bench", "report"}
    assert len({c["id"] for c in CASES}) == len(CASES)


@pytest.mark.parametrize(
    "case",
    [
        pytest.param(
            c,
            id=c["id"],
            marks=[pytest.mark.xfail(strict=True, reason=c["xfail"])] if c.get("xfail") else [],
        )
        for c in CASES
    ],
)
def test_hostile_input_is_one_clear_error(case, outcomes):
    r = outcomes[case["id"]]
    expect = case.get("expect", {})
    stderr = r["stderr"]
    errors = [line for line in stderr.splitlines() if line.startswith("error:")]
    assert "Traceback" not in stderr, stderr
    assert r["exit_code"] == expect.get("exit", 2), stderr
    assert len(errors) == (1 if expect.get("exit", 2) == 2 else 0), stderr
    for part in expect.get("match", []):  # the one line names the file, the field, the cause
        assert part in errors[0], (part, errors[0])
    if expect.get("warning"):
        assert any(line.startswith("warning:") for line in stderr.splitlines()), stderr
    left = expect.get("left", "none")
    if left == "none":
        assert r["left"] == [], f"left behind: {r['left']}"
    elif left == "dirs":  # empty parent folders may stay, never a file
        assert r["left_files"] == [], f"left behind: {r['left_files']}"
    # never a temporary file of an interrupted atomic write
    assert not [f for f in r["left_files"] if Path(f).name.endswith(".tmp")], r["left_files"]
    if "state" in expect:  # the run folder says what failed
        assert r["states"], "no run.json"
        (state,) = r["states"]
        assert state["status"] == expect["state"], state
        reason = os.strerror(getattr(__import__("errno"), case["fault"]["errno"]))
        assert reason in state["message"], state
    if case.get("fault"):  # the one error line says what happened to which file
        reason = os.strerror(getattr(__import__("errno"), case["fault"]["errno"]))
        assert reason in errors[0] or reason in stderr, stderr
    assert r["corpus_changed"] == [], f"corpus changed: {r['corpus_changed']}"


if __name__ == "__main__":
    _worker_main()
