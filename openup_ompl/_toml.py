"""Typed readers for values in TOML tables: each bad value raises :class:`ConfigError`."""

from __future__ import annotations

import difflib
import math
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl._io import read_bytes
from openup_ompl.exceptions import ConfigError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


def read_toml(path: Path, what: str) -> dict[str, Any]:
    """Parse a TOML file, turning syntax and I/O errors into :class:`ConfigError`; a file
    that is not a regular one, or larger than :data:`~openup_ompl._io.MAX_FILE_BYTES`, is
    refused unread (:func:`~openup_ompl._io.read_bytes`)."""
    try:
        return tomllib.loads(read_bytes(path, what).decode("utf-8"))
    except FileNotFoundError:
        raise ConfigError(what, str(path), "an existing TOML file") from None
    except (OSError, UnicodeDecodeError, RecursionError, tomllib.TOMLDecodeError) as error:
        raise ConfigError(what, str(path), f"a readable TOML file ({error})") from None


def unknown_key(where: str, key: str, value: Any, known: Iterable[str]) -> ConfigError:
    """The error for an unknown ``key`` of the table at ``where``: it names the key, the
    nearest valid one (a likely typo) and every valid one."""
    known = sorted(known)
    near = difflib.get_close_matches(key, known, n=1)
    hint = f"did you mean {near[0]!r}? " if near else ""
    prefix = f"{where}." if where and not where.endswith(": ") else where
    return ConfigError(f"{prefix}{key}", value, f"a known key ({hint}one of {known})")


def check_keys(table: Mapping[str, Any], known: Iterable[str], where: str) -> None:
    """Reject a table holding a key outside ``known`` (see :func:`unknown_key`)."""
    known = set(known)
    unknown = sorted(set(table) - known)
    if unknown:
        raise unknown_key(where, unknown[0], table[unknown[0]], known)


def require(table: Mapping[str, Any], key: str, where: str) -> Any:
    """The value at ``key``, or a :class:`ConfigError` saying it is missing, located at
    ``where.key`` (``file.toml: key`` when ``where`` is a file's name)."""
    if key not in table:
        top = where.endswith((".toml", ".json"))
        raise ConfigError(
            f"{where}{': ' if top else '.'}{key}", None, "a value (the key is missing)"
        )
    return table[key]


def string(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise ConfigError(where, value, "a non-empty string")
    return value


def is_number(value: Any) -> bool:
    """Whether ``value`` is a real number, Python's or numpy's (a bool is not)."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_)
    )


def is_finite(value: Any) -> bool:
    """Whether ``value`` is a finite real number, Python's or numpy's (a bool is not)."""
    return is_number(value) and math.isfinite(value)


def is_integer(value: Any) -> bool:
    """Whether ``value`` is an integer, Python's or numpy's (a bool is not)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def number(value: Any, where: str, *, low: float | None = None, high: float | None = None) -> float:
    """A finite float, optionally within ``[low, high]``."""
    ok = is_number(value)
    if ok:
        value = float(value)
        ok = (
            math.isfinite(value)
            and (low is None or value >= low)
            and (high is None or value <= high)
        )
    if not ok:
        if low is not None and high is not None:
            span = f" in [{low}, {high}]"
        elif low is not None:
            span = f" >= {low}"
        else:
            span = "" if high is None else f" <= {high}"
        raise ConfigError(where, value, f"a finite number{span}")
    return float(value)


def floats(value: Any) -> np.ndarray | None:
    """``value`` as an array of floats (a copy), or ``None`` when it is not numbers (a
    string, ``None``, a ragged list): the caller then names the value as given."""
    if isinstance(value, (str, bytes)):
        return None
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError):
        return None


def shown(value: Any) -> Any:
    """``value`` as an error message shows it: a numpy array as a list, not its repr."""
    return value.tolist() if isinstance(value, np.ndarray) else value


def vector(value: Any, where: str, length: int | None = None) -> np.ndarray:
    """A list of finite numbers (a tuple or a numpy array too, for values given in
    code), optionally of a given length."""
    value = shown(value)
    if isinstance(value, tuple):
        value = list(value)
    ok = isinstance(value, list) and all(is_number(x) for x in value)
    if ok:
        array = np.array(value, dtype=float)
        ok = bool(np.all(np.isfinite(array))) and (length is None or array.size == length)
    if not ok:
        size = f"{length} " if length is not None else ""
        raise ConfigError(where, value, f"a list of {size}finite numbers")
    return array


def string_list(value: Any, where: str) -> list[str]:
    if not (isinstance(value, list) and value and all(isinstance(x, str) and x for x in value)):
        raise ConfigError(where, value, "a non-empty list of names")
    if len(set(value)) != len(value):
        raise ConfigError(where, value, "a list of distinct names")
    return list(value)


#: The largest position coordinate or shape dimension accepted [m]. Coal's mesh checks
#: lose their precision long before a float overflows (a 1e12 m box far from the robot is
#: found touching every link), and nothing a robot reaches needs more than a kilometre.
MAX_EXTENT = 1e3


def pose(value: Any, where: str) -> np.ndarray:
    """A pose ``[x, y, z, qx, qy, qz, qw]`` with a unit quaternion (tolerance 1e-3) and a
    position within :data:`MAX_EXTENT` of the origin along each axis."""
    array = vector(value, where, 7)
    if np.any(np.abs(array[:3]) > MAX_EXTENT):
        raise ConfigError(
            where, value, f"[x, y, z, qx, qy, qz, qw] with |x|, |y|, |z| <= {MAX_EXTENT:g} m"
        )
    if np.any(np.abs(array[3:]) > 1.0 + 1e-3):  # not unit; its norm may overflow
        raise ConfigError(
            where, value, "[x, y, z, qx, qy, qz, qw] with a unit quaternion (|qx|, ... <= 1)"
        )
    norm = float(np.linalg.norm(array[3:]))
    if abs(norm - 1.0) > 1e-3:
        raise ConfigError(
            where, value, f"[x, y, z, qx, qy, qz, qw] with a unit quaternion (norm is {norm:.6g})"
        )
    array[3:] /= norm
    return array
