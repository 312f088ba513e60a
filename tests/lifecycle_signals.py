"""SIGTERM at each file a command writes: the folder ends complete or says it is incomplete.

:func:`sigterm_at_each_file` starts the command (``python -m``-style, as a user's shell would)
again and again; run ``k`` polls the output folder and sends SIGTERM as soon as its ``k``-th
file appears, then checks what a user finds: exit 130, ``interrupted: <folder> is incomplete``
on stderr, ``run.json`` status ``incomplete`` and the ``INCOMPLETE`` marker, no temporary file.
The last run is the one whose files all appeared before the signal could be sent: it must have
finished complete. Each write of ``ident.fileio`` is preceded by a short pause in the child so
that the signal lands between the ``k``-th file and the next one.

Each run is a process of its own, forked from a Python process (one per test process) that has
imported ``ident.cli`` and the modules the commands import on their way (Pinocchio, SciPy,
Matplotlib, MuJoCo, CVXPY: 4-5 s of CPU a fresh process paid at each of some 15 runs); the
child runs the console entry point with the command's argv, cwd and environment, its stderr
captured, and exits as a fresh interpreter would (the code of ``SystemExit``, 1 and a
traceback for an uncaught exception, the signal's death once the command's handler is gone).
"""

from __future__ import annotations

import atexit
import json
import os
import select
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAUSE_S = 0.15  # before each atomic write in the child
#: Set, every test interrupts at every file (``every=1``), whatever its ``at`` and ``every``.
EVERY_FILE_VARIABLE = "IDENT_SIGTERM_EVERY_FILE"
#: What the commands import on their way, loaded once before the forks (a missing one is
#: only not preloaded: the child imports what it needs, as a fresh process does).
_PRELOAD = (
    "scipy.signal",
    "scipy.stats",
    "matplotlib",
    "mujoco",
    "cvxpy",
    "ident.run.pipeline",
    "ident.run.setup",
    "ident.run.exports.run_exports",
    "ident.identify.pipeline.real",
    "ident.identify.payload.payload",
    "ident.report.run_report",
    "ident.report.identify_report",
    "ident.bench.campaign",
    "ident.bench.report",
)
_ZYGOTE = f"""
import importlib, json, os, sys, time
import ident.fileio as fileio
write = fileio._write_data
def paused(file, data, path):
    time.sleep({PAUSE_S})
    write(file, data, path)
fileio._write_data = paused
from ident.cli import main
for name in {_PRELOAD!r}:
    try:
        importlib.import_module(name)
    except ImportError:
        pass
def say(**fields):
    sys.stdout.write(json.dumps(fields) + "\\n")
    sys.stdout.flush()
say(ready=True)
for line in sys.stdin:
    job = json.loads(line)
    pid = os.fork()
    if pid == 0:  # the command: an interpreter that ends as a fresh one would
        os.chdir(job["cwd"])
        null = os.open(os.devnull, os.O_RDWR)
        err = os.open(job["stderr"], os.O_WRONLY | os.O_TRUNC)
        os.dup2(null, 0)
        os.dup2(null, 1)
        os.dup2(err, 2)
        os.close(null)
        os.close(err)
        sys.argv = ["-c", *job["args"]]
        main()
        sys.exit(0)
    say(pid=pid)
    say(code=os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))
"""


class _Zygote:
    """The preloaded Python process that forks each run (see the module's docstring)."""

    def __init__(self) -> None:
        env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "COLUMNS": "200"}
        self.proc = subprocess.Popen(
            [sys.executable, "-c", _ZYGOTE],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env=env,
            cwd=ROOT,
        )
        self._buffer = b""  # read from its stdout with os.read: select sees what is unread
        self._code: int | None = None  # the last forked command's, once it ended
        assert self._message(120.0) == {"ready": True}

    def _message(self, timeout: float) -> dict | None:
        """The next line of the process as JSON; None if none came within ``timeout`` s."""
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        while b"\n" not in self._buffer:
            if not select.select([fd], [], [], timeout)[0]:
                return None
            chunk = os.read(fd, 4096)
            assert chunk, f"the forking process died (exit {self.proc.poll()})"
            self._buffer += chunk
        line, self._buffer = self._buffer.split(b"\n", 1)
        return json.loads(line)

    def start(self, args: list[str], cwd: Path, stderr: str) -> int:
        """Fork ``ident ARGS`` in ``cwd``, its stderr into the file ``stderr``: its pid."""
        assert self.proc.stdin is not None
        job = {"args": args, "cwd": str(cwd), "stderr": stderr}
        self.proc.stdin.write((json.dumps(job) + "\n").encode())
        self.proc.stdin.flush()
        self._code = None
        message = self._message(120.0)
        assert message is not None, "the forking process did not answer"
        return int(message["pid"])

    def finished(self, timeout: float = 0.0) -> bool:
        """Whether the forked command has ended (within ``timeout`` s): then :attr:`code`."""
        if self._code is None:
            message = self._message(timeout)
            if message is not None:
                self._code = int(message["code"])
        return self._code is not None

    def code(self, timeout: float = 300.0) -> int:
        """The forked command's exit code (negative: the signal that ended it)."""
        assert self.finished(timeout), f"the command still runs after {timeout} s"
        assert self._code is not None
        return self._code

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()


