"""Property tests: whatever a config file holds, loading it ends in a dict or a ConfigError."""

import math
import string

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ident.bench.campaign import CampaignConfig
from ident.config import MAX_INT_DIGITS, read_yaml, validate_config
from ident.errors import ConfigError
from ident.inputs import check_number, safe_component
from ident.run.config import RunConfig

FAST = settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=20),
)
structures = st.recursive(
    scalars,
    lambda children: st.one_of(
        st.lists(children, max_size=5),
        st.dictionaries(st.text(string.ascii_lowercase + "_.", max_size=12), children, max_size=5),
    ),
    max_leaves=40,
)
yaml_alphabet = string.printable + "&*!|>{}[]:-#'\"\t\x00\x85\ufeff"


@FAST
@given(text=st.text(alphabet=yaml_alphabet, max_size=300))
def test_any_text_reads_as_mapping_or_config_error(tmp_path, text):
    path = tmp_path / "c.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        data = read_yaml(path)
    except ConfigError as e:
        message = str(e)
    else:
        assert isinstance(data, dict)
        return
    assert message.startswith(str(path))


@FAST
@given(data=st.binary(max_size=300))
def test_any_bytes_read_as_mapping_or_config_error(tmp_path, data):
    path = tmp_path / "c.yaml"
    path.write_bytes(data)
    try:
        assert isinstance(read_yaml(path), dict)
    except ConfigError:
        pass


@FAST
@given(section=st.dictionaries(st.sampled_from(sorted(RunConfig.model_fields)), structures))
def test_random_run_config_is_valid_or_config_error(tmp_path, section):
    path = tmp_path / "run.yaml"
    try:
        text = yaml.safe_dump(section)
    except yaml.YAMLError:
        return
    path.write_text(text)
    try:
        validate_config(RunConfig, read_yaml(path), path)
    except ConfigError as e:
        message = str(e)
    else:
        return
    assert len(message) < 3000  # values are quoted cut short, never expanded


@FAST
@given(section=st.dictionaries(st.sampled_from(sorted(CampaignConfig.model_fields)), structures))
def test_random_campaign_config_is_valid_or_config_error(section):
    try:
        cfg = validate_config(CampaignConfig, section, "bench.yaml")
    except ConfigError:
        return
    assert "/" not in cfg.name
    assert not cfg.name.startswith(".")


@FAST
@given(value=st.one_of(scalars, st.lists(scalars, max_size=2)))
def test_check_number_accepts_only_finite_numbers_in_range(value):
    try:
        out = check_number(value, "--x", low=0.0, high=10.0)
    except ConfigError:
        return
    assert not isinstance(out, bool)
    assert math.isfinite(out)
    assert 0.0 <= out <= 10.0


@FAST
@given(name=st.text(max_size=200))
def test_safe_component_is_one_harmless_path_component(name):
    part = safe_component(name)
    assert part
    assert "/" not in part
    assert "\\" not in part
    assert part not in (".", "..")
    assert not part.startswith(".")
    assert len(part) <= 80


@pytest.mark.parametrize("digits", [MAX_INT_DIGITS + 1, 400, 5000])
def test_long_integers_are_refused(tmp_path, digits):
    path = tmp_path / "c.yaml"
    path.write_text(f"seed: {'9' * digits}\n")
    with pytest.raises(ConfigError, match="more than 19 digits"):
        read_yaml(path)
