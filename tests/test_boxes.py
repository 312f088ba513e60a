"""The paper's Cartesian families in a box sized to the workspace (configs/*-box.yaml).

They must load and prepare like the paper's configs, differ from them only in the search box
and the safety section, and their box must contain the paper's +-10 box and be wider.
"""

from pathlib import Path

import numpy as np
import pytest

from ident.run.setup import load_run

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


@pytest.mark.parametrize("stage", ["wrist", "arm"])
def test_box_configs_prepare_and_widen_the_papers_box(stage):
    paper = load_run(CONFIGS / f"{stage}.yaml")
    box = load_run(CONFIGS / f"{stage}-box.yaml")
    assert box.config.excitation.family == paper.config.excitation.family == f"paper_{stage}"
    assert box.family.variable_names == paper.family.variable_names
    for section in ("stage", "seed", "elites", "emupso", "measurement", "estimation", "quick"):
        assert getattr(box.config, section) == getattr(paper.config, section), section
    assert box.config.excitation.n_samples == paper.config.excitation.n_samples
    assert box.config.excitation.options == paper.config.excitation.options
    # every variable of the family is overridden
    assert set(box.config.excitation.bounds) == set(box.family.variable_names)
    low, high = box.bounds.T
    paper_low, paper_high = paper.bounds.T
    width, paper_width = high - low, paper_high - paper_low
    assert np.all(width > paper_width)
    assert np.all(width >= 4.0 * paper_width)  # several times the paper's spans
    # the circle radius sum(a0) and the Fourier amplitudes are centimetres, not millimetres
    names = list(box.family.variable_names)
    a = [names.index(n) for n in names if n.startswith("a0")]
    assert np.sum(high[a]) * box.family.length_unit >= 0.1  # m
    assert box.config.safety is not None
    assert box.config.safety.floor.enabled
    assert paper.config.safety is None


def test_the_wrist_box_stays_within_the_flange_sphere():
    """The wrist family's flange moves on a sphere of radius d6 about the wrist centre: the
    circle radius sum(a0) of the box stays inside it."""
    box = load_run(CONFIGS / "wrist-box.yaml")
    names = list(box.family.variable_names)
    a = [names.index(n) for n in names if n.startswith("a0")]
    radius = np.sum(box.bounds[a, 1]) * box.family.length_unit
    assert radius < box.family.geometry.d6
