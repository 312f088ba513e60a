from pathlib import Path

import pytest
import yaml

from ident.errors import ConfigError, IdentError
from ident.run.config import RunConfig, load_run_config
from ident.run.setup import load_run

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def _write(tmp_path, text, robot=True):
    if robot:
        (tmp_path / "robot.yaml").write_text("placeholder: true\n")
    path = tmp_path / "run.yaml"
    path.write_text(text)
    return path


MINIMAL = "robot: robot.yaml\nstage: wrist\nexcitation: {family: paper_wrist}\n"


def test_defaults_are_the_papers_procedure_but_one_long_run(tmp_path):
    # the paper's elite search and swarm; its budget (5 x 31 x 20 = 3100 evaluations) spent
    # in one run of 150 iterations (3020), the split docs/optimizers.md measured better
    config = load_run_config(_write(tmp_path, MINIMAL))
    assert (config.elites.n_particles, config.elites.n_elites) == (10, 5)
    assert (config.emupso.n_particles, config.emupso.maxiter) == (20, 150)
    assert (config.emupso.stagnation, config.emupso.n_runs) == (10, 1)
    assert config.optimizer == "pso"
    assert config.estimation.methods == ["ols", "wls"]
    assert config.name == "run"  # the file stem
    assert config.robot.description == (tmp_path / "robot.yaml").resolve()
    assert config.stage == "wrist"
    assert (
        RunConfig.model_validate(
            {"robot": "r.urdf", "excitation": {"family": "joint_fourier"}}
        ).stage
        == "whole"
    )


@pytest.mark.parametrize("name", ["wrist", "arm"])
def test_shipped_configs_are_the_papers_settings(name):
    raw = yaml.safe_load((CONFIGS / f"{name}.yaml").read_text())
    config = RunConfig.model_validate(raw)  # robot existence checked by load_run_config
    assert config.stage == name
    assert config.excitation.family == f"paper_{name}"
    assert config.elites.n_particles == 10
    assert config.elites.n_elites == 5
    assert config.emupso.n_particles == 20
    assert config.emupso.maxiter == 30
    assert config.emupso.stagnation == 10
    assert config.emupso.n_runs == 5
    quick = config.quick_version()
    assert quick.emupso.n_particles < 20
    assert quick.emupso.n_runs < 5
    assert quick.excitation.n_samples < config.excitation.n_samples
    assert quick.seed == config.seed
    assert quick.stage == config.stage


def test_unknown_key_suggests_closest(tmp_path):
    path = _write(tmp_path, MINIMAL + "emupso: {n_particle: 3}\n")
    with pytest.raises(ConfigError, match=r"emupso.n_particle.*did you mean 'n_particles'"):
        load_run_config(path)


def test_missing_robot_names_key_and_path(tmp_path):
    path = _write(tmp_path, MINIMAL, robot=False)
    with pytest.raises(
        ConfigError, match=r"robot.description = 'robot.yaml' resolves to .*robot.yaml"
    ):
        load_run_config(path)


def test_family_must_match_stage(tmp_path):
    robot = CONFIGS / "paper6r.yaml"
    path = _write(tmp_path, f"robot: {robot}\nstage: arm\nexcitation: {{family: paper_wrist}}\n")
    with pytest.raises(ConfigError, match="use stage: wrist, or joint_fourier"):
        load_run(path)


def test_unknown_family_suggests_the_closest(tmp_path):
    path = _write(tmp_path, MINIMAL.replace("paper_wrist", "joint_fourrier"))
    with pytest.raises(ConfigError, match="did you mean 'joint_fourier'"):
        load_run_config(path)


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        ("measurement: {torque_noise_std: -1.0}\n", "torque_noise_std"),
        ("measurement: {torque_noise_std: [0.1, -2]}\n", "torque_noise_std"),
        ("emupso: {n_runs: 0}\n", "emupso.n_runs"),
        ("estimation: {methods: []}\n", "estimation.methods"),
        ("estimation: {methods: [gls]}\n", r"estimation.methods\[0\]"),
    ],
)
def test_bad_values_name_the_key(tmp_path, extra, match):
    with pytest.raises(ConfigError, match=match):
        load_run_config(_write(tmp_path, MINIMAL + extra))


def test_bounds_must_be_ordered(tmp_path):
    text = MINIMAL.replace("{family: paper_wrist}", "{family: paper_wrist, bounds: {a1: [2, 1]}}")
    with pytest.raises(ConfigError, match="low < high"):
        load_run_config(_write(tmp_path, text))


