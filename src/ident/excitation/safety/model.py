"""The safety model of one robot (:class:`SafetyModel`, :func:`build_safety_model`): its
collision geometry with the floor, the obstacles and a payload's box, the pairs it checks,
the margin, the limits, and the clearances the optimizer and the dense check measure.

Building one runs the rooms of :mod:`ident.excitation.safety` in order: the geometry
(:mod:`~ident.excitation.safety.geometry`), the environment
(:mod:`~ident.excitation.safety.environment`), the pair rules
(:mod:`~ident.excitation.safety.pairs`, :mod:`~ident.excitation.safety.exclusions`), then the
measures (:mod:`~ident.excitation.safety.certificate`, :mod:`~ident.excitation.safety.fast`).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.errors import ConfigError
from ident.excitation.constraints import JointLimits
from ident.excitation.family import FloatArray
from ident.excitation.safety.bounds import _motion_coefficients, _pair_motion_coefficients, _reach
from ident.excitation.safety.certificate import _clearances, _pair_clearances, _poor_hull_pairs
from ident.excitation.safety.config import SafetyConfig
from ident.excitation.safety.distances import CheckedPairs
from ident.excitation.safety.environment import (
    _add_environment,
    _attach_payload_box,
    _constant_pairs,
    _estimate_environment,
    _judge_candidates,
)
from ident.excitation.safety.exclusions import (
    _add_contact_exclusions,
    _exclusion_postures,
    _settle_margin,
)
from ident.excitation.safety.fast import FastClearances
from ident.excitation.safety.geometry import _Hulls, _loaded_geometry, _screen, _with_pairs
from ident.excitation.safety.pairs import (
    ExcludedPair,
    _add_srdf_exclusions,
    _adjacent_pairs,
    _candidate_pairs,
    _flat_pairs,
    _mesh_pairs,
)

__all__ = ["SafetyModel", "build_safety_model", "clearances"]


def _effort_max(limits: JointLimits, torque_limits: bool) -> FloatArray:
    """Read-only torque limits [N*m or N], shape (nv,): the robot's effort limits
    (``limits.tau_max``), ``inf`` where unknown (``limits.unknown`` says why) or when
    ``torque_limits`` is off."""
    out = np.array(limits.tau_max if torque_limits else np.full(limits.nq, np.inf), dtype=float)
    out.setflags(write=False)
    return out


class SafetyModel:
    """Collision geometry, environment and limits of one robot; see :mod:`ident.excitation.safety`.

    Build it with :func:`build_safety_model`.

    Attributes
    ----------
    pair_names :
        Checked link pairs ``"<link>|<link or obstacle>"``, in the column order of
        :meth:`clearances`.
    pair_kinds :
        ``"self"``, ``"floor"`` or ``"obstacle"`` per link pair.
    excluded_pairs :
        Robot link pairs left out, with the reason: ``adjacent``, ``SRDF``, ``reference
        contact`` or ``always in contact`` (judged on the exact geometry, never on a hull).
    constant_pairs :
        Environment pairs whose distance no motion changes (the base on the floor, a first
        link turning on it), judged once when the model is built, with their distance.
    geometry_notes :
        ``(link, what)``: links whose visual geometry stands in for their collision geometry,
        and links left without geometry (``self_collision: false`` with a mesh missing).
    clearance_m :
        Required clearance [m].
    motion_coefficients :
        Shape (n_pairs, nv): a pair's relative displacement over a step is at most
        ``motion_coefficients @ (|dq| dt)`` [m] (see :func:`_motion_coefficients`; the joints
        above both links of a pair move them together and count 0).
    reach_m :
        A bound on the distance of any point of the robot from its base [m].
    seconds_per_posture, hull_seconds_per_posture, mesh_seconds_per_posture :
        CPU of one posture of the dense check [s] (the meshes' exact distances timed when
        the model is built, at random postures), of the same on the hulls (the optimizer's
        cheap term), and of every mesh pair's exact distance at one posture (a share of the
        dense check's samples makes each pair's smallest value exact), for the run's time
        estimate.
    keepable_clearances :
        Per tested link pair, its largest clearance over the sampled postures [m]: exact
        below the margin asked for, at least that margin otherwise.
    effort_max :
        Torque limits [N*m or N], shape (nv,); ``inf`` where unknown or when torque limits are
        off.
    limits :
        Position, velocity, acceleration limits.
    """

    def __init__(
        self,
        robot: Any,
        config: SafetyConfig,
        *,
        urdf: str | Path | None = None,
        package_dirs: Sequence[str | Path] = (),
        reference_q: npt.ArrayLike | None = None,
        home_q: npt.ArrayLike | None = None,
        rng: np.random.Generator | int | None = 0,
        lower_margin: bool | None = None,
    ) -> None:
        self.config = config
        self.clearance_m = float(config.clearance_m)
        # the default margin (no safety.clearance_m given) may be lowered to one the robot's
        # links can keep (see _self_exclusions); None: lower it only when not given
        self.lower_margin = (
            "clearance_m" not in config.model_fields_set if lower_margin is None else lower_margin
        )
        self.margin_note = ""
        self.seconds_per_posture = self.hull_seconds_per_posture = 0.0  # _poor_hull_pairs
        self.mesh_seconds_per_posture = 0.0
        self.keepable_clearances: dict[tuple[str, str], float] = {}  # see _settle_margin
        self.robot_model: pin.Model = robot.model
        self.limits = JointLimits.from_robot(robot)
        geom, link_of, joint_of, coefficients = self._load_robot(robot, urdf, package_dirs)
        n_robot = len(link_of)
        environment = _add_environment(geom, config)
        self._hulls = _Hulls(self._geometry_key, geom)
        self.postures = _exclusion_postures(self.limits, reference_q, rng)
        excluded = (
            self._self_exclusions(geom, link_of, joint_of, n_robot) if config.self_collision else {}
        )
        candidates = _candidate_pairs(link_of, environment, excluded, config.self_collision)
        _estimate_environment(n_robot, len(environment))
        constant = _judge_candidates(
            self.model, geom, self._hulls, candidates, self.postures, self.clearance_m, home_q
        )
        self.excluded_pairs = tuple(
            ExcludedPair(f"{a}|{b}", reason) for (a, b), reason in excluded.items()
        )
        self.constant_pairs = _constant_pairs(geom.geometryObjects, candidates, constant)
        kept = [candidates[k] for k in range(len(candidates)) if k not in constant]
        self._check_pairs(geom, kept, coefficients, len(environment))
        self.effort_max: FloatArray = _effort_max(self.limits, config.torque_limits)

    # ------------------------------------------------------------------ building
    def _load_robot(
        self, robot: Any, urdf: str | Path | None, package_dirs: Sequence[str | Path]
    ) -> tuple[pin.GeometryModel, list[str], list[int], FloatArray]:
        """Load the robot's collision geometry, its payload's box attached (sets ``model``,
        ``geometry_notes`` and ``reach_m``); return it with the link and the parent joint of
        each of its objects and their motion coefficients (:func:`_motion_coefficients`).

        Raises
        ------
        ConfigError
            If the margin is beyond the robot's reach.
        """
        config = self.config
        # geometry_notes: (link, what) of visual stand-ins and links without geometry
        model, geom, self.geometry_notes, self._geometry_key = _loaded_geometry(
            robot, urdf, package_dirs, config.self_collision
        )
        if config.payload_box is not None:  # part of the robot: before anything counts links
            _attach_payload_box(model, geom, config.payload_box)
        self.model = model
        n_robot = len(geom.geometryObjects)
        objects = geom.geometryObjects
        link_of = [model.frames[o.parentFrame].name for o in objects]
        joint_of = [int(o.parentJoint) for o in objects]
        coefficients = _motion_coefficients(model, geom, n_robot)
        self.reach_m = _reach(model, objects, joint_of, coefficients)
        if n_robot and self.clearance_m > self.reach_m:
            raise ConfigError(
                f"safety.clearance_m = {self.clearance_m:g} m is larger than the robot's reach "
                f"({self.reach_m:.3f} m): no posture could keep it; give a margin of a few "
                "centimetres (default 0.03)."
            )
        return geom, link_of, joint_of, coefficients

    def _self_exclusions(
        self,
        geom: pin.GeometryModel,
        link_of: list[str],
        joint_of: list[int],
        n_robot: int,
    ) -> dict[tuple[str, str], str]:
        """Robot link pairs left out, keyed by the sorted link names, with the reason.

        Adjacent (parent and child joints, links welded by fixed joints included), named in
        the SRDF, in contact (exact geometry) in the reference posture, or in contact in at
        least :data:`ALWAYS_IN_CONTACT_FRACTION` of the random postures. A remaining pair that
        is closer than the margin in every posture is an input error.

        The convex hulls screen the postures first (:func:`_screen`): a hull contains its
        mesh, so two hulls apart are two meshes apart; the exact geometry is measured only
        where the hulls are close. The answer is the exact geometry's.
        """
        parents = list(self.model.parents)
        excluded, geometry_pairs = _adjacent_pairs(parents, link_of, joint_of, n_robot)
        if self.config.srdf is not None:
            _add_srdf_exclusions(excluded, Path(self.config.srdf), set(link_of))
        tested = [k for k in geometry_pairs if k not in excluded]
        if not tested:
            return excluded
        pairs, _ = _flat_pairs(tested, geometry_pairs)
        hull = _screen(self.model, self.postures, self.clearance_m, geom, pairs, self._hulls)
        screened = dict(zip(pairs, hull.T, strict=True))
        _add_contact_exclusions(
            self.model, self.postures, excluded, geom, tested, geometry_pairs, screened
        )
        if self.clearance_m > 0.0:
            tested = [k for k in tested if k not in excluded]
            self.keepable_clearances, self.clearance_m, self.margin_note = _settle_margin(
                self.model,
                self.postures,
                self.clearance_m,
                self.lower_margin,
                geom,
                tested,
                geometry_pairs,
                screened,
            )
        return excluded

    def _check_pairs(
        self,
        geom: pin.GeometryModel,
        kept: list[tuple[int, int, str, str]],
        coefficients: FloatArray,
        n_environment: int,
    ) -> None:
        """Check the geometry pairs ``kept`` (``(a, b, link pair name, kind)``): set the pairs'
        names, kinds and motion coefficients (from the robot objects' ``coefficients``), the
        exact and hull geometry with exactly these pairs, and the measures on them."""
        self.exact_geometry_model = _with_pairs(geom, kept)
        self.geometry_model = _with_pairs(self._hulls.get(), kept)
        geometry_pair_names = [pair[2] for pair in kept]
        self.pair_names: tuple[str, ...] = tuple(dict.fromkeys(geometry_pair_names))
        kinds = {pair[2]: pair[3] for pair in kept}
        self.pair_kinds: tuple[str, ...] = tuple(kinds[n] for n in self.pair_names)
        group = np.array([self.pair_names.index(n) for n in geometry_pair_names], dtype=int)
        self.motion_coefficients = _pair_motion_coefficients(
            coefficients, n_environment, kept, group, self.n_pairs, self.model.nv
        )
        self._checked = CheckedPairs(
            self.model,
            self.geometry_model,
            self.exact_geometry_model,
            group,
            self.n_pairs,
            _mesh_pairs(geom, kept),
        )
        poor, self.seconds_per_posture, self.hull_seconds_per_posture, mesh = _poor_hull_pairs(
            self._checked, self.postures, self.clearance_m
        )
        self.mesh_seconds_per_posture = mesh
        self._fast = FastClearances(self._checked, poor)

    # ------------------------------------------------------------------ measuring
    def fast_clearances(self, q: npt.ArrayLike) -> FloatArray:
        """Clearances of the link pairs, vectorized over postures, for the cheap term [m].

        Never more than the exact clearance (every proxy is conservative), and equal to it
        wherever a pair is within the margin without touching, except for meshes, whose
        convex hull stands in (a hull contains its mesh, so its distance is a lower bound).
        Where a pair touches, the depth is the bound's (the capsule around a cylinder, a
        mesh's hull): as deep or deeper than the exact one, without coal's EPA.

        - cylinder, capsule and sphere geometry is handled by compiled code over all postures
          (:mod:`ident.excitation.safety.primitives`): exact against half-spaces (the floor,
          planes); for a cylinder against another geometry the capsule around it gives a
          lower bound, and where that bound is within the margin coal computes the exact
          distance (only for those postures and pairs; not where the capsules inside the two
          cylinders already touch: the cylinders do too);
        - every other pair goes through coal, meshes as their convex hulls; where a pair's
          hulls are closer than the margin in most postures (:func:`_poor_hull_pairs`: the
          UR5's forearm and wrist 2) the mesh itself is measured wherever the hulls are within
          the margin.

        Shape (n_samples, n_pairs). Each posture's row depends on that posture alone (not on
        the others passed with it).
        """
        return self._fast.clearances(q, self.clearance_m)

    def fast_min_clearances(self, q: npt.ArrayLike) -> FloatArray:
        """The smallest :meth:`fast_clearances` of each trajectory, pair by pair [m], up to
        the margin (what the cheap term reads).

        Below the margin, ``fast_min_clearances(q) == fast_clearances(q.reshape(-1, nq))
        .reshape(n, s, -1).min(axis=1)``, bit for bit, with fewer exact distances: coal's pairs
        are measured only where their bounding spheres are within the margin (elsewhere the
        spheres' distance stands, at least the margin), and of a trajectory's postures whose
        lower bound (capsule, hull) of a pair is within the margin, coal measures them in
        increasing order of the bound and stops once the next bound is not below the smallest
        distance found (no posture left can be closer).

        Parameters
        ----------
        q :
            Joint positions [rad or m], shape (n_trajectories, n_samples, nq).

        Returns
        -------
        :
            Shape (n_trajectories, n_pairs).
        """
        return self._fast.min_clearances(q, self.clearance_m, self)

    def with_optimizer_margin(self, clearance_m: float) -> SafetyModel:
        """The same model whose cheap term (:func:`collision_violations`) asks for
        ``clearance_m`` [m] instead: the optimizer's penalty margin, set above the
        certificate's when trajectories kept the margin at the checked samples but not
        between them. Geometry, pairs and limits are shared; the dense check of a trajectory
        uses the model it is given (keep the original for the certificate)."""
        if not clearance_m >= self.clearance_m:
            raise ValueError(
                f"the optimizer's margin {clearance_m} m is below the certificate's "
                f"{self.clearance_m} m"
            )
        tighter = copy.copy(self)
        tighter.clearance_m = float(clearance_m)
        return tighter

    @property
    def n_pairs(self) -> int:
        """Number of checked link pairs."""
        return len(self.pair_names)

    def clearances(
        self,
        q: npt.ArrayLike,
        within: npt.ArrayLike | None = None,
        travel: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """Signed distance of every checked link pair on the exact geometry [m].

        Meshes are measured as they are (coal BVH), primitives as primitives. Where two meshes
        touch, coal gives 0: the value is then their hulls' signed distance (<= 0, a depth).

        Parameters
        ----------
        q :
            Joint positions [rad or m], shape (n_samples, nq).
        within :
            Optional, shape (n_samples, n_pairs) [m]: the exact distance is needed only where
            it is below these values. Elsewhere the convex hulls' distance (a lower bound: a
            hull contains its mesh) stands in, except that each pair's smallest value is made
            exact (the postures are measured in increasing order of their hulls' distance
            until it exceeds the smallest exact distance found). Default: exact everywhere.
        travel :
            Optional with ``within``, shape (n_samples, n_pairs) [m], nondecreasing: a bound of
            each pair's relative motion since the first sample (the pair's bodies move apart
            or together by at most ``travel[s] - travel[r]`` between samples ``r < s``). Then
            a sample whose exact distance provably stays above ``within`` (the last exact
            value less the travel since) is not measured either (conservative advancement),
            and each pair's smallest value is found with those bounds.

        Returns
        -------
        :
            Shape (n_samples, n_pairs), columns named by :attr:`pair_names`; never more than
            the exact distance.
        """
        return _clearances(self._checked, q, within, travel)

    def pair_clearances(self, q: npt.ArrayLike, columns: Sequence[int]) -> FloatArray:
        """Exact clearances of some link pairs only [m], shape (n_samples, len(columns)).

        The same values as ``clearances(q)[:, columns]`` (a depth where meshes touch is
        reported as 0 or less), for the few pairs :func:`ident.excitation.check` refines.
        """
        return _pair_clearances(self._checked, q, columns)


def build_safety_model(
    robot: Any,
    config: SafetyConfig | Mapping[str, Any] | None = None,
    *,
    urdf: str | Path | None = None,
    package_dirs: Sequence[str | Path] = (),
    reference_q: npt.ArrayLike | None = None,
    home_q: npt.ArrayLike | None = None,
    lower_margin: bool | None = None,
) -> SafetyModel:
    """The safety model of a robot (see :class:`SafetyModel` and the module docstring).

    Parameters
    ----------
    robot :
        An :class:`ident.Robot` (or an object with ``model`` and the limits, plus ``urdf``).
    config :
        The ``safety`` section (a :class:`SafetyConfig` or its mapping); default
        ``SafetyConfig()`` (floor at z = 0, 0.03 m margin,
        self-collision and torque limits on).
    urdf :
        URDF path or text with the collision geometry; default ``robot.urdf_text``.
    package_dirs :
        Folders searched for ``package://`` meshes.
    reference_q :
        The reference posture of the exclusion rule [rad], shape (nq,); default 0 clipped into
        the position limits.
    home_q :
        The posture the robot starts from (``controller.home``) [rad], shape (nq,): closer
        than the margin to the floor or an obstacle there is an input error.
    lower_margin :
        Lower the margin (halving it, not below :data:`MIN_LOWERED_CLEARANCE_M`) while a link
        pair is closer than it in every sampled posture, and say so in ``margin_note``;
        default: only when the config does not give ``clearance_m`` (the default margin).

    Raises
    ------
    ModelError
        If the collision geometry cannot be loaded or does not match the robot's joints.
    ConfigError
        If the environment or the margin cannot be kept whatever the robot does (a base inside
        the floor or an obstacle, a link closer than the margin in every sampled posture, a
        margin beyond the robot's reach), or the SRDF cannot be read.
    """
    if config is None:
        config = SafetyConfig()
    elif not isinstance(config, SafetyConfig):
        config = SafetyConfig.model_validate(config)
    return SafetyModel(
        robot,
        config,
        urdf=urdf,
        package_dirs=package_dirs,
        reference_q=reference_q,
        home_q=home_q,
        lower_margin=lower_margin,
    )


def clearances(safety: SafetyModel, q: npt.ArrayLike) -> FloatArray:
    """Signed link-pair distances [m], shape (n_samples, n_pairs).

    See :meth:`SafetyModel.clearances`.
    """
    return safety.clearances(q)
