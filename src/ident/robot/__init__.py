"""Robot descriptions: DH tables, robot config files, inertial parameters, URDF generation."""

from __future__ import annotations

from ident.robot.dh import DHTable
from ident.robot.robot_config import RobotDescription, load_robot_config

__all__ = ["DHTable", "RobotDescription", "load_robot_config"]
