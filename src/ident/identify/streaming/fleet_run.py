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
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import IdentError
from ident.identify.estimation.log_chunks import DASK_CONNECT_TIMEOUT
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

__all__ = ["FleetSums", "ReadLog", "fleet_client", "fleet_sums", "plan_chunks"]

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
    unit's motion time [s]; the samples processed and the wall time of the pass [s]."""

    units: list[NormalEquations]
    windows: list[list[WindowSums]]
    log_offsets: list[list[float]]
    samples: int = 0
    wall_s: float = 0.0
    cores: int = 1
    durations: dict[tuple[int, int], float] = field(default_factory=dict)


def plan_chunks(log: RobotLog, window_s: float, settings: ChunkSettings) -> list[tuple]:
    """The chunks of a log: ``(r0, r1, span, t0, t1)`` per chunk, ``[r0, r1)`` the raw samples
    with the filter's margins, ``span`` the rows' range relative to ``r0``
    (:func:`~ident.identify.streaming.fleet.chunk_equations`), ``t0``, ``t1`` [s]."""
    fs = log.sampling_rate_hz
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


def _plan_task(log: RobotLog, window_s: float, settings: ChunkSettings) -> tuple[list, float]:
    """The chunks of a log and its duration [s]."""
    return plan_chunks(log, window_s, settings), float(log.t[-1] - log.t[0])


def _chunk_task(
    log: RobotLog, chunk: tuple, cols: FleetColumns, settings: ChunkSettings, index: int
) -> tuple[NormalEquations, WindowSums, int]:
    """One chunk's equations, its window sums and its raw sample count."""
    r0, r1, span, t0, t1 = chunk
    eq = chunk_equations(log.q[r0:r1], log.tau[r0:r1], log.sampling_rate_hz, span, cols, settings)
    return eq, window_sums(eq, cols, (t0, t1, index)), span[1] - span[0]


def _load_task(source: LogSource) -> RobotLog:
    return source()


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
        from distributed import Client, LocalCluster
    except ImportError as e:
        raise IdentError(
            "ident fleet needs dask.distributed; install it with `pip install 'ident[dask]'`."
        ) from e
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=DASK_CONNECT_TIMEOUT)
        except (OSError, TimeoutError) as e:
            raise IdentError(
                f"cannot reach the dask scheduler at {scheduler}: {e}; start one with "
                "`dask scheduler` and `dask worker <address>`, or set fleet.scheduler: null."
            ) from e
        with client:
            yield client
        return
    with (
        LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                     dashboard_address=None) as cluster,  # fmt: skip
        Client(cluster) as client,
    ):
        yield client


def fleet_sums(
    client: Any,
    units: list[list[LogSource]],
    cols: FleetColumns,
    settings: ChunkSettings,
    window_s: float,
    logs_in_flight: int = 4,
) -> FleetSums:
    """Every unit's summed normal equations and window sums (module docstring)."""
    from distributed import as_completed

    nv = cols.columns.chain.n_joints
    out = FleetSums(units=[NormalEquations(nv, cols.p) for _ in units],
                    windows=[[] for _ in units], log_offsets=[[] for _ in units])  # fmt: skip
    out.cores = int(sum(client.nthreads().values()))
    [cols_f] = client.scatter([cols], broadcast=True)
    queue = deque((u, k, src) for u, logs in enumerate(units) for k, src in enumerate(logs))
    tags: dict[str, tuple] = {}
    done = as_completed()
    live: dict[tuple[int, int], list] = {}  # (unit, log) -> [log future, chunks left]

    def start() -> None:
        u, k, src = queue.popleft()
        log_f = client.submit(_load_task, src, pure=False)
        plan_f = client.submit(_plan_task, log_f, window_s, settings, pure=False)
        live[(u, k)] = [log_f, None]
        tags[plan_f.key] = ("plan", u, k)
        done.add(plan_f)

    t0 = time.perf_counter()
    for _ in range(min(logs_in_flight, len(queue))):
        start()
    for fut in done:
        kind, u, k = tags.pop(fut.key)
        if kind == "plan":
            chunks, duration = fut.result()
            out.durations[(u, k)] = duration
            live[(u, k)][1] = len(chunks)
            for chunk in chunks:
                f = client.submit(_chunk_task, live[(u, k)][0], chunk, cols_f, settings, k,
                                  pure=False)  # fmt: skip
                tags[f.key] = ("chunk", u, k)
                done.add(f)
        else:
            eq, win, n = fut.result()
            out.units[u].iadd(eq)
            out.windows[u].append(win)
            out.samples += n
            live[(u, k)][1] -= 1
        fut.release()
        if live[(u, k)][1] == 0:
            del live[(u, k)]  # the log's data leave the worker
            if queue:
                start()
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
