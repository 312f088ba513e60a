"""Measurement sources: simulators and log readers, each yielding joint-side SI signals.

``ident run`` measures an excitation trajectory with a simulator (the ideal Pinocchio RNEA
model, or MuJoCo in closed loop, which writes a controller-like log); ``ident identify``
reads a log a robot controller wrote. Everything after this package works on the same
arrays whatever their source.

Modules: ``ideal`` (:class:`~ident.measure.ideal.Measurements` from the RNEA plus noise),
``mujoco_config`` / ``mujoco_model`` / ``mujoco_sim`` (the closed-loop MuJoCo source),
``readers/`` (the file readers' registry: CSV, ROS 2 bags, MCAP), ``timebase`` (time stamps,
gaps, uniform grids), and a log declared in a config: ``log_config`` (the ``log:`` and
``transmission:`` schema: :class:`~ident.measure.log_config.LogConfig`,
:class:`~ident.measure.log_config.TransmissionConfig`), ``logs`` (the public face:
:class:`~ident.measure.logs.RobotLog`, :func:`~ident.measure.logs.read_log`,
:func:`~ident.measure.logs.estimate_log`: units, transmission, SI once) and ``log_tables``
(the signal columns found in the readers' tables, joined on time, put on a uniform grid).
Import the submodules directly.
"""
