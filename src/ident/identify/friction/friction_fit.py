"""Friction models fitted with the rigid-body model, and compared on held-out data.

The rows are those of the identification (:mod:`ident.identify.estimation.accumulate`): the base
columns of everything but the joints' viscous and Coulomb friction (rigid bodies, rotor inertias,
offsets, coupled-motor terms: ``W_rest``), the joint velocities, the measured torques and the
velocity-threshold mask. A friction model of the registry (:mod:`ident.dynamics.friction_models`)
adds its columns for each joint that has friction.

**Separable least squares** (variable projection, Golub and Pereyra 1973). With ``W`` the
weighted rows of ``W_rest`` (QR ``W = Q R``), ``F(p)`` the friction columns for the nonlinear
parameters ``p`` and ``y`` the weighted torques, the linear parameters are eliminated::

    r(p) = (I - Q Q^T) (y - F(p) c(p)),   c(p) = argmin_c ||(I - Q Q^T)(y - F(p) c)||

and ``scipy.optimize.least_squares`` minimises ``||r(p)||`` over the few nonlinear parameters
(positive ones on a log scale, within a factor 30 of their start), started from the best of a
short scan of their scale around ``FrictionModel.initial``: a common scale of all joints, then
each joint's own scale with the others held (two sweeps).
The rest follows from ``R theta_rest = Q^T (y - F c)``. A linear model is one solve. Rows are
weighted per joint by ``1 / sigma_j``, the residual standard deviation of the
``viscous_coulomb`` fit (as WLS does), the same weights for every model so that fits compare.

:func:`compare_friction_models` fits every model and ranks them by the held-out total relative
residual ``||tau - tau_pred|| / ||tau||`` (the figure the identify report gives for the
identified parameters), on the held-out rows, or on the identification rows when there are none.

**Load.** The load of a load-dependent model is the torque of the rest of the model,
``W_rest theta_rest`` (rigid bodies, rotor inertias, offsets): never the measured torque, which
would put the measurement (and its noise) into the regressor and let the load term copy it
(on the TX40 log it did: ``fl`` near 1 on the wrist). Since the rest depends on the fit, the
fit is repeated with the last fit's load until it settles.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from ident.blas import one_blas_thread
from ident.dynamics.friction_models import FRICTION_MODELS, FrictionModel, get_friction_model
from ident.dynamics.parameter_model import ParameterModel
from ident.errors import DataError
from ident.identify.estimation import log_chunks
from ident.identify.estimation.validation import prediction_metrics

__all__ = [
    "FrictionComparison",
    "FrictionFit",
    "FrictionRows",
    "compare_friction_models",
    "fit_friction_model",
    "friction_rows",
    "predict_friction_rows",
    "rest_parameters",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.intp]

#: Common scale factors of the nonlinear parameters tried before the local fit.
_SCAN = np.geomspace(0.05, 20.0, 9)
#: Finer scale factors of each joint's own scan (ratio 1.41 between neighbours: on the UR5
#: processed log the true Stribeck basin is about a factor 1.7 wide).
_JOINT_SCAN = np.geomspace(0.05, 20.0, 18)
#: Sweeps of the per-joint scan (:func:`_scanned_start`).
_SWEEPS = 2
#: Scale of the first local step of the nonlinear parameters (log scale for positive ones).
_STEP = 0.1
#: A second minimum: at least this factor from the fit, cost within this fraction of its cost.
_AMBIGUOUS_FACTOR = 2.0
_AMBIGUOUS_COST = 0.01
#: Positive nonlinear parameters stay within this factor of their start.
_RANGE = 30.0
#: Fixed-point iterations of a load-dependent model (error shrinks like ``fl^k``).
_LOAD_ITERATIONS = 12


@dataclass(frozen=True, eq=False)
class FrictionRows:
    """Samples for a friction fit.

    Attributes
    ----------
    W_rest :
        Regressor columns of every parameter but the joints' friction, shape (n, nv, p).
    dq :
        Joint velocities [rad/s], shape (n, nv).
    tau :
        Measured joint torques [N*m], shape (n, nv).
    keep :
        Entries used (velocity threshold), shape (n, nv).
    joints :
        0-based joints with friction.
    """

    W_rest: FloatArray
    dq: FloatArray
    tau: FloatArray
    keep: BoolArray
    joints: tuple[int, ...]

    def __post_init__(self) -> None:
        n, nv = self.tau.shape
        if (
            self.W_rest.shape[:2] != (n, nv)
            or self.dq.shape != (n, nv)
            or self.keep.shape
            != (
                n,
                nv,
            )
        ):
            raise DataError(
                f"friction rows: W_rest {self.W_rest.shape}, dq {self.dq.shape}, keep "
                f"{self.keep.shape} do not match tau {self.tau.shape}."
            )


@dataclass(frozen=True, eq=False)
class FrictionFit:
    """One friction model fitted with the rest of the model.

    Attributes
    ----------
    model :
        The model's name.
    linear, nonlinear :
        Per-joint parameters, shapes (nv, n_linear), (nv, n_nonlinear) (zero for joints
        without friction), in the units of the model's formula.
    rest :
        The other parameters (the columns of ``W_rest``), shape (p,).
    fit_residual :
        Total relative residual on the fit rows.
    held_out_residual :
        Total relative residual on the held-out rows (NaN before :func:`compare_friction_models`).
    held_out_rmse :
        Held-out RMSE per joint [N*m], shape (nv,).
    success, message, nfev :
        Outcome of the nonlinear fit (a linear model: one solve, ``nfev = 1``).
    ambiguous :
        Empty, or why the data cannot tell the nonlinear parameters apart
        (:func:`_ambiguity`): ``auto`` does not pick such a model.
    """

    model: str
    linear: FloatArray
    nonlinear: FloatArray
    rest: FloatArray
    fit_residual: float
    success: bool
    message: str
    nfev: int
    held_out_residual: float = float("nan")
    held_out_rmse: FloatArray | None = None
    ambiguous: str = ""


def _friction_block(
    model: FrictionModel, rows: FrictionRows, load: FloatArray, p: FloatArray
) -> FloatArray:
    """Friction columns as full rows (n * nv, len(joints) * n_linear), sample-major."""
    F = model.columns(rows.dq, load, p)
    n, nv, n_lin = F.shape
    joints = np.asarray(rows.joints, dtype=np.intp)
    block = np.zeros((n, nv, joints.size, n_lin))
    block[:, joints, np.arange(joints.size), :] = F[:, joints, :]
    return block.reshape(n * nv, joints.size * n_lin)


def _weighted(rows: FrictionRows, weights: FloatArray) -> tuple[BoolArray, FloatArray, FloatArray]:
    """Kept-row mask (n * nv,), their weights and the weighted torques."""
    keep = rows.keep.reshape(-1)
    w = np.broadcast_to(weights, rows.tau.shape).reshape(-1)[keep]
    return keep, w, rows.tau.reshape(-1)[keep] * w


def fit_friction_model(
    model: FrictionModel | str,
    rows: FrictionRows,
    *,
    weights: FloatArray | None = None,
    rest: FloatArray | None = None,
) -> FrictionFit:
    """Fit ``model`` and the rest of the parameters by separable least squares (module doc).

    Parameters
    ----------
    model :
        A registered model or its name.
    rows :
        The identification rows.
    weights :
        Per-joint row weights [1/(N*m)], shape (nv,); None: all 1.
    rest :
        The rest of the parameters held at these values (the columns of ``W_rest``),
        shape (p,): only the friction is fitted, to ``tau - W_rest rest`` (each joint alone;
        a load-dependent model's load is ``W_rest rest``). None: fitted with the friction.

    Raises
    ------
    DataError
        If the rest of the columns are rank deficient on the kept rows.
    """
    model = get_friction_model(model) if isinstance(model, str) else model
    with one_blas_thread():  # small problems: threads only wait
        if rest is not None:
            held = FrictionRows(
                W_rest=np.zeros((*rows.tau.shape, 0)),
                dq=rows.dq,
                tau=rows.tau - rows.W_rest @ rest,
                keep=rows.keep,
                joints=rows.joints,
            )
            fit = _fit(model, held, weights, rows.W_rest @ rest)
            pred = predict_friction_rows(fit, held) + rows.W_rest @ rest
            total = prediction_metrics(rows.tau, pred, rows.keep).total_relative_residual
            return FrictionFit(
                **{**fit.__dict__, "rest": np.asarray(rest, dtype=float)}
                | {"fit_residual": float(total)}
            )
        if not model.uses_load:
            return _fit(model, rows, weights, np.zeros_like(rows.tau))
        # the load is the torque of the rest of the model: a fixed point, started from the
        # viscous + Coulomb fit's (contracts by the load coefficients, well below 1)
        fit = _fit(get_friction_model("viscous_coulomb"), rows, weights, rows.tau)
        for _ in range(_LOAD_ITERATIONS):
            fit = _fit(model, rows, weights, rows.W_rest @ fit.rest)
        return fit


def _fit(
    model: FrictionModel,
    rows: FrictionRows,
    weights: FloatArray | None,
    load: FloatArray,
) -> FrictionFit:
    nv = rows.tau.shape[1]
    weights = np.ones(nv) if weights is None else np.asarray(weights, dtype=float)
    keep, w, y = _weighted(rows, weights)
    W = rows.W_rest.reshape(keep.size, rows.W_rest.shape[2])[keep] * w[:, None]
    Q, R = np.linalg.qr(W)
    d = np.abs(np.diag(R))
    if W.shape[1] and d.min() <= max(W.shape) * np.finfo(float).eps * d.max():
        raise DataError("friction fit: the rigid-body and other columns are rank deficient.")
    y_perp = y - Q @ (Q.T @ y)
    positive = np.asarray(model.positive, dtype=bool)

    def decode(x: FloatArray) -> FloatArray:
        p = x.reshape(nv, -1).copy()
        p[:, positive] = np.exp(p[:, positive])
        return p

    def solve(p: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        Fw = _friction_block(model, rows, load, p)[keep] * w[:, None]
        F_perp = Fw - Q @ (Q.T @ Fw)
        c = np.asarray(np.linalg.lstsq(F_perp, y_perp, rcond=None)[0], dtype=float)
        return y_perp - F_perp @ c, c, Fw

    p0 = np.zeros((nv, 0))
    success, message, nfev = True, "linear model: one least-squares solve", 1
    ambiguous = ""
    if not model.is_linear:
        x, success, message, nfev, ambiguous = _nonlinear_search(
            model, rows, lambda x: solve(decode(x))[0]
        )
        p0 = decode(x)
    r, c, Fw = solve(p0 if p0.size else np.zeros((nv, 0)))
    rest = np.linalg.solve(R, Q.T @ (y - Fw @ c)) if W.shape[1] else np.zeros(0)
    linear = np.zeros((nv, len(model.linear)))
    linear[list(rows.joints)] = c.reshape(len(rows.joints), len(model.linear))
    nonlinear = p0 if p0.size else np.zeros((nv, 0))
    fit = FrictionFit(
        model=model.name,
        linear=linear,
        nonlinear=nonlinear,
        rest=rest,
        fit_residual=0.0,
        success=success,
        message=message,
        nfev=nfev,
        ambiguous=ambiguous,
    )
    pred = predict_friction_rows(fit, rows)
    total = prediction_metrics(rows.tau, pred, rows.keep).total_relative_residual
    return FrictionFit(**{**fit.__dict__, "fit_residual": float(total)})


def _nonlinear_search(
    model: FrictionModel, rows: FrictionRows, residual: Callable[[FloatArray], FloatArray]
) -> tuple[FloatArray, bool, str, int, str]:
    """The nonlinear parameters of a nonlinear ``model`` minimising ``||residual(x)||``:
    ``(x, success, message, nfev, ambiguous)``, ``x`` shape (nv * n_nonlinear,) with the
    positive parameters on a log scale, the solver's outcome, the cost evaluations (the scans'
    included) and why the minimum is not determined (or "", :func:`_ambiguity`).

    Started from the best of the scans of :func:`_scanned_start`, then
    ``scipy.optimize.least_squares`` with each positive parameter within a factor
    :data:`_RANGE` of ``model.initial``. ``residual`` is the projected residual of the whole
    fit for ``x`` (the linear parameters eliminated, module docstring)."""
    assert model.initial is not None  # checked by register_friction_model
    nv = rows.tau.shape[1]
    positive = np.asarray(model.positive, dtype=bool)
    initial = np.asarray(model.initial(rows.dq), dtype=float)

    def cost(x: FloatArray) -> float:
        return float(np.sum(residual(x) ** 2))

    x_best = _scanned_start(cost, initial, positive, rows.joints)
    # positive parameters within a factor _RANGE of their start: past the velocities seen,
    # a Stribeck velocity makes its column a copy of the Coulomb one (a flat direction)
    span = np.where(np.tile(positive, nv), np.log(_RANGE), np.inf)
    x_start = initial.copy()
    x_start[:, positive] = np.log(initial[:, positive])
    bounds = (x_start.reshape(-1) - span, x_start.reshape(-1) + span)
    x_best = np.clip(x_best, *bounds)
    # steps from the scan's best, the first trust region 0.1 wide (in log scale: 10 %);
    # from x_best itself the first region is |x_best| wide and left the scan's basin
    result = least_squares(
        lambda dx: residual(x_best + dx),
        np.zeros_like(x_best),
        bounds=(bounds[0] - x_best, bounds[1] - x_best),
        method="trf",
        x_scale=_STEP,
        max_nfev=400,
    )
    nfev = int(result.nfev) + _SCAN.size + _JOINT_SCAN.size * (_SWEEPS + 1) * len(rows.joints)
    ambiguous = _ambiguity(cost, x_best + result.x, initial, model, rows.joints)
    return x_best + result.x, bool(result.success), str(result.message), nfev, ambiguous


def _ambiguity(
    cost: Callable[[FloatArray], float],
    x: FloatArray,
    initial: FloatArray,
    model: FrictionModel,
    joints: tuple[int, ...],
) -> str:
    """Why the fit's nonlinear parameters are not determined, or "".

    For each joint, its positive parameters are scanned again (``_JOINT_SCAN`` times
    ``initial``, the others at the fit ``x``, flattened, log scale); a scan point a factor
    ``_AMBIGUOUS_FACTOR`` or more from the fit whose cost is within ``_AMBIGUOUS_COST``
    (relative) of the fit's is a second minimum the data cannot tell apart. On a 2 s UR5
    Stribeck log (1 % noise, filtered and differentiated) the shoulder's cost at ``vs`` = 1.08
    rad/s was 0.3 % *below* the one at the true 0.2 rad/s: such a fit is a coin toss.
    """
    positive = np.asarray(model.positive, dtype=bool)
    labels = [label for label, p in zip(model.nonlinear, positive, strict=True) if p]
    if not labels:
        return ""
    fitted = x.reshape(initial.shape[0], -1)
    c_fit = cost(x)
    logged = np.log(initial[:, positive])
    problems = []
    for j in joints:
        for step in np.log(_JOINT_SCAN):
            trial = fitted.copy()
            trial[j, positive] = logged[j] + step
            if np.max(np.abs(trial[j, positive] - fitted[j, positive])) < np.log(_AMBIGUOUS_FACTOR):
                continue
            c = cost(trial.reshape(-1))
            if c <= c_fit * (1.0 + _AMBIGUOUS_COST):
                found = ", ".join(f"{v:.3g}" for v in np.exp(fitted[j, positive]))
                other = ", ".join(f"{v:.3g}" for v in np.exp(trial[j, positive]))
                problems.append(
                    f"joint {j + 1}: {'/'.join(labels)} = {found} and {other} fit within "
                    f"{100 * _AMBIGUOUS_COST:g} % of the same cost"
                )
                break
    if not problems:
        return ""
    return "; ".join(problems) + " (the data cannot tell them apart)"


def _scanned_start(
    cost: Callable[[FloatArray], float],
    start: FloatArray,
    positive: BoolArray,
    joints: tuple[int, ...],
) -> FloatArray:
    """Start of the local fit, flattened (log scale for the positive parameters): the best
    common scale of the positive parameters (``_SCAN`` times ``start``, all joints at once),
    then ``_SWEEPS`` sweeps over ``joints``, each joint's own scale scanned with the others
    held (the cost is nearly separable by joint: the joints share only the rest's columns).

    A common scale alone is not enough: on the UR5 processed log the Stribeck cost has a
    second basin near ``vs = 1`` rad/s (cost 82 against 66 at the true 0.2 rad/s) that a
    common scale, a compromise between the joints, fell into."""
    logged = start.copy()
    logged[:, positive] = np.log(start[:, positive])

    def shifted(x: FloatArray, joints: slice | int, step: float) -> FloatArray:
        x = x.copy()
        x[joints, positive] += step
        return x

    x_best, cost_best = logged, np.inf
    for step in np.log(_SCAN):
        x = shifted(logged, slice(None), step)
        c = cost(x.reshape(-1))
        if c < cost_best:
            x_best, cost_best = x, c
    for _ in range(_SWEEPS):
        for j in joints:
            base = x_best.copy()
            base[j, positive] = logged[j, positive]
            for step in np.log(_JOINT_SCAN):
                x = shifted(base, j, step)
                c = cost(x.reshape(-1))
                if c < cost_best:
                    x_best, cost_best = x, c
    return x_best.reshape(-1)


def predict_friction_rows(fit: FrictionFit, rows: FrictionRows) -> FloatArray:
    """Torques [N*m] the fitted model predicts on ``rows``, shape (n, nv)."""
    model = get_friction_model(fit.model)
    friction = model.torque(rows.dq, rows.W_rest @ fit.rest, fit.linear, fit.nonlinear)
    mask = np.zeros(rows.tau.shape[1], dtype=bool)
    mask[list(rows.joints)] = True
    return rows.W_rest @ fit.rest + np.where(mask, friction, 0.0)


@dataclass(frozen=True, eq=False)
class FrictionComparison:
    """Every model fitted and ranked by held-out fit.

    Attributes
    ----------
    fits :
        The fits, best (lowest held-out residual) first.
    winner :
        Name of the best model whose parameters are determined (not ``ambiguous``): a model
        ranked above it with an ambiguous fit is not picked (the report says why).
    baseline :
        Name of the reference model (``viscous_coulomb``), for "better by".
    on_held_out :
        False when there were no held-out rows (ranked on the identification rows).
    """

    fits: tuple[FrictionFit, ...]
    winner: str
    baseline: str
    on_held_out: bool

    def fit(self, name: str) -> FrictionFit:
        """The fit of model ``name``."""
        return next(f for f in self.fits if f.model == name)

    def improvement(self) -> float:
        """Relative reduction of the held-out residual of the winner over the baseline."""
        base = self.fit(self.baseline).held_out_residual
        return float(1.0 - self.fit(self.winner).held_out_residual / base)


def compare_friction_models(
    fit_rows: FrictionRows,
    held_out: FrictionRows | None,
    names: Sequence[str] | None = None,
    *,
    baseline: str = "viscous_coulomb",
) -> FrictionComparison:
    """Fit each model of ``names`` (default: every registered one), rank them by held-out
    residual and pick the best one whose fit is not ``ambiguous``.

    The row weights are ``1 / sigma_j`` of the unweighted ``baseline`` fit (same for all).
    """
    names = list(FRICTION_MODELS) if names is None else list(dict.fromkeys([baseline, *names]))
    first = fit_friction_model(baseline, fit_rows)
    r = fit_rows.tau - predict_friction_rows(first, fit_rows)
    count = np.maximum(fit_rows.keep.sum(axis=0), 1)
    sigma = np.sqrt(np.sum(np.where(fit_rows.keep, r, 0.0) ** 2, axis=0) / count)
    weights = 1.0 / np.maximum(sigma, 1e-12 * max(float(sigma.max()), 1e-300))
    val = held_out if held_out is not None else fit_rows
    fits = []
    for name in names:
        fit = fit_friction_model(name, fit_rows, weights=weights)
        metrics = prediction_metrics(val.tau, predict_friction_rows(fit, val), val.keep)
        fits.append(
            FrictionFit(
                **{
                    **fit.__dict__,
                    "held_out_residual": float(metrics.total_relative_residual),
                    "held_out_rmse": metrics.rmse,
                }
            )
        )
    fits.sort(key=lambda f: f.held_out_residual)
    # the best fit whose parameters the data determine (the baseline is linear: always)
    winner = next(f.model for f in fits if not f.ambiguous)
    return FrictionComparison(
        fits=tuple(fits), winner=winner, baseline=baseline, on_held_out=held_out is not None
    )


#: Most decimated samples of each part (identification, held out) a comparison uses: the rows
#: are kept whole in memory (``n * nv * p`` floats), so a long log is thinned evenly.
MAX_SAMPLES = 20_000

_FRICTION_BASE = re.compile(r"(fv|fs)\d+R?")


def _rows_of(
    tasks: Sequence[log_chunks.ChunkTask], drop: BoolArray, joints: tuple[int, ...], stride: int
) -> FrictionRows:
    parts = []
    for task in tasks:
        chunk, keep = task.chunk()
        p = task.columns.order.size
        Yb = chunk.Yb[::stride, :, :p][:, :, ~drop]
        parts.append((Yb, chunk.dq[::stride], chunk.tau[::stride], keep[::stride]))
    W, dq, tau, keep = (np.concatenate([part[i] for part in parts]) for i in range(4))
    return FrictionRows(W_rest=W, dq=dq, tau=tau, keep=keep, joints=joints)


def _friction_columns(
    chunked: log_chunks.ChunkedLog, pm: ParameterModel
) -> tuple[IntArray, BoolArray]:
    """The planned base columns (indices into ``pm.base_names``) and which are the joints'
    ``fv``/``fs``."""
    order = np.asarray(chunked.fit_tasks[0].columns.order, dtype=np.intp)
    names = [pm.base_names[i] for i in order]
    return order, np.array([_FRICTION_BASE.fullmatch(n) is not None for n in names], dtype=bool)


def rest_parameters(
    chunked: log_chunks.ChunkedLog, pm: ParameterModel, x: FloatArray
) -> FloatArray:
    """The entries of base parameters ``x`` (shape (n_base,), in ``pm.base_names``' order)
    that multiply the columns of :func:`friction_rows`' ``W_rest``, shape (p,)."""
    order, drop = _friction_columns(chunked, pm)
    return np.asarray(x, dtype=float)[order][~drop]


def friction_rows(
    chunked: log_chunks.ChunkedLog, pm: ParameterModel, *, max_samples: int = MAX_SAMPLES
) -> tuple[FrictionRows, FrictionRows | None]:
    """The identification and held-out rows of a planned log, without the joints' ``fv``/``fs``
    base columns (None for the held-out rows when the log has no held-out part).

    Every part is thinned evenly to at most ``max_samples`` decimated samples.
    """
    _, drop = _friction_columns(chunked, pm)
    joints = tuple(sorted({*pm.terms.per_joint["fv"], *pm.terms.per_joint["fs"]}))
    if not joints:
        raise DataError("model.friction: no joint has viscous or Coulomb friction terms.")

    def stride(tasks: Sequence[log_chunks.ChunkTask]) -> int:
        n = sum(t.d1 - t.d0 for t in tasks)
        return max(1, -(-n // max_samples))

    fit = _rows_of(chunked.fit_tasks, drop, joints, stride(chunked.fit_tasks))
    if chunked.in_sample or not chunked.val_tasks:
        return fit, None
    return fit, _rows_of(chunked.val_tasks, drop, joints, stride(chunked.val_tasks))
