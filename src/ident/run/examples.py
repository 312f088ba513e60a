"""Minimal working examples of the run config's sections, for messages that teach.

A message about a missing section shows one of these (one line of flow-style YAML that the
loader accepts as it stands); a run that ends unsafe without a ``safety:`` section shows the
safety example. They are tested to load (tests/test_errors_teach.py), so they cannot drift
from the schema.
"""

from __future__ import annotations

__all__ = ["SECTION_EXAMPLES", "unsafe_run_advice"]

#: Top-level key -> a minimal section that loads, as one line of YAML.
SECTION_EXAMPLES: dict[str, str] = {
    "robot": "robot: {urdf: path/to/robot.urdf, acceleration_limits: 8.0}",
    "excitation": (
        "excitation: {family: joint_fourier, n_samples: 250, options: {n_harmonics: 4, "
        "base_frequency: 0.628, amplitude_bound: 0.05}}"
    ),
    "safety": (
        "safety: {floor: {enabled: true, z: 0.0}, clearance_m: 0.03, self_collision: true, "
        "torque_limits: true}"
    ),
}

_INIT = "or let 'ident init URDF -o CONFIG' write a whole config for your robot"


def missing_section_hint(key: str) -> str:
    """The text after "missing required key 'key'": a working example of the section."""
    example = SECTION_EXAMPLES.get(key)
    if example is None:
        return "add it"
    return f"add it, for example '{example}' ({_INIT})"


def unsafe_run_advice(has_safety_section: bool) -> str:
    """What to add when a run ends without a safe trajectory (empty if nothing to suggest).

    Without a ``safety:`` section the optimizer did not see the floor, the obstacles or the
    collisions (only the final check did): the section puts them into the design.
    """
    if has_safety_section:
        return ""
    return (
        "; the config has no safety: section, so the optimizer designed without the floor "
        "and collision constraints that the check then applied: add one, for example "
        f"'{SECTION_EXAMPLES['safety']}'"
    )
