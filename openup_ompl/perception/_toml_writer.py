"""A TOML writer for scene files (tables, arrays of tables, strings, numbers, booleans and
arrays of them): what ``perceived.toml`` needs, read back by ``tomllib``."""

from __future__ import annotations

import json
import math
from typing import Any

from openup_ompl.exceptions import ConfigError

__all__ = ["dumps"]


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ConfigError("TOML value", value, "a finite number")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a JSON string is a TOML basic string
    if isinstance(value, list):
        return "[" + ", ".join(_value(x) for x in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_value(v)}" for k, v in value.items()) + "}"
    raise ConfigError("TOML value", value, "a string, number, boolean, array or table")


def _is_table_array(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(x, dict) for x in value)


def dumps(document: dict[str, Any]) -> str:
    """The document as TOML text: plain keys first, then tables, then arrays of tables."""
    lines = [f"{k} = {_value(v)}" for k, v in document.items() if not _nested(v)]
    for key, value in document.items():
        if isinstance(value, dict):
            lines += ["", f"[{key}]", *(f"{k} = {_value(v)}" for k, v in value.items())]
    for key, value in document.items():
        if _is_table_array(value):
            for table in value:
                lines += ["", f"[[{key}]]", *(f"{k} = {_value(v)}" for k, v in table.items())]
    return "\n".join(lines) + "\n"


def _nested(value: Any) -> bool:
    return isinstance(value, dict) or _is_table_array(value)
