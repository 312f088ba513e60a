"""MuJoCo's warnings as Python warnings, never a ``MUJOCO_LOG.TXT`` file.

MuJoCo's default warning handler prints the message and appends it to ``MUJOCO_LOG.TXT`` in
the working folder: a file outside every ``--out`` folder, left wherever the user happened to
be. :func:`route_mujoco_warnings` replaces that handler (process-wide, once) by one that
issues an :class:`~ident.errors.IdentWarning` (shown on stderr like every other warning of
``ident``). MuJoCo's errors already raise ``mujoco.FatalError`` in Python and write nothing.
Every module of ``ident`` that imports ``mujoco`` calls it at import.
"""

from __future__ import annotations

import warnings

import mujoco

from ident.errors import IdentWarning

__all__ = ["route_mujoco_warnings"]


def _warn(message: str) -> None:
    warnings.warn(f"MuJoCo: {message}", IdentWarning, stacklevel=2)


def route_mujoco_warnings() -> None:
    """Send MuJoCo's warnings to :mod:`warnings` instead of ``MUJOCO_LOG.TXT`` (idempotent)."""
    if mujoco.get_mju_user_warning() is not _warn:
        mujoco.set_mju_user_warning(_warn)


route_mujoco_warnings()
