"""Run folders: ``runs/<config-name>-<timestamp>/``, never overwritten, always consistent.

A run folder is created empty and exclusively (``mkdir`` without ``exist_ok``); if the name
is taken (two runs in the same second) a suffix ``-2``, ``-3``, ... is added. Its state lives
in ``run.json`` (wall-clock data: start and end time, duration, status, command line), which
is rewritten atomically at every transition:

``running``  the run is in progress (or the process died without a word: a crash that
             could not even write ``failed`` leaves ``running`` behind, which
             :func:`read_status` reports as such);
``complete`` everything was written;
``incomplete`` the run was interrupted (Ctrl-C) or failed; what had finished is saved and
             ``message`` says what is missing. An ``INCOMPLETE`` marker file sits beside it
             so that a plain ``ls`` shows it.

``result.json`` never contains times, so that the same config and seed give a
byte-identical file. Its ``status`` and ``message`` are those of ``run.json``: a folder made
with ``status_copy="result.json"`` (``ident run``'s) has :meth:`RunDir.finish` write them into
both, ``result.json`` first and ``run.json`` last, so a run is marked ``complete`` only after
its last file and the two files never disagree. Until then ``result.json`` says ``running``
(:data:`RUNNING`).

Every command that writes a folder writes it inside :func:`run_folder` (a new folder) or
:func:`rewriting` (files rewritten into an existing one): whatever the moment of an error,
Ctrl-C or SIGTERM, the folder ends ``complete`` only after its last file and ``incomplete``
(with the marker) otherwise, and an interruption surfaces as :class:`FolderInterrupted`,
which names the folder. Ctrl-C and SIGTERM are held while the folder is created and while
its state is written, so that no folder is left without ``run.json`` or with ``running``.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from ident.errors import IdentError
from ident.fileio import atomic_write_text, describe_os_error
from ident.inputs import safe_component

__all__ = [
    "INCOMPLETE_MARKER",
    "RUNNING",
    "RUN_STATE_FILE",
    "FolderInterrupted",
    "RunDir",
    "create_run_dir",
    "failure_note",
    "read_status",
    "rewriting",
    "run_folder",
    "unfinished_note",
    "write_result_json",
]

RUN_STATE_FILE = "run.json"
INCOMPLETE_MARKER = "INCOMPLETE"
STATUSES = ("running", "complete", "incomplete")
RUNNING = STATUSES[0]


def write_result_json(path: Path, data: dict[str, Any]) -> None:
    """Write a run's ``result.json`` (JSON, indent 1; non-finite numbers must already be null)."""
    atomic_write_text(path, json.dumps(data, indent=1, allow_nan=False) + "\n")


_SAFE = re.compile(r"[^A-Za-z0-9._-]+")


