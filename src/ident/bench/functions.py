"""The benchmark functions of the paper's Tables 4-6, in an extensible registry.

The definitions are the formulas of this module, with the bounds and optima of their registry
entries (checked against Jamil & Yang 2013, Surjanovic & Bingham, Gavana/scipy, Adorio MVF, Molga &
Smutnicki, Mirjalili's benchmark file). Every function maps a population ``(n_pop, dim)`` to
``(n_pop,)``; a 1-D ``x`` is one point. Functions defined for a fixed number ``k`` of variables
read columns ``0..k-1`` and ignore the others (so the paper's "Dim 30" vectors still work).

Two orders are available: :func:`table_functions` (the 36 rows of Tables 4-6/8: the appendix set
minus Schwefel 2.26, plus Pen Holder as table F16, with the appendix F16-F23 shifted to table
F17-F24) and :func:`appendix_functions` (appendix F1-F36, with Schwefel 2.26 as F24). Each entry
carries both IDs. Documented alternative definitions are registered too (``step2_floor``,
``cosine_mixture_jy``, ``hartmann3_paper_bounds``, ``langerman5_paper``); they are in neither
order. Users add their own with :func:`register_function`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import ConfigError

__all__ = [
    "BenchmarkFunction",
    "appendix_functions",
    "get_function",
    "list_functions",
    "register_function",
    "table_functions",
]

FloatArray = npt.NDArray[np.float64]
Objective = Callable[[FloatArray], FloatArray]

GROUPS = ("unimodal", "multimodal", "fixed")


@dataclass(frozen=True, eq=False)
class BenchmarkFunction:
    """A test function with its known optimum.

    Attributes
    ----------
    key :
        Registry key, e.g. ``"sphere"``.
    name :
        Human-readable name, e.g. ``"Sphere"``.
    fun :
        Vectorized objective ``(n_pop, dim) -> (n_pop,)``.
    bounds :
        ``(low, high)`` per variable, length ``dim``.
    f_star :
        Exact global minimum (not the paper's rounded f_min).
    x_star :
        One global minimiser, shape (dim,), or ``None`` if unknown.
    group :
        ``"unimodal"`` (Table 4), ``"multimodal"`` (Table 5) or ``"fixed"`` (Table 6).
    appendix_id, table_id :
        IDs in the paper's appendix and in its tables (``None`` where absent).
    tol :
        Tolerance of ``f(x_star) - f_star`` (the registry's check: 1e-6).
    note :
        Where the definition departs from the paper's appendix, in one line.
    """

    key: str
    name: str
    fun: Objective
    bounds: tuple[tuple[float, float], ...]
    f_star: float
    x_star: FloatArray | None = None
    group: str = "multimodal"
    appendix_id: str | None = None
    table_id: str | None = None
    tol: float = 1e-6
    note: str = ""

    @property
    def dim(self) -> int:
        """Number of variables."""
        return len(self.bounds)

    @property
    def label(self) -> str:
        """Row label of the tables, e.g. ``"F16 Pen Holder"``."""
        return f"{self.table_id or self.appendix_id or '-'} {self.name}"

    def __call__(self, x: npt.ArrayLike) -> FloatArray | float:
        a = np.asarray(x, dtype=float)
        if a.ndim == 1:
            return float(self.fun(a[None, :])[0])
        return self.fun(a)


_REGISTRY: dict[str, BenchmarkFunction] = {}
_TABLE_ORDER: list[str] = []
_APPENDIX_ORDER: list[str] = []


def register_function(
    key: str,
    fun: Objective,
    bounds: Sequence[tuple[float, float]],
    f_star: float,
    *,
    name: str | None = None,
    x_star: npt.ArrayLike | None = None,
    group: str = "multimodal",
    appendix_id: str | None = None,
    table_id: str | None = None,
    tol: float = 1e-6,
    note: str = "",
    overwrite: bool = False,
) -> BenchmarkFunction:
    """Add a function to the registry (usable by key in ``configs/bench.yaml``).

    ``x_star`` (if given) is checked: it must have ``dim`` finite values inside the bounds
    (closed box, no tolerance) and satisfy ``|f(x_star) - f_star| <= tol`` (absolute; the
    default ``tol = 1e-6`` is the registry's check). Pass a larger ``tol`` for a minimiser known
    only to a few digits.

    Raises
    ------
    ConfigError
        If ``key`` exists (and not ``overwrite``), the bounds are malformed, ``group`` is
        unknown, or ``x_star`` has the wrong length, lies outside the bounds, or does not give
        ``f_star`` within ``tol``.
    """
    if key in _REGISTRY and not overwrite:
        raise ConfigError(f"benchmark function '{key}' is already registered; pick another key")
    b = tuple((float(lo), float(hi)) for lo, hi in bounds)
    if not b or any(lo >= hi for lo, hi in b):
        raise ConfigError(f"benchmark function '{key}': bounds must be (low < high) pairs")
    if group not in GROUPS:
        raise ConfigError(f"benchmark function '{key}': group must be one of {GROUPS}")
    xs = None
    if x_star is not None:
        xs = _checked_x_star(key, fun, b, float(f_star), x_star, tol)
    bf = BenchmarkFunction(
        key=key,
        name=name or key,
        fun=fun,
        bounds=b,
        f_star=float(f_star),
        x_star=xs,
        group=group,
        appendix_id=appendix_id,
        table_id=table_id,
        tol=tol,
        note=note,
    )
    _REGISTRY[key] = bf
    return bf


def _checked_x_star(
    key: str,
    fun: Objective,
    bounds: tuple[tuple[float, float], ...],
    f_star: float,
    x_star: npt.ArrayLike,
    tol: float,
) -> FloatArray:
    """``x_star`` as a read-only array (dim,), after the checks of :func:`register_function`."""
    try:
        xs = np.array(x_star, dtype=float).reshape(len(bounds))
    except (TypeError, ValueError) as e:
        raise ConfigError(
            f"benchmark function '{key}': x_star must be {len(bounds)} numbers (one per "
            f"variable), got {x_star!r}"
        ) from e
    if not np.all(np.isfinite(xs)):
        raise ConfigError(f"benchmark function '{key}': x_star must be finite, got {xs.tolist()}")
    lo = np.array([p[0] for p in bounds])
    hi = np.array([p[1] for p in bounds])
    out = np.flatnonzero((xs < lo) | (xs > hi))
    if out.size:
        i = int(out[0])
        raise ConfigError(
            f"benchmark function '{key}': x_star[{i}] = {xs[i]:g} lies outside its bounds "
            f"[{lo[i]:g}, {hi[i]:g}]; fix x_star or the bounds."
        )
    f = float(np.asarray(fun(xs[None, :]), dtype=float).reshape(-1)[0])
    if not abs(f - f_star) <= tol:
        raise ConfigError(
            f"benchmark function '{key}': f(x_star) = {f:.10g} but f_star = {f_star:.10g} "
            f"(difference {f - f_star:.3g} > tol = {tol:g}); fix x_star or f_star, or pass "
            "a larger tol."
        )
    xs.setflags(write=False)
    return xs


def get_function(key: str) -> BenchmarkFunction:
    """The registered function ``key``; unknown keys raise with the closest match."""
    if key not in _REGISTRY:
        import difflib

        close = difflib.get_close_matches(key, list(_REGISTRY), n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise ConfigError(f"unknown benchmark function '{key}'{hint}")
    return _REGISTRY[key]


def list_functions() -> list[str]:
    """All registered keys (paper functions first, in table order)."""
    rest = [k for k in _REGISTRY if k not in _TABLE_ORDER]
    return [*_TABLE_ORDER, *rest]


def table_functions() -> list[BenchmarkFunction]:
    """The 36 functions of Tables 4-6 and 8, in table order F1..F36."""
    return [_REGISTRY[k] for k in _TABLE_ORDER]


def appendix_functions() -> list[BenchmarkFunction]:
    """The 36 functions of the paper's appendix, in appendix order F1..F36."""
    return [_REGISTRY[k] for k in _APPENDIX_ORDER]


# ---------------------------------------------------------------------------------------------
# definitions (1-based formulas as documented, 0-based columns here)


def _c(x: FloatArray, k: int) -> FloatArray:
    return x[:, k]


def sphere(x: FloatArray) -> FloatArray:
    """Sphere: ``(n_pop, dim) -> (n_pop,)``."""
    return np.sum(x**2, axis=1)


def beale(x: FloatArray) -> FloatArray:
    """Beale: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return (1.5 - a + a * b) ** 2 + (2.25 - a + a * b**2) ** 2 + (2.625 - a + a * b**3) ** 2


def matyas(x: FloatArray) -> FloatArray:
    """Matyas: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return 0.26 * (a**2 + b**2) - 0.48 * a * b


def rosenbrock(x: FloatArray) -> FloatArray:
    """Rosenbrock: ``(n_pop, dim) -> (n_pop,)``."""
    return np.sum(100.0 * (x[:, 1:] - x[:, :-1] ** 2) ** 2 + (x[:, :-1] - 1.0) ** 2, axis=1)


def step2(x: FloatArray) -> FloatArray:
    """Step2: ``(n_pop, dim) -> (n_pop,)``."""
    return np.sum((x + 0.5) ** 2, axis=1)


def step2_floor(x: FloatArray) -> FloatArray:
    """Step2 floor: ``(n_pop, dim) -> (n_pop,)``."""
    return np.sum(np.floor(x + 0.5) ** 2, axis=1)


def _schaffer_den(a: FloatArray, b: FloatArray) -> FloatArray:
    return (1.0 + 0.001 * (a**2 + b**2)) ** 2


def schaffer2(x: FloatArray) -> FloatArray:
    """Schaffer2: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return 0.5 + (np.sin(a**2 - b**2) ** 2 - 0.5) / _schaffer_den(a, b)


def schaffer3(x: FloatArray) -> FloatArray:
    """Schaffer3: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return 0.5 + (np.sin(np.cos(np.abs(a**2 - b**2))) ** 2 - 0.5) / _schaffer_den(a, b)


def schwefel12(x: FloatArray) -> FloatArray:
    """Schwefel12: ``(n_pop, dim) -> (n_pop,)``."""
    return np.sum(np.cumsum(x, axis=1) ** 2, axis=1)


def schwefel221(x: FloatArray) -> FloatArray:
    """Schwefel221: ``(n_pop, dim) -> (n_pop,)``."""
    return np.max(np.abs(x), axis=1)


def schwefel222(x: FloatArray) -> FloatArray:
    """Schwefel222: ``(n_pop, dim) -> (n_pop,)``."""
    ax = np.abs(x)
    return np.sum(ax, axis=1) + np.prod(ax, axis=1)


def _i(x: FloatArray) -> FloatArray:
    return np.arange(1, x.shape[1] + 1, dtype=float)


def dejong4(x: FloatArray) -> FloatArray:
    """Dejong4: ``(n_pop, dim) -> (n_pop,)``."""
    return np.sum(_i(x) * x**4, axis=1)


def axis_parallel(x: FloatArray) -> FloatArray:
    """Axis parallel: ``(n_pop, dim) -> (n_pop,)``."""
    return np.sum(_i(x) * x**2, axis=1)


def easom(x: FloatArray) -> FloatArray:
    """Easom: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return -np.cos(a) * np.cos(b) * np.exp(-((a - np.pi) ** 2) - (b - np.pi) ** 2)


def griewank(x: FloatArray) -> FloatArray:
    """Griewank: ``(n_pop, dim) -> (n_pop,)``."""
    return 1.0 + np.sum(x**2, axis=1) / 4000.0 - np.prod(np.cos(x / np.sqrt(_i(x))), axis=1)


def rastrigin(x: FloatArray) -> FloatArray:
    """Rastrigin: ``(n_pop, dim) -> (n_pop,)``."""
    return np.sum(x**2 - 10.0 * np.cos(2.0 * np.pi * x) + 10.0, axis=1)


def pen_holder(x: FloatArray) -> FloatArray:
    """Pen holder: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    inner = np.abs(np.cos(a) * np.cos(b) * np.exp(np.abs(1.0 - np.hypot(a, b) / np.pi)))
    with np.errstate(divide="ignore"):
        return -np.exp(-1.0 / inner)  # inner = 0 -> -exp(-inf) = -0, the limit


def test_tube_holder(x: FloatArray) -> FloatArray:
    """Test tube holder: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return -4.0 * np.abs(np.sin(a) * np.cos(b) * np.exp(np.abs(np.cos((a**2 + b**2) / 200.0))))


def egg_holder(x: FloatArray) -> FloatArray:
    """Egg holder: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return -(b + 47.0) * np.sin(np.sqrt(np.abs(b + a / 2.0 + 47.0))) - a * np.sin(
        np.sqrt(np.abs(a - b - 47.0))
    )


def damavandi(x: FloatArray) -> FloatArray:
    """Damavandi: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    # np.sinc(t) = sin(pi t) / (pi t) with the removable singularity handled
    return (1.0 - np.abs(np.sinc(a - 2.0) * np.sinc(b - 2.0)) ** 5) * (
        2.0 + (a - 7.0) ** 2 + 2.0 * (b - 7.0) ** 2
    )


def cross_leg_table(x: FloatArray) -> FloatArray:
    """Cross leg table: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    e = np.exp(np.abs(100.0 - np.hypot(a, b) / np.pi))
    return -((np.abs(np.sin(a) * np.sin(b) * e) + 1.0) ** -0.1)


def bukin4(x: FloatArray) -> FloatArray:
    """Bukin4: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return 100.0 * b**2 + 0.01 * np.abs(a + 10.0)


def bukin6(x: FloatArray) -> FloatArray:
    """Bukin6: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return 100.0 * np.sqrt(np.abs(b - 0.01 * a**2)) + 0.01 * np.abs(a + 10.0)


def cosine_mixture(x: FloatArray) -> FloatArray:
    """Cosine mixture: ``(n_pop, dim) -> (n_pop,)``."""
    return np.sum(x**2, axis=1) - 0.1 * np.sum(np.cos(5.0 * np.pi * x), axis=1)


def cosine_mixture_jy(x: FloatArray) -> FloatArray:
    """Cosine mixture jy: ``(n_pop, dim) -> (n_pop,)``."""
    return -0.1 * np.sum(np.cos(5.0 * np.pi * x), axis=1) - np.sum(x**2, axis=1)


def modified_rosenbrock(x: FloatArray) -> FloatArray:
    """Modified rosenbrock: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return (
        74.0
        + 100.0 * (b - a**2) ** 2
        + (1.0 - a) ** 2
        - 400.0 * np.exp(-((a + 1.0) ** 2 + (b + 1.0) ** 2) / 0.1)
    )


def schwefel226(x: FloatArray) -> FloatArray:
    """Schwefel226: ``(n_pop, dim) -> (n_pop,)``."""
    return -np.mean(x * np.sin(np.sqrt(np.abs(x))), axis=1)


def paviani(x: FloatArray) -> FloatArray:
    """Paviani: ``(n_pop, dim) -> (n_pop,)``."""
    y = x[:, :10]
    with np.errstate(divide="ignore", invalid="ignore"):
        return (
            np.sum(np.log(y - 2.0) ** 2 + np.log(10.0 - y) ** 2, axis=1) - np.prod(y, axis=1) ** 0.2
        )


def modified_ackley(x: FloatArray) -> FloatArray:
    """Modified ackley: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return math.exp(-0.2) * np.hypot(a, b) + 3.0 * (np.cos(2.0 * a) + np.sin(2.0 * b))


def camel6(x: FloatArray) -> FloatArray:
    """Camel6: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return (4.0 - 2.1 * a**2 + a**4 / 3.0) * a**2 + a * b + (-4.0 + 4.0 * b**2) * b**2


def branin(x: FloatArray) -> FloatArray:
    """Branin: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    return (
        (b - 5.1 / (4.0 * np.pi**2) * a**2 + 5.0 / np.pi * a - 6.0) ** 2
        + 10.0 * (1.0 - 1.0 / (8.0 * np.pi)) * np.cos(a)
        + 10.0
    )


_H3_A = np.array([[3.0, 10, 30], [0.1, 10, 35], [3.0, 10, 30], [0.1, 10, 35]])
_H3_P = np.array(
    [[0.3689, 0.1170, 0.2673], [0.4699, 0.4387, 0.7470], [0.1091, 0.8732, 0.5547],
     [0.03815, 0.5743, 0.8828]]
)  # fmt: skip
_H6_A = np.array(
    [[10.0, 3, 17, 3.5, 1.7, 8], [0.05, 10, 17, 0.1, 8, 14], [3.0, 3.5, 1.7, 10, 17, 8],
     [17.0, 8, 0.05, 10, 0.1, 14]]
)  # fmt: skip
_H6_P = 1e-4 * np.array(
    [[1312.0, 1696, 5569, 124, 8283, 5886], [2329, 4135, 8307, 3736, 1004, 9991],
     [2348, 1451, 3522, 2883, 3047, 6650], [4047, 8828, 8732, 5743, 1091, 381]]
)  # fmt: skip
_H_C = np.array([1.0, 1.2, 3.0, 3.2])


def _hartmann(x: FloatArray, a: FloatArray, p: FloatArray) -> FloatArray:
    y = x[:, : a.shape[1]]
    inner = np.einsum("kj,nkj->nk", a, (y[:, None, :] - p[None]) ** 2)
    return -np.exp(-inner) @ _H_C


def hartmann3(x: FloatArray) -> FloatArray:
    """Hartmann3: ``(n_pop, dim) -> (n_pop,)``."""
    return _hartmann(x, _H3_A, _H3_P)


def hartmann6(x: FloatArray) -> FloatArray:
    """Hartmann6: ``(n_pop, dim) -> (n_pop,)``."""
    return _hartmann(x, _H6_A, _H6_P)


_SHEKEL_A = np.array(
    [[4.0, 4, 4, 4], [1, 1, 1, 1], [8, 8, 8, 8], [6, 6, 6, 6], [3, 7, 3, 7], [2, 9, 2, 9],
     [5, 5, 3, 3], [8, 1, 8, 1], [6, 2, 6, 2], [7, 3.6, 7, 3.6]]
)  # fmt: skip
_SHEKEL_C = 0.1 * np.array([1.0, 2, 2, 4, 4, 6, 3, 7, 5, 5])


def _shekel(x: FloatArray, m: int) -> FloatArray:
    d = np.sum((x[:, None, :4] - _SHEKEL_A[None, :m]) ** 2, axis=2)  # (n, m)
    return -np.sum(1.0 / (d + _SHEKEL_C[:m]), axis=1)


def shekel5(x: FloatArray) -> FloatArray:
    """Shekel5: ``(n_pop, dim) -> (n_pop,)``."""
    return _shekel(x, 5)


def shekel7(x: FloatArray) -> FloatArray:
    """Shekel7: ``(n_pop, dim) -> (n_pop,)``."""
    return _shekel(x, 7)


def shekel10(x: FloatArray) -> FloatArray:
    """Shekel10: ``(n_pop, dim) -> (n_pop,)``."""
    return _shekel(x, 10)


def perm(x: FloatArray, beta: float = 0.5) -> FloatArray:
    """Perm: ``(n_pop, dim) -> (n_pop,)``."""
    y = x[:, :4]
    d = y.shape[1]
    j = np.arange(1, d + 1, dtype=float)
    i = j[:, None]  # (d_i, 1)
    terms = (j[None, :] ** i + beta)[None] * ((y[:, None, :] / j) ** i[None] - 1.0)
    return np.sum(np.sum(terms, axis=2) ** 2, axis=1)


def goldstein_price(x: FloatArray) -> FloatArray:
    """Goldstein price: ``(n_pop, dim) -> (n_pop,)``."""
    a, b = _c(x, 0), _c(x, 1)
    f1 = 1.0 + (a + b + 1.0) ** 2 * (19 - 14 * a + 3 * a**2 - 14 * b + 6 * a * b + 3 * b**2)
    f2 = 30.0 + (2 * a - 3 * b) ** 2 * (18 - 32 * a + 12 * a**2 + 48 * b - 36 * a * b + 27 * b**2)
    return f1 * f2


_LANG_A = np.array(
    [[9.681, 0.667, 4.783, 9.095, 3.517, 9.325, 6.544, 0.211, 5.122, 2.020],
     [9.400, 2.041, 3.788, 7.931, 2.882, 2.672, 3.568, 1.284, 7.033, 7.374],
     [8.025, 9.152, 5.114, 7.621, 4.564, 4.711, 2.996, 6.126, 0.734, 4.982],
     [2.196, 0.415, 5.649, 6.979, 9.510, 9.166, 6.304, 6.054, 9.377, 1.426],
     [8.074, 8.777, 3.467, 1.863, 6.708, 6.349, 4.534, 0.276, 7.633, 1.567]]
)  # fmt: skip
_LANG_C = np.array([0.806, 0.517, 0.1, 0.908, 0.965])
_LANG_C_PAPER = np.array([0.806, 0.517, 1.5, 0.908, 0.965])


def _langerman(x: FloatArray, c: FloatArray) -> FloatArray:
    d = np.sum((x[:, None, :10] - _LANG_A[None]) ** 2, axis=2)  # (n, 5)
    return (np.exp(-d / np.pi) * np.cos(np.pi * d)) @ c


def langerman5(x: FloatArray) -> FloatArray:
    """Langerman5: ``(n_pop, dim) -> (n_pop,)``."""
    return -_langerman(x, _LANG_C)


def langerman5_paper(x: FloatArray) -> FloatArray:
    """Langerman5 paper: ``(n_pop, dim) -> (n_pop,)``."""
    return _langerman(x, _LANG_C_PAPER)


# ---------------------------------------------------------------------------------------------
# registry: (key, name, fun, dim, bounds per var or one pair, f*, x*, group, appendix, table)

_PI = math.pi
_U, _M, _F = "unimodal", "multimodal", "fixed"
_SPECS: list[tuple[Any, ...]] = [
    ("sphere", "Sphere", sphere, 30, (-100, 100), 0.0, [0.0] * 30, _U, "F1", "F1"),
    ("beale", "Beale", beale, 2, (-4.5, 4.5), 0.0, [3.0, 0.5], _U, "F2", "F2"),
    ("matyas", "Matyas", matyas, 2, (-10, 10), 0.0, [0.0, 0.0], _U, "F3", "F3"),
    ("rosenbrock", "Rosenbrock", rosenbrock, 30, (-30, 30), 0.0, [1.0] * 30, _U, "F4", "F4"),
    ("step2", "Step 2", step2, 30, (-100, 100), 0.0, [-0.5] * 30, _U, "F5", "F5"),
    ("schaffer2", "Schaffer 2", schaffer2, 2, (-100, 100), 0.0, [0, 0], _U, "F6", "F6"),
    ("schaffer3", "Schaffer 3", schaffer3, 2, (-100, 100), 0.001566854526004,
     [0.0, 1.253114957], _U, "F7", "F7"),
    ("schwefel12", "Schwefel 1.2", schwefel12, 30, (-100, 100), 0.0, [0.0] * 30, _U, "F8",
     "F8"),
    ("schwefel221", "Schwefel 2.21", schwefel221, 30, (-100, 100), 0.0, [0.0] * 30, _U, "F9",
     "F9"),
    ("schwefel222", "Schwefel 2.22", schwefel222, 30, (-10, 10), 0.0, [0.0] * 30, _U, "F10",
     "F10"),
    ("dejong4", "De Jong 4", dejong4, 30, (-5.12, 5.12), 0.0, [0.0] * 30, _U, "F11", "F11"),
    ("axis_parallel", "Axis Parallel", axis_parallel, 30, (-5.12, 5.12), 0.0, [0.0] * 30, _U,
     "F12", "F12"),
    ("easom", "Easom", easom, 2, (-100, 100), -1.0, [_PI, _PI], _M, "F13", "F13"),
    ("griewank", "Griewank", griewank, 30, (-600, 600), 0.0, [0.0] * 30, _M, "F14", "F14"),
    ("rastrigin", "Rastrigin", rastrigin, 30, (-5.12, 5.12), 0.0, [0.0] * 30, _M, "F15",
     "F15"),
    ("pen_holder", "Pen Holder", pen_holder, 2, (-11, 11), -0.9635348327265058,
     [9.646167671043401, 9.646167671043401], _M, None, "F16"),
    ("test_tube_holder", "Test-tube Holder", test_tube_holder, 2, (-10, 10),
     -10.872300105622745, [1.5706026142145, 0.0], _M, "F16", "F17"),
    ("egg_holder", "Egg Holder", egg_holder, 2, (-512, 512), -959.6406627208505,
     [512.0, 404.2318058], _M, "F17", "F18"),
    ("damavandi", "Damavandi", damavandi, 2, (0, 14), 0.0, [2.0, 2.0], _M, "F18", "F19"),
    ("cross_leg_table", "Cross-leg Table", cross_leg_table, 2, (-10, 10), -1.0, [0.0, 0.0],
     _M, "F19", "F20"),
    ("bukin4", "Bukin 4", bukin4, 2, [(-15, -5), (-3, 3)], 0.0, [-10.0, 0.0], _M, "F20",
     "F21"),
    ("bukin6", "Bukin 6", bukin6, 2, [(-15, -5), (-3, 3)], 0.0, [-10.0, 1.0], _M, "F21",
     "F22"),
    ("cosine_mixture", "Cosine Mixture", cosine_mixture, 30, (-1, 1), -3.0, [0.0] * 30, _M,
     "F22", "F23"),
    ("modified_rosenbrock", "Modified Rosenbrock", modified_rosenbrock, 2, (-2, 2),
     34.04024310664062, [-0.9095537365, -0.9505717127], _M, "F23", "F24"),
    ("schwefel226", "Schwefel 2.26", schwefel226, 30, (-500, 500), -418.9828872724338,
     [420.9687463593] * 30, _M, "F24", None),
    ("paviani", "Paviani", paviani, 10, (2.001, 9.999), -45.77846970744629,
     [9.350265833] * 10, _F, "F25", "F25"),
    ("modified_ackley", "Modified Ackley", modified_ackley, 2, (-35, 35), -4.590101634158666,
     [1.5096201128, -0.7548651213], _F, "F26", "F26"),
    ("camel6", "Camel 6 Hump", camel6, 2, (-5, 5), -1.0316284534898774,
     [0.0898420137, -0.7126564033], _F, "F27", "F27"),
    ("branin", "Branin RCOS", branin, 2, [(-5, 10), (0, 15)], 5.0 / (4.0 * _PI),
     [_PI, 2.275], _F, "F28", "F28"),
    ("hartmann3", "Hartmann 3", hartmann3, 3, (0, 1), -3.8627821478207558,
     [0.11461292, 0.55564907, 0.85254697], _F, "F29", "F29"),
    ("hartmann6", "Hartmann 6", hartmann6, 6, (0, 1), -3.3223680114155153,
     [0.20168951, 0.15001069, 0.47687398, 0.27533243, 0.31165162, 0.65730054], _F, "F30",
     "F30"),
    ("shekel5", "Shekel 5", shekel5, 4, (0, 10), -10.153199679058231,
     [4.0000371, 4.0001333, 4.0000371, 4.0001333], _F, "F31", "F31"),
    ("shekel7", "Shekel 7", shekel7, 4, (0, 10), -10.402940566818664,
     [4.0005729, 4.0006894, 3.9994897, 3.9996062], _F, "F32", "F32"),
    ("shekel10", "Shekel 10", shekel10, 4, (0, 10), -10.536409816692046,
     [4.0007465, 4.0005929, 3.9996634, 3.9995098], _F, "F33", "F33"),
    ("perm", "Perm", perm, 4, (-4, 4), 0.0, [1.0, 2.0, 3.0, 4.0], _F, "F34", "F34"),
    ("goldstein_price", "Goldstein Price", goldstein_price, 2, (-2, 2), 3.0, [0.0, -1.0], _F,
     "F35", "F35"),
    ("langerman5", "Langerman 5", langerman5, 10, (0, 10), -0.965, _LANG_A[4].tolist(), _F,
     "F36", "F36"),
]  # fmt: skip

_ALTERNATIVES: list[tuple[Any, ...]] = [
    ("step2_floor", "Step 2 (floored, J&Y)", step2_floor, 30, (-100, 100), 0.0, [0.0] * 30, _U),
    ("cosine_mixture_jy", "Cosine Mixture (J&Y sign)", cosine_mixture_jy, 30, (-1, 1), -27.0,
     [1.0] * 30, _M),
    ("hartmann3_paper_bounds", "Hartmann 3 on [1,3] (paper box)", hartmann3, 3, (1, 3),
     float(hartmann3(np.ones((1, 3)))[0]), [1.0, 1.0, 1.0], _F),
    ("langerman5_paper", "Langerman 5 (paper variant)", langerman5_paper, 10, (0, 10),
     -1.096671262013792,
     [8.077429232374135, 9.096912554556821, 5.381054875955856, 7.6647431245401085,
      4.340627014156601, 4.861784364424851, 3.53976522653243, 6.520930734584603,
      0.4405439067993628, 4.4543219404115195], _F),
]  # fmt: skip

_NOTES = {
    "step2": "continuous form sum (x+0.5)^2 (the paper's results are not integers)",
    "schaffer2": "canonical denominator [1+0.001(x1^2+x2^2)]^2",
    "schaffer3": "canonical; the paper's -3.37e-4 rows are unexplained",
    "schwefel12": "inner sum j=1..i (the appendix prints j=1..D)",
    "pen_holder": "table-only function (not in the appendix)",
    "test_tube_holder": "true minimum at x1=1.5706026 (literature uses pi/2)",
    "egg_holder": "2-D with +47 and |.| (appendix formula garbled, sign of f_min lost)",
    "cosine_mixture": "minimisation form, f* = -0.1 D (appendix: f_min 0.4)",
    "modified_rosenbrock": "GAV/scipy form; tables show f*/10 = 3.404024",
    "paviani": "bounds [2.001, 9.999] (appendix [2, 10] gives log(0))",
    "modified_ackley": "J&Y Ackley 4 with constant e^-0.2 (appendix f_min -3.9172)",
    "branin": "Branin RCOS (appendix prints a hybrid with RCOS2)",
    "hartmann3": "box [0,1]^3 (appendix [1,3] excludes the minimiser)",
    "perm": "Perm d,beta with beta=0.5 (appendix formula garbled)",
    "goldstein_price": "-36 x1 x2 (appendix +36)",
    "langerman5": "canonical ICEO/MVF; tables match the variant langerman5_paper",
}


def _expand(dim: int, b: Any) -> list[tuple[float, float]]:
    if isinstance(b, tuple):
        return [b] * dim
    return list(b)


for _s in _SPECS:
    _key, _name, _fun, _dim, _b, _fs, _xs, _grp, _app, _tab = _s
    register_function(
        _key, _fun, _expand(_dim, _b), _fs, name=_name, x_star=_xs, group=_grp,
        appendix_id=_app, table_id=_tab, note=_NOTES.get(_key, ""),
    )  # fmt: skip
    if _tab is not None:
        _TABLE_ORDER.append(_key)
    if _app is not None:
        _APPENDIX_ORDER.append(_key)
for _s in _ALTERNATIVES:
    _key, _name, _fun, _dim, _b, _fs, _xs, _grp = _s
    register_function(_key, _fun, _expand(_dim, _b), _fs, name=_name, x_star=_xs, group=_grp)
