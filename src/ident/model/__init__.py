"""The robot as the rest of ``ident`` sees it: :class:`Robot` and the selection that builds it.

``Robot`` (:mod:`ident.model.robot`) is a Pinocchio model of the chain to identify with its
names, limits and true parameters; :mod:`ident.model.selection` turns a config's ``robot:``
section, or the command-line flags, into one, the same way for every command.
"""

from __future__ import annotations

from ident.model.robot import Robot
from ident.robot.urdf_load import URDF_INERTIA_RTOL, continuous_as_revolute, suggested_locks

__all__ = ["URDF_INERTIA_RTOL", "Robot", "continuous_as_revolute", "suggested_locks"]
