"""Measurement sources: simulators and log readers, each yielding joint-side SI signals.

``ident run`` measures an excitation trajectory with a simulator (the ideal Pinocchio RNEA
model, or MuJoCo in closed loop, which writes a controller-like log); ``ident identify``
reads a log a robot controller wrote. Everything after this package works on the same
arrays whatever their source.
"""
