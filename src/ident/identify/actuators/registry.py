"""The actuator kinds of identification: how a log becomes joint torques to identify from.

One entry per ``actuator.kind`` (:data:`ident.dynamics.actuators.ACTUATOR_LAWS` holds the laws):

- ``motor``: the log's torque is the measurement; nothing to do here (its delay and gains are
  :mod:`ident.identify.corrections.signal_correction`'s);
- ``position``: a servo logging its command and no torque:
  :func:`ident.identify.actuators.servo_fit.servo_log` gives the torque ``kp e`` and the fit.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import pinocchio as pin

from ident.dynamics.actuators import ActuatorLaw, actuator_law
from ident.identify.actuators.servo_fit import ServoFit, servo_log
from ident.identify.config import IdentifyConfig
from ident.measure.logs import RobotLog

__all__ = ["ACTUATORS", "Actuator", "Prepared", "get_actuator"]


@dataclass(frozen=True, eq=False)
class Prepared:
    """A log ready to identify: the config (automatic settings possibly resolved), the log
    with its joint torques, and the actuator's fit (None for a motor)."""

    config: IdentifyConfig
    log: RobotLog
    fit: ServoFit | None = None


@dataclass(frozen=True)
class Actuator:
    """One actuator kind: its law, and ``prepare(cfg, model, log, source)``."""

    law: ActuatorLaw
    prepare: Callable[[IdentifyConfig, pin.Model, RobotLog, str], Prepared]


def _motor(cfg: IdentifyConfig, model: pin.Model, log: RobotLog, source: str) -> Prepared:
    """The torque is logged: the log as it is."""
    return Prepared(cfg, log)


def _position(cfg: IdentifyConfig, model: pin.Model, log: RobotLog, source: str) -> Prepared:
    """The torque from the servo's law (:func:`~ident.identify.actuators.servo_fit.servo_log`)."""
    cfg, log, fit = servo_log(cfg, model, log, source)
    return Prepared(cfg, log, fit)


#: The actuator kinds, by ``actuator.kind``.
ACTUATORS: dict[str, Actuator] = {
    "motor": Actuator(actuator_law("motor"), _motor),
    "position": Actuator(actuator_law("position"), _position),
}


def get_actuator(kind: str) -> Actuator:
    """The entry of ``kind`` (:class:`ConfigError` listing the kinds when there is none)."""
    actuator_law(kind)  # raises, naming the kinds
    return ACTUATORS[kind]
