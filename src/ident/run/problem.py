"""The excitation problem of a run config: what `ident run` optimizes, as one object.

:func:`excitation_problem` builds the stage's base parameters and the objective the pipeline
minimizes (eq. 15 on the scaled base Gram matrix of the stage's base columns, plus the
constraint penalties of the family and, with a ``safety:`` section, the clearance and torque
terms), with the family's bounds. :func:`ident.run.pipeline.run_pipeline` optimizes it, and
``benchmarks/bench_excitation.py`` compares optimizers on exactly the same problem.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.blas import one_blas_thread
from ident.excitation.objective import ExcitationObjective
from ident.run.results import StageInfo
from ident.run.setup import RunSetup
from ident.run.stage_info import build_stage_info

__all__ = ["ExcitationProblem", "excitation_problem"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class ExcitationProblem:
    """What the optimizer of a run minimizes.

    Attributes
    ----------
    stage_info :
        The stage's base parameters and true values.
    objective :
        The swarm objective ``(n_particles, n_vars) -> (n_particles,)``; its ``violation``
        is the constraint degree the initial elite search minimizes.
    bounds :
        The family's variable bounds, shape (n_vars, 2).
    """

    stage_info: StageInfo
    objective: ExcitationObjective
    bounds: FloatArray


def excitation_problem(setup: RunSetup, rng: np.random.Generator) -> ExcitationProblem:
    """The excitation problem of a prepared run config.

    Parameters
    ----------
    setup :
        :func:`ident.run.setup.prepare_run` of a run config.
    rng :
        Random states for the stage's numerical base parameters.
    """
    config, robot, stage, family = setup.config, setup.robot, setup.stage, setup.family
    with one_blas_thread():
        stage_info = build_stage_info(robot, stage, family, config.estimation.base_method, rng)
    # the objective scores the rigid-body base columns the estimate uses; the joint terms a
    # MuJoCo measurement adds to the estimate (friction, rotor inertia) are not designed for
    objective = ExcitationObjective(
        robot,
        stage,
        family,
        criterion=config.excitation.criterion,
        base_columns=[stage_info.columns[i] for i in stage_info.base.independent],
        safety=setup.safety if config.safety is not None else None,
    )
    return ExcitationProblem(stage_info, objective, np.asarray(family.bounds, dtype=float))
