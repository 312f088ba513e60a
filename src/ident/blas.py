"""BLAS on one thread, the one way ident limits it.

ident's dense algebra is small and repeated: Gram matrices of a few hundred samples per
particle (70 x 1750 for a 7-joint arm), least-squares solves of tens of columns over a weight
grid or trust-region steps. OpenBLAS threads them all the same, and on a machine with other
work its threads spin while they wait: the Panda swarm's Gram matrices took 0.66 s of CPU per
call of 20 particles with two threads on a loaded 2-core machine, 0.028 s with one (24x);
a (1500 x 17) weighted solve 41-160 ms against 1.3-3.4 ms. Nothing here is large enough for
threads to pay.
"""

from __future__ import annotations

import contextlib
import functools
from typing import Any

__all__ = ["one_blas_thread"]


def one_blas_thread() -> contextlib.AbstractContextManager[Any]:
    """A context in which the loaded BLAS libraries run on one thread (restored on exit)."""
    return _blas_controller().limit(limits=1, user_api="blas")  # type: ignore[no-any-return]


@functools.cache
def _blas_controller() -> Any:
    """threadpoolctl's view of the loaded BLAS libraries, scanned once: a scan of the
    process's shared libraries takes 3-7 ms, as long as a small solve. SciPy's BLAS is
    loaded first so that the scan finds it; a library loaded later keeps its threads (a
    matter of speed only)."""
    import scipy.linalg  # noqa: F401
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()
