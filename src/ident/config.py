"""Reading YAML configuration files into validated pydantic models.

Domain modules define their own pydantic models (``extra="forbid"``, frozen); this module
turns YAML and validation failures into one-line :class:`~ident.errors.ConfigError` messages
that name the file, the key path and the fix, and suggest the closest valid key for a typo.

Config files are untrusted input. :func:`read_yaml` reads them with bounds that keep a
hostile file from costing more than a small config does (see ``docs/robustness.md``):

* at most :data:`MAX_CONFIG_BYTES` bytes, decoded as UTF-8 (a binary or otherwise encoded
  file is refused with its byte offset);
* nesting at most :data:`MAX_DEPTH` levels deep;
* at most :data:`MAX_ALIASES` aliases (``*name``) and :data:`MAX_NODES` values once aliases
  are expanded (a "billion laughs" file is refused before anything reads it);
* a key given twice in one mapping is an error naming both lines;
* integers of at most :data:`MAX_INT_DIGITS` digits, floats finite (``.nan`` and ``.inf`` are
  refused: an unset value is ``null``).
"""

from __future__ import annotations

import difflib
import math
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError, model_validator

from ident.errors import ConfigError

__all__ = [
    "MAX_ALIASES",
    "MAX_CONFIG_BYTES",
    "MAX_DEPTH",
    "MAX_INT_DIGITS",
    "MAX_NODES",
    "StrictModel",
    "file_problem",
    "load_config_file",
    "read_text_input",
    "read_yaml",
    "short_repr",
    "validate_config",
]

ModelT = TypeVar("ModelT", bound=BaseModel)

MAX_CONFIG_BYTES = 1 << 20  # 1 MiB: the largest shipped config is a few kB
MAX_DEPTH = 32  # nesting levels; real configs use 4
MAX_ALIASES = 64  # '*name' references in one file
MAX_NODES = 100_000  # values after alias expansion
MAX_INT_DIGITS = 19  # the digits of an int64; counts, seeds and sizes all fit
_MAX_SCALAR_CHARS = 64  # text of one number
_SHORT = 60  # characters of a value quoted in a message

_MERGE_TAG = "tag:yaml.org,2002:merge"
_FLOAT_TAG = "tag:yaml.org,2002:float"


def _takes_bool(annotation: Any) -> bool:
    """Whether a field annotated ``annotation`` takes ``true``/``false`` as such (``bool``,
    ``Any``, a ``Literal`` of them, or a union holding one)."""
    if annotation is bool or annotation is Any:
        return True
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) is typing.Literal:
        return any(isinstance(a, bool) for a in args)
    return any(_takes_bool(a) for a in args if a is not None)


class StrictModel(BaseModel):
    """Base for config sections: unknown keys are errors, instances are immutable.

    Float fields refuse NaN and infinities, also when given as the strings ``nan`` or ``inf``.
    Number fields refuse ``true``/``false`` (pydantic's lax mode reads them as 1 and 0: a
    ``sampling_rate_hz: true`` became a 1 Hz log).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _no_bool_for_a_number(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        for key, value in data.items():
            values = value if isinstance(value, list) else [value]
            field = cls.model_fields.get(key) if isinstance(key, str) else None
            if field is None or not any(isinstance(v, bool) for v in values):
                continue
            if not _takes_bool(field.annotation):
                raise ValueError(
                    f"{key} = {value!r}: a yes/no value where a number or a name is expected"
                )
        return data


def short_repr(value: Any, limit: int = _SHORT) -> str:
    """``repr(value)`` cut to ``limit`` characters, for messages about untrusted values."""
    if isinstance(value, (list, tuple, dict, set)) and len(value) > limit:
        return f"<{type(value).__name__} of {len(value)} items>"
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


class _LimitExceeded(yaml.YAMLError):
    """A bound of the loader was reached; ``mark`` says where."""

    def __init__(self, problem: str, mark: Any = None) -> None:
        super().__init__(problem)
        self.problem = problem
        self.problem_mark = mark


class _BoundedLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` with bounded depth, aliases, expanded size and number size.

    It also rejects duplicated keys. The checks run while the document is composed into
    nodes, before any Python object is built.
    """

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0
        self._aliases = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                raise _LimitExceeded(
                    f"more than {MAX_ALIASES} aliases (*name); write the values out",
                    self.peek_event().start_mark,
                )
        self._depth += 1
        if self._depth > MAX_DEPTH:
            raise _LimitExceeded(
                f"nested more than {MAX_DEPTH} levels deep", self.peek_event().start_mark
            )
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def compose_mapping_node(self, anchor: Any) -> Any:
        node = super().compose_mapping_node(anchor)
        seen: dict[tuple[str, str], int] = {}
        for key_node, _ in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == _MERGE_TAG:
                continue
            key = (key_node.tag, key_node.value)
            line = key_node.start_mark.line + 1
            if key in seen:
                raise _LimitExceeded(
                    f"key {short_repr(key_node.value)} is given twice (lines {seen[key]} "
                    f"and {line}); keep one",
                    key_node.start_mark,
                )
            seen[key] = line
        return node

    def construct_yaml_int(self, node: Any) -> int:
        text = str(node.value).replace("_", "")
        digits = text.lstrip("+-")
        if len(text) > _MAX_SCALAR_CHARS or (
            digits.isdigit() and len(digits.lstrip("0")) > MAX_INT_DIGITS
        ):
            raise _LimitExceeded(
                f"integer {short_repr(node.value, 24)} has more than {MAX_INT_DIGITS} digits",
                node.start_mark,
            )
        value = super().construct_yaml_int(node)
        if abs(value) >= 2**63:
            raise _LimitExceeded(
                f"integer {short_repr(node.value, 24)} does not fit in 64 bits", node.start_mark
            )
        return value

    def construct_yaml_float(self, node: Any) -> float:
        if len(str(node.value)) > _MAX_SCALAR_CHARS:
            raise _LimitExceeded(
                f"number {short_repr(node.value, 24)} is longer than {_MAX_SCALAR_CHARS} "
                "characters",
                node.start_mark,
            )
        return float(super().construct_yaml_float(node))

    def get_single_node(self) -> Any:
        node = super().get_single_node()
        if node is not None:
            _check_tree(self, node)
        return node


