"""Refinement of the identified model beyond the regressor: ``rollout_refinement`` (the MJCF's
joint frictionloss, damping and armature adjusted on MuJoCo rollouts, ``refinement: rollout``).
Import the submodules directly.
"""
