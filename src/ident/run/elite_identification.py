"""The ideal measurement of an elite trajectory and its least-squares estimate.

``measurement.source: ideal``: joint torques from Pinocchio's RNEA on the true parameters plus
the configured noise (:mod:`ident.measure.ideal`), then OLS/WLS on the stage's base
parameters: the estimators of the registry (:mod:`ident.identify.estimators`) on the rows
reduced per joint, as :func:`ident.identify.core.identify_measurements` runs them. Bodies
outside the stage are known: their torque contribution is computed from their true parameters
and subtracted.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import IdentError, NotIdentifiable
from ident.identify.estimators import EstimationProblem, get_estimator
from ident.identify.observations import ReducedObservations
from ident.measure.ideal import NoiseModel, simulate_measurements
from ident.run.config import MeasurementSection, RunConfig
from ident.run.results import EliteOutcome, StageInfo
from ident.run.stage_info import stage_matrix

__all__ = ["elite_trajectory", "identify_elite"]

FloatArray = npt.NDArray[np.float64]


def elite_trajectory(
    family: Any, x: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray | None]:
    """One period of a design: ``t`` (n,), ``q, dq, ddq`` (n, nq) and the traced points
    (n, 3) [m] or None."""
    batch = family.trajectories(x[None, :])
    t = np.asarray(batch.t, dtype=float)
    q, dq, ddq = (np.asarray(a[0], dtype=float) for a in (batch.q, batch.dq, batch.ddq))
    traced = None if batch.traced_points is None else np.asarray(batch.traced_points[0])
    return t, q, dq, ddq, traced


def identify_elite(
    config: RunConfig,
    robot: Any,
    family: Any,
    stage: StageInfo,
    index: int,
    x: FloatArray,
    fitness: float,
    details: dict[str, float],
    seed: Any,
) -> EliteOutcome:
    """Measure (simulate) one elite trajectory and estimate the stage's base parameters.

    Estimator failures (rank-deficient base matrix on this trajectory, ...) are recorded in
    ``failures`` with their message; they do not raise.
    """
    t, q, dq, ddq, traced = elite_trajectory(family, x)
    m = config.measurement
    if not isinstance(m, MeasurementSection):
        raise IdentError("the ideal measurement needs measurement.source: ideal")
    std = m.torque_noise_std
    noise = NoiseModel(
        torque_std=tuple(std) if isinstance(std, list) else float(std),
        encoder_counts_per_rev=m.encoder_counts_per_rev,
        filter_cutoff_hz=m.filter_cutoff_hz,
    )
    meas = simulate_measurements(robot.model, t, q, dq, ddq, noise, rng=np.random.default_rng(seed))
    W, known = stage_matrix(robot, stage.rows, stage.columns, meas.q, meas.dq, meas.ddq)
    y = (meas.tau[:, list(stage.rows)] - known).reshape(-1)
    estimates: dict[str, Any] = {}
    failures: dict[str, str] = {}
    Wb = np.asarray(stage.base.base_columns(W), dtype=float)
    n_rows = len(stage.rows)
    problem = EstimationProblem(
        observations=ReducedObservations.from_samples(
            Wb.reshape(-1, n_rows, Wb.shape[1]), y.reshape(-1, n_rows)
        ),
        names=tuple(stage.base_names),
        n_samples=t.shape[0],
    )
    for method in config.estimation.methods:
        try:
            est = get_estimator(method)(problem)
        except NotIdentifiable as e:
            failures[method] = f"not identifiable on this trajectory: {e}"
            continue
        except IdentError as e:
            failures[method] = str(e)
            continue
        if not est.success:
            failures[method] = est.message
            continue
        estimates[method] = est
    return EliteOutcome(
        rank=index + 1,
        x=x,
        fitness=fitness,
        details=details,
        t=t,
        q=q,
        dq=dq,
        ddq=ddq,
        traced_points=traced,
        tau=np.asarray(meas.tau),
        estimates=estimates,
        failures=failures,
        base_column_norms=np.linalg.norm(Wb, axis=0),
        true_torque_norm=float(np.linalg.norm(Wb @ stage.true_base)),
    )
