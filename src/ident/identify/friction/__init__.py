"""Friction in identification: the friction models fitted, ranked and written.

``friction_fit`` (every model of the registry fitted on the identification rows and ranked
on the held-out ones: ``compare_friction_models``, ``friction_rows``) and ``friction_law``
(the law the identified model carries: ``written_friction_law``, ``friction_law_torque``).
The laws themselves (their torque and parameters) are :mod:`ident.dynamics.friction_models`,
lower in the layers, where the regressor's friction columns are built. Import the submodules
directly.
"""
