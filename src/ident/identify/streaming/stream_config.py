"""Schema of an ``ident stream`` config: an identify config (robot, log, transmission, model)
plus a ``stream:`` section.

The robot section names the arm *without* the payload (its URDF's inertials are taken as known,
as in ``ident payload``); ``log:`` is the log replayed; ``model:`` the friction / rotor-inertia
columns estimated with the payload. Example::

    name: ur5-lifetime
    robot: {urdf: ur5_identified.urdf}
    log: {path: shift.csv, time: {column: t}, position: {...}, torque: {...}}
    model: {viscous: true, coulomb: true, rotor_inertia: true, offset: false}
    stream:
      link: tool0                 # frame of the reported centre of mass (the controller's)
      memory_s: 60                # forgetting time constant [s]
      false_alarm_per_hour: 0.01  # stated false-alarm rate of the change test
      after_s: 1.0                # seconds of rows after a change before its estimate
      controller: {max_mass_kg: 5.0, max_com_distance_m: 0.3}

Every path is relative to the config file. The ``preprocess``, ``estimation``, ``validation``,
``reference`` and ``urdf_update`` sections of an identify config are accepted and not used (a
stream is filtered causally: :mod:`ident.identify.streaming.filters`).
"""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, PositiveFloat, model_validator

from ident.config import StrictModel
from ident.errors import ConfigError
from ident.identify.config import IdentifyConfig, load_identify_config
from ident.identify.payload.controller_load import LoadLimits
from ident.identify.streaming.estimator import StreamSettings

__all__ = ["ControllerLimits", "StreamConfig", "StreamSection", "load_stream_config"]


class ControllerLimits(StrictModel):
    """``stream.controller``: the limits the exported payload is checked against (SI);
    ``null``: not known, the check is reported as not run."""

    max_mass_kg: PositiveFloat | None = None
    max_com_distance_m: PositiveFloat | None = None

    def limits(self) -> LoadLimits:
        """As :class:`~ident.identify.payload.controller_load.LoadLimits`."""
        return LoadLimits(self.max_mass_kg, self.max_com_distance_m)


class StreamSection(StrictModel):
    """``stream:`` (the fields of :class:`~ident.identify.streaming.estimator.StreamSettings`,
    plus ``link`` and ``controller``)."""

    link: str | None = Field(default=None, min_length=1)
    window: int = Field(default=41, ge=5, le=401)
    order: int = Field(default=3, ge=2, le=5)
    block_rows: int = Field(default=4, ge=1, le=100)
    memory_s: PositiveFloat = 60.0
    test_blocks: int = Field(default=4, ge=2, le=100)
    false_alarm_per_hour: PositiveFloat = 0.01
    after_s: PositiveFloat = 1.0
    solve_every_s: PositiveFloat = 5.0
    warmup_s: float = Field(default=10.0, ge=0.0)
    velocity_threshold: float = Field(default=0.15, ge=0.0)
    consistent: bool = True
    interval_resolves: int = Field(default=40, ge=0, le=1000)
    controller: ControllerLimits = Field(default_factory=ControllerLimits)

    @model_validator(mode="after")
    def _window(self) -> StreamSection:
        if self.window % 2 == 0:
            raise ValueError(f"window: {self.window} samples must be odd (the fit's centre)")
        if self.order >= self.window:
            raise ValueError(f"order: {self.order} must be below window ({self.window})")
        return self

    def settings(self) -> StreamSettings:
        """The estimator's settings."""
        fields = self.model_dump(exclude={"link", "controller"})
        return StreamSettings(**fields)


class StreamConfig(IdentifyConfig):
    """An identify config (robot, log, transmission, model) plus ``stream:``."""

    name: str = "stream"
    stream: StreamSection = Field(default_factory=StreamSection)


def load_stream_config(path: str | Path) -> StreamConfig:
    """Load an ``ident stream`` config; paths made absolute (relative to the config file).

    Raises
    ------
    ConfigError
        Naming the file and key: malformed entries, missing files, a log without torques.
    """
    path = Path(path)
    cfg = load_identify_config(path, schema=StreamConfig)
    assert isinstance(cfg, StreamConfig)  # the schema asked for
    if cfg.actuator.kind != "motor":
        raise ConfigError(
            f"{path}: actuator.kind: {cfg.actuator.kind}: 'ident stream' needs logged torques "
            "(or currents); remove the actuator section and name log.torque."
        )
    return cfg
