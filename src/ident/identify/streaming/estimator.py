"""The streaming payload estimator: samples in, a tracked payload and detected changes out.

Every block of raw samples (any length) goes through the causal differentiator
(:mod:`ident.identify.streaming.filters`); its rows are the payload problem's rows
(:class:`~ident.identify.payload.payload_rows.PayloadColumns`: the last body's 10 columns, the
friction / rotor-inertia columns of ``model:``, the arm's known torque moved to the right-hand
side), a joint's row left out below ``velocity_threshold`` (the Coulomb sign is undefined there).
Rows are summed in blocks of ``block_rows`` rows (:class:`~ident.identify.streaming.normal.
NormalEquations`); the last ``test_blocks`` blocks are the change test's window
(:mod:`ident.identify.streaming.detect`), and a block that leaves the window joins the
reference sums with exponential forgetting (memory ``memory_s``).

**Why exponential forgetting plus a short ring of blocks.** Exponential forgetting keeps the
estimate's cost and memory constant (one ``p x p`` sum per joint) and never subtracts (a sliding
window's downdate loses precision over hours); the ring of the last blocks, kept exactly, gives
the change test rows the reference has not seen and, after an alarm, the rows since the change.

**On a schedule** (``solve_every_s``) the tracked payload is solved from reference + window:
weighted least squares with its sandwich covariance, then, with ``consistent``, the registry's
``lmi`` estimate on the same sums (pseudo-inertia positive definite, friction >= 0; the
intervals stay those of the least squares, as ``ident payload``'s).

**After an alarm** the rows before the onset (the reference) and after it are solved as one
problem whose payload (or friction) differs between the two (:func:`~ident.identify.streaming.
normal.split_equations`) once ``after_s`` seconds of rows follow the onset; which of the two
changed is the split with the more significant likelihood ratio; with ``consistent`` the
change's estimate is the ``lmi`` one on the same epochs, its intervals from
``interval_resolves`` re-solves of the same LMI on rows drawn about it (a parametric bootstrap:
:meth:`StreamingEstimator._change_point`). The rows after the change then become the new
reference.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from scipy.stats import chi2

from ident.dynamics.chain import KinematicChain
from ident.dynamics.friction import ExtraTerms, extra_names
from ident.errors import NotIdentifiable
from ident.identify.assessment.model_intervals import parametric_resolves, spread_about
from ident.identify.estimation.consistency import pseudo_inertia_min_eigenvalue
from ident.identify.estimation.estimate import least_squares_reduced
from ident.identify.estimation.uncertainty import z_value
from ident.identify.estimators import get_repeated_estimator
from ident.identify.estimators.problem import EstimationProblem
from ident.identify.estimators.registry import Estimator
from ident.identify.payload.controller_load import (
    LoadLimits,
    check_load,
    franka_set_load,
    ur_set_payload,
)
from ident.identify.payload.payload import PAYLOAD_NAMES, consistent_problem, in_reporting_frame
from ident.identify.payload.payload_rows import PayloadColumns
from ident.identify.streaming import detect
from ident.identify.streaming.filters import CausalDifferentiator
from ident.identify.streaming.normal import (
    Epochs,
    NormalEquations,
    Solution,
    reduced_observations,
)

__all__ = ["ChangeEvent", "StreamEstimate", "StreamSettings", "StreamingEstimator"]

FloatArray = npt.NDArray[np.float64]

#: Change-free windows whose variance ratios set ``kappa`` (a few minutes of blocks).
KAPPA_WINDOWS = 2000


@dataclass(frozen=True)
class StreamSettings:
    """How the stream is estimated (SI; the ``stream:`` section of the config).

    ``window``/``order``: the causal Savitzky-Golay fit (odd samples, degree); ``block_rows``:
    rows per block; ``memory_s``: forgetting time constant [s] (``inf``: none);
    ``test_blocks``: blocks of the change test's window; ``false_alarm_per_hour``: the stated
    false-alarm rate; ``after_s``: seconds of rows after a change before its estimate;
    ``solve_every_s``: schedule of the tracked solve; ``warmup_s``: seconds of rows in the
    reference before the test is armed; ``velocity_threshold``: [rad/s];
    ``consistent``: the LMI on the schedule; ``level``: the intervals' confidence;
    ``interval_resolves``: re-solves of the change's consistent estimate for its intervals
    (a parametric bootstrap; fewer than 2: the least squares' intervals).
    """

    window: int = 41
    order: int = 3
    block_rows: int = 4
    memory_s: float = 60.0
    test_blocks: int = 4
    false_alarm_per_hour: float = 0.01
    after_s: float = 1.0
    solve_every_s: float = 5.0
    warmup_s: float = 10.0
    velocity_threshold: float = 0.15
    consistent: bool = True
    level: float = 0.95
    interval_resolves: int = 40


@dataclass(frozen=True, eq=False)
class StreamEstimate:
    """The payload at time ``t`` [s] of the log (SI, ``link``'s frame for ``com`` and
    ``inertia_com``); ``covariance`` (p, p) of ``x`` (payload (10,) then ``extras``), the one
    the intervals come from (``interval_method``)."""

    t: float
    x: FloatArray
    covariance: FloatArray
    names: tuple[str, ...]
    mass: float
    com: FloatArray
    com_std: FloatArray
    inertia_com: FloatArray
    method: str
    n_eff: float
    sigma: FloatArray
    level: float = 0.95
    interval_method: str = "least squares"

    @property
    def mass_std(self) -> float:
        """Standard deviation of the mass [kg]."""
        return float(np.sqrt(max(self.covariance[0, 0], 0.0)))

    def mass_interval(self) -> tuple[float, float]:
        """The mass's interval at ``level`` [kg]."""
        z = z_value(self.level)
        return self.mass - z * self.mass_std, self.mass + z * self.mass_std

    def summary(self) -> dict:
        """JSON-ready values (SI)."""
        z = z_value(self.level)
        std = np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))
        return {
            "t_s": self.t,
            "method": self.method,
            "mass_kg": self.mass,
            "mass_std_kg": self.mass_std,
            "mass_interval_kg": list(self.mass_interval()),
            "com_m": self.com.tolist(),
            "com_interval_m": np.column_stack(
                [self.com - z * self.com_std, self.com + z * self.com_std]
            ).tolist(),
            "inertia_com_kgm2": self.inertia_com.tolist(),
            "pseudo_inertia_min_eigenvalue": float(pseudo_inertia_min_eigenvalue(self.x[:10])),
            "parameters": dict(zip(self.names, self.x.tolist(), strict=True)),
            "parameters_std": dict(zip(self.names, std.tolist(), strict=True)),
            "effective_rows": self.n_eff,
            "noise_std_per_joint": self.sigma.tolist(),
            "interval_level": self.level,
            "interval_method": self.interval_method,
        }


