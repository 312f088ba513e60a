"""The "Extending" examples of the docs work as written: a test registers them and runs them.

The code is read from the docs (the python block under "## Extending"), so the documentation
cannot drift from what works.
"""

import re

import numpy as np
import pytest
from conftest import REPO_ROOT

from ident.errors import ConfigError
from ident.excitation import registry
from ident.run.config import RunConfig
from ident.run.pipeline import run_pipeline
from ident.run.setup import prepare_run


def _extending_code(doc: str) -> str:
    text = (REPO_ROOT / "docs" / doc).read_text()
    section = text[text.index("## Extending") :]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


@pytest.fixture
def sines(monkeypatch):
    monkeypatch.setattr(registry, "FAMILIES", dict(registry.FAMILIES))  # undone after the test
    exec(_extending_code("your-robot.md"), {})
    assert "sines" in registry.FAMILIES


def _config(**excitation) -> RunConfig:
    return RunConfig.model_validate(
        {
            "robot": str(REPO_ROOT / "configs" / "paper6r.yaml"),
            "stage": {"moving": ["joint_4", "joint_5", "joint_6"]},
            "seed": 1,
            "excitation": {"family": "sines", "n_samples": 60, **excitation},
            "elites": {"n_particles": 6, "n_elites": 2, "maxiter": 20},
            "emupso": {"n_particles": 6, "maxiter": 3, "n_runs": 1, "n_report_elites": 1},
        }
    )


def test_the_documented_toy_family_runs_end_to_end(sines) -> None:
    setup = prepare_run(_config())
    assert setup.family.variable_names == ("amp[joint_4]", "amp[joint_5]", "amp[joint_6]")
    result = run_pipeline(setup)
    assert result.status == "complete"
    chosen = result.elites[0]
    # the design is a sine of the chosen amplitudes: q - held = x sin(w t)
    expected = chosen.x[None, :] * np.sin(2 * np.pi / 5.0 * chosen.t)[:, None]
    np.testing.assert_allclose(
        chosen.q[:, 3:] - setup.stage.held_positions[3:], expected, rtol=1e-12, atol=1e-12
    )
    assert chosen.estimates  # the stage's base parameters were identified from it


def test_the_toy_family_is_refused_with_a_clear_option_error(sines) -> None:
    with pytest.raises(ConfigError, match="excitation.options.*'sines'"):
        prepare_run(_config(options={"periods": 3}))


def test_registering_a_taken_name_is_refused() -> None:
    with pytest.raises(ValueError, match="registered already"):
        registry.register_family("joint_fourier", lambda robot, stage, options: None)
