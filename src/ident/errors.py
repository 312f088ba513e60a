"""Exceptions and warnings of ``ident``.

Every error a user can cause derives from :class:`IdentError`. Its message names what is
wrong, where (file, key, column, joint) and how to fix it; the CLI prints it on one line and
exits with code 2, without a traceback.
"""

from __future__ import annotations

__all__ = [
    "ConfigError",
    "DataError",
    "IdentError",
    "IdentWarning",
    "ModelError",
    "NotIdentifiable",
    "OptimizationError",
    "TrajectoryError",
]


class IdentError(Exception):
    """Base class for every error ``ident`` reports to a user."""


class ConfigError(IdentError):
    """A configuration file is missing, malformed or inconsistent."""


class ModelError(IdentError):
    """A robot description (DH table, URDF, Pinocchio model) is unusable."""


class DataError(IdentError):
    """Measured or simulated data are malformed (shape, NaN, time base, units)."""


class TrajectoryError(IdentError):
    """An excitation trajectory is infeasible (unreachable, violates limits)."""


class NotIdentifiable(IdentError):
    """The observation matrix is rank deficient for the requested parameters.

    ``idle_joints`` names the joints none of whose samples reached their velocity threshold
    (empty when that is not the cause), so that a caller can name its own config field.
    """

    def __init__(self, message: str, *, idle_joints: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.idle_joints = idle_joints


class OptimizationError(IdentError):
    """An optimizer was called with invalid bounds, options or budget."""


class IdentWarning(UserWarning):
    """Something suspicious that does not stop the computation."""
