"""A payload identified from logs with and without it (``ident payload``).

``payload_config`` (the config: :class:`~ident.identify.payload.payload_config.PayloadConfig`,
``load_payload_config``), ``payload`` (the payload's inertial parameters and their intervals:
:func:`~ident.identify.payload.payload.identify_payload`, ``read_payload_logs``,
``arm_with_payload``), ``payload_rows`` (a log's rows and their block equations),
``payload_arm`` (where the arm's parameters come from) and ``payload_gain`` (per-joint torque
gains from a known payload: ``estimate_payload_gains``). Import the submodules directly.
"""