_BoundedLoader.add_constructor("tag:yaml.org,2002:int", _BoundedLoader.construct_yaml_int)
_BoundedLoader.add_constructor("tag:yaml.org,2002:float", _BoundedLoader.construct_yaml_float)


def _check_tree(loader: _BoundedLoader, root: Any) -> None:
    """Walk the composed nodes once: expanded size, recursion, non-finite floats.

    A node reached through an alias is counted again (its expanded size), but walked once.
    Non-finite floats (``.nan``, ``.inf``, ``1.0e999``) are refused with their key path.
    """
    sizes: dict[int, int] = {}
    active: set[int] = set()

    def size(node: Any, where: str) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in active:
            raise _LimitExceeded("an alias refers to a value that contains it", node.start_mark)
        active.add(key)
        total = 1
        if isinstance(node, yaml.SequenceNode):
            total += sum(size(child, f"{where}[{k}]") for k, child in enumerate(node.value))
        elif isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                label = str(k.value) if isinstance(k, yaml.ScalarNode) else "?"
                total += size(k, where) + size(v, f"{where}.{label}" if where else label)
        elif node.tag == _FLOAT_TAG and len(str(node.value)) <= _MAX_SCALAR_CHARS:
            value = yaml.SafeLoader.construct_yaml_float(loader, node)
            if not math.isfinite(value):
                raise _LimitExceeded(
                    f"{short_repr(where or '<top level>', 80)[1:-1]} = "
                    f"{short_repr(node.value, 24)} is not a finite number; give a finite "
                    "value (or null for an unset one)",
                    node.start_mark,
                )
        active.discard(key)
        if total > MAX_NODES:
            raise _LimitExceeded(
                f"more than {MAX_NODES} values once aliases are expanded", node.start_mark
            )
        sizes[key] = total
        return total

    size(root, "")


def file_problem(path: str | Path) -> str | None:
    """Why ``path`` is no input file (``"not found"``, ``"is a folder"``, ``"is not a regular
    file ..."``: a device such as /dev/zero, a FIFO, a socket), or None for a regular file.
    Such a file is refused before it is opened: reading it could block or never end."""
    path = Path(path)
    if path.is_file():
        return None
    if path.is_dir():
        return "is a folder"
    if not path.exists():
        return "not found"
    return "is not a regular file (a device, a FIFO or a socket)"


