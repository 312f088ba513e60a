"""What an identification is worth: the verdict and the checks shown with the result.

``verdict`` (:func:`~ident.identify.assessment.verdict.decide_verdict`,
``identify_verdict``, ``log_evidence``, ``truth_from_config``), ``metrics`` (error measures
against a known truth), ``sanity`` (the result's warnings, ``joint_units``),
``identifiability`` (which standard parameters the data see alone, in combination or not),
``model_intervals`` (the bootstrap of the written model's constrained fit),
``repeatability`` (the spread of several identifications of one robot) and ``rollout`` (open-loop
MuJoCo rollouts of the written MJCF over held-out windows of the log).

Above the estimation core, below ``friction`` (pyproject.toml's ``[tool.importlinter]``);
import the submodules directly.
"""
