"""The friction-model registry: per-joint friction laws looked up by the name a config gives.

A friction model is the torque [N*m] a joint's friction adds to the rigid-body torque, written
as *linear* parameters times columns that may depend on a few *nonlinear* parameters::

    tau_f[k, j] = sum_i columns(dq, load, p)[k, j, i] * linear[j, i]

with ``dq`` the joint velocity [rad/s], ``load`` the joint's load torque [N*m] (the torque the
gear passes to the link: the rigid-body and rotor-inertia torque, i.e. the motor torque minus
the friction; the rest of the model's prediction in an identification) and ``p`` the
nonlinear parameters of each joint, shape (nv, n_nonlinear).
A model without nonlinear parameters is *linear*: its columns enter the friction fit's
regressor beside the rest of the model (one solve; ``viscous_coulomb`` is also the
identification's own model, :mod:`ident.dynamics.friction`). The others are fitted around the
linear estimate by separable least squares (:mod:`ident.identify.friction.friction_fit`). Registered
models (``sign(0) = 0``):

=========================  ==================================================  ==============
name                       torque                                              nonlinear
=========================  ==================================================  ==============
``viscous_coulomb``        ``fv dq + fc sign(dq)``                             --
``viscous_coulomb_offset`` ``fv dq + fc sign(dq) + off``                       --
``stribeck``               ``fv dq + (fc + fst exp(-(dq/vs)^2)) sign(dq)``     ``vs`` [rad/s]
``sigmoid``                ``phi1 (s(phi2 (dq + phi3)) - s(phi2 phi3))``       ``phi2, phi3``
``load_dependent``         ``fv dq + (fc + fl |load|) sign(dq)``               --
=========================  ==================================================  ==============

``s(x) = 1 / (1 + exp(-x))``. The Stribeck static friction is ``fc + fst``. The sigmoid is the
Franka Panda model of Gaz et al., "Dynamic identification of the Franka Emika Panda robot with
retrieval of feasible parameters using penalty-based optimization", IEEE RA-L 4(4), 2019
(``phi2`` [s/rad], ``phi3`` [rad/s]; zero torque at rest). Adding a model is a new
:class:`FrictionModel` and :func:`register_friction_model` (see ``docs/friction.md``).
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from ident.errors import ConfigError

__all__ = [
    "AUTO",
    "FRICTION_MODELS",
    "FrictionModel",
    "get_friction_model",
    "register_friction_model",
]

FloatArray = npt.NDArray[np.float64]
#: ``columns(dq, load, nonlinear) -> (n_samples, nv, n_linear)``.
Columns = Callable[[FloatArray, FloatArray, FloatArray], FloatArray]

#: The config value that compares every registered model on held-out data.
AUTO = "auto"


@dataclass(frozen=True, eq=False)
class FrictionModel:
    """A per-joint friction law (module docstring).

    Attributes
    ----------
    name :
        Registry name (``model.friction: <name>``).
    linear :
        Labels of the per-joint linear parameters, in column order (e.g. ``("fv", "fc")``).
    columns :
        ``columns(dq, load, nonlinear)``: ``dq``, ``load`` shape (n_samples, nv) [rad/s, N*m],
        ``nonlinear`` shape (nv, len(nonlinear)); returns shape (n_samples, nv, len(linear)).
    nonlinear :
        Labels of the per-joint nonlinear parameters (empty for a linear model).
    positive :
        For each nonlinear parameter, whether it must be > 0 (then fitted on a log scale).
    initial :
        ``initial(dq)`` -> starting nonlinear parameters, shape (nv, len(nonlinear)), from the
        velocities' scale; None for a linear model.
    formula :
        The torque as text, for reports.
    uses_load :
        Whether the columns depend on ``load`` (fitted by a fixed point on the load).
    units :
        Unit of each parameter by label (SI), for the written model's joint-extras file.
    """

    name: str
    linear: tuple[str, ...]
    columns: Columns
    nonlinear: tuple[str, ...] = ()
    positive: tuple[bool, ...] = ()
    initial: Callable[[FloatArray], FloatArray] | None = None
    formula: str = ""
    uses_load: bool = False
    units: dict[str, str] = field(default_factory=dict)

    @property
    def is_linear(self) -> bool:
        """True when the model has no nonlinear parameters (its columns enter the regressor)."""
        return not self.nonlinear

    def torque(
        self, dq: FloatArray, load: FloatArray, linear: FloatArray, nonlinear: FloatArray
    ) -> FloatArray:
        """Friction torque [N*m], shape (n_samples, nv).

        ``linear`` shape (nv, len(linear)), ``nonlinear`` shape (nv, len(nonlinear)).
        """
        cols = self.columns(np.asarray(dq, float), np.asarray(load, float), nonlinear)
        return np.einsum("kji,ji->kj", cols, np.asarray(linear, dtype=float))


#: Registered friction models by name.
FRICTION_MODELS: dict[str, FrictionModel] = {}


def register_friction_model(model: FrictionModel) -> FrictionModel:
    """Make ``model`` available as ``model.friction: <model.name>``.

    Raises
    ------
    ValueError
        If the name is taken (or is ``auto``).
    """
    if model.name in FRICTION_MODELS or model.name == AUTO:
        raise ValueError(f"friction model {model.name!r} is registered twice")
    if len(model.positive) != len(model.nonlinear) or (model.nonlinear and not model.initial):
        raise ValueError(f"friction model {model.name!r}: give positive and initial per nonlinear")
    FRICTION_MODELS[model.name] = model
    return model


def get_friction_model(name: str) -> FrictionModel:
    """The model registered as ``name``.

    Raises
    ------
    ConfigError
        For an unknown name, listing the known ones and the closest match.
    """
    if name not in FRICTION_MODELS:
        close = difflib.get_close_matches(name, [*FRICTION_MODELS, AUTO], n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ConfigError(
            f"unknown friction model {name!r}{hint} (known: "
            f"{', '.join(sorted(FRICTION_MODELS))}, or {AUTO!r} to pick by held-out fit)."
        )
    return FRICTION_MODELS[name]


def _velocity_scale(dq: FloatArray) -> FloatArray:
    """RMS velocity per joint [rad/s], shape (nv,), floored at 1e-3 rad/s."""
    return np.maximum(np.sqrt(np.mean(np.asarray(dq, float) ** 2, axis=0)), 1e-3)


def _viscous_coulomb(dq: FloatArray, load: FloatArray, p: FloatArray) -> FloatArray:
    return np.stack([dq, np.sign(dq)], axis=-1)


def _with_offset(dq: FloatArray, load: FloatArray, p: FloatArray) -> FloatArray:
    return np.stack([dq, np.sign(dq), np.ones_like(dq)], axis=-1)


def _stribeck(dq: FloatArray, load: FloatArray, p: FloatArray) -> FloatArray:
    sign = np.sign(dq)
    return np.stack([dq, sign, np.exp(-((dq / p[:, 0]) ** 2)) * sign], axis=-1)


def _sigmoid(dq: FloatArray, load: FloatArray, p: FloatArray) -> FloatArray:
    slope, shift = p[:, 0], p[:, 1]

    def s(x: FloatArray) -> FloatArray:
        return 0.5 * (1.0 + np.tanh(0.5 * x))  # the logistic function, overflow-free

    return (s(slope * (dq + shift)) - s(slope * shift))[..., None]


def _load_dependent(dq: FloatArray, load: FloatArray, p: FloatArray) -> FloatArray:
    sign = np.sign(dq)
    return np.stack([dq, sign, np.abs(load) * sign], axis=-1)


#: Units of the registered models' parameters (``FrictionModel.units``).
_UNITS = {
    "fv": "N*m*s/rad",
    "fc": "N*m",
    "off": "N*m",
    "fst": "N*m",
    "vs": "rad/s",
    "phi1": "N*m",
    "phi2": "s/rad",
    "phi3": "rad/s",
    "fl": "1 (N*m per N*m of load)",
}

register_friction_model(
    FrictionModel(
        "viscous_coulomb",
        ("fv", "fc"),
        _viscous_coulomb,
        formula="fv dq + fc sign(dq)",
        units=_UNITS,
    )
)
register_friction_model(
    FrictionModel(
        "viscous_coulomb_offset",
        ("fv", "fc", "off"),
        _with_offset,
        formula="fv dq + fc sign(dq) + off",
        units=_UNITS,
    )
)
register_friction_model(
    FrictionModel(
        "stribeck",
        ("fv", "fc", "fst"),
        _stribeck,
        nonlinear=("vs",),
        positive=(True,),
        initial=lambda dq: 0.2 * _velocity_scale(dq)[:, None],
        formula="fv dq + (fc + fst exp(-(dq/vs)^2)) sign(dq)",
        units=_UNITS,
    )
)
register_friction_model(
    FrictionModel(
        "sigmoid",
        ("phi1",),
        _sigmoid,
        nonlinear=("phi2", "phi3"),
        positive=(True, False),
        initial=lambda dq: np.stack([2.0 / _velocity_scale(dq), np.zeros(np.shape(dq)[1])], axis=1),
        formula="phi1 (s(phi2 (dq + phi3)) - s(phi2 phi3)), s(x) = 1/(1 + exp(-x))",
        units=_UNITS,
    )
)
register_friction_model(
    FrictionModel(
        "load_dependent",
        ("fv", "fc", "fl"),
        _load_dependent,
        formula="fv dq + (fc + fl |load|) sign(dq)",
        uses_load=True,
        units=_UNITS,
    )
)
