"""The registry of excitation families: a config's ``excitation.family`` names one of them.

A family turns a design vector ``x`` (shape (n_particles, n_vars)) into joint trajectories and
their constraint report (:class:`ident.excitation.family.TrajectoryBatch`). It is built for a
robot and a stage by a *builder*::

    builder(robot, stage, options) -> family

``options`` is the config's ``excitation.options`` mapping with ``n_samples`` filled in; a
builder raises ``TypeError`` for an unknown option and ``ValueError`` for a bad value (the run
turns both into one config error naming the key). Register a new family with
:func:`register_family`; nothing else needs to know its name::

    from ident.excitation.registry import register_family

    def build_sines(robot, stage, options):
        return MySinesFamily(robot, stage.moving_joints, **options)

    register_family("sines", build_sines)

The family object needs ``variable_names``, ``bounds`` (n_vars, 2), ``moving_joints``,
``held_positions``, ``trajectories(x)`` and optionally ``traced_frame`` (docs/excitation.md,
"Extending").
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from typing import Any

import numpy as np

from ident.dynamics.stage import Stage
from ident.errors import ConfigError
from ident.excitation.fourier import JointFourierFamily
from ident.excitation.mfs import PaperArmFamily
from ident.excitation.payload import build_payload_family
from ident.excitation.wrist import PaperWristFamily

__all__ = ["FAMILIES", "FamilyBuilder", "build_family", "family_names", "register_family"]

FamilyBuilder = Callable[[Any, Stage, dict[str, Any]], Any]

#: name -> builder; filled below with the built-in families and by :func:`register_family`.
FAMILIES: dict[str, FamilyBuilder] = {}


def register_family(name: str, builder: FamilyBuilder, *, replace: bool = False) -> None:
    """Make ``excitation.family: name`` build its family with ``builder``.

    Raises
    ------
    ValueError
        If ``name`` is taken (pass ``replace=True`` to override a family on purpose).
    """
    if not name or not name.replace("_", "").isalnum():
        raise ValueError(f"family name {name!r} must be a non-empty identifier")
    if name in FAMILIES and not replace:
        raise ValueError(f"excitation family {name!r} is registered already")
    FAMILIES[name] = builder


def family_names() -> tuple[str, ...]:
    """Registered family names, in registration order."""
    return tuple(FAMILIES)


def check_family_name(name: str) -> str:
    """``name`` if it is registered; else a ConfigError suggesting the closest name."""
    if name not in FAMILIES:
        close = difflib.get_close_matches(name, list(FAMILIES), n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise ConfigError(
            f"excitation.family '{name}' is not a known family; {hint}"
            f"families: {', '.join(FAMILIES)}."
        )
    return name


def build_family(name: str, robot: Any, stage: Stage, options: dict[str, Any]) -> Any:
    """The family ``name`` for ``robot`` and ``stage``.

    Raises
    ------
    ConfigError
        For an unknown family, or options the family rejects (naming the family).
    """
    builder = FAMILIES[check_family_name(name)]
    try:
        return builder(robot, stage, dict(options))
    except TypeError as e:
        raise ConfigError(
            f"excitation.options: {e}; see docs/excitation.md for the options of '{name}'."
        ) from e
    except ValueError as e:
        raise ConfigError(f"excitation: {e}") from e


# ---------------------------------------------------------------------------- built-ins


def _joint_fourier(robot: Any, stage: Stage, options: dict[str, Any]) -> Any:
    moving = options.pop("moving_joints", None) or stage.moving_joints
    options.setdefault("held_positions", np.asarray(stage.held_positions))
    return JointFourierFamily(robot, moving, **options)


def _paper_stage_family(stage_name: str, cls: type) -> FamilyBuilder:
    """The paper's Cartesian family of one of its two stages (it holds the other joints)."""

    def build(robot: Any, stage: Stage, options: dict[str, Any]) -> Any:
        if stage.name != stage_name:
            raise ConfigError(
                f"excitation.family 'paper_{stage_name}' designs the paper's {stage_name} stage "
                f"but stage is '{stage.name}'; use stage: {stage_name}, or joint_fourier."
            )
        return cls(robot, **options)

    return build


register_family("joint_fourier", _joint_fourier)
register_family("payload", build_payload_family)
register_family("paper_wrist", _paper_stage_family("wrist", PaperWristFamily))
register_family("paper_arm", _paper_stage_family("arm", PaperArmFamily))
