"""Rigid-body dynamics linear in the inertial parameters.

Kinematic chains read from Pinocchio models (:mod:`.chain`), the standard parameters
(:mod:`.parameters`), the hand-derived Newton-Euler regressor (:mod:`.regressor`) and its
Pinocchio check (:mod:`.pinocchio_check`), Gram matrices of observation matrices (:mod:`.gram`),
base parameters (:mod:`.base_parameters`) and the paper's identification stages
(:mod:`.stage`). Submodules are imported on demand.
"""
