"""Where the arm's own parameters come from when ``ident payload`` estimates a payload.

The payload rows are ``tau - Y theta_URDF = Y_n phi + E e + Y_b dbeta``: ``dbeta`` is the
correction of the arm's base parameters (:mod:`ident.dynamics.base_parameters`, ``Y_b`` their
columns) that a URDF from CAD needs. Three sources of the arm (:data:`ARM_FROM`):

``without``
    A log without the payload: ``dbeta`` is estimated with ``phi`` and ``e`` from both logs
    stacked (the unloaded rows have no ``Y_n`` columns), so a CAD arm's errors cancel. The
    payload is identifiable iff its columns keep rank 10 once the arm's columns' span is
    projected out (:func:`lost_payload_directions`); directions lost there fall back to the
    CAD prior.
``model``
    An identified arm (``<stem>_identified.urdf`` of ``ident identify``): ``dbeta = 0``.
``prior``
    One log on a CAD arm: ``dbeta`` has the prior ``N(0, T S T^T)`` (:func:`cad_prior_covariance`:
    ``S`` the CAD's accuracy per standard parameter, ``T`` the base projection) and the
    estimate is the posterior mean (ridge), its covariance the posterior's, so the intervals
    carry the arm's uncertainty.

Every mode also fits the same rows with the arm free and no payload columns (the *floor*: what
noise and the unmodelled effects leave); a fit residual well above it names the arm model as the
likely cause (:func:`payload_fit_warnings`).
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ident.dynamics.base_parameters import RANK_RTOL, compute_base_parameters
from ident.dynamics.chain import KinematicChain, random_states
from ident.dynamics.friction import ExtraTerms, extra_columns, extra_names
from ident.dynamics.parameters import parameter_names
from ident.dynamics.regressor import joint_torque_regressor
from ident.errors import IdentWarning, NotIdentifiable
from ident.identify.estimation.estimate import Estimate, least_squares_reduced
from ident.identify.estimation.observations import ReducedObservations, reduce_rows
from ident.identify.estimation.uncertainty import BlockEquations
from ident.identify.model_files.files import COVARIANCE_SUFFIX

__all__ = [
    "ARM_FROM",
    "CAD_COM_STD_M",
    "CAD_RELATIVE_STD",
    "MAX_FIT_EXCESS",
    "MAX_RELATIVE_RESIDUAL",
    "ArmBase",
    "arm_base",
    "arm_source",
    "cad_prior_covariance",
    "floor_fit",
    "identified_covariance",
    "lost_payload_directions",
    "payload_fit_warnings",
    "select_blocks",
    "select_columns",
]

FloatArray = npt.NDArray[np.float64]

#: How the result names the source of the arm's parameters.
ARM_FROM = {
    "without": "the log without payload",
    "model": "identified model",
    "prior": "CAD prior",
}

#: The CAD prior's standard deviations: each mass and inertia within this share (1 σ) ...
CAD_RELATIVE_STD = 0.2
#: ... and each centre of mass within this distance (1 σ) [m].
CAD_COM_STD_M = 0.02

#: A fit residual above this share of the torque warns whatever the floor (the torques are
#: not what the model explains: wrong joint order, units, a gross arm error).
MAX_RELATIVE_RESIDUAL = 0.2
#: A fit residual above this multiple of the floor's (the same rows, the arm free) names the
#: arm model; the intervals are then widened by the ratio.
MAX_FIT_EXCESS = 1.5

_N_RANDOM_STATES = 200  # random states for the arm's structural base parameters


@dataclass(frozen=True, eq=False)
class ArmBase:
    """The arm's base parameters as correction unknowns of the payload rows.

    Attributes
    ----------
    index :
        Their columns in the rigid-body regressor (Pinocchio order), shape (n_b,).
    names :
        ``arm_<base name>``, length n_b.
    projection :
        ``T`` with ``dbeta = T dtheta`` for a correction ``dtheta`` of the standard parameters,
        shape (n_b, 10 n_bodies).
    extra_projection :
        The same base parameters' coefficients on the extra terms (the extras' own columns
        absorb them), shape (n_b, n_extra).
    """

    index: npt.NDArray[np.intp]
    names: tuple[str, ...]
    projection: FloatArray
    extra_projection: FloatArray


def arm_base(chain: KinematicChain, terms: ExtraTerms, *, rng: int = 0) -> ArmBase:
    """The rigid-body base parameters left once the extra columns ``terms`` are unknowns.

    Found on random states with the sequential choice, the extras first (they stay unknowns
    by name: a rigid parameter with the same column, e.g. the first link's ``Izz`` and the rotor
    inertia, merges into the extra).
    """
    extras = extra_names(terms)
    rigid = parameter_names(chain.n_bodies)
    q, dq, ddq = random_states(chain, _N_RANDOM_STATES, rng=rng)
    Y = joint_torque_regressor(chain, q, dq, ddq)
    W = np.concatenate([extra_columns(terms, dq, ddq), Y], axis=2).reshape(
        -1, len(extras) + len(rigid)
    )
    with warnings.catch_warnings():  # the arm's own near dependences are `ident verify`'s
        warnings.simplefilter("ignore", IdentWarning)
        base = compute_base_parameters(W, extras + rigid, method="sequential")
    n_e = len(extras)
    rows = np.flatnonzero(base.independent >= n_e)
    index = (base.independent[rows] - n_e).astype(np.intp)
    names = tuple(f"arm_{base.base_names[k]}" for k in rows)
    return ArmBase(
        index=index,
        names=names,
        projection=base.projection[rows][:, n_e:],
        extra_projection=base.projection[rows][:, :n_e],
    )


def arm_source(setting: str, urdf: str | Path | None, has_without: bool) -> str:
    """Key of :data:`ARM_FROM`: ``without`` with a log without the payload, else ``setting``
    (``model`` or ``prior``), ``auto``: ``model`` for ``ident identify``'s
    ``<stem>_identified.urdf`` with its ``<stem>_joint_extras.json`` beside it, else ``prior``."""
    if has_without:
        return "without"
    if setting != "auto":
        return setting
    path = Path(str(urdf)) if urdf is not None else None
    if path is not None and path.name.endswith("_identified.urdf"):
        extras = path.with_name(path.name[: -len("_identified.urdf")] + "_joint_extras.json")
        if extras.exists():
            return "model"
    return "prior"


def cad_prior_covariance(
    theta: FloatArray,
    base: ArmBase,
    relative: float = CAD_RELATIVE_STD,
    com_std: float = CAD_COM_STD_M,
) -> FloatArray:
    """Prior covariance of ``dbeta`` (n_b, n_b) for a CAD arm of standard parameters ``theta``
    (10 n_bodies,) [SI, Pinocchio order]: independent ``dtheta`` with standard deviations
    ``relative * m`` [kg], ``hypot(relative * |m c_i|, m * com_std)`` [kg*m] and, for the
    inertias about the body origin, ``relative * tr(I) / 2 + 2 m |c| com_std`` [kg*m^2]
    (``com_std`` [m])."""
    bodies = np.asarray(theta, dtype=float).reshape(-1, 10)
    m = np.abs(bodies[:, 0])
    h = bodies[:, 1:4]
    c = np.linalg.norm(h, axis=1) / np.maximum(m, 1e-12)
    trace = bodies[:, 4] + bodies[:, 6] + bodies[:, 9]
    std = np.empty_like(bodies)
    std[:, 0] = relative * m
    std[:, 1:4] = np.hypot(relative * np.abs(h), (m * com_std)[:, None])
    std[:, 4:] = (relative * np.abs(trace) / 2 + 2 * m * c * com_std)[:, None]
    T = base.projection
    return (T * std.reshape(-1) ** 2) @ T.T


def identified_covariance(
    urdf: str | Path | None, base: ArmBase, extras: tuple[str, ...], rigid: tuple[str, ...]
) -> tuple[FloatArray | None, str]:
    """Covariance of the identified arm's error along the payload rows' arm corrections
    ``dbeta`` (n_b, n_b), from ``<stem>_identified_covariance.json`` beside ``ident identify``'s
    ``urdf`` (:func:`~ident.identify.model_files.files.covariance_json`: ``beta_id = T_id theta``,
    its covariance ``C_id``; with its ``model_bootstrap``, the written model's own re-estimates'
    covariance over the standard parameters, ``T_id = I``), and a note; ``(None, why)`` when it
    is missing or does not map.

    The corrections are ``dbeta = T_arm theta`` (:class:`ArmBase`, rigid and extra
    coefficients, ``extras`` and ``rigid`` name their columns). Both are base parameters of the
    same columns, so ``T_arm = M T_id`` with ``M = T_arm T_id^+`` and ``cov(dbeta) = M C_id M^T``;
    a residual ``||M T_id - T_arm|| > 1e-6 ||T_arm||`` means other model terms (the
    identification's ``model`` differs from the payload's) and gives None.
    """
    path = Path(str(urdf)) if urdf is not None else None
    if path is None or not path.name.endswith("_identified.urdf"):
        return None, "the arm is not an identified model"
    file = path.with_name(path.name[: -len("_identified.urdf")] + COVARIANCE_SUFFIX)
    if not file.exists():
        return None, f"no {file.name} beside the identified URDF (an older ident identify)"
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        return None, f"{file.name} unreadable ({e})"
    if "model_bootstrap" in data:  # the written model's own spread: T_id = identity
        boot = data["model_bootstrap"]
        n = len(boot["parameter_names"])
        data = {**boot, "projection": np.eye(n)}
    column = {name: k for k, name in enumerate(data["parameter_names"])}
    T_id = np.asarray(data["projection"], dtype=float)
    T_arm = np.zeros((len(base.names), T_id.shape[1]))
    for coefficients, names in ((base.extra_projection, extras), (base.projection, rigid)):
        for k, name in enumerate(names):
            if name in column:
                T_arm[:, column[name]] += coefficients[:, k]
            elif np.any(coefficients[:, k]):
                return None, f"{file.name} has no parameter {name} (other model terms)"
    M = np.linalg.lstsq(T_id.T, T_arm.T, rcond=None)[0].T
    if np.linalg.norm(M @ T_id - T_arm) > 1e-6 * np.linalg.norm(T_arm):
        return (
            None,
            f"{file.name}'s base parameters do not map onto the payload's arm (other model terms)",
        )
    how = "the model's bootstrap" if "n_samples" in data else "the least-squares covariance"
    return M @ np.asarray(data["covariance"], dtype=float) @ M.T, f"from {file.name}, {how}"


def select_columns(red: ReducedObservations, keep: npt.ArrayLike) -> ReducedObservations:
    """The reduction of the same rows with only the columns ``keep`` (indices)."""
    keep = np.asarray(keep, dtype=np.intp)
    n = keep.size
    R = np.empty((red.n_groups, n, n))
    z = np.empty((red.n_groups, n))
    rho = np.empty(red.n_groups)
    for j in range(red.n_groups):
        # the dropped residual rho_j enters as a row (0 ... 0 | sqrt(rho)), as merge does
        R[j], z[j], rho[j] = reduce_rows(
            np.vstack([red.R[j][:, keep], np.zeros((1, n))]),
            np.concatenate([red.z[j], [np.sqrt(max(red.rho[j], 0.0))]]),
            n,
        )
    return ReducedObservations(R=R, z=z, rho=rho, yty=red.yty, n_rows=red.n_rows)


def select_blocks(
    blocks: tuple[BlockEquations, ...], keep: npt.ArrayLike
) -> tuple[BlockEquations, ...]:
    """Per-joint block normal equations of the columns ``keep`` (indices)."""
    keep = np.asarray(keep, dtype=np.intp)
    return tuple(
        BlockEquations(
            A=b.A[:, keep][:, :, keep], c=b.c[:, keep], n_rows=b.n_rows,
            block_samples=b.block_samples,
        )
        for b in blocks
    )  # fmt: skip


def lost_payload_directions(
    red: ReducedObservations, n_payload: int, names: tuple[str, ...]
) -> list[str]:
    """Payload directions the rows cannot tell from the other columns: ``[]`` when the first
    ``n_payload`` columns keep rank ``n_payload`` after the others' span is projected out
    (relative to their own norms, tolerance :data:`~ident.dynamics.base_parameters.RANK_RTOL`);
    else one text per lost direction naming its largest payload parameters."""
    W = red.R.reshape(-1, red.n_params)  # same Gram matrix as the rows
    P, O = W[:, :n_payload], W[:, n_payload:]
    norms = np.linalg.norm(P, axis=0)
    Q = np.linalg.qr(O)[0] if O.shape[1] else np.zeros((W.shape[0], 0))
    rest = P - Q @ (Q.T @ P)
    _, s, vt = np.linalg.svd(rest / np.where(norms > 0, norms, 1.0), full_matrices=False)
    lost = []
    for k in np.flatnonzero(s <= RANK_RTOL):
        top = np.argsort(-np.abs(vt[k]))[:3]
        lost.append(" + ".join(f"{vt[k, i]:+.2f} {names[i]}" for i in top))
    return lost


def floor_fit(
    red: ReducedObservations, keep: npt.ArrayLike, names: tuple[str, ...]
) -> Estimate | None:
    """WLS of the rows on the columns ``keep`` (the arm free, no payload columns) after
    dropping those the rows do not determine (pivoted QR): the residual that noise and the
    unmodelled effects leave. None when even that fails."""
    keep = np.asarray(keep, dtype=np.intp)
    sub = select_columns(red, keep)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentWarning)
        base = compute_base_parameters(
            sub.R.reshape(-1, keep.size), [names[k] for k in keep], method="qr"
        )
    if base.rank < keep.size:
        sub = select_columns(red, keep[base.independent])
    try:
        return least_squares_reduced(
            sub, tuple(names[k] for k in keep[base.independent]), method="wls"
        )
    except NotIdentifiable:
        return None


def payload_fit_warnings(
    relative_residual: float, floor_residual: float | None, arm_from: str
) -> tuple[list[str], float]:
    """The payload fit's warnings and the factor its intervals are widened by (>= 1).

    ``relative_residual``: the fit's residual over the torque; ``floor_residual``: the same
    rows fitted with the arm free and no payload (:func:`floor_fit`), None when it could not
    run (named in the warnings); ``arm_from``: :data:`ARM_FROM`'s key. The residual above
    :data:`MAX_RELATIVE_RESIDUAL` warns; the CAD prior warns (the payload is as good as the
    CAD's assumed accuracy); a residual above :data:`MAX_FIT_EXCESS` times the floor names the
    arm model and widens the intervals by the ratio.
    """
    out: list[str] = []
    if relative_residual > MAX_RELATIVE_RESIDUAL:
        out.append(  # a good log leaves its noise (simulated, 1 %: 0.010); mixed-up columns 0.5-0.9
            f"the fit leaves {100 * relative_residual:.0f} % of the torques unexplained (a good "
            "log leaves its noise, a few %): the estimate is suspect. Likely causes: a log's "
            "joint columns that do not match the URDF's joints (list them in joint order or name "
            "them after the joints), a torque sign or unit wrong, a log of another robot, a "
            "delay between the signals, a friction term the model lacks, or the arm model."
        )
    if arm_from == "prior":
        out.append(
            "arm from the CAD prior: one log cannot tell the payload from the arm's own errors; "
            f"the intervals assume the CAD within {100 * CAD_RELATIVE_STD:g} % (mass, inertia) "
            f"and {100 * CAD_COM_STD_M:g} cm (centres of mass), 1 σ. Give a log without the "
            "payload (payload.without) or an identified arm for a payload as good as the log."
        )
    if floor_residual is None:
        out.append(
            "arm-model check not run: the log does not determine the arm's base parameters "
            "(the residual of a free arm is unknown); the intervals assume the arm model exact."
        )
        return out, 1.0
    excess = relative_residual / floor_residual if floor_residual > 0 else float("inf")
    if excess <= MAX_FIT_EXCESS:
        return out, 1.0
    out.append(
        f"the fit residual {100 * relative_residual:.2f} % is {excess:.1f}x the "
        f"{100 * floor_residual:.2f} % the same rows leave with the arm free: the arm model "
        f"({ARM_FROM[arm_from]}) is likely wrong, and the payload absorbs its error. The "
        f"intervals are widened {excess:.1f}x; give a log without the payload (payload.without) "
        "or an identified arm."
    )
    return out, float(excess)
