"""Schema of an ``ident payload`` config: an identify config plus a ``payload:`` section.

The robot section names the arm *without* the payload (the URDF ``ident identify`` wrote, or
any URDF); ``log:`` is a log with the payload attached. Example::

    name: ur5-payload
    robot: {urdf: ur5_identified.urdf}
    log: {path: with_payload.csv, time: {column: t}, position: {...}, torque: {...}}
    preprocess: {lowpass: {cutoff_hz: 10.0}, decimation: [10], trim_samples: 500}
    model: {viscous: true, coulomb: true, rotor_inertia: true, offset: false}
    payload:
      without: {path: without_payload.csv, ...}   # optional: the same arm without it
      link: null          # frame of the reported centre of mass (default: last moving link)
      method: lmi         # lmi (consistent) or wls

Every path is relative to the config file. The ``estimation``, ``validation``, ``reference``
and ``urdf_update`` sections of an identify config are accepted and not used.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field

from ident.config import StrictModel
from ident.errors import ConfigError
from ident.identify.config import IdentifyConfig, load_identify_config, resolve_log
from ident.measure.log_config import LogConfig

__all__ = ["PayloadConfig", "PayloadSection", "load_payload_config"]


class PayloadSection(StrictModel):
    """``payload:``: what ``ident payload`` estimates and from which logs.

    Attributes
    ----------
    without :
        A log of the same arm without the payload (a complete ``log:`` section), or ``null``.
        Its rows share the friction, rotor-inertia and offset parameters with the payload
        log's and carry no payload columns, which separates the two.
    link :
        URDF link whose frame expresses the reported centre of mass and inertia (it must ride
        on the last moving joint, e.g. a flange); ``null``: the last moving link.
    method :
        ``lmi``: physically consistent (pseudo-inertia positive definite, friction and rotor
        inertia >= 0); ``wls``: unconstrained weighted least squares.
    arm :
        Where the arm's parameters come from with one log (with ``without`` they always come
        from both logs): ``model``: the URDF is exact (an identified arm); ``prior``: the URDF
        is a CAD prior estimated with the payload; ``auto``: ``model`` for ``ident identify``'s
        ``<stem>_identified.urdf`` with its ``<stem>_joint_extras.json`` beside it, else
        ``prior`` (:mod:`ident.identify.payload.payload_arm`).
    """

    without: LogConfig | None = None
    link: str | None = Field(default=None, min_length=1)
    method: Literal["lmi", "wls"] = "lmi"
    arm: Literal["auto", "model", "prior"] = "auto"


class PayloadConfig(IdentifyConfig):
    """An identify config (robot, log, transmission, preprocess, model) plus ``payload:``."""

    name: str = "payload"
    payload: PayloadSection = Field(default_factory=PayloadSection)


def load_payload_config(path: str | Path) -> PayloadConfig:
    """Load an ``ident payload`` config; paths made absolute (relative to the config file).

    Raises
    ------
    ConfigError
        Naming the file and key: malformed entries, missing files.
    """
    path = Path(path)
    cfg = load_identify_config(path, schema=PayloadConfig)
    assert isinstance(cfg, PayloadConfig)  # the schema asked for
    without = cfg.payload.without
    if cfg.actuator.kind != "motor":
        raise ConfigError(
            f"{path}: actuator.kind: {cfg.actuator.kind}: 'ident payload' needs logged torques "
            "(or currents); remove the actuator section and name log.torque."
        )
    if without is not None and without.torque is None:
        raise ConfigError(
            f"{path}: payload.without.torque is missing: name the logged torques (or currents)."
        )
    if cfg.signals.gain_reference is not None and without is None:
        raise ConfigError(
            f"{path}: signals.gain_reference needs a log without the payload: add "
            "payload.without (the same arm, same kind of motion), or remove gain_reference."
        )
    if without is None:
        return cfg
    if without.more:
        raise ConfigError(
            f"{path}: payload.without.more: give one log without the payload; remove 'more'."
        )
    without = resolve_log(without, path.resolve().parent)
    files = [("path", without.path)] + [
        (f"files[{k}].path", f.path) for k, f in enumerate(without.files)
    ]
    for key in ("position", "torque", "velocity", "time"):
        value = getattr(without, key)
        if value is not None:
            files.append((f"{key}.path", value.path))
    for key, file in files:
        if file is not None and not Path(file).exists():
            raise ConfigError(
                f"{path}: payload.without.{key} = {file}: file not found; fix the path."
            )
    section = cfg.payload.model_copy(update={"without": without})
    return cfg.model_copy(update={"payload": section})
