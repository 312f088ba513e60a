"""Identification from measured or simulated torques, in rooms (one concept each).

``config`` (the ``ident identify`` config schema, beside the rooms: every room reads it) and

- ``pipeline/``: ``ident identify`` and the one identification every command runs
  (``core.identify_measurements``, ``real.identify``);
- ``estimation/``: the estimation core: preprocessing, the chunked accumulation of reduced
  rows, least squares with standard deviations and intervals, essential parameters, physical
  consistency, the held-out split, the reference's parameters;
- ``estimators/``: the estimators' registry (OLS, WLS, LMI, log-Cholesky);
- ``assessment/``: what the result is worth: verdict, error measures, sanity warnings,
  identifiability, the written model's intervals, repeatability;
- ``friction/``: the friction models fitted and the law written into the model (the laws
  themselves are :mod:`ident.dynamics.friction_models`);
- ``corrections/``: signal corrections of a log (torque delay, payload gains);
- ``payload/``: a payload identified from logs with and without it;
- ``model_files/``: the identified model's URDF, MJCF and joint-extras files.

Reading logs is :mod:`ident.measure.logs` (below this package). Import the submodules
directly; this package and its rooms import nothing (docs/conventions.md, "Where things live").
"""
