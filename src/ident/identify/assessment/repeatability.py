"""Repeatability: do the estimates of several logs of one robot agree within their std?

A robot identified twice should give the same parameters within their predicted standard
deviations (:mod:`ident.identify.estimation.uncertainty`). When it does not, the robot drifted
(friction changes with temperature and wear) or a log is bad. :func:`repeatability` compares the
spread with the prediction, parameter by parameter, and names the log farthest from the others;
``ident repeatability CONFIG CONFIG...`` prints it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.stats

from ident.errors import DataError

__all__ = ["Repeatability", "repeatability"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Repeatability:
    """Spread of the estimates of several logs of one robot beside their predicted std.

    Attributes
    ----------
    names :
        Parameter names, length n.
    mean :
        Inverse-variance weighted mean per parameter, shape (n,).
    spread :
        Sample standard deviation of the estimates across logs, shape (n,).
    predicted :
        RMS of the logs' predicted standard deviations, shape (n,).
    p_value :
        Of ``sum_r ((x_r - mean) / std_r)^2 ~ chi2(n_logs - 1)`` (agreement), shape (n,).
    disagree :
        Parameters whose p-value is below ``alpha / n`` (Bonferroni), with the log whose
        estimate lies farthest from the mean in its own std.
    """

    names: tuple[str, ...]
    mean: FloatArray
    spread: FloatArray
    predicted: FloatArray
    p_value: FloatArray
    disagree: tuple[tuple[str, int], ...]

    def lines(self) -> list[str]:
        """One sentence per disagreeing parameter."""
        out = []
        for name, log in self.disagree:
            k = self.names.index(name)
            out.append(
                f"{name}: spread {self.spread[k]:.3g} across the logs is "
                f"{self.spread[k] / self.predicted[k]:.1f}x the predicted std "
                f"{self.predicted[k]:.3g} (p = {self.p_value[k]:.1e}); log {log + 1} lies "
                "farthest: a drifting robot or a bad log"
            )
        return out


def repeatability(
    x: npt.ArrayLike, std: npt.ArrayLike, names: tuple[str, ...], *, alpha: float = 0.01
) -> Repeatability:
    """Do the estimates of ``n_logs`` logs agree within their predicted std?

    ``x``, ``std``: estimates and their standard deviations, shape (n_logs, n), n_logs >= 2.
    """
    x = np.asarray(x, dtype=float)
    std = np.asarray(std, dtype=float)
    if x.ndim != 2 or x.shape != std.shape or x.shape[0] < 2:
        raise DataError(f"x {x.shape} and std {std.shape}: need (n_logs >= 2, n) each.")
    w = 1.0 / std**2
    mean = np.sum(w * x, axis=0) / np.sum(w, axis=0)
    z = (x - mean) / std
    stat = np.sum(z**2, axis=0)
    p = scipy.stats.chi2.sf(stat, df=x.shape[0] - 1)
    bad = np.flatnonzero(p < alpha / x.shape[1])
    return Repeatability(
        names=tuple(names),
        mean=mean,
        spread=np.std(x, axis=0, ddof=1),
        predicted=np.sqrt(np.mean(std**2, axis=0)),
        p_value=p,
        disagree=tuple((names[k], int(np.argmax(np.abs(z[:, k])))) for k in bad),
    )