@pytest.mark.parametrize("pair", ["[.nan, 1]", "[0, .inf]", "[-.inf, 0]"])
def test_bounds_must_be_finite_and_name_their_key(tmp_path, pair):
    text = MINIMAL.replace(
        "{family: paper_wrist}", f"{{family: paper_wrist, bounds: {{'a0(1)': {pair}}}}}"
    )
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError, match=r"excitation\.bounds\.a0\(1\).*finite") as info:
        load_run_config(path)
    assert str(info.value).startswith(f"{path}: ")


def _paper_config(tmp_path, bounds):
    robot = CONFIGS / "paper6r.yaml"
    return _write(
        tmp_path,
        f"robot: {robot}\nstage: wrist\nexcitation: {{family: paper_wrist, bounds: {bounds}}}\n",
        robot=False,
    )


def test_bound_names_are_checked_before_the_run_with_the_closest_name(tmp_path):
    good = load_run(_paper_config(tmp_path, "{'a0(2)': [-3, 3], e0: [0, 1]}"))
    assert good.config.excitation.bounds == {"a0(2)": (-3.0, 3.0), "e0": (0.0, 1.0)}
    path = _paper_config(tmp_path, "{'a0(1)': [-3, 3], 'b0(4)': [0, 1]}")
    with pytest.raises(ConfigError) as info:
        load_run(path)
    message = str(info.value)
    assert message.startswith(f"{path}: unknown key 'excitation.bounds.b0(4)'")
    assert "did you mean 'b0(3)'?" in message
    assert message.endswith("Variables: a0(1), a0(2), a0(3), b0(1), b0(2), b0(3), c0, d0, e0.")
    assert "\n" not in message


def test_with_seed(tmp_path):
    config = load_run_config(_write(tmp_path, MINIMAL))
    assert config.with_seed(7).seed == 7
    with pytest.raises(ConfigError, match="seed"):
        config.with_seed(-1)


@pytest.mark.parametrize("name", ["wrist", "arm"])
def test_fourier_configs_use_the_papers_procedure_and_noise(name):
    paper = load_run_config(CONFIGS / f"{name}.yaml")
    fourier = load_run_config(CONFIGS / f"{name}-fourier.yaml")
    assert fourier.stage == name
    assert fourier.excitation.family == "joint_fourier"
    assert fourier.excitation.n_samples == paper.excitation.n_samples
    for section in ("elites", "emupso", "measurement", "estimation", "quick", "seed"):
        assert getattr(fourier, section) == getattr(paper, section), section
    # beyond the paper: the optimization keeps clear of the floor (the paper's does not)
    assert paper.safety is None
    assert fourier.safety is not None
    assert fourier.safety.floor.enabled
    assert fourier.safety.floor.z == 0.0
    assert fourier.safety.clearance_m == 0.03


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (
            "measurement: {encoder_counts_per_rev: 4096, filter_cutoff_hz: 30.0}\n",
            "filter_cutoff_hz = 30 Hz is at or above the Nyquist frequency 25 Hz",
        ),
        ("measurement: {torque_noise_std: [0.1, 0.1]}\n", "torque_noise_std has 2 values"),
        ("stage: arm\n", "paper_wrist.*use stage: wrist"),
        ("stage: {moving: [joint_9]}\n", "stage.moving: 'joint_9' is not a joint"),
    ],
)
def test_settings_that_need_the_robot_are_checked_before_the_run(tmp_path, extra, match):
    robot = CONFIGS / "paper6r.yaml"
    text = f"robot: {robot}\nexcitation: {{family: paper_wrist}}\n"
    text = text if "stage" in extra else text + "stage: wrist\n"
    with pytest.raises(IdentError, match=match):
        load_run(_write(tmp_path, text + extra, robot=False))


def test_a_run_above_the_time_ceiling_is_refused_before_it_starts(tmp_path, monkeypatch):
    monkeypatch.setenv("IDENT_MAX_HOURS", "0.001")  # 3.6 s
    config = load_run_config(CONFIGS / "wrist.yaml")
    with pytest.raises(ConfigError, match=r"run: .* objective evaluations .*IDENT_MAX_HOURS"):
        load_run(CONFIGS / "wrist.yaml")
    monkeypatch.setenv("IDENT_MAX_HOURS", "1")
    setup = load_run(CONFIGS / "wrist.yaml")
    assert 1.0 < setup.estimate.seconds < 100.0  # measured: about 8 s on 2 cores
    assert config.emupso.n_runs == 5
