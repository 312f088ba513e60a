"""Samples into the streaming estimator: a log replayed at its rate, and the stream's result.

:class:`SampleSource` is what the estimator is fed from: blocks ``(t, q, tau, restart)``.
:class:`LogReplay` replays a read log (:class:`~ident.measure.logs.RobotLog`) in blocks of
``block_samples``, at its own rate (``speed = 1``: a block is handed over when the wall clock
reaches its last time stamp, as a robot would stream it), faster (``speed = 10``), or as fast
as the computer allows (``speed = 0``: tests, benchmarks, offline logs). A new segment of the
log (a gap) restarts the causal filters.

**A live robot.** A ROS 2 ``sensor_msgs/JointState`` topic is another :class:`SampleSource`:
its subscription callback appends ``header.stamp``, ``position`` and ``effort`` (reordered to
the model's joints, converted to SI once, as the log reader does) to a buffer, and its
``blocks()`` yields the buffer every ``block_samples`` messages, ``restart`` set after a gap in
the stamps. It needs ``rclpy``, which this package does not depend on; :func:`stream` takes any
source.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from ident.blas import one_blas_thread
from ident.identify.streaming.estimator import ChangeEvent, StreamingEstimator
from ident.measure.logs import RobotLog

__all__ = ["LogReplay", "SampleSource", "StreamRun", "stream"]

FloatArray = npt.NDArray[np.float64]

Block = tuple[FloatArray, FloatArray, FloatArray, bool]


class SampleSource(Protocol):
    """Blocks of samples: ``(t (n,) [s], q (n, nv) [rad], tau (n, nv) [N*m], restart)``;
    ``restart``: a gap precedes the block (the filters start again)."""

    def blocks(self) -> Iterator[Block]:
        """The blocks, in time order."""
        ...


@dataclass(frozen=True)
class LogReplay:
    """A log replayed in blocks of ``block_samples`` at ``speed`` times its rate (0: as fast
    as possible)."""

    log: RobotLog
    block_samples: int = 100
    speed: float = 1.0

    def blocks(self) -> Iterator[Block]:
        """The log's blocks, each segment's first with ``restart``."""
        start_wall = time.monotonic()
        t0 = float(self.log.t[0]) if self.log.t.size else 0.0
        for a, b in self.log.segments:
            for k in range(a, b, self.block_samples):
                stop = min(k + self.block_samples, b)
                t = self.log.t[k:stop]
                if self.speed > 0:  # the wall clock reaches the block's last sample
                    wait = (float(t[-1]) - t0) / self.speed - (time.monotonic() - start_wall)
                    if wait > 0:
                        time.sleep(wait)
                yield t, self.log.q[k:stop], self.log.tau[k:stop], k == a


@dataclass(frozen=True)
class StreamRun:
    """What a stream gave: ``n_samples``, the CPU time of the updates [s], the events."""

    n_samples: int
    cpu_s: float
    events: tuple[ChangeEvent, ...]

    @property
    def cpu_per_sample_us(self) -> float:
        """CPU time per sample [µs] (filters, rows, sums, tests, scheduled solves)."""
        return 1e6 * self.cpu_s / max(self.n_samples, 1)


def stream(
    source: SampleSource,
    estimator: StreamingEstimator,
    on_event: Callable[[ChangeEvent], None] | None = None,
) -> StreamRun:
    """Feed every block of ``source`` to ``estimator``; ``on_event`` is called with each
    change as soon as its estimate is complete. BLAS runs on one thread: the solves are small
    and threads only wait (and a robot's computer has other work)."""
    n, cpu = 0, 0.0
    with one_blas_thread():
        for t, q, tau, restart in source.blocks():
            c0 = time.process_time()
            if restart:
                estimator.restart_filter()
            events = estimator.push(t, q, tau)
            cpu += time.process_time() - c0
            n += t.size
            for event in events:
                if on_event is not None:
                    on_event(event)
    return StreamRun(n, cpu, tuple(estimator.events))
