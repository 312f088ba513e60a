"""Result objects of the optimizers: :class:`OptimizeResult`, its history and the elite archive.

All arrays are made read-only on construction, so a result can be shared between threads,
cached and compared by value without surprises.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

__all__ = ["EliteArchive", "IntermediateResult", "OptimizeHistory", "OptimizeResult"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def _frozen(a: npt.ArrayLike | None, dtype: type = np.float64) -> np.ndarray | None:
    if a is None:
        return None
    out: np.ndarray = np.array(a, dtype=dtype, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class OptimizeHistory:
    """Per-iteration record of a run; index 0 is the initial population.

    Attributes
    ----------
    best_fun :
        Best objective value found so far, shape (nit + 1,).
    nfev :
        Objective evaluations used up to and including each iteration, shape (nit + 1,).
    radius :
        eMuPSO only: swarm radius of eq. 5, ``GlobalBestCost - mean(personal best costs)``
        (<= 0), shape (nit + 1,); ``None`` for the other methods.
    stagnation :
        eMuPSO only: stagnation counter ``g`` of eq. 6 after each iteration, shape (nit + 1,).
    mutation_iterations :
        eMuPSO only: iterations whose population was produced by a mutation (eq. 8), ascending.
    """

    best_fun: FloatArray
    nfev: IntArray
    radius: FloatArray | None = None
    stagnation: IntArray | None = None
    mutation_iterations: IntArray = field(default_factory=lambda: np.zeros(0, np.int64))

    def __post_init__(self) -> None:
        object.__setattr__(self, "best_fun", _frozen(self.best_fun))
        object.__setattr__(self, "nfev", _frozen(self.nfev, np.int64))
        object.__setattr__(self, "radius", _frozen(self.radius))
        object.__setattr__(self, "stagnation", _frozen(self.stagnation, np.int64))
        object.__setattr__(self, "mutation_iterations", _frozen(self.mutation_iterations, np.int64))


@dataclass(frozen=True, eq=False)
class EliteArchive:
    """Distinct elite solutions kept by eMuPSO, best first.

    For a single objective "non-dominated" means: the best solutions that are not duplicates
    of a better one (distance measured in units of the search range, see
    ``distinct_tol`` of :mod:`ident.optim.emupso`). The paper suggests choosing among them
    with a second criterion (e.g. condition number vs estimation error).

    Attributes
    ----------
    x :
        Elite positions, shape (n_elites, dim).
    fun :
        Their objective values, shape (n_elites,), ascending.
    """

    x: FloatArray
    fun: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "x", _frozen(self.x))
        object.__setattr__(self, "fun", _frozen(self.fun))

    def __len__(self) -> int:
        return int(self.fun.shape[0])


@dataclass(frozen=True, eq=False)
class IntermediateResult:
    """State passed to ``callback`` after every iteration (best so far)."""

    x: FloatArray
    fun: float
    nit: int
    nfev: int


@dataclass(frozen=True, eq=False)
class OptimizeResult:
    """Outcome of :func:`ident.optim.minimize`; check ``success`` before use.

    Attributes
    ----------
    x :
        Best point found, shape (dim,).
    fun :
        Objective value at ``x``.
    nit :
        Iterations run (the initial population is iteration 0 and not counted).
    nfev :
        Objective evaluations used (never more than ``max_nfev``).
    success :
        True when the run ended normally: budget used up or ``f_target`` reached.
    message :
        Why the run ended.
    history :
        Per-iteration record, see :class:`OptimizeHistory`.
    method :
        Name of the method.
    n_nonfinite :
        Number of evaluations that returned NaN or +-inf (treated as +inf).
    archive :
        eMuPSO only: the elite archive, else ``None``.
    """

    x: FloatArray
    fun: float
    nit: int
    nfev: int
    success: bool
    message: str
    history: OptimizeHistory
    method: str
    n_nonfinite: int = 0
    archive: EliteArchive | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "x", _frozen(self.x))
