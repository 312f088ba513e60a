"""The verdict of an identification: one rule, one function, for every command.

:func:`decide_verdict` turns an :class:`Evidence` (what is known about an estimate) into a
:class:`Verdict` (``good``, ``usable``, ``not identified`` or ``unsafe``). ``ident run``,
``ident identify``, both reports, both ``result.json`` files, the terminal and ``ident
report`` render that one value; nothing else decides a verdict. The rule and its thresholds
are documented once, in ``docs/verdict.md`` (a test holds its table equal to
:data:`THRESHOLDS`).

Two kinds of evidence:

- **truth known** (a simulation: ``ident run``, or ``ident identify`` on a simulated log whose
  config carries the simulator's truth, ``validation.truth``): the worst relative error of the
  *major* base parameters (reference torque share >= ``MAJOR_SHARE``) and the relative torque
  residual;
- **no truth** (every real log): the held-out torque residual against the URDF nominal
  parameters' residual on the same rows, the worst relative standard deviation of the
  parameters that carry the torques (torque share >= ``MAJOR_SHARE`` on the identification
  rows, computed from the estimate's covariance: :func:`covariance_torque_shares`; the σ is
  the result's one standard deviation, the default interval method's:
  :func:`ident.identify.estimation.uncertainty.parameter_std`), the
  physical consistency of the reported estimate, and the warnings.

In both, an unsafe trajectory gives ``unsafe`` (never ``usable``) and a missing estimate gives
``not identified``. Pure functions: no files, no printing.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.identify.assessment.metrics import MAJOR_SHARE, error_measures
from ident.identify.estimation.uncertainty import parameter_std

__all__ = [
    "GOOD_ERROR_PERCENT",
    "GOOD_RESIDUAL",
    "GOOD_STD_PERCENT",
    "LABELS",
    "MAJOR_SHARE",
    "THRESHOLDS",
    "USABLE_ERROR_PERCENT",
    "USABLE_RESIDUAL",
    "VERDICT_RULE",
    "VERDICT_RULE_REAL",
    "Evidence",
    "Truth",
    "Verdict",
    "covariance_torque_shares",
    "decide_verdict",
    "identify_verdict",
    "judged_method",
    "log_evidence",
    "thresholds_markdown",
    "truth_error",
    "truth_from_config",
]

FloatArray = npt.NDArray[np.float64]

GOOD_ERROR_PERCENT = 5.0  # [%] worst relative error of the major parameters (truth known)
USABLE_ERROR_PERCENT = 20.0
GOOD_STD_PERCENT = 5.0  # [%] worst relative std of the torque-carrying parameters (no truth)
GOOD_RESIDUAL = 0.10  # relative torque residual ||tau - tau_pred|| / ||tau||
USABLE_RESIDUAL = 0.25

LABELS = ("good", "usable", "not identified", "unsafe")

#: Every threshold of the rule by the name docs/verdict.md gives it (value, unit).
THRESHOLDS: dict[str, tuple[float, str]] = {
    "MAJOR_SHARE": (MAJOR_SHARE, "fraction of the torques"),
    "GOOD_ERROR_PERCENT": (GOOD_ERROR_PERCENT, "%"),
    "USABLE_ERROR_PERCENT": (USABLE_ERROR_PERCENT, "%"),
    "GOOD_STD_PERCENT": (GOOD_STD_PERCENT, "%"),
    "GOOD_RESIDUAL": (GOOD_RESIDUAL, "fraction"),
    "USABLE_RESIDUAL": (USABLE_RESIDUAL, "fraction"),
}

#: The rule with the truth known, as the reports print it.
VERDICT_RULE = (
    f"unsafe if the executed trajectory failed its safety check; good: every major parameter "
    f"(torque share >= {100 * MAJOR_SHARE:g} %) within {GOOD_ERROR_PERCENT:g} % of its true "
    f"value, torque residual below {100 * GOOD_RESIDUAL:g} % and no warning; usable: within "
    f"{USABLE_ERROR_PERCENT:g} % and below {100 * USABLE_RESIDUAL:g} %; otherwise not "
    "identified (docs/verdict.md)"
)
#: The rule without the truth (a real log), as the reports print it.
VERDICT_RULE_REAL = (
    "not identified if the held-out torque residual is not below the URDF nominal "
    f"parameters'; good: held-out residual below {100 * GOOD_RESIDUAL:g} %, every parameter "
    f"carrying >= {100 * MAJOR_SHARE:g} % of the torques with relative std (σ) below "
    f"{GOOD_STD_PERCENT:g} %, every link physically consistent and no warning; usable: "
    f"held-out residual below {100 * USABLE_RESIDUAL:g} % (the parameters predict the "
    "torques; the warnings say what to trust less); otherwise not identified "
    "(docs/verdict.md)"
)


@dataclass(frozen=True)
class Verdict:
    """``label`` (one of :data:`LABELS`), the reason in one sentence, and the ``rule``
    applied (``"truth"`` or ``"log"``)."""

    label: str
    reason: str
    rule: str = "truth"

    def as_dict(self) -> dict[str, str]:
        """JSON-ready."""
        return {"label": self.label, "reason": self.reason, "rule": self.rule}


@dataclass(frozen=True)
class Truth:
    """The true base parameters of a simulated measurement.

    Attributes
    ----------
    names :
        Base-parameter names, in the estimate's order.
    values :
        True base parameters (SI), shape (n_base,).
    reference_share :
        Torque share of each base parameter on the stage's reference motion (unit-free), shape
        (n_base,); a share of at least ``MAJOR_SHARE`` makes the parameter *major*.
    """

    names: tuple[str, ...]
    values: FloatArray
    reference_share: FloatArray


@dataclass(frozen=True)
class Evidence:
    """What is known about an estimate (see the module docstring).

    Attributes
    ----------
    estimated :
        False when no estimate exists (every estimator failed).
    residual :
        Relative torque residual ``||tau - tau_pred|| / ||tau||`` (held-out or validation data
        when there are some), None if unknown.
    residual_where :
        Which data ``residual`` is on (for the reason).
    nominal_residual :
        The URDF nominal parameters' residual on the same rows (logs), None if unknown.
    worst_error_percent, worst_error_name :
        Truth known: worst relative error [%] of the major parameters and its name.
    worst_std_percent, worst_std_name :
        No truth: worst relative std [%] of the torque-carrying parameters and its name.
    std_method :
        The interval method of that std (``"bootstrap"``, or ``"ordinary"`` when the log has
        too few blocks for it: :func:`ident.identify.estimation.uncertainty.parameter_std`).
    n_inconsistent, n_links :
        Links the reported estimate makes physically inconsistent, of ``n_links`` (None:
        not checked).
    warnings :
        The result's warnings (every one of them is shown with the verdict).
    safe :
        The executed trajectory passed its safety check (None: not checked, a measured log).
    truth :
        Whether true values are known (None: whether ``worst_error_percent`` is set); with
        the truth known and no error, the verdict is ``not identified``.
    method :
        The estimator judged (its residual and consistency).
    """

    estimated: bool = True
    residual: float | None = None
    residual_where: str = "held-out data"
    nominal_residual: float | None = None
    worst_error_percent: float | None = None
    worst_error_name: str | None = None
    worst_std_percent: float | None = None
    worst_std_name: str | None = None
    std_method: str | None = None
    n_inconsistent: int | None = None
    n_links: int | None = None
    warnings: tuple[str, ...] = field(default_factory=tuple)
    safe: bool | None = None
    truth: bool | None = None
    method: str | None = None

    @property
    def truth_known(self) -> bool:
        """True when the evidence has errors against true values (``truth``, else whether
        ``worst_error_percent`` is set)."""
        return self.worst_error_percent is not None if self.truth is None else self.truth


def _pct(value: float | None) -> str:
    return "unknown" if value is None or not math.isfinite(value) else f"{value:.3g} %"


def decide_verdict(e: Evidence) -> Verdict:
    """The verdict of the rule of docs/verdict.md.

    Parameters
    ----------
    e :
        The evidence; truth-known evidence (``worst_error_percent`` set) uses the simulation
        rule, otherwise the log rule.

    Returns
    -------
    :
        The :class:`Verdict`, its reason naming every number it used.
    """
    rule = "truth" if e.truth_known else "log"
    res = math.inf if e.residual is None or not math.isfinite(e.residual) else e.residual
    res_text = f"torque residual {_pct(None if e.residual is None else 100 * e.residual)}"
    res_text += f" ({e.residual_where})"
    notes: list[str] = []
    if e.warnings:
        notes.append(f"{len(e.warnings)} warning(s)")
    if e.n_inconsistent:
        notes.append(f"{e.n_inconsistent} of {e.n_links} links physically inconsistent")
    if e.safe is False:
        return Verdict("unsafe", "the executed trajectory failed its safety check", rule)
    if not e.estimated:
        return Verdict("not identified", "no estimate (every estimator failed)", rule)
    if e.truth_known:
        return _truth_verdict(e, res, res_text, notes)
    if e.residual is None:
        return Verdict("not identified", "no torque prediction to judge", rule)
    std = math.inf if e.worst_std_percent is None else e.worst_std_percent
    std_text = f"worst σ {_pct(e.worst_std_percent)}"
    named = [n for n in (e.worst_std_name, e.std_method) if n]
    if named:
        std_text += f" ({', '.join(named)})"
    nominal = e.nominal_residual
    nominal_text = "" if nominal is None else f", URDF nominal {_pct(100 * nominal)}"
    reason = "; ".join([f"{res_text}{nominal_text}, {std_text}", *notes])
    if nominal is not None and math.isfinite(nominal) and not res < nominal:
        return Verdict("not identified", reason + "; not better than the URDF nominal", rule)
    good = (
        res <= GOOD_RESIDUAL and std <= GOOD_STD_PERCENT and not e.warnings and not e.n_inconsistent
    )
    if good:
        return Verdict("good", reason, rule)
    if res <= USABLE_RESIDUAL:  # a log that predicts held-out torques is not "not identified"
        return Verdict("usable", reason, rule)
    return Verdict("not identified", reason, rule)


def _truth_verdict(e: Evidence, res: float, res_text: str, notes: list[str]) -> Verdict:
    """The simulation rule of :func:`decide_verdict`: worst major-parameter error against the
    truth and relative torque residual ``res`` (described by ``res_text``)."""
    rule = "truth"
    if e.worst_error_percent is None:
        return Verdict("not identified", "no error against the truth (no estimate)", rule)
    worst = float(e.worst_error_percent)
    what = f"worst major-parameter error {worst:.3g} %"
    if e.worst_error_name:
        what += f" ({e.worst_error_name})"
    reason = "; ".join([f"{what}, {res_text}", *notes])
    good = worst <= GOOD_ERROR_PERCENT and res <= GOOD_RESIDUAL and not e.warnings
    if good:
        return Verdict("good", reason, rule)
    if worst <= USABLE_ERROR_PERCENT and res <= USABLE_RESIDUAL:
        return Verdict("usable", reason, rule)
    return Verdict("not identified", reason, rule)


def covariance_torque_shares(x: FloatArray, covariance: FloatArray) -> FloatArray:
    """Share of the (noise-weighted) torques each parameter explains, from the estimate alone.

    The inverse covariance of a (weighted) least-squares estimate is the weighted Gram matrix
    ``G = W_w^T W_w`` of its observation rows, so ``|x_i| sqrt(G_ii) / sqrt(x^T G x)`` is
    ``|x_i| ||W_w[:, i]|| / ||W_w x||``: unit-free, the part of the torques parameter i
    carries.

    Parameters
    ----------
    x :
        Estimate, shape (n,).
    covariance :
        Its covariance, shape (n, n).

    Returns
    -------
    :
        Shares, shape (n,); NaN where the covariance does not say.
    """
    x = np.asarray(x, dtype=float)
    cov = np.asarray(covariance, dtype=float)
    if cov.shape != (x.size, x.size) or not np.all(np.isfinite(cov)):
        return np.full(x.shape, np.nan)
    gram = np.linalg.pinv(cov, hermitian=True)
    total = float(x @ gram @ x)
    if not total > 0:
        return np.full(x.shape, np.nan)
    return np.abs(x) * np.sqrt(np.clip(np.diag(gram), 0.0, None)) / math.sqrt(total)


def truth_error(
    x: FloatArray, std: FloatArray, names: Sequence[str], truth: Truth
) -> tuple[float, str | None, int] | None:
    """Worst relative error [%] of the major parameters, its name and the number of majors.

    The measures of :func:`ident.identify.assessment.metrics.error_measures` (the same ones a run
    saves); None when the names are not the truth's.
    """
    if tuple(names) != tuple(truth.names):
        return None
    m = error_measures(x, std, truth.values, reference_share=truth.reference_share)
    worst = m.get("max_rel_error_major_percent")
    if worst is None:
        return None
    i = m.get("worst_major")
    return float(worst), None if i is None else str(names[i]), int(sum(m["major"]))


def _worst_carrying_std(est: Any, rel: FloatArray) -> tuple[float | None, str | None]:
    """The largest relative standard deviation [%] ``rel`` (shape (n_base,)) among the base
    parameters of ``est`` that carry a major share of the torques (every one when the shares are
    not finite), and its name; ``(None, None)`` when none carries one."""
    x = np.asarray(est.x, dtype=float)
    # the ordinary covariance's inverse is the Gram matrix of the rows: shares, not a σ
    shares = covariance_torque_shares(x, np.asarray(getattr(est, "covariance", ()), dtype=float))
    carrying = shares >= MAJOR_SHARE if np.all(np.isfinite(shares)) else np.ones(x.size, bool)
    if not carrying.any():
        return None, None
    rel_c = np.where(np.isfinite(rel[carrying]), rel[carrying], np.inf)
    k = int(np.argmax(rel_c))
    return float(rel_c[k]), str(np.asarray(est.names)[carrying][k])


def log_evidence(
    result: Any,
    *,
    truth: Truth | None = None,
    safe: bool | None = None,
    extra_warnings: Sequence[str] = (),
) -> Evidence:
    """The evidence of an identification from a log (an ``IdentifyResult``).

    The same function for ``ident identify`` and for each log ``ident run`` simulates, so the
    same log gives the same verdict.

    Parameters
    ----------
    result :
        The :class:`~ident.identify.pipeline.real.IdentifyResult`.
    truth :
        The simulator's truth of a simulated log (None: a real log, judged without).
    safe :
        Whether the executed trajectory passed its safety check (``ident run``).
    extra_warnings :
        Warnings of the caller put before the result's own.
    """
    est = result.estimate
    x = np.asarray(est.x, dtype=float)
    sd = parameter_std(est, getattr(result, "uncertainty", None))
    worst_std, worst_std_name = _worst_carrying_std(est, sd.relative_std)
    method = judged_method(result)
    pred = result.predictions.get(method, result.predictions.get("identified"))
    nominal = result.predictions.get("URDF nominal")
    n_bad, n_links = _consistency_counts(result, method)
    in_sample = result.config.validation.identify_fraction >= 1.0  # no held-out part
    evidence = Evidence(
        estimated=True,
        residual=None if pred is None else float(pred.metrics.total_relative_residual),
        residual_where="identification rows" if in_sample else "held-out data",
        nominal_residual=None
        if nominal is None
        else float(nominal.metrics.total_relative_residual),
        worst_std_percent=worst_std,
        worst_std_name=worst_std_name,
        std_method=sd.method,
        n_inconsistent=n_bad,
        n_links=n_links,
        warnings=(*extra_warnings, *result.warnings),
        safe=safe,
        method=method,
    )
    if truth is not None:
        err = truth_error(x, sd.std, est.names, truth)
        if err is not None:
            evidence = dataclasses.replace(
                evidence, worst_error_percent=err[0], worst_error_name=err[1]
            )
    return evidence


def truth_from_config(entry: Any) -> Truth | None:
    """The :class:`Truth` of an identify config's ``validation.truth`` (None when unset)."""
    if entry is None:
        return None
    return Truth(
        names=tuple(entry.base_names),
        values=np.asarray(entry.values, dtype=float),
        reference_share=np.asarray(entry.reference_share, dtype=float),
    )


