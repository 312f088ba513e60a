"""The fleet's rows on dask.distributed: one task per log (read on a worker), one task per
chunk of it (its per-joint normal equations), summed per unit as they come.

At most ``logs_in_flight`` logs are held by the workers at once: a log's data are released as
soon as its last chunk is summed, so memory is bounded by that many logs plus the chunks in
progress, whatever the fleet's size. A chunk task reads its samples from the log already on
its worker (dask runs it there); only the chunk's sums travel back (``nv p^2`` floats, never a
sample). The same code runs on a ``LocalCluster`` (:func:`fleet_client` without address) and
on a running scheduler (``tcp://HOST:PORT``).
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import DataError, IdentError
from ident.identify.estimation.log_chunks import connect_scheduler
from ident.identify.streaming.fleet import (
    ChunkSettings,
    FleetColumns,
    WindowSums,
    chunk_equations,
    window_sums,
)
from ident.identify.streaming.normal import NormalEquations
from ident.measure.log_config import LogConfig, TransmissionConfig
from ident.measure.logs import RobotLog, read_log

__all__ = [
    "FleetSums",
    "ReadLog",
    "fleet_client",
    "fleet_sums",
    "local_cluster_config",
    "plan_chunks",
]

FloatArray = npt.NDArray[np.float64]
#: A picklable callable that returns a unit's log (read or simulated on a worker).
LogSource = Callable[[], RobotLog]


@dataclass(frozen=True)
class ReadLog:
    """A log file of the config, read where the task runs (:func:`ident.measure.logs.read_log`)."""

    log: LogConfig
    transmission: TransmissionConfig
    joints: tuple[str, ...]
    source: str

    def __call__(self) -> RobotLog:
        return read_log(self.log, self.transmission, self.joints, source=self.source)


@dataclass
class FleetSums:
    """Per unit: its summed normal equations, its windows' sums, each log's start in the
    unit's motion time [s]; the samples processed, the wall time of the pass [s], the cores
    of the cluster and the CPU time of the chunk tasks [s] (reading the logs not counted)."""

    units: list[NormalEquations]
    windows: list[list[WindowSums]]
    log_offsets: list[list[float]]
    samples: int = 0
    wall_s: float = 0.0
    cores: int = 1
    chunk_cpu_s: float = 0.0
    durations: dict[tuple[int, int], float] = field(default_factory=dict)


def plan_chunks(log: RobotLog, window_s: float, settings: ChunkSettings) -> list[tuple]:
    """The chunks of a log (:class:`DataError` when the cut-off is not below half the row
    rate): ``(r0, r1, span, t0, t1)`` per chunk, ``[r0, r1)`` the raw samples
    with the filter's margins, ``span`` the rows' range relative to ``r0``
    (:func:`~ident.identify.streaming.fleet.chunk_equations`), ``t0``, ``t1`` [s]."""
    fs = log.sampling_rate_hz
    nyquist = 0.5 * fs / settings.decimation
    if not settings.cutoff_hz < nyquist:
        raise DataError(
            f"fleet.cutoff_hz = {settings.cutoff_hz:g} Hz is not below {nyquist:g} Hz, half the "
            f"row rate of a {fs:g} Hz log decimated by {settings.decimation}; lower the cut-off "
            "or fleet.decimation."
        )
    m = settings.margin(fs)
    d = settings.decimation
    size = d * max(1, int(round(window_s * fs / d)))  # rows on one grid from the segment start
    out = []
    for s0, s1 in log.segments:
        for a in range(s0, s1, size):
            b = min(s1, a + size)
            r0, r1 = max(s0, a - m), min(s1, b + m)
            span = (a - r0, b - r0, s0 + m - r0, s1 - m - r0)
            out.append((r0, r1, span, float(log.t[a]), float(log.t[b - 1])))
    return out


def _plan_task(
    log: RobotLog | IdentError, window_s: float, settings: ChunkSettings
) -> tuple[list, float] | IdentError:
    """The chunks of a log and its duration [s]; a user's error returned, not raised (so the
    worker logs no traceback: the driver raises it)."""
    if isinstance(log, IdentError):
        return log
    try:
        return plan_chunks(log, window_s, settings), float(log.t[-1] - log.t[0])
    except IdentError as e:
        return e


def _chunk_task(
    log: RobotLog, chunk: tuple, cols: FleetColumns, settings: ChunkSettings, index: int
) -> tuple[NormalEquations, WindowSums, int, float]:
    """One chunk's equations, its window sums, its raw sample count and the CPU time it took
    [s] (its thread's: a loaded machine's waits are not counted)."""
    c0 = time.thread_time()
    r0, r1, span, t0, t1 = chunk
    eq = chunk_equations(log.q[r0:r1], log.tau[r0:r1], log.sampling_rate_hz, span, cols, settings)
    win = window_sums(eq, cols, (t0, t1, index))
    return eq, win, span[1] - span[0], time.thread_time() - c0


def _load_task(source: LogSource) -> RobotLog | IdentError:
    """The log, or the user's error reading it (returned: see :func:`_plan_task`)."""
    try:
        return source()
    except IdentError as e:
        return e


