"""ident.blas: the one way ident runs BLAS on one thread (threadpoolctl as the reference)."""

from __future__ import annotations

import numpy as np
import scipy.linalg  # noqa: F401 (its BLAS loaded before the limits below)
from threadpoolctl import threadpool_info, threadpool_limits

from ident.blas import one_blas_thread


def _blas_threads() -> set[int]:
    return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


def test_one_blas_thread_limits_inside_and_restores_after() -> None:
    np.ones((2, 2)) @ np.ones((2, 2))  # BLAS loaded
    with threadpool_limits(limits=2, user_api="blas"):
        outside = _blas_threads()
        with one_blas_thread():
            assert _blas_threads() == {1}
        assert _blas_threads() == outside
