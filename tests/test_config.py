import pytest

from ident.config import StrictModel, load_config_file, read_yaml
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


# --- bounded loading of hostile files -------------------------------------------------------


def _write(tmp_path, data):
    path = tmp_path / "c.yaml"
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    return path


def test_alias_bomb_is_refused_fast_and_short(tmp_path):
    rows = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    rows += [
        f"{c}: &{c} [" + ",".join([f"*{p}"] * 9) + "]"
        for p, c in zip("abcdefgh", "bcdefghi", strict=True)
    ]
    path = _write(tmp_path, "\n".join(rows))
    with pytest.raises(ConfigError, match="alias") as info:
        read_yaml(path)
    assert len(str(info.value)) < 300


def test_many_aliases_are_refused(tmp_path):
    path = _write(tmp_path, "a: &a 1\nb: [" + ",".join(["*a"] * 100) + "]\n")
    with pytest.raises(ConfigError, match="aliases"):
        read_yaml(path)


def test_a_few_aliases_and_merge_keys_still_work(tmp_path):
    path = _write(tmp_path, "base: &b {x: 1, y: 2}\nother: {<<: *b, y: 3}\nsame: *b\n")
    assert read_yaml(path) == {
        "base": {"x": 1, "y": 2},
        "other": {"x": 1, "y": 3},
        "same": {"x": 1, "y": 2},
    }


def test_recursive_alias_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="contains it"):
        read_yaml(_write(tmp_path, "a: &a [1, *a]\n"))


@pytest.mark.parametrize(
    "text", ["a: " + "[" * 3000 + "]" * 3000, "a: " + "{b: " * 500 + "1" + "}" * 500]
)
def test_deep_nesting_is_refused(tmp_path, text):
    with pytest.raises(ConfigError, match="nested more than"):
        read_yaml(_write(tmp_path, text))


def test_duplicate_key_names_both_lines(tmp_path):
    with pytest.raises(ConfigError, match=r"key 'order' is given twice \(lines 2 and 4\)"):
        read_yaml(_write(tmp_path, "filter:\n  order: 2\n  cutoff_hz: 3.0\n  order: 4\n"))


@pytest.mark.parametrize("value", [".nan", ".inf", "-.Inf", "1.0e+999"])
def test_non_finite_yaml_numbers_are_refused(tmp_path, value):
    with pytest.raises(ConfigError, match="not a finite number"):
        read_yaml(_write(tmp_path, f"x: {value}\n"))


@pytest.mark.parametrize("value", ["nan", "inf", "-Infinity", "1e400"])
def test_non_finite_strings_in_float_fields_are_refused(tmp_path, value):
    path = _write(tmp_path, f"name: x\nfilter: {{cutoff_hz: {value}}}\n")
    with pytest.raises(ConfigError, match="filter.cutoff_hz"):
        load_config_file(Experiment, path)


def test_binary_and_non_utf8_files_are_one_clear_error(tmp_path):
    with pytest.raises(ConfigError, match="binary file"):
        read_yaml(_write(tmp_path, bytes(range(256))))
    with pytest.raises(ConfigError, match=r"not UTF-8 text \(byte 14, line 2\)"):
        read_yaml(_write(tmp_path, "name: a\nx: caf\xe9\n".encode("latin-1")))


def test_utf8_with_bom_is_read(tmp_path):
    assert read_yaml(_write(tmp_path, "\ufeffname: x\n".encode())) == {"name": "x"}


def test_python_tags_are_refused(tmp_path):
    with pytest.raises(ConfigError, match="malformed YAML"):
        read_yaml(_write(tmp_path, "a: !!python/object/apply:os.system ['true']\n"))


def test_messages_quote_long_values_cut_short(tmp_path):
    path = _write(tmp_path, "name: x\nfilter: {cutoff_hz: [" + ", ".join(["1"] * 5000) + "]}\n")
    with pytest.raises(ConfigError) as info:
        load_config_file(Experiment, path)
    assert len(str(info.value)) < 500
