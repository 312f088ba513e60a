"""Which reported trajectories a robot may run: the dense safety check and ``trajectory.csv``.

Every reported elite is checked at the controller's rate (at least 1 kHz) against the robot's
own links, the floor, the config's obstacles, and the position, velocity, acceleration and
torque limits (:func:`ident.excitation.check.check_trajectory`, on the family's closed form at
the dense times). The best elite that passes becomes the executable trajectory: an approach
from the home posture, the excitation periods and the return, at the controller's rate,
checked again as a whole, and, for each ``controller.export`` target with published limits
(libfranka, UR), by that export's own check (:func:`ident.run.exports.run_exports.
check_export_targets`: libfranka's jerk included). A trajectory that fails is never reported
as usable; when none passes, the run says which pair or limit, when and by how much, and
writes no ``trajectory.csv``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.excitation.check import SafetyReport, check_trajectory, dense_family_states
from ident.excitation.executable import executable_trajectory
from ident.excitation.safety import SafetyModel
from ident.run.config import RunConfig
from ident.run.exports.run_exports import check_export_targets
from ident.trajectory import JointTrajectory

__all__ = ["ExecutablePlan", "check_elites", "plan_executable", "retry_margin"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class ExecutablePlan:
    """The trajectory a controller runs, or why there is none.

    Attributes
    ----------
    elite :
        1-based rank of the elite it executes, or None.
    trajectory :
        Approach + periods + return at the controller's rate, or None.
    report :
        Its dense safety check, or None.
    message :
        One line: what was chosen, or why nothing is usable.
    """

    elite: int | None
    trajectory: JointTrajectory | None
    report: SafetyReport | None
    message: str

    @property
    def usable(self) -> bool:
        """True when a checked trajectory is ready for the controller."""
        return self.report is not None and self.report.usable


def check_elites(
    config: RunConfig, robot: Any, family: Any, safety: SafetyModel, xs: FloatArray
) -> list[SafetyReport]:
    """The dense safety check of every design in ``xs`` (shape (n, n_vars)), one period each."""
    rate = max(safety.config.check_rate_hz, config.controller.rate_hz)
    return [
        check_trajectory(robot, safety, *_period_states(family, x, rate), rate_hz=rate)
        for x in np.atleast_2d(xs)
    ]


def _period_states(
    family: Any, x: FloatArray, rate_hz: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """One period at ``rate_hz``: the family's closed form where it offers ``with_samples``
    (exact), else its samples, which the check interpolates (cubic Hermite)."""
    if hasattr(family, "with_samples"):
        return dense_family_states(family, x, rate_hz)
    batch = family.trajectories(np.atleast_2d(x))
    return batch.t, batch.q[0], batch.dq[0], batch.ddq[0]


def plan_executable(
    config: RunConfig,
    robot: Any,
    family: Any,
    safety: SafetyModel,
    xs: FloatArray,
    reports: list[SafetyReport],
) -> ExecutablePlan:
    """The executable trajectory of the best elite whose excitation passed the dense check."""
    ctl = config.controller
    rate = max(safety.config.check_rate_hz, ctl.rate_hz)
    tried = []
    for rank, (x, report) in enumerate(zip(np.atleast_2d(xs), reports, strict=True), start=1):
        if not report.usable:
            continue
        if not hasattr(family, "with_samples"):
            tried.append(f"elite {rank}: the family has no closed form for the controller's rate")
            continue
        start = np.asarray(family.trajectories(x[None, :]).q[0, 0], dtype=float)
        home = start if ctl.home is None else np.asarray(ctl.home, dtype=float)
        trajectory = executable_trajectory(
            family, x, home, rate_hz=ctl.rate_hz, n_periods=ctl.n_periods
        )
        full = check_trajectory(
            robot, safety, trajectory.t, trajectory.q, trajectory.dq, trajectory.ddq, rate_hz=rate
        )
        refusal = None
        if full.usable and ctl.export:  # the export targets' own limits (libfranka's jerk)
            refusal = check_export_targets(
                ctl.export, trajectory, str(robot.urdf_text), getattr(robot, "ddq_max", None)
            )
        if full.usable and refusal is None:
            return ExecutablePlan(
                rank,
                trajectory,
                full,
                f"elite {rank}: approach, {ctl.n_periods} period(s) and return at "
                f"{ctl.rate_hz:g} Hz, {full.summary()}",
            )
        if refusal is not None:
            tried.append(f"elite {rank}: refused by controller.export: {refusal}")
            continue
        tried.append(f"elite {rank}'s approach or return: {full.summary()}")
    if not tried:
        worst = reports[0].summary() if reports else "no elite"
        return ExecutablePlan(None, None, None, f"no elite trajectory is safe; elite 1 is {worst}")
    return ExecutablePlan(None, None, None, "no safe executable trajectory: " + "; ".join(tried))


def retry_margin(reports: list[SafetyReport], clearance_m: float) -> float | None:
    """The optimizer's margin for a second optimization when no elite passed the check.

    Only when every elite failed on clearances alone and by at most half the margin (1 mm
    when the margin is 0): the cheap term kept the margin at its samples, the certificate,
    between them too, found the elites a little inside. Then the
    certificate's margin plus twice the worst shortfall, and at least a quarter of the margin
    (1 mm when the margin is 0) more [m]. ``None`` when an elite passed, there are no
    reports, a limit other than a clearance failed or an elite is deeper inside (a wider
    margin would not help).
    """
    if not reports or any(r.usable for r in reports):
        return None
    failures = [c for r in reports for c in r.failures()]
    if not failures or any(c.kind != "clearance" for c in failures):
        return None
    shortfall = max(float(c.excess) for c in failures)
    if not shortfall <= max(0.5 * clearance_m, 1e-3):  # deeper: the motion itself is wrong
        return None
    return clearance_m + max(2.0 * shortfall, 0.25 * clearance_m, 1e-3 if clearance_m == 0 else 0)