@dataclass(frozen=True, eq=False)
class ChangeEvent:
    """A detected change: when (``t_alarm``, ``t_onset`` [s]), the test (``statistic`` against
    ``threshold``, ``dof``), what changed (``kind``: ``payload`` or ``friction``; ``log_p``: the
    log p-value of each split), and the estimates before and after it."""

    t_alarm: float
    t_onset: float
    statistic: float
    threshold: float
    dof: int
    kind: str
    log_p: dict[str, float]
    before: StreamEstimate | None
    after: StreamEstimate

    def summary(self, limits: LoadLimits) -> dict:
        """JSON-ready (SI): the test, the estimates, and the new payload in the controllers'
        formats with its checks against ``limits``
        (:mod:`ident.identify.payload.controller_load`)."""
        a = self.after
        checks = check_load(a.mass, a.com, a.inertia_com, a.mass_interval(), limits)
        return {
            "kind": self.kind,
            "t_alarm_s": self.t_alarm,
            "t_onset_s": self.t_onset,
            "detection_delay_s": self.t_alarm - self.t_onset,
            "statistic": self.statistic,
            "threshold": self.threshold,
            "dof": self.dof,
            "log_p_value": self.log_p,
            "before": None if self.before is None else self.before.summary(),
            "after": a.summary(),
            "controllers": {
                "ur": ur_set_payload(a.mass, a.com, a.inertia_com),
                "franka": franka_set_load(a.mass, a.com, a.inertia_com),
            },
            "limit_checks": [vars(c) for c in checks],
        }


