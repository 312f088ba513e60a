"""Reading YAML configuration files into validated pydantic models.

Domain modules define their own pydantic models (``extra="forbid"``, frozen); this module
turns YAML and validation failures into one-line :class:`~ident.errors.ConfigError` messages
that name the file, the key path and the fix, and suggest the closest valid key for a typo.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from ident.errors import ConfigError

__all__ = ["StrictModel", "load_config_file", "read_yaml", "validate_config"]

ModelT = TypeVar("ModelT", bound=BaseModel)


class StrictModel(BaseModel):
    """Base for config sections: unknown keys are errors, instances are immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True)


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML file whose top level is a mapping.

    Raises
    ------
    ConfigError
        If the file is missing, is not valid YAML, or its top level is not a mapping.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: config file not found; check the path.")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise ConfigError(f"{path}: malformed YAML{where}: {problem}; fix the syntax.") from e
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
            if err["type"] == "extra_forbidden":
                allowed = _allowed_keys(model, loc)
                close = difflib.get_close_matches(str(loc[-1]), allowed, n=1)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                valid = f" Valid keys: {', '.join(allowed)}." if allowed else ""
                messages.append(f"unknown key '{where}'{hint}{valid}")
            elif err["type"] == "missing":
                messages.append(f"missing required key '{where}'; add it")
            else:
                messages.append(
                    f"'{where}' = {err.get('input')!r}: {err['msg']}".replace("Value error, ", "")
                )
        more = f" (+{len(e.errors()) - 3} more)" if len(e.errors()) > 3 else ""
        raise ConfigError(f"{source}: " + "; ".join(messages) + more) from e


def load_config_file(model: type[ModelT], path: str | Path) -> ModelT:
    """Read and validate a YAML config file in one step."""
    return validate_config(model, read_yaml(path), path)