def read_text_input(path: str | Path, *, what: str = "file", max_bytes: int | None = None) -> str:
    """Read a UTF-8 text input file (a config, a CSV, a URDF) with one clear error.

    Parameters
    ----------
    path :
        The file.
    what :
        What the file is, for messages (``"config file"``, ``"trajectory"``).
    max_bytes :
        Refuse larger files (``None``: no limit).

    Raises
    ------
    ConfigError
        If the file is missing, not a regular file, unreadable, larger than ``max_bytes``,
        binary (holds NUL bytes) or not UTF-8 (the message gives the byte offset).
    """
    path = Path(path)
    problem = file_problem(path)
    if problem is not None:
        raise ConfigError(f"{path}: {what} {problem}; check the path.")
    try:
        with path.open("rb") as f:
            data = f.read() if max_bytes is None else f.read(max_bytes + 1)
    except OSError as e:
        raise ConfigError(f"{path}: cannot read the {what} ({e.strerror}).") from e
    if max_bytes is not None and len(data) > max_bytes:
        raise ConfigError(
            f"{path}: {what} is larger than {max_bytes // 1024} KiB; is it the right file?"
        )
    if b"\x00" in data:
        raise ConfigError(f"{path}: {what} is a binary file (NUL bytes), not UTF-8 text.")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        raise ConfigError(
            f"{path}: {what} is not UTF-8 text (byte {e.start}, line {line}); save it as UTF-8."
        ) from e


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML file whose top level is a mapping, within the bounds of this module.

    Raises
    ------
    ConfigError
        If the file is missing, not UTF-8, too large, not valid YAML, beyond a bound (depth,
        aliases, expanded size, number size), has a duplicated key, or its top level is not a
        mapping.
    """
    path = Path(path)
    text = read_text_input(path, what="config file", max_bytes=MAX_CONFIG_BYTES)
    try:
        loader = _BoundedLoader(text)
        try:
            data = loader.get_single_data()
        finally:
            loader.dispose()
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        if isinstance(e, _LimitExceeded):
            at = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
            raise ConfigError(f"{path}: {problem}{at}.") from e
        raise ConfigError(f"{path}: malformed YAML{where}: {problem}; fix the syntax.") from e
    except RecursionError as e:  # pragma: no cover - the depth bound comes first
        raise ConfigError(f"{path}: nested too deeply.") from e
    if not isinstance(data, Mapping):
        raise ConfigError(
            f"{path}: the top level must be a mapping of sections (key: value), "
            f"got {type(data).__name__}."
        )
    return dict(data)


def _location(loc: tuple[int | str, ...]) -> str:
    parts: list[str] = []
    for item in loc:
        if isinstance(item, int):
            parts.append(f"[{item}]")
        else:
            parts.append(("." if parts else "") + str(item))
    return "".join(parts) or "<top level>"


def _allowed_keys(model: type[BaseModel], loc: tuple[int | str, ...]) -> list[str]:
    """Field names valid at the parent of ``loc`` (best effort, for suggestions)."""
    current: Any = model
    for item in loc[:-1]:
        if isinstance(item, int):
            continue
        fields = getattr(current, "model_fields", None)
        if not fields or item not in fields:
            return []
        annotation = fields[item].annotation
        current = _unwrap_model(annotation)
        if current is None:
            return []
    fields = getattr(current, "model_fields", None)
    return sorted(fields) if fields else []


def _unwrap_model(annotation: Any) -> type[BaseModel] | None:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in getattr(annotation, "__args__", ()) or ():
        found = _unwrap_model(arg)
        if found is not None:
            return found
    return None


def validate_config(model: type[ModelT], data: Mapping[str, Any], source: str | Path) -> ModelT:
    """Validate ``data`` against ``model``; report the first problems as one message.

    Parameters
    ----------
    model :
        The pydantic model class of the config.
    data :
        Raw mapping, usually from :func:`read_yaml`.
    source :
        File name used in messages.

    Raises
    ------
    ConfigError
        Naming the file, the dotted key path, what is wrong and, for unknown keys,
        the closest valid key.
    """
    try:
        return model.model_validate(data)
    except ValidationError as e:
        messages = []
        for err in e.errors()[:3]:
            loc = tuple(err["loc"])
            where = _location(loc)
            if len(where) > 2 * _SHORT:
                where = where[: 2 * _SHORT - 3] + "..."
            if err["type"] == "extra_forbidden":
                allowed = _allowed_keys(model, loc)
                close = difflib.get_close_matches(str(loc[-1])[:100], allowed, n=1)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                valid = f" Valid keys: {', '.join(allowed)}." if allowed else ""
                messages.append(f"unknown key '{where}'{hint}{valid}")
            elif err["type"] == "finite_number":
                # name the field, not the element: "links[1].com", as hand-written checks do
                field = loc
                while field and isinstance(field[-1], int):
                    field = field[:-1]
                messages.append(
                    f"{_location(field)}: values are not finite ({short_repr(err.get('input'))}); "
                    "give finite numbers"
                )
            elif err["type"] == "missing":
                teach = getattr(model, "missing_key_hint", None)  # a working example
                text = teach(where) if callable(teach) else "add it"
                messages.append(f"missing required key '{where}'; {text}")
            else:
                msg = str(err["msg"]).replace("Value error, ", "")
                if len(msg) > 400:
                    msg = msg[:397] + "..."
                messages.append(f"'{where}' = {short_repr(err.get('input'))}: {msg}")
        more = f" (+{len(e.errors()) - 3} more)" if len(e.errors()) > 3 else ""
        raise ConfigError(f"{source}: " + "; ".join(messages) + more) from e


def load_config_file(model: type[ModelT], path: str | Path) -> ModelT:
    """Read and validate a YAML config file in one step."""
    return validate_config(model, read_yaml(path), path)