@dataclass
class _Alarm:
    """An alarm waiting for ``after_s`` of rows: the sums before and after the onset."""

    t_alarm: float
    t_onset: float
    statistic: float
    threshold: float
    dof: int
    before: Solution
    pre: Epochs
    post: NormalEquations
    post_blocks: int = 0


@dataclass
class _State:
    """What the estimator carries from block to block."""

    ref: Epochs
    block: NormalEquations
    ring: deque = field(default_factory=deque)
    ref_solution: Solution | None = None
    ref_dirty: bool = True
    alarm: _Alarm | None = None
    next_solve: float = 0.0
    ref_blocks: int = 0
    ratios: deque = field(default_factory=lambda: deque(maxlen=KAPPA_WINDOWS))


class StreamingEstimator:
    """Feeds on ``(t, q, tau)`` blocks (:meth:`push`); tracked estimates in :attr:`timeline`,
    changes in :attr:`events` (module docstring).

    Parameters
    ----------
    chain, terms, theta_arm :
        The arm's chain, the extra columns (friction...) and its known standard parameters
        (10 n_bodies,), as for :class:`~ident.identify.payload.payload_rows.PayloadColumns`.
    rate_hz :
        The samples' rate [Hz].
    settings :
        :class:`StreamSettings`.
    placement, link :
        Pose of the reporting frame in the last joint's frame, and its name.
    """

    def __init__(
        self,
        chain: KinematicChain,
        terms: ExtraTerms,
        theta_arm: FloatArray,
        rate_hz: float,
        settings: StreamSettings,
        *,
        placement: pin.SE3 | None = None,
        link: str = "last link",
    ) -> None:
        self.columns = PayloadColumns(chain, terms, theta_arm)
        self.extra = extra_names(terms)
        self.names = PAYLOAD_NAMES + self.extra
        self.nv, self.p = chain.nv, 10 + len(self.extra)
        self.s = settings
        self.rate_hz = rate_hz
        self.filter = CausalDifferentiator(chain.nv, rate_hz, settings.window, settings.order)
        self.block_s = settings.block_rows * settings.window / rate_hz
        self.gamma = float(np.exp(-self.block_s / settings.memory_s))
        self.alpha = detect.per_test_alpha(settings.false_alarm_per_hour, self.block_s)
        self.placement, self.link = placement, link
        self.timeline: list[StreamEstimate] = []
        self.events: list[ChangeEvent] = []
        self.n_tests = 0
        self.max_ratio = 0.0  # largest statistic / threshold of a test without alarm
        self.solve_cpu_s = 0.0  # CPU time of the scheduled solves and the changes' [s]
        self.change_cpu_s = 0.0  # of which the changes' estimates (and their intervals) [s]
        self._st = _State(ref=Epochs([self._empty()], []), block=self._empty(),
                          next_solve=settings.solve_every_s)  # fmt: skip
        self._rows_in_block = 0

    def _empty(self) -> NormalEquations:
        return NormalEquations(self.nv, self.p)

    def restart_filter(self) -> None:
        """A gap in the samples: the causal filters start again (their first outputs wait)."""
        self.filter.reset()

    def push(self, t: FloatArray, q: FloatArray, tau: FloatArray) -> list[ChangeEvent]:
        """Feed samples ``t`` (n,) [s], ``q`` (n, nv) [rad], ``tau`` (n, nv) [N*m]; the changes
        whose estimate this block completed."""
        index, qf, dqf, ddqf, tauf = self.filter.push(q, tau)
        if index.size == 0:
            return []
        cols = self.columns(qf, dqf, ddqf)
        X = cols[:, :, :-1]
        y = tauf - cols[:, :, -1]
        keep = np.abs(dqf) >= self.s.velocity_threshold
        t_rows = t[index] - self.filter.delay / self.rate_hz
        new: list[ChangeEvent] = []
        k = 0
        while k < index.size:
            take = min(self.s.block_rows - self._rows_in_block, index.size - k)
            self._st.block.add_rows(X[k : k + take], y[k : k + take], keep[k : k + take])
            self._rows_in_block += take
            k += take
            if self._rows_in_block == self.s.block_rows:
                event = self._close_block(float(t_rows[k - 1]))
                if event is not None:
                    new.append(event)
        self.events.extend(new)
        return new

    def _close_block(self, t: float) -> ChangeEvent | None:
        """A full block: into the alarm's rows, or the ring (and the test, the schedule)."""
        st = self._st
        block, st.block, self._rows_in_block = st.block, self._empty(), 0
        if st.alarm is not None:
            st.alarm.post.iadd(block)
            st.alarm.post_blocks += 1
            if st.alarm.post_blocks * self.block_s >= self.s.after_s - 1e-9:
                return self._estimate_change(t)
            return None
        st.ring.append(block)
        if len(st.ring) > self.s.test_blocks:
            st.ref.add(st.ring.popleft(), self.gamma)
            st.ref_blocks += 1
            # re-solved every test_blocks blocks: an older reference holds no row of the
            # window either, and the solve is the update's largest cost
            st.ref_dirty = st.ref_dirty or st.ref_blocks % self.s.test_blocks == 0
        if len(st.ring) == self.s.test_blocks:
            self._test(t)
        if st.alarm is None and t >= st.next_solve:
            st.next_solve = t + self.s.solve_every_s
            self._track(t)
        return None

    @property
    def kappa(self) -> float:
        """The score covariance's model-error factor (:mod:`ident.identify.streaming.detect`):
        the 95th percentile of the last change-free windows' variance ratios, at least 1."""
        ratios = [r for r in self._st.ratios if np.isfinite(r)]
        return max(1.0, float(np.percentile(ratios, 95))) if ratios else 1.0

    def _reference(self) -> Solution | None:
        """The reference solution (cached until the reference sums change); None before the
        rows determine every unknown."""
        st = self._st
        if st.ref_dirty:
            st.ref_dirty = False
            try:
                st.ref_solution = st.ref.solve()
            except NotIdentifiable:
                st.ref_solution = None
        return st.ref_solution

    def _test(self, t: float) -> None:
        """The GLR test of the ring against the reference; an alarm splits the ring."""
        st = self._st
        if st.ref_blocks * self.block_s < self.s.warmup_s:
            return
        ref = self._reference()
        if ref is None:
            return
        window = self._empty()
        for b in st.ring:
            window.iadd(b)
        T, r = detect.glr_statistic(window, ref)
        self.n_tests += 1
        if r == 0:
            return
        threshold = detect.alarm_threshold(self.alpha, r)
        if T > threshold:  # kappa >= 1 can only lower it: computed when it matters
            T /= self.kappa
        self.max_ratio = max(self.max_ratio, T / threshold)
        if T <= threshold:
            st.ratios.append(detect.variance_ratio(window, ref))
            return
        blocks = list(st.ring)
        s = detect.onset_block(blocks, ref, kappa=self.kappa)
        # the change lies in block s (or, for a small one, before it): the rows before are the
        # reference alone, the rows after are those after block s; the window's others are
        # left out, so neither side holds rows of the other
        post = self._empty()
        for b in blocks[s + 1 :]:
            post.iadd(b)
        st.alarm = _Alarm(t, t - (len(blocks) - s) * self.block_s, T, threshold, r, ref,
                          st.ref.copy(), post, post_blocks=len(blocks) - s - 1)  # fmt: skip
        st.ring.clear()

    def _estimate_change(self, t: float) -> ChangeEvent | None:
        """The split problem of the alarm's rows (module docstring); the rows after the change
        become the reference."""
        st = self._st
        alarm = st.alarm
        assert alarm is not None
        st.alarm = None
        st.ring.clear()
        st.ref_dirty = True
        try:
            kind, st.ref, sol, log_p = self._split_fit(alarm.pre, alarm.post)
        except NotIdentifiable:  # too few rows after the change: they start a new reference
            st.ref = Epochs([alarm.post], [])
            return None
        before = self._estimate(alarm.t_onset, alarm.before.x, alarm.before.covariance,
                                "wls", alarm.before)  # fmt: skip
        c0 = time.process_time()
        x, cov, method, intervals = self._change_point(st.ref, sol)
        self.change_cpu_s += time.process_time() - c0
        self.solve_cpu_s += time.process_time() - c0
        after = self._estimate(t, x, cov, method, sol, intervals)
        return ChangeEvent(alarm.t_alarm, alarm.t_onset, alarm.statistic, alarm.threshold,
                           alarm.dof, kind, log_p, before, after)  # fmt: skip

    def _split_fit(
        self, pre: Epochs, post: NormalEquations
    ) -> tuple[str, Epochs, Solution, dict[str, float]]:
        """Which split explains the change best: ``(kind, the epochs with the rows after the
        change as the new one, their solution, log p-value per kind)``."""
        both = pre.copy()
        both.add(post)
        none = both.solve()
        v = 1.0 / none.sigma**2
        fits, log_p = {}, {}
        # only the columns the rows after the change excite can change (a joint that stood
        # still since has no new friction)
        excited = np.einsum("jpp->p", post.A) > 0.0
        kinds = {"payload": np.arange(10), "friction": np.flatnonzero(excited[10:]) + 10}
        for kind, split in kinds.items():
            if split.size == 0:
                continue
            epochs = Epochs([e.copy() for e in pre.epochs] + [post.copy()], [*pre.splits, split])
            try:
                sol = epochs.solve()
            except NotIdentifiable:
                continue
            lr = float(np.sum(v * (none.residual_ss - sol.residual_ss)))
            fits[kind], log_p[kind] = (epochs, sol), float(chi2.logsf(max(lr, 0.0), split.size))
        if not log_p:
            raise NotIdentifiable("the rows after the change determine neither split.")
        kind = min(log_p, key=log_p.__getitem__)
        epochs, sol = fits[kind]
        return kind, epochs, sol, log_p

    def _track(self, t: float) -> None:
        """The scheduled solve of reference + window (and its consistent estimate)."""
        st = self._st
        c0 = time.process_time()
        current = st.ref.copy()
        for b in st.ring:
            current.add(b, self.gamma)
        try:
            sol = current.solve()
        except NotIdentifiable:
            return
        x, method = self._point(current, sol)
        self.timeline.append(self._estimate(t, x, sol.covariance, method, sol))
        self.solve_cpu_s += time.process_time() - c0

    def _point(self, epochs: Epochs, sol: Solution) -> tuple[FloatArray, str]:
        """The estimate of ``epochs``' current parameters (p,) and its method: with
        ``consistent`` the LMI's on the same rows, else (or when it fails) the WLS ``sol``.

        Why after a change too: 1 s of rows can leave one direction of the new centre of mass
        barely excited (its three components' errors then nearly +-1 correlated); the WLS
        wanders along it, the payload's realizability bounds it."""
        if self.s.consistent:
            try:
                return self._consistent(epochs), "lmi"
            except NotIdentifiable:
                pass  # the WLS stands, named by its method
        return sol.x, "wls"

    def _consistent(self, epochs: Epochs) -> FloatArray:
        """The registry's ``lmi`` estimate (the current payload realizable, friction >= 0) on
        every epoch's rows, the current parameters (p,) (:meth:`_consistent_fit`)."""
        return self._consistent_fit(epochs, get_repeated_estimator("lmi"))[0][: self.p]

    def _change_point(
        self, epochs: Epochs, sol: Solution
    ) -> tuple[FloatArray, FloatArray, str, str]:
        """The change's estimate (p,), the covariance (p, p) its intervals come from, its
        method and the intervals' method.

        With ``consistent``, the LMI's estimate with a parametric bootstrap of its re-solve
        (:func:`~ident.identify.assessment.model_intervals.parametric_resolves`): the rows drawn
        as if the consistent estimate were the truth, each draw solved again by the same LMI,
        the covariance the re-estimates' second moment about the estimate (their spread and
        bias). Why not the least squares' covariance: where the constraints bind (1 s of rows
        leaves a direction of the centre of mass barely excited, a realizable payload cannot
        wander along it) the consistent estimate's error is smaller than the least squares'
        (simulated UR5, 100 changes: intervals 0.71 times as wide on the centre of mass, 92.5 %
        of 400 holding the truth; docs/lifetime.md, "Measured")."""
        if not self.s.consistent:
            return sol.x, sol.covariance, "wls", "least squares"
        resolver = get_repeated_estimator("lmi")  # one program for the estimate and re-solves
        try:
            x, problem, eq = self._consistent_fit(epochs, resolver)
        except NotIdentifiable:
            return sol.x, sol.covariance, "wls", "least squares"
        n = self.s.interval_resolves
        if n < 2:
            return x[: self.p], sol.covariance, "lmi", "least squares"
        assert problem.weights is not None
        w = problem.weights**2  # the LMI's joint weights 1 / s_j^2
        noise = np.nan_to_num(sol.sigma**2)  # the rows' noise variance per joint
        A = np.einsum("j,jpq->pq", w, eq.A)
        B = np.einsum("j,jpq->pq", w * w * noise, eq.B)
        samples = parametric_resolves(resolver, problem, A, B, x, n_boot=n,
                                      rows=float(eq.sw.sum()), rng=len(self.events))  # fmt: skip
        if samples.shape[0] < 2:  # named: the re-solves failed, the least squares stand
            return x[: self.p], sol.covariance, "lmi", f"least squares ({n} re-solves failed)"
        cov = spread_about(samples[:, : self.p], x[: self.p])
        return x[: self.p], cov, "lmi", f"consistent re-solves ({samples.shape[0]} of {n})"

    def _consistent_fit(
        self, epochs: Epochs, resolver: Estimator
    ) -> tuple[FloatArray, EstimationProblem, NormalEquations]:
        """The ``lmi`` estimate of every extended unknown (q,), its problem and the extended
        normal equations (in its column order). The extended unknowns are reordered so that
        the current parameters come first, the payload's 10 (the LMI's body) then the extras;
        the older epochs' replaced unknowns are free.

        Raises
        ------
        NotIdentifiable
            When the rows do not determine every unknown, or the LMI fails."""
        eq, M = epochs.extended()
        q = eq.p
        current = [int(np.argmax(M[i])) for i in range(self.p)]
        order = current + [k for k in range(q) if k not in current]
        P = np.eye(q)[:, order]  # extended unknowns in the new order
        eq.A = P.T @ eq.A @ P
        eq.B = P.T @ eq.B @ P
        eq.c = eq.c @ P
        names = self.names + tuple(f"replaced{k}" for k in range(q - self.p))
        red = reduced_observations(eq)
        wls = least_squares_reduced(red, names, method="wls")
        problem = consistent_problem(red, wls, self.extra, names)
        fit = resolver(problem)
        if not fit.success or fit.theta is None:
            raise NotIdentifiable(f"the consistent estimate failed: {fit.message}")
        return np.asarray(fit.theta, dtype=float), problem, eq

    def _estimate(
        self, t: float, x: FloatArray, cov: FloatArray, method: str, sol: Solution,
        intervals: str = "least squares",
    ) -> StreamEstimate:  # fmt: skip
        """A :class:`StreamEstimate` of ``x`` (p,) with covariance ``cov`` in ``link``'s frame."""
        mass, com, com_std, inertia = in_reporting_frame(x[:10], cov[:10, :10], self.placement)
        return StreamEstimate(t, np.asarray(x, dtype=float), cov, self.names, mass, com, com_std,
                              inertia, method, sol.n_eff, sol.sigma, self.s.level,
                              intervals)  # fmt: skip