@contextlib.contextmanager
def fleet_client(scheduler: str | None, workers: int, processes: bool = True) -> Iterator[Any]:
    """A ``distributed.Client``: on ``scheduler`` when given, else on a new LocalCluster of
    ``workers`` workers of one thread each (closed on exit).

    Raises
    ------
    IdentError
        dask.distributed missing, or the scheduler unreachable.
    """
    try:
        import dask
        from distributed import Client, LocalCluster
    except ImportError as e:
        raise IdentError(
            "ident fleet needs dask.distributed; install it with `pip install 'ident[dask]'`."
        ) from e
    if scheduler is not None:
        client = connect_scheduler(scheduler, "ident fleet", "set fleet.scheduler: null")
        with client:
            yield client
        return
    with (
        dask.config.set(local_cluster_config()),
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=processes,
            dashboard_address=None,  # nobody watches it; its callbacks cost CPU
            silence_logs=logging.CRITICAL,  # a worker's shutdown chatter is no user's error
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def local_cluster_config() -> dict[str, Any]:
    """The dask settings of :func:`fleet_client`'s LocalCluster (its workers inherit them).

    Measured on ``ident fleet`` (2 workers, 2.4e6 samples of npz logs; docs/fleet.md):

    - ``MALLOC_TRIM_THRESHOLD_`` is left out of the workers' environment (dask sets it to
      64 KiB by default). Setting it turns off glibc's adaptive mmap threshold, so every
      array above 128 KiB (a chunk's filtered signals, a log's columns) is mapped afresh and
      its pages faulted in and zeroed each time: 5 times the page faults, and the workers'
      system time went from 1.2 to 3.6 s.
    - The worker's statistical profiler (a thread sampling the task's stack every 10 ms),
      the event-loop tick (20 ms), the system and memory monitors (0.5 s, 0.1 s), work
      stealing and the active memory manager are off or slowed: an idle cluster of 2 workers
      spent 0.18 core-seconds per second on them (0.02 with these settings). Work stealing
      would move a 60 MB log to run one of its chunks elsewhere.
    """
    import dask

    env = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    env.pop("MALLOC_TRIM_THRESHOLD_", None)
    return {
        "distributed.nanny.pre-spawn-environ": env,
        "distributed.worker.profile.enabled": False,
        "distributed.admin.tick.interval": "1s",
        "distributed.admin.system-monitor.interval": "2s",
        "distributed.admin.system-monitor.gil.enabled": False,
        "distributed.worker.memory.monitor-interval": "1s",
        "distributed.scheduler.work-stealing": False,
        "distributed.scheduler.active-memory-manager.start": False,
    }


class _Pass:
    """The bookkeeping of :func:`fleet_sums`: which logs are live, what each future is."""

    def __init__(self, client: Any, cols_f: Any, settings: ChunkSettings, window_s: float) -> None:
        from distributed import as_completed

        self.client, self.cols_f, self.settings, self.window_s = client, cols_f, settings, window_s
        self.done = as_completed()
        self.tags: dict[str, tuple] = {}
        self.live: dict[tuple[int, int], list] = {}  # (unit, log) -> [log future, chunks left]

    def start(self, u: int, k: int, src: LogSource) -> None:
        """Read log ``k`` of unit ``u`` on a worker and plan its chunks there."""
        log_f = self.client.submit(_load_task, src, pure=False)
        plan_f = self.client.submit(_plan_task, log_f, self.window_s, self.settings, pure=False)
        self.live[(u, k)] = [log_f, None]
        self.tags[plan_f.key] = ("plan", u, k)
        self.done.add(plan_f)

    def submit_chunks(self, u: int, k: int, chunks: list) -> None:
        """One task per chunk, on the log's future (dask runs it where the log is)."""
        self.live[(u, k)][1] = len(chunks)
        for chunk in chunks:
            args = (self.live[(u, k)][0], chunk, self.cols_f, self.settings, k)
            f = self.client.submit(_chunk_task, *args, pure=False)
            self.tags[f.key] = ("chunk", u, k)
            self.done.add(f)


def fleet_sums(
    client: Any,
    units: Sequence[Sequence[LogSource]],
    cols: FleetColumns,
    settings: ChunkSettings,
    window_s: float,
    logs_in_flight: int = 4,
) -> FleetSums:
    """Every unit's summed normal equations and window sums (module docstring)."""
    nv = cols.columns.chain.n_joints
    out = FleetSums(
        units=[NormalEquations(nv, cols.p) for _ in units],
        windows=[[] for _ in units],
        log_offsets=[[] for _ in units],
    )
    out.cores = int(sum(client.nthreads().values()))
    [cols_f] = client.scatter([cols], broadcast=True)
    queue = deque((u, k, src) for u, logs in enumerate(units) for k, src in enumerate(logs))
    run = _Pass(client, cols_f, settings, window_s)
    t0 = time.perf_counter()
    for _ in range(min(logs_in_flight, len(queue))):
        run.start(*queue.popleft())
    for fut in run.done:
        kind, u, k = run.tags.pop(fut.key)
        if kind == "plan":
            planned = fut.result()
            if isinstance(planned, IdentError):
                raise planned
            chunks, out.durations[(u, k)] = planned
            run.submit_chunks(u, k, chunks)
        else:
            eq, win, n, cpu = fut.result()
            out.units[u].iadd(eq)
            out.windows[u].append(win)
            out.samples += n
            out.chunk_cpu_s += cpu
            run.live[(u, k)][1] -= 1
        fut.release()
        if run.live[(u, k)][1] == 0:
            del run.live[(u, k)]  # the log's data leave the worker
            if queue:
                run.start(*queue.popleft())
    out.wall_s = time.perf_counter() - t0
    _order(out, [len(logs) for logs in units])
    return out


def _order(out: FleetSums, n_logs: list[int]) -> None:
    """Windows in time order; each log's start in its unit's motion time (the logs one after
    the other)."""
    for u, n in enumerate(n_logs):
        out.windows[u].sort(key=lambda w: (w.log, w.t0))
        starts, t = [], 0.0
        for k in range(n):
            starts.append(t)
            t += out.durations.get((u, k), 0.0)
        out.log_offsets[u] = starts
