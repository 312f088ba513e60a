import pytest

from ident.config import StrictModel, load_config_file
from ident.errors import ConfigError


class Filter(StrictModel):
    cutoff_hz: float
    order: int = 4


class Experiment(StrictModel):
    name: str
    filter: Filter


def test_unknown_key_suggests_closest(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("name: x\nfilter: {cutof_hz: 3.0}\n")
    with pytest.raises(ConfigError) as info:
        load_config_file(Experiment, path)
    message = str(info.value)
    assert str(path) in message
    assert "filter.cutof_hz" in message
    assert "did you mean 'cutoff_hz'" in message


def test_malformed_yaml_names_line(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("name: x\nfilter: {cutoff_hz: [1,\n")
    with pytest.raises(ConfigError, match=r"malformed YAML at line"):
        load_config_file(Experiment, path)


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_config_file(Experiment, tmp_path / "nope.yaml")


def test_valid_file_loads(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("name: x\nfilter: {cutoff_hz: 3.0}\n")
    config = load_config_file(Experiment, path)
    assert config.filter.cutoff_hz == 3.0
    assert config.filter.order == 4
