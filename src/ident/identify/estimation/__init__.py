"""The estimation core: measurements -> reduced identification rows -> estimates.

``preprocess`` (filtering, differentiation, decimation, automatic settings), ``motion``
(the measured motion for the replay), ``accumulate`` (one chunk: regressor rows reduced per
joint; :class:`~ident.identify.estimation.accumulate.BaseColumns`), ``log_chunks`` (a log cut
in chunk tasks run on threads or Dask: ``plan_log``, ``reduce_log``, ``predict_log``),
``observations`` (:class:`~ident.identify.estimation.observations.ReducedObservations`),
``estimate`` (OLS/WLS: :class:`~ident.identify.estimation.estimate.Estimate`,
``least_squares_reduced``), ``essential`` (essential parameters), ``uncertainty`` (HAC and
block-bootstrap covariances, ``parameter_std``), ``validation`` (the held-out split and
prediction metrics), ``consistency`` (pseudo-inertias and physical consistency, which the
consistent estimators constrain), ``reference`` (a reference's base parameters as weights and
comparisons). The estimators themselves are ``ident.identify.estimators``.

The bottom room of ``ident.identify`` (pyproject.toml's ``[tool.importlinter]``); import the
submodules directly (this file imports nothing, so that ``ident.identify.config`` can read
``reference`` without loading the whole core).
"""