class RunDir:
    """A run folder and its ``run.json`` state.

    Use :func:`create_run_dir` to make one; :meth:`open` wraps an existing folder.
    """

    def __init__(self, path: Path, state: dict[str, Any], status_copy: str | None = None) -> None:
        self.path = path
        self._state = state
        self._t0 = time.monotonic()
        self._status_copy = status_copy  # a JSON file whose status/message finish() sets too

    @classmethod
    def open(cls, path: str | Path) -> RunDir:
        """Wrap an existing run folder (for ``ident report``)."""
        path = Path(path)
        return cls(path, read_status(path))

    @property
    def status(self) -> str:
        """``running``, ``complete`` or ``incomplete``."""
        return str(self._state.get("status", "running"))

    @property
    def state(self) -> dict[str, Any]:
        """A copy of the ``run.json`` content."""
        return dict(self._state)

    def file(self, name: str) -> Path:
        """Path of a file inside the run folder."""
        return self.path / name

    def update(self, **fields: Any) -> None:
        """Merge ``fields`` into ``run.json`` and rewrite it atomically."""
        self._state.update(fields)
        atomic_write_text(
            self.path / RUN_STATE_FILE, json.dumps(self._state, indent=2, sort_keys=True) + "\n"
        )

    def stamp_wall_time(self) -> None:
        """Record the wall time so far (before the report, which shows it, is written)."""
        self.update(wall_time_s=round(time.monotonic() - self._t0, 3))

    def finish(self, status: str, message: str = "", *, stamp_wall_time: bool = True) -> None:
        """Record the final status, end time and wall time; manage the marker file.

        ``stamp_wall_time=False`` keeps the wall time of :meth:`stamp_wall_time` (the one the
        report already shows).
        """
        if status not in STATUSES[1:]:
            raise ValueError(f"final status must be complete or incomplete, got {status!r}")
        with _signals_held():  # a second Ctrl-C never leaves the state half-recorded
            self._finish(status, message, stamp_wall_time)

    def _finish(self, status: str, message: str, stamp_wall_time: bool) -> None:
        fields: dict[str, Any] = {"status": status, "message": message, "finished_at": _now_iso()}
        if stamp_wall_time or "wall_time_s" not in self._state:
            fields["wall_time_s"] = round(time.monotonic() - self._t0, 3)
        marker = self.path / INCOMPLETE_MARKER
        if status == "complete":
            try:  # the results' status first: run.json says complete after every file
                self._copy_status(status, message)
            except OSError as e:
                self.finish("incomplete", f"could not mark the results complete: {e}")
                raise
            marker.unlink(missing_ok=True)
            self.update(**fields)
            return
        # on the way out of a failure (often a full disk): best effort, never a second error
        # that hides the first; run.json first, the marker (a convenience for ls) second
        for write in (
            lambda: self._copy_status(status, message),
            lambda: self.update(**fields),
            lambda: atomic_write_text(marker, (message or "run did not finish") + "\n"),
        ):
            try:
                write()
            except OSError:
                pass

    def _copy_status(self, status: str, message: str) -> None:
        """Set ``status`` and ``message`` of the status copy (``result.json``), if written."""
        if self._status_copy is None:
            return
        path = self.path / self._status_copy
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):  # not written (the run stopped before): run.json says it
            return
        if isinstance(data, dict):
            write_result_json(path, {**data, "status": status, "message": message})


def create_run_dir(
    out: str | Path,
    name: str,
    *,
    now: datetime | None = None,
    info: dict[str, Any] | None = None,
    exact: bool = False,
    status_copy: str | None = None,
) -> RunDir:
    """Create a new, empty run folder ``<out>/<name>-<YYYYmmdd-HHMMSS>``.

    Parameters
    ----------
    out :
        Parent folder (created if missing).
    name :
        Run name (config name); characters outside ``[A-Za-z0-9._-]`` become ``_``.
    now :
        Time stamp of the folder name (UTC); the current time by default.
    info :
        Extra fields for ``run.json`` (command line, seed, ...).
    exact :
        The folder is ``out`` itself (``name`` unused), or ``out-2``, ``out-3``, ... when
        ``out`` is taken meanwhile (an empty existing ``out`` is taken).
    status_copy :
        A JSON file of the folder (``result.json``) whose ``status`` and ``message``
        :meth:`RunDir.finish` sets with ``run.json``'s (see the module docstring).

    Returns
    -------
    :
        The run folder, with ``run.json`` in state ``running``.

    Raises
    ------
    IdentError
        If the parent folder cannot be created or written.
    """
    out = Path(out)
    now = now or datetime.now(timezone.utc)
    stem = f"{safe_component(name, default='run')}-{now.strftime('%Y%m%d-%H%M%S')}"
    parent, stem = (out.parent, out.name) if exact else (out, stem)
    path = _new_folder(parent, stem, exact)
    run = RunDir(path, {"status": RUNNING, "started_at": _now_iso(), **(info or {})}, status_copy)
    try:
        run.update()
    except OSError as e:  # a folder without run.json is no run: leave nothing behind
        path.rmdir()
        raise IdentError(
            f"{path / RUN_STATE_FILE}: cannot write the run state ({e.strerror}); free some "
            "space or use --out."
        ) from e
    return run