def identify_verdict(result: Any) -> Verdict:
    """The verdict of an ``ident identify`` result (the one its terminal, report and
    ``result.json`` show): :func:`log_evidence` with the config's ``validation.truth``."""
    truth = truth_from_config(result.config.validation.truth)
    return decide_verdict(log_evidence(result, truth=truth))


def judged_method(result: Any) -> str:
    """The estimator a log's verdict judges: the configured ``estimation.method`` when the
    result has its consistency data (a constrained estimate beside least squares), else the
    least-squares estimate's."""
    configured = result.config.estimation.method
    consistent = getattr(result, "consistent", None)
    if consistent is not None and configured in consistent.estimates:
        return str(configured)
    return str(result.estimate.method)


def _consistency_counts(result: Any, method: str) -> tuple[int | None, int | None]:
    """Inconsistent links of ``method``'s estimate, and the number of links (None, None when
    the result has no consistency data for it)."""
    consistent = getattr(result, "consistent", None)
    if consistent is None or method not in consistent.estimates:
        return None, None
    links = consistent.estimates[method].consistency
    return sum(not c.consistent for c in links), len(links)


def thresholds_markdown() -> list[str]:
    """The threshold table of docs/verdict.md, generated from :data:`THRESHOLDS`."""
    lines = ["| threshold | value | unit |", "| --- | --- | --- |"]
    lines += [f"| `{name}` | {value:g} | {unit} |" for name, (value, unit) in THRESHOLDS.items()]
    return lines
