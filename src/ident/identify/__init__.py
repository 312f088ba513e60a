"""Identification from measured or simulated torques.

Modules: ``estimate`` (OLS/WLS with standard deviations), ``logs`` (reading robot logs declared
in a config), ``preprocess`` (filtering, differentiation, decimation), ``essential`` (essential
parameters), ``validation`` (held-out prediction), ``real`` (the ``ident identify`` pipeline),
``urdf_update`` / ``urdf_edit`` / ``mjcf`` / ``model_files`` (the identified model's URDF, MJCF
and joint-extras files).
Import the submodules directly; this package imports nothing heavy.
"""
