"""Essential parameters: the base parameters the data really determine.

Starting from all base parameters, repeatedly drop the one with the largest relative standard
deviation and re-estimate, while (a) some parameter's relative std exceeds a bound and (b) the
fit holds: the relative residual stays within ``(1 + max_residual_increase)`` times that of the
full base set. The result is a smaller, better-conditioned model whose parameters all have small
uncertainty (Pham and Gautier, "Essential parameters of robots", CDC 1991).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.identify.estimation.estimate import Estimate, least_squares

__all__ = ["EssentialResult", "backward_elimination", "essential_parameters"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class EssentialResult:
    """Outcome of the essential-parameter reduction.

    Attributes
    ----------
    estimate :
        Estimate with the kept parameters only.
    kept :
        Column indices (into the input ``W``) of the kept parameters.
    dropped :
        One entry per removal, in order: name, its relative std [%] when dropped, and the
        relative residual after dropping it.
    stop_reason :
        Why the reduction stopped.
    """

    estimate: Estimate
    kept: tuple[int, ...]
    dropped: tuple[dict, ...]
    stop_reason: str


def essential_parameters(
    W: FloatArray,
    tau: FloatArray,
    names: tuple[str, ...] | list[str],
    *,
    method: str = "ols",
    groups: npt.ArrayLike | None = None,
    rows_per_sample: int | None = None,
    max_relative_std_pct: float = 10.0,
    max_residual_increase: float = 0.05,
) -> EssentialResult:
    """Reduce base parameters to essential ones by backward elimination on relative std.

    Parameters
    ----------
    W :
        Base observation matrix, shape (m, n_base).
    tau :
        Measured torques [N*m], stacked (m,) or (n_samples, nv).
    names :
        Base parameter names, length n_base.
    method, groups, rows_per_sample :
        Passed to :func:`~ident.identify.estimation.estimate.least_squares`.
    max_relative_std_pct :
        Stop once every kept parameter has a relative std at or below this [%].
    max_residual_increase :
        Reject a removal if the relative residual grows above ``(1 + this)`` times the
        residual of the full base set, and stop.

    Returns
    -------
    :
        The :class:`EssentialResult`.
    """
    names = tuple(names)

    def fit(columns: list[int]) -> Estimate:
        return least_squares(
            W[:, columns],
            tau,
            [names[i] for i in columns],
            method=method,
            groups=groups,
            rows_per_sample=rows_per_sample,
        )

    return backward_elimination(
        fit,
        names,
        max_relative_std_pct=max_relative_std_pct,
        max_residual_increase=max_residual_increase,
    )


def backward_elimination(
    fit: Callable[[list[int]], Estimate],
    names: Sequence[str],
    *,
    max_relative_std_pct: float,
    max_residual_increase: float,
) -> EssentialResult:
    """The essential-parameter rule on any fit of a subset of the parameters.

    Starting from every parameter, drop the one with the largest relative standard deviation
    while it is above ``max_relative_std_pct`` and the relative residual stays within
    ``1 + max_residual_increase`` of the full set's. ``fit(columns)`` estimates the parameters
    ``columns`` (indices into ``names``); rows or a reduction of them, the rule is the same.
    """
    kept = list(range(len(names)))
    current = fit(kept)
    limit = current.relative_residual * (1.0 + max_residual_increase)
    dropped: list[dict] = []
    stop_reason = "every parameter has a relative std within the bound"
    while len(kept) > 1:
        worst = int(np.argmax(current.relative_std))
        if current.relative_std[worst] <= max_relative_std_pct:
            break
        trial_columns = kept[:worst] + kept[worst + 1 :]
        trial = fit(trial_columns)
        if trial.relative_residual > limit:
            stop_reason = (
                f"dropping {names[kept[worst]]} would raise the relative residual to "
                f"{trial.relative_residual:.4g} (limit {limit:.4g})"
            )
            break
        dropped.append(
            {
                "name": names[kept[worst]],
                "relative_std_pct": float(current.relative_std[worst]),
                "relative_residual_after": float(trial.relative_residual),
            }
        )
        kept, current = trial_columns, trial
    else:
        stop_reason = "one parameter left"
    return EssentialResult(
        estimate=current, kept=tuple(kept), dropped=tuple(dropped), stop_reason=stop_reason
    )