def _new_folder(parent: Path, stem: str, exact: bool) -> Path:
    """Create and return the folder ``parent/stem``, or ``stem-2``, ``stem-3``, ... when it is
    taken (``exact``: an empty existing ``stem`` is taken as it is). The folder is made
    exclusively: an earlier run is never reused.

    Raises
    ------
    IdentError
        If ``parent`` cannot be created or written.
    """
    try:
        parent.mkdir(parents=True, exist_ok=True)
        for k in range(1, 1000):
            path = parent / (stem if k == 1 else f"{stem}-{k}")
            try:
                path.mkdir()  # exclusive: an earlier run is never reused
                break
            except FileExistsError:
                if exact and k == 1 and path.is_dir() and not any(path.iterdir()):
                    break  # an empty --out is the user's choice
        else:  # pragma: no cover - a thousand runs in one second
            raise IdentError(f"{parent}: could not find a free run folder name for {stem}.")
    except OSError as e:
        raise IdentError(
            f"{parent}: cannot create the run folder ({e.strerror}); use --out."
        ) from e
    return path


def unfinished_note(path: str | Path, state: dict[str, Any]) -> str | None:
    """What a reader of run folder ``path`` must know when the run did not complete, or None.

    ``state`` is its ``run.json`` content (:func:`read_status`).
    """
    status = state.get("status", "running")
    if status == "complete":
        return None
    if status == "running":
        since = state.get("started_at", "an unknown time")
        return (
            f"{path}: the run is still running (run.json: status 'running' since {since}), or "
            "its process died without a word; what it saved so far is all there is, and its "
            "files may still change"
        )
    message = state.get("message") or "no reason recorded"
    return f"{path}: the run is {status} ({message}); only what it finished is shown"


def read_status(path: str | Path) -> dict[str, Any]:
    """Read ``run.json`` of a run folder.

    Raises
    ------
    IdentError
        If the folder or its ``run.json`` is missing or unreadable.
    """
    path = Path(path)
    state_file = path / RUN_STATE_FILE
    if not path.is_dir():
        raise IdentError(f"{path}: not a run folder (does not exist or is not a directory).")
    if not state_file.is_file():
        raise IdentError(
            f"{path}: no {RUN_STATE_FILE}; this is not a folder written by 'ident run'."
        )
    try:
        state = json.loads(state_file.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError, RecursionError) as e:
        raise IdentError(f"{state_file}: unreadable ({e}); the run folder is damaged.") from e
    if not isinstance(state, dict):
        raise IdentError(f"{state_file}: expected a JSON object.")
    return state


def _now_iso() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


# ---------------------------------------------------------------------------------------------
# one mechanism for every command that writes a folder: complete after the last file,
# incomplete (run.json and marker) on any error or interruption, whatever the moment

_HELD_SIGNALS = {signal.SIGINT, signal.SIGTERM}


class FolderInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM stopped a command while it wrote ``folder``, now marked incomplete."""

    def __init__(self, folder: Path) -> None:
        super().__init__(str(folder))
        self.folder = folder


def failure_note(error: BaseException) -> str:
    """What stopped a run, for its ``run.json`` ``message`` (one line)."""
    if isinstance(error, OSError):
        text = describe_os_error(error)
    elif isinstance(error, KeyboardInterrupt):
        text = "interrupted (Ctrl-C or SIGTERM)"
    else:
        text = f"{type(error).__name__}: {error}"
    return " ".join(text.split("\n"))[:2000]


@dataclass
class _Held:
    """The handlers :func:`_hold_signals` replaced and the signals that came meanwhile."""

    handlers: dict[int, Any]
    pending: list[int]


def _hold_signals() -> _Held | None:
    """Defer Ctrl-C and SIGTERM (main thread only: Python runs its handlers there).

    The Python handlers are replaced by one that records the signal: blocking the signal with
    ``pthread_sigmask`` would hold it in this thread only, and another thread (a progress
    display, a thread pool) would take it and have the main thread run the handler at once.
    """
    if threading.current_thread() is not threading.main_thread():
        return None
    held = _Held({}, [])
    for number in _HELD_SIGNALS:
        held.handlers[number] = signal.signal(number, lambda n, _f: held.pending.append(n))
    return held


def _release_signals(held: _Held | None) -> None:
    """Undo :func:`_hold_signals`; a signal that came meanwhile is delivered here, to the
    handler it would have met (Ctrl-C's ``KeyboardInterrupt``, the CLI's SIGTERM handler)."""
    if held is None:
        return
    for number, handler in held.handlers.items():
        signal.signal(number, handler)
    if not held.pending:
        return
    number = held.pending[0]
    handler = held.handlers[number]
    if callable(handler):
        handler(number, None)
    elif handler == signal.SIG_DFL:  # the default action, as if never held
        os.kill(os.getpid(), number)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    previous = _hold_signals()
    try:
        yield
    finally:
        _release_signals(previous)


def _mark_stopped(run: RunDir, note: str) -> None:
    """Mark ``run`` incomplete with ``note``, unless it completed (stopped after its last file:
    nothing is missing) or the command recorded a more precise reason."""
    if run.status == "running":
        run.finish("incomplete", note)
    elif run.status == "incomplete" and not (run.path / INCOMPLETE_MARKER).exists():
        run.finish("incomplete", str(run.state.get("message") or note))


def _naming_folder(run: RunDir, error: BaseException) -> BaseException:
    """The exception to raise for ``error`` once ``run`` is marked: one that names the folder
    (an interruption, a user error, an OS failure), or ``error`` itself."""
    if run.status == "complete":
        return error
    if isinstance(error, KeyboardInterrupt):
        return FolderInterrupted(run.path)
    if isinstance(error, (IdentError, OSError)):
        what = describe_os_error(error) if isinstance(error, OSError) else str(error)
        return IdentError(f"{what.rstrip('.')} ({run.path} is incomplete).")
    return error


@contextlib.contextmanager
def run_folder(
    out: str | Path,
    name: str,
    *,
    info: dict[str, Any] | None = None,
    exact: bool = False,
    status_copy: str | None = None,
) -> Iterator[RunDir]:
    """Create a run folder (:func:`create_run_dir`) and guard the writing of its files.

    The block writes the files and ends with ``run.finish("complete", ...)``. Any exception
    out of the block marks the folder incomplete (``run.json`` and the marker) unless it was
    marked complete; Ctrl-C and SIGTERM then raise :class:`FolderInterrupted`, and an
    :class:`IdentError` or :class:`OSError` becomes an :class:`IdentError` naming the folder.
    Signals are held from before the folder exists until this guard is in place.
    """
    previous = _hold_signals()
    try:
        run = create_run_dir(out, name, info=info, exact=exact, status_copy=status_copy)
    except BaseException:
        _release_signals(previous)
        raise
    try:
        _release_signals(previous)  # a signal that came meanwhile is raised here, guarded
        yield run
    except BaseException as e:
        _mark_stopped(run, failure_note(e))
        raised = _naming_folder(run, e)
        if raised is e:
            raise
        raise raised from e


@contextlib.contextmanager
def rewriting(path: str | Path, what: str) -> Iterator[RunDir]:
    """Guard files rewritten into the existing run folder ``path`` (``ident report``).

    A failure or an interruption marks the folder incomplete with ``missing: what`` (the
    command's advice: write it again); a later success where ``what`` was all that was
    missing marks the folder complete again, with the message it had. A folder still
    ``running`` belongs to its own process: its state is left alone.
    """
    run = RunDir.open(path)
    if run.status == "running":
        yield run
        return
    try:
        yield run
    except BaseException as e:
        note = f"stopped while writing the {what}: {failure_note(e)}"
        if run.status == "complete":
            run.update(missing=what, complete_message=run.state.get("message", ""))
            run.finish("incomplete", note)
        _mark_stopped(run, note)
        raised = _naming_folder(run, e)
        if raised is e:
            raise
        raise raised from e
    if run.status == "incomplete" and run.state.get("missing") == what:
        message = str(run.state.get("complete_message") or "")
        run.update(missing=None, complete_message=None)
        run.finish("complete", message)
