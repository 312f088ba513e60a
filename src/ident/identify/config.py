"""Schema of an ``ident identify`` config: robot, log files, transmission, processing, model.

Every physical quantity is converted to SI here or in :mod:`ident.measure.logs` (degrees to
radians, amperes to N*m through the torque constants), once. Paths are relative to the config
file. Example (``configs/tx40.yaml``)::

    name: tx40
    robot: {urdf: ../data/staubli-tx40/urdf/tx40_mdh_modified.urdf}
    log:
      sampling_rate_hz: 5000.0
      position: {path: ../data/staubli-tx40/data/pos_read_data.csv.gz}
      torque: {path: ../data/staubli-tx40/data/curr_data.csv.gz}
    transmission:
      gear_ratios: [32, 32, 45, -48, 45, 32]
      coupling: [{motor: 6, joint: 5, ratio: 32}]
      zero_offsets: [0, -1.5707963267948966, 1.5707963267948966, 0, 0, 0]
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator, model_validator

from ident.config import StrictModel, load_config_file
from ident.dynamics.actuators import ACTUATOR_LAWS, actuator_law
from ident.dynamics.friction import ExtraTerms
from ident.dynamics.friction_models import AUTO, get_friction_model
from ident.errors import ConfigError, DataError
from ident.identify.estimation.reference import read_reference
from ident.identify.estimators import get_contract, get_estimator
from ident.measure.log_config import LogConfig, SignalFile, TransmissionConfig
from ident.measure.mujoco_config import PositiveNm, PositiveStiffness
from ident.model.selection import RobotSelection

__all__ = [
    "ActuatorSection",
    "EssentialConfig",
    "EstimationConfig",
    "FilterConfig",
    "GainReferenceConfig",
    "IdentifyConfig",
    "ModelConfig",
    "PreprocessConfig",
    "ReferenceConfig",
    "RefinementConfig",
    "RegularizationConfig",
    "SignalsConfig",
    "TruthConfig",
    "UrdfUpdateConfig",
    "ValidationConfig",
    "load_identify_config",
    "refinement_shorthand",
    "resolve_log",
]


class FilterConfig(StrictModel):
    """Zero-phase Butterworth low-pass filter on the joint positions."""

    cutoff_hz: float = Field(gt=0.0)
    order: int = Field(default=4, ge=1, le=10)


class PreprocessConfig(StrictModel):
    """Signal processing before the regressor is built (see
    :mod:`ident.identify.estimation.preprocess`).

    ``lowpass`` and ``decimation`` default to ``auto``: chosen from the sampling rate and the
    excitation band (``excitation_band_hz``, the highest frequency of the motion; estimated
    from the positions when null), and recorded. ``lowpass: null`` leaves the positions
    unfiltered (a warning), ``decimation: []`` keeps the rate.
    """

    lowpass: FilterConfig | Literal["auto"] | None = "auto"
    torque_lowpass: FilterConfig | None = None
    trim_samples: int = Field(default=20, ge=0)
    decimation: list[int] | Literal["auto"] = "auto"
    excitation_band_hz: float | None = Field(default=None, gt=0.0)
    velocity_threshold: list[float] | None = None
    # bounded memory (see ident.identify.estimation.accumulate): "auto" chunks logs with several
    # segments or a regressor above max_regressor_mb; chunk_samples null = automatic
    chunked: Literal["auto", "always", "never"] = "auto"
    max_regressor_mb: float = Field(default=1024.0, gt=0.0)
    chunk_samples: int | None = Field(default=None, ge=16)

    @field_validator("velocity_threshold")
    @classmethod
    def _thresholds(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and not all(math.isfinite(v) and v >= 0.0 for v in value):
            raise ValueError(
                f"velocity thresholds are speeds [rad/s or m/s], each finite and >= 0 "
                f"(0 keeps every sample), got {value}"
            )
        return value

    @field_validator("decimation")
    @classmethod
    def _factors(cls, value: list[int] | str) -> list[int] | str:
        if not isinstance(value, str) and any(f < 1 for f in value):
            raise ValueError("decimation factors must be >= 1")
        return value


class ModelConfig(StrictModel):
    """Parameters beyond the rigid bodies (see :mod:`ident.dynamics.friction`).

    Per-joint options take ``true`` (all joints), ``false`` or a list of 1-based joints.
    ``coupled_wrist`` names the two joints whose motor is shared (TX40: ``[5, 6]``).
    ``friction``: a model of the friction registry (:mod:`ident.dynamics.friction_models`)
    fitted beside the identification on the joints with ``viscous`` or ``coulomb`` terms, or
    ``auto`` (every model, ranked by held-out fit; :mod:`ident.identify.friction.friction_fit`).
    ``viscous_coulomb`` (default) is the identification's own model: nothing more is fitted.
    """

    viscous: bool | list[int] = True
    coulomb: bool | list[int] = True
    offset: bool | list[int] = True
    rotor_inertia: bool | list[int] = True
    coupled_wrist: list[int] | None = None
    friction: str = "viscous_coulomb"

    @field_validator("friction")
    @classmethod
    def _friction_model(cls, value: str) -> str:
        if value != AUTO:
            try:
                get_friction_model(value)
            except ConfigError as e:
                raise ValueError(str(e)) from e
        return value

    @field_validator("coupled_wrist")
    @classmethod
    def _pair(cls, value: list[int] | None) -> list[int] | None:
        if value is not None and len(value) != 2:
            raise ValueError("coupled_wrist takes two 1-based joints, e.g. [5, 6]")
        return value

    def extra_terms(self, nv: int, source: str) -> ExtraTerms:
        """The regressor's columns beyond the rigid bodies that this section asks for, for a
        robot of ``nv`` joints (:class:`ConfigError` naming ``source`` when they do not fit)."""
        try:
            return ExtraTerms.from_options(
                nv,
                rotor_inertia=self.rotor_inertia,
                viscous=self.viscous,
                coulomb=self.coulomb,
                offset=self.offset,
                coupled_wrist=self.coupled_wrist,
            )
        except ConfigError as e:
            raise ConfigError(f"{source}: {e}") from e


class EssentialConfig(StrictModel):
    """Essential-parameter reduction (see :mod:`ident.identify.estimation.essential`)."""

    enabled: bool = True
    max_relative_std_pct: float = Field(default=10.0, gt=0.0)
    max_residual_increase: float = Field(default=0.05, ge=0.0)


class RegularizationConfig(StrictModel):
    """Prior toward the nominal (URDF) parameters of the constrained estimators.

    ``weight``: ``lambda`` of ``lambda ||G D (theta - theta_nominal)||^2`` (``G``: the
    directions no data see, :mod:`ident.identify.estimators.constrained`), a number >= 0 or
    ``auto`` (chosen on the last 20 % of the identification part from a grid and reported; see
    :mod:`ident.identify.estimators.regularization`).
    """

    weight: float | Literal["auto"] = "auto"
    prior: Literal["nominal"] = "nominal"

    @field_validator("weight")
    @classmethod
    def _nonnegative(cls, value: float | str) -> float | str:
        if not isinstance(value, str) and not value >= 0.0:
            raise ValueError("regularization.weight must be >= 0 or 'auto'")
        return value


class EstimationConfig(StrictModel):
    """Estimator choice: a name of the estimator registry (:mod:`ident.identify.estimators`).

    ``ols`` and ``wls`` estimate the base parameters; constrained estimators (``lmi``,
    ``log_cholesky``) estimate physically consistent standard parameters, WLS-weighted, next to
    the WLS estimate (which the essential parameters and the reference comparison use).
    ``ellipsoids: true`` (``lmi`` only) also keeps each link's mass inside the bounding
    ellipsoid of its URDF geometry (:mod:`ident.robot.ellipsoids`); every moving link then
    needs ``<collision>`` or ``<visual>`` geometry. ``friction`` (constrained estimators):
    ``least_squares`` keeps every friction parameter the WLS fit finds positive at its WLS
    value, ``free`` estimates friction jointly with the constrained inertial parameters
    (:mod:`ident.identify.estimators.constrained`).
    """

    method: str = "wls"
    essential: EssentialConfig = Field(default_factory=EssentialConfig)
    regularization: RegularizationConfig = Field(default_factory=RegularizationConfig)
    ellipsoids: bool = False
    friction: Literal["least_squares", "free"] = "least_squares"

    @field_validator("method")
    @classmethod
    def _registered(cls, value: str) -> str:
        try:
            get_estimator(value)
        except ConfigError as e:
            raise ValueError(str(e)) from e
        if not get_contract(value).supports_chunks:  # every log is reduced chunk by chunk
            raise ValueError(
                f"estimator {value!r} declares supports_chunks=False: the identification "
                "gives every estimator the rows reduced per joint, never the rows; register "
                "it with a contract that works on problem.observations."
            )
        return value

    @model_validator(mode="after")
    def _ellipsoids_need_lmi(self) -> EstimationConfig:
        if self.ellipsoids and self.method != "lmi":
            raise ValueError(
                f"ellipsoids: true needs method: lmi (the estimator with the ellipsoid "
                f"constraint), not {self.method!r}"
            )
        return self

    @property
    def least_squares_method(self) -> str:
        """``ols`` or ``wls``: the unconstrained estimate (``wls`` beside constrained ones)."""
        return self.method if get_contract(self.method).least_squares else "wls"


class TruthConfig(StrictModel):
    """The true base parameters of a simulated log (``ident run`` writes them into the
    ``identify.yaml`` of each log it simulates): with them the verdict judges the errors of the
    major parameters, as ``ident run`` does (docs/verdict.md). A real log has none."""

    base_names: list[str]
    values: list[float]
    reference_share: list[float]


class ValidationConfig(StrictModel):
    """Time split: the first ``identify_fraction`` of the log identifies, the rest validates.

    The identified parameters are checked on the held-out part (rows above the velocity
    threshold): a relative residual worse than the URDF's nominal parameters', or above
    ``max_relative_residual`` when given, is a warning in the terminal, the report and
    ``result.json``. ``fail_on_warning: true`` makes ``ident identify`` exit with code 1 after
    writing the run folder (default: exit 0, the warning is reported).
    """

    identify_fraction: float = Field(default=0.7, gt=0.0, le=1.0)
    max_relative_residual: float | None = Field(default=None, gt=0.0)
    fail_on_warning: bool = False
    truth: TruthConfig | None = None


class ReferenceConfig(StrictModel):
    """Published reference base parameters (CSV: expression, OLS value, OLS rel. std %, WLS
    value, WLS rel. std %, no header) to compare with."""

    base_parameters: Path | None = None
    essential_parameters: Path | None = None
    column: Literal["ols", "wls"] = "wls"


class UrdfUpdateConfig(StrictModel):
    """The identified model's files (see :mod:`ident.identify.model_files.files`).

    ``model: consistent`` (default): the physically consistent estimate of every link (the
    configured estimator when its contract promises consistency, else
    :data:`~ident.identify.pipeline.core.MODEL_METHOD` computed beside the least-squares fit, with
    the prior along the directions the log does not see) is written as ``<urdf>_identified.urdf``,
    ``<urdf>_identified.xml`` (MJCF) and ``<urdf>_joint_extras.json``; ``none``: no model file.

    ``cautious: true`` also writes ``<urdf>_cautious.urdf``: only the standard parameters that
    a base parameter determines alone and whose relative standard deviation is below
    ``max_relative_std_pct`` changed; a link that would become physically inconsistent keeps
    its nominal inertial.

    ``model_bootstrap`` (default 30, 0 switches it off, at most 1000): resamples of the
    moving-block bootstrap on which the written model's constrained fit is re-solved, for a
    95 % interval on every written standard parameter (each about as long as the model's own
    solve; the time is in ``run.json``'s timings).
    """

    model: Literal["consistent", "none"] = "consistent"
    cautious: bool = False
    max_relative_std_pct: float = Field(default=10.0, gt=0.0)
    #: Re-solves of the written model's constrained fit for its intervals (0: none);
    #: :mod:`ident.identify.assessment.model_intervals`.
    model_bootstrap: int = Field(default=30, ge=0, le=1000)


class GainReferenceConfig(StrictModel):
    """The reference of the torque gains: a payload of known mass [kg] (``ident payload``
    with ``payload.without``; :mod:`ident.identify.payload.payload_gain`)."""

    payload_mass_kg: float = Field(gt=0.0)


class SignalsConfig(StrictModel):
    """Errors of the measured torque corrected where the log is read
    (:mod:`ident.identify.corrections.signal_correction`).

    ``delay_s``: the torque lags the positions by this [s] (``0``: none, the default) or
    ``auto``: estimated within ``max_delay_s`` on the log (the fit's residual against the
    delay). The torque is advanced by it before any processing. ``gain_reference``
    (``ident payload`` only): with a payload of known mass and a log without it, a gain per
    joint is estimated and every torque divided by it; ``null``: no gain correction.
    """

    delay_s: float | Literal["auto"] = 0.0
    max_delay_s: float = Field(default=0.02, gt=0.0, le=1.0)
    gain_reference: GainReferenceConfig | None = None

    @model_validator(mode="after")
    def _delay_in_bound(self) -> SignalsConfig:
        if not isinstance(self.delay_s, str) and not 0.0 <= self.delay_s <= self.max_delay_s:
            raise ValueError(
                f"signals.delay_s = {self.delay_s:g} s: give a delay >= 0 and at most "
                f"signals.max_delay_s = {self.max_delay_s:g} s, or 'auto'"
            )
        return self


class ActuatorSection(StrictModel):
    """``actuator:``: what drives the joints, so what the log's torque is
    (:mod:`ident.dynamics.actuators`; the estimation: :mod:`ident.identify.actuators`).

    ``kind: motor`` (default): the torque is logged (``log.torque``). ``kind: position``: a
    position servo logging its command (``log.command``) and no torque, whose torque is
    ``clip(kp (q_cmd(t - d) - q) - kd dq, +-forcerange)``; the data fix it only up to one
    common scale, set by ``scale_from``: ``mass`` (the URDF's masses, through the gravity
    load they put on the logged postures) or ``kp`` (the gain ``kp`` [N*m/rad] given, one
    value or one per joint, from a datasheet). Default: ``kp`` when ``kp`` is given, else
    ``mass``. ``forcerange`` [N*m] (one value or one per joint): samples where the servo may
    reach it are excluded (``null``: never saturates). ``delay``: the command's transport
    delay [s] (a fraction of a sample allowed), or ``auto``: the delay within
    ``max_delay_s`` with the smallest residual (whole samples, the best refined to a
    fraction). ``equal_kp`` (``scale_from: mass``): groups of joint names whose servos have
    the same gain (one servo model, one P setting): one ``kp`` per group, which ties a joint
    that carries no gravity load to one that does.
    """

    kind: str = "motor"
    kp: PositiveStiffness | None = None
    forcerange: PositiveNm | None = None
    delay: float | Literal["auto"] = "auto"
    max_delay_s: float = Field(default=0.05, gt=0.0, le=1.0)
    scale_from: Literal["mass", "kp"] | None = None
    equal_kp: list[list[str]] | None = None

    @field_validator("kind")
    @classmethod
    def _known(cls, value: str) -> str:
        if value not in ACTUATOR_LAWS:
            raise ValueError(f"{value!r}; allowed: {', '.join(ACTUATOR_LAWS)}")
        return value

    @model_validator(mode="after")
    def _options_of_the_kind(self) -> ActuatorSection:
        if self.kind != "position":
            given = [
                k
                for k in ("kp", "forcerange", "scale_from", "equal_kp")
                if getattr(self, k) is not None
            ]
            if given:
                raise ValueError(
                    f"actuator.{given[0]} is an option of kind: position (a servo logging no "
                    "torque); remove it, or set actuator.kind: position"
                )
            return self
        if not isinstance(self.delay, str) and not 0.0 <= self.delay <= self.max_delay_s:
            raise ValueError(
                f"actuator.delay = {self.delay:g} s: give a delay >= 0 and at most "
                f"actuator.max_delay_s = {self.max_delay_s:g} s, or 'auto'"
            )
        if self.scale_from == "kp" and self.kp is None:
            raise ValueError(
                "actuator.scale_from: kp needs actuator.kp [N*m/rad] (the servo's gain, from "
                "its datasheet); give it, or set scale_from: mass"
            )
        if self.scale_from == "mass" and self.kp is not None:
            raise ValueError(
                "actuator.kp is used only with scale_from: kp (the gain fixes the scale); "
                "remove kp to identify it from the URDF's mass, or set scale_from: kp"
            )
        self._check_equal_kp()
        return self

    def _check_equal_kp(self) -> None:
        """``equal_kp``: only when the gains are identified; groups of two or more distinct
        joints, each joint in one group at most (the names are matched in the servo fit)."""
        if self.equal_kp is None:
            return
        if self.scale == "kp":
            raise ValueError(
                "actuator.equal_kp ties identified gains; with actuator.kp given it has no "
                "use: remove it, or remove kp (scale_from: mass)"
            )
        names = [n for group in self.equal_kp for n in group]
        if any(len(group) < 2 for group in self.equal_kp) or len(set(names)) < len(names):
            raise ValueError(
                f"actuator.equal_kp = {self.equal_kp}: give groups of two or more joint names, "
                "each joint in one group at most"
            )

    @property
    def scale(self) -> str:
        """What fixes the scale: ``kp`` (given) or ``mass`` (the URDF's)."""
        if self.scale_from is not None:
            return self.scale_from
        return "kp" if self.kp is not None else "mass"


class RefinementConfig(StrictModel):
    """Refinement of the written MJCF's joint extras on MuJoCo rollouts (``refinement:``).

    ``method: rollout`` adjusts each moving joint's ``frictionloss``, ``damping`` and
    ``armature`` (never the link inertials) so that open-loop MuJoCo rollouts of windows of the
    identification part replay the log, warm-started from and pulled toward the regressor's
    values (:mod:`ident.identify.refinement.rollout_refinement`); the shorthand
    ``refinement: rollout`` is ``{method: rollout}``. ``none`` (the default) writes the
    regressor's values only. The CPU is bounded by ``max_windows`` training windows of 0.5 s
    and ``max_iterations`` iterations (trust-region Gauss-Newton), each ``3 n + 1`` rollouts
    of the windows (``n`` joints). By default 64 (the held-out check's cap) of the
    identification part's windows, which start every 0.1 s and overlap: the training objective
    averages the log's noise over its windows, and with fewer its optimum strays from the
    held-out one by more than the regressor's own error (measured: 12 of the Panda's 40
    disjoint windows left its refined model 7.7 % above the truth's held-out rollout error, all
    40 reach 4.4 %; on the UR5's seed-1 log 40 disjoint windows led to a step that a fresh noise
    draw scored worse, :data:`~ident.identify.assessment.rollout.IDENTIFICATION_OVERLAP`).
    """

    method: Literal["none", "rollout"] = "none"
    max_windows: int = Field(default=64, ge=1, le=64)
    max_iterations: int = Field(default=8, ge=1, le=50)
    #: Weight of the prior term, relative to the training objective at the start.
    prior_weight: float = Field(default=0.01, ge=0.0, le=1e6)


def refinement_shorthand(value: object) -> object:
    """``refinement: rollout`` (or ``none``) is ``{method: ...}``; other values unchanged."""
    return {"method": value} if isinstance(value, str) else value


class IdentifyConfig(StrictModel):
    """Everything ``ident identify`` needs."""

    name: str = "identify"
    robot: RobotSelection  # the section every command reads (file, chain, checks)
    log: LogConfig
    transmission: TransmissionConfig = Field(default_factory=TransmissionConfig)
    preprocess: PreprocessConfig = Field(default_factory=PreprocessConfig)
    model: ModelConfig = Field(default_factory=ModelConfig)
    estimation: EstimationConfig = Field(default_factory=EstimationConfig)
    validation: ValidationConfig = Field(default_factory=ValidationConfig)
    reference: ReferenceConfig = Field(default_factory=ReferenceConfig)
    urdf_update: UrdfUpdateConfig = Field(default_factory=UrdfUpdateConfig)
    signals: SignalsConfig = Field(default_factory=SignalsConfig)
    actuator: ActuatorSection = Field(default_factory=ActuatorSection)
    refinement: RefinementConfig = Field(default_factory=RefinementConfig)
    source: Path | None = None

    @field_validator("refinement", mode="before")
    @classmethod
    def _method_shorthand(cls, value: object) -> object:
        return refinement_shorthand(value)

    @model_validator(mode="after")
    def _log_of_the_actuator(self) -> IdentifyConfig:
        law = actuator_law(self.actuator.kind)
        for n, entry in enumerate(self.log.all_logs()):
            where = "log" if n == 0 else f"log.more[{n - 1}]"
            if law.logs_torque and entry.torque is None:
                raise ValueError(
                    f"{where}.torque is missing: name the logged torques (or currents), or set "
                    "actuator.kind: position for a position servo that logs none"
                )
            if not law.logs_torque and entry.torque is not None:
                raise ValueError(
                    f"{where}.torque: actuator.kind: {law.kind} takes its torque from the "
                    "servo's law, not from the log; remove log.torque, or set actuator.kind: "
                    "motor"
                )
            if law.needs_command and entry.command is None:
                raise ValueError(
                    f"{where}.command is missing: actuator.kind: {law.kind} needs the "
                    "commanded positions (a LeRobot dataset's 'action'); name them"
                )
        if not law.logs_torque:
            self._check_servo_options()
        if self.refinement.method != "none" and self.actuator.kind != "motor":
            raise ValueError(
                f"refinement.method: {self.refinement.method} refines joint extras driven by "
                f"logged torques; actuator.kind: {self.actuator.kind}'s gains and delay are not "
                "refined. Remove refinement (or set refinement: none)"
            )
        return self

    def _check_servo_options(self) -> None:
        """What a servo's log cannot have: a torque delay (no torque), no viscous column."""
        if self.signals.delay_s != 0.0:
            raise ValueError(
                "signals.delay_s: the log has no torque to delay; the command's delay is "
                "actuator.delay. Remove signals.delay_s"
            )
        if self.model.viscous is not True:
            raise ValueError(
                "model.viscous must be true with actuator.kind: position: the servo's kd "
                "multiplies dq as the viscous friction does (kd + fv is identified per joint)"
            )


def _resolve(path: Path | None, base: Path) -> Path | None:
    if path is None:
        return None
    path = Path(path).expanduser()
    return path if path.is_absolute() else (base / path)


def resolve_log(log: LogConfig, base: Path) -> LogConfig:
    """The log section with every path made absolute (relative to the config's folder)."""

    def signal(s: SignalFile | None) -> SignalFile | None:
        return None if s is None else s.model_copy(update={"path": _resolve(s.path, base)})

    return log.model_copy(
        update={
            "path": _resolve(log.path, base),
            "files": [f.model_copy(update={"path": _resolve(f.path, base)}) for f in log.files],
            "position": signal(log.position),
            "torque": signal(log.torque),
            "velocity": signal(log.velocity),
            "command": signal(log.command),
            "time": None
            if log.time is None
            else log.time.model_copy(update={"path": _resolve(log.time.path, base)}),
        }
    )


def load_identify_config(
    path: str | Path, schema: type[IdentifyConfig] = IdentifyConfig
) -> IdentifyConfig:
    """Load an identify config; make its paths absolute (relative to the config file).

    ``schema``: the config class (a subclass adds sections, e.g. ``ident payload``'s).

    Raises
    ------
    ConfigError
        Naming the file and key, for malformed or missing entries and missing files.
    """
    path = Path(path)
    cfg = load_config_file(schema, path)
    if cfg.signals.gain_reference is not None and schema is IdentifyConfig:
        raise ConfigError(
            f"{path}: signals.gain_reference: a payload of known mass is the gain reference of "
            "'ident payload' (with payload.without); remove it from an identify config."
        )
    base = path.resolve().parent
    try:
        logs = [resolve_log(entry, base) for entry in cfg.log.all_logs()]
    except ValueError as e:
        raise ConfigError(f"{path}: log.more: {e}") from e
    log = logs[0].model_copy(update={"more": [x.model_dump(exclude={"more"}) for x in logs[1:]]})
    reference = cfg.reference.model_copy(
        update={
            "base_parameters": _resolve(cfg.reference.base_parameters, base),
            "essential_parameters": _resolve(cfg.reference.essential_parameters, base),
        }
    )
    robot = cfg.robot.resolved(base)
    checks = [("robot.urdf" if robot.urdf is not None else "robot.description", robot.path)]
    for n, entry in enumerate(logs):
        where = "log" if n == 0 else f"log.more[{n - 1}]"
        if entry.path is not None:
            checks.append((f"{where}.path", entry.path))
        checks += [(f"{where}.files[{k}].path", f.path) for k, f in enumerate(entry.files)]
        for key in ("position", "torque", "velocity", "command", "time"):
            value = getattr(entry, key)
            if value is not None and value.path is not None:
                checks.append((f"{where}.{key}.path", value.path))
    for key in ("base_parameters", "essential_parameters"):
        value = getattr(reference, key)
        if value is not None:
            checks.append((f"reference.{key}", value))
    for key, file in checks:
        if not Path(file).exists():
            raise ConfigError(f"{path}: {key} = {file}: file not found; fix the path.")
    for key in ("base_parameters", "essential_parameters"):
        file = getattr(reference, key)
        if file is not None:  # read now: never a failure after the identification
            try:
                read_reference(file)
            except DataError as e:
                raise ConfigError(f"{path}: reference.{key}: {e}") from e
    return cfg.model_copy(
        update={"robot": robot, "log": log, "reference": reference, "source": path}
    )
