"""Streaming identification of a robot's payload over its lifetime, with change detection.

``normal`` (per-joint normal equations with exponential forgetting, their weighted solution
and sandwich covariance, the two-stretch split problem), ``filters`` (causal Savitzky-Golay
differentiation with its delay compensated), ``detect`` (the GLR change test and its
threshold), ``estimator`` (:class:`~ident.identify.streaming.estimator.StreamingEstimator`:
samples in, tracked payload and changes out), ``stream_config`` (the ``ident stream`` config),
``replay`` (a log replayed at its rate: the sample source of ``ident stream``); the fleet of
``ident fleet``: ``fleet`` (shared and per-unit columns, chunk rows, the joint solve),
``fleet_run`` (the chunk tasks on dask.distributed), ``fleet_drift`` (the tests across units
and over time), ``fleet_report`` (the run folder's files), ``fleet_config`` (its config).
Import the submodules directly.
"""
