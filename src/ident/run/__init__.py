"""``ident run``: the paper's method end to end for one stage.

``config`` (the run config schema), ``pipeline`` (config -> :class:`RunResult`, pure, progress
through a callback), ``rundir`` (run folders that are never overwritten and stay consistent
when a run is interrupted). Import the submodules directly; this package imports nothing heavy.
"""
