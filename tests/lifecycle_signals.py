"""SIGTERM at each file a command writes: the folder ends complete or says it is incomplete.

:func:`sigterm_at_each_file` starts the command (``python -m``-style, as a user's shell would)
again and again; run ``k`` polls the output folder and sends SIGTERM as soon as its ``k``-th
file appears, then checks what a user finds: exit 130, ``interrupted: <folder> is incomplete``
on stderr, ``run.json`` status ``incomplete`` and the ``INCOMPLETE`` marker, no temporary file.
The last run is the one whose files all appeared before the signal could be sent: it must have
finished complete. Each write of ``ident.fileio`` is preceded by a short pause in the child so
that the signal lands between the ``k``-th file and the next one.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAUSE_S = 0.15  # before each atomic write in the child
#: Set, every test interrupts at every file (``every=1``), whatever its ``at`` and ``every``.
EVERY_FILE_VARIABLE = "IDENT_SIGTERM_EVERY_FILE"
_DRIVER = f"""
import time
import ident.fileio as fileio
write = fileio._write_data
def paused(file, data, path):
    time.sleep({PAUSE_S})
    write(file, data, path)
fileio._write_data = paused
from ident.cli import main
main()
"""


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
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "COLUMNS": "200"}
    proc = subprocess.Popen(
        [sys.executable, "-c", _DRIVER, *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=cwd,
    )
    sent = False
    while proc.poll() is None:
        if len(_files(find())) >= before + k:
            proc.send_signal(signal.SIGTERM)
            sent = True
            break
        # a walk of the folder each time: well within PAUSE_S, not a core of its own
        time.sleep(0.02)
    _, stderr = proc.communicate(timeout=300)
    return proc.returncode, stderr, find(), sent


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
