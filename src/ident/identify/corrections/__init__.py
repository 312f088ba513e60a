"""Corrections of a measured log before the identification: torque delay and signal gains.

``signal_errors`` (the delay between torque and motion, per-joint gains from a known payload:
``estimate_delay``, ``estimate_gains``) and ``signal_correction`` (the ``signals:`` section
applied to a log: :func:`~ident.identify.corrections.signal_correction.correct_log`,
``identify_corrected_payload``). Import the submodules directly.
"""