_zygotes: list[_Zygote] = []


def _zygote() -> _Zygote:
    if not _zygotes or _zygotes[0].proc.poll() is not None:
        _zygotes[:] = [_Zygote()]
        atexit.register(_zygotes[0].close)
    return _zygotes[0]


def _files(folder: Path | None) -> list[Path]:
    """Files of ``folder`` (not the temporary ones of atomic writes), oldest first."""
    if folder is None or not folder.is_dir():
        return []
    found = [p for p in folder.rglob("*") if p.is_file() and not p.name.startswith(".")]
    return sorted(found, key=lambda p: p.stat().st_mtime_ns)


def _interrupt_at(
    args: list[str], find: Callable[[], Path | None], k: int, before: int, cwd: Path
) -> tuple[int, str, Path | None, bool]:
    """Run once; SIGTERM when the folder holds ``before + k`` files. Returns the exit code,
    stderr, the folder and whether the signal was sent."""
    zygote = _zygote()
    with tempfile.NamedTemporaryFile("r", prefix="ident-stderr-", encoding="utf-8") as err:
        pid = zygote.start(args, cwd, err.name)
        sent = False
        while not zygote.finished():
            if len(_files(find())) >= before + k:
                os.kill(pid, signal.SIGTERM)
                sent = True
                break
            # a walk of the folder each time: well within PAUSE_S, not a core of its own
            time.sleep(0.02)
        code = zygote.code()
        stderr = err.read()
    return code, stderr, find(), sent


def sigterm_at_each_file(
    args: list[str],
    find: Callable[[], Path | None],
    cwd: Path,
    *,
    reset: Callable[[], None] = lambda: None,
    before: int = 0,
    every: int = 1,
    max_files: int = 60,
    at: tuple[int, ...] | None = None,
) -> int:
    """Interrupt ``ident ARGS`` at its 1st, then every ``every``-th file until a run completes;
    returns the number of files the command wrote before its last one.

    ``find()`` is the folder the command writes (None before it exists); ``reset()`` clears
    what a run left (called before each run); ``before`` files are already in the folder.
    ``every`` > 1 keeps a long command's test short (each run starts the command again);
    ``at`` interrupts at those files only, then lets a last run complete (a long command:
    its first file, one in the middle of the model files, and the end). With
    ``IDENT_SIGTERM_EVERY_FILE=1`` in the environment every file is tried.
    """
    if os.environ.get(EVERY_FILE_VARIABLE):  # the whole check, on demand (minutes of CPU)
        at, every = None, 1
    ks = range(1, max_files + 1, every) if at is None else (*at, max_files + 1)
    for k in ks:
        reset()
        code, stderr, folder, sent = _interrupt_at(args, find, k, before, cwd)
        assert "Traceback" not in stderr, stderr
        assert folder is not None, stderr
        state = json.loads((folder / "run.json").read_text())
        assert not [p for p in folder.rglob(".*") if p.is_file()], "temporary file left"
        if not sent:  # every file written before the k-th appeared: the run finished
            assert code == 0, stderr
            assert state["status"] == "complete", state
            assert not (folder / "INCOMPLETE").exists()
            return len(_files(folder)) - before
        if state["status"] == "complete":  # the signal came after the last file
            # (130, or the default SIGTERM death once the command's handler is gone)
            assert code in (0, 130, -signal.SIGTERM), stderr
            assert not (folder / "INCOMPLETE").exists()
            return len(_files(folder)) - before
        assert code == 130, (k, stderr)
        assert f"interrupted: {folder} is incomplete" in stderr, (k, stderr)
        assert state["status"] == "incomplete", (k, state)
        assert "interrupted" in state["message"], (k, state)
        assert (folder / "INCOMPLETE").is_file(), k
    raise AssertionError(f"no run of {args} completed within {max_files} files")
